// SolverProcess and SignalGuard with real child processes (/bin/sh, /bin/sleep).
#include <catch2/catch.hpp>

#include <csignal>

#include "launch/supervisor.hpp"

using namespace demfem::coupling;
using namespace std::chrono_literals;

TEST_CASE("a child's exit code is reported") {
  SolverProcess p("test child", "/bin/sh", {"-c", "exit 7"});
  REQUIRE(p.start() > 0);
  CHECK(p.wait_for(5000ms) == 7);
  CHECK_FALSE(p.running());
}

TEST_CASE("stop() escalates to SIGTERM for a child that does not end") {
  SolverProcess p("sleeper", "/bin/sleep", {"30"});
  p.start();
  CHECK(p.running());
  CHECK(p.stop(100ms) == 128 + SIGTERM);
  CHECK_FALSE(p.running());
}

TEST_CASE("a missing executable is named") {
  SolverProcess p("DEM solver", "/nonexistent/dem_server", {});
  CHECK_THROWS_WITH(p.start(),
                    Catch::Contains("/nonexistent/dem_server") && Catch::Contains("DEM solver"));
}

TEST_CASE("SIGTERM to the coupler sets the stop flag and is forwarded to the children") {
  SignalGuard guard;
  SolverProcess p("sleeper", "/bin/sleep", {"30"});
  p.start();
  CHECK_FALSE(SignalGuard::stop_flag().load());
  std::raise(SIGTERM);
  CHECK(SignalGuard::stop_flag().load());
  CHECK(SignalGuard::signal_number() == SIGTERM);
  CHECK(p.wait_for(5000ms) == 128 + SIGTERM);  // ended by the forwarded signal
}
