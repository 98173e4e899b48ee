// The launcher's parts that need no process (coupler/src/launch/): --debug-kill's parsing and
// the exit-status map of the exceptions that end a run (exit_map.hpp), against the codes of
// demfem/interface/exit_status.hpp. The runs themselves are tested in tests/system and
// tests/reliability.

#include <catch2/catch.hpp>
#include <csignal>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "demfem/interface/exit_status.hpp"
#include "demfem/scene/scene_reader.hpp"
#include "launch/debug_kill.hpp"
#include "launch/exit_map.hpp"

using namespace demfem;
using namespace demfem::coupling;
using namespace demfem::coupling::launch;

TEST_CASE("launch: --debug-kill forms", "[launch]") {
  CHECK_FALSE(parse_debug_kill("").has_value());
  const auto dem = parse_debug_kill("dem:17");
  REQUIRE(dem);
  CHECK(dem->role == "dem");
  CHECK(dem->step == 17);
  CHECK_FALSE(dem->always);
  CHECK(parse_debug_kill("fem:5:always")->always);
  CHECK(parse_debug_kill("coupler:0:stop")->stop);
  CHECK(parse_debug_kill("job:12:usr2")->job_signal == SIGUSR2);
  CHECK(parse_debug_kill("job:3:usr1")->job_signal == SIGUSR1);
  for (const char* bad : {"dem", "dem:", "dem:-1", "dem:1x", "solver:3", "job:3", "dem:3:usr1",
                          "fem:2:never", "dem:x"}) {
    INFO(bad);
    CHECK_THROWS(parse_debug_kill(bad));
  }
}

namespace {

struct Ended {
  int code;
  std::string reason;
  bool folder_lost;
  bool given_up;
};

// The outcome of a run that `error` ended, with no solver process (as in process).
template <class Error>
Ended end_with(const Error& error) {
  LaunchOptions opt;
  CheckedRun run;
  RunSolvers solvers(opt, run);
  Progress progress(stdout, false, true);
  RunOutcome outcome(progress);
  fail_with_exit_status(std::make_exception_ptr(error), solvers, "out", 300.0, outcome);
  return {outcome.code, outcome.reason, outcome.folder_lost, outcome.given_up.has_value()};
}

}  // namespace

TEST_CASE("launch: each way a run ends has its exit status", "[launch]") {
  using protocol::ErrorKind;
  using protocol::Role;
  CHECK(end_with(BlowUp(4, 0.1, "drift", 2.0, 1.0, "drift blew up")).code == kExitBlowUp);
  const Ended exhausted =
      end_with(RecoveryExhausted(Role::dem, 7, 0.2, "dem kept dying", true, ErrorKind::failure));
  CHECK(exhausted.code == kExitRecoveryExhausted);
  CHECK(exhausted.given_up);
  CHECK(end_with(SolverFailure(Role::fem, 1, 0.0, "mechanism", false, ErrorKind::bad_input)).code ==
        kExitBadInput);
  CHECK(end_with(SolverFailure(Role::fem, 1, 0.0, "x", false, ErrorKind::blow_up)).code ==
        kExitBlowUp);
  // An unclassified error whose text reports a blow-up is one; any other is a failure.
  CHECK(end_with(SolverFailure(Role::dem, 1, 0.0, "velocity is not finite")).code == kExitBlowUp);
  const Ended died = end_with(SolverFailure(Role::dem, 1, 0.0, "gone", true));
  CHECK(died.code == kExitFailed);
  CHECK(died.given_up);
  CHECK(died.reason == "gone\n  output so far is in out");
  const Ended lost = end_with(OutputFolderLost("lock removed"));
  CHECK(lost.code == kExitFailed);
  CHECK(lost.folder_lost);
  CHECK(end_with(ResumeRefused("changed mesh")).code == kExitBadInput);
  CHECK(end_with(InterfaceMismatch("12 nodes, not 10")).code == kExitBadInput);
  CHECK(end_with(HandshakeFailed(Role::fem, "refused")).code == kExitFailed);
  const Ended scene = end_with(scene::SceneError("a.toml:3: key"));
  CHECK(scene.code == kExitBadInput);
  CHECK(scene.reason == "scene error: a.toml:3: key");
  CHECK(end_with(protocol::PeerDied(Role::dem, "no Hello")).code == kExitFailed);
  CHECK(end_with(protocol::BackendError(ErrorKind::bad_input, "model")).code == kExitBadInput);
  CHECK(end_with(protocol::BackendError(ErrorKind::blow_up, "nan")).code == kExitBlowUp);
  CHECK(end_with(protocol::BackendError(ErrorKind::failure, "io")).code == kExitFailed);
  CHECK(end_with(std::runtime_error("disk full")).code == kExitFailed);
}
