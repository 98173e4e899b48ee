#include <catch2/catch.hpp>

#include "launch/progress.hpp"

TEST_CASE("progress line: time, percentage, rate and ETA") {
  // 50 of 100 steps in 10 s: 5 steps/s, 50 left -> 10 s.
  const auto l = demfem::coupling::Progress::line(49, 100, 0.05, 0.1, 10.0);
  CHECK_THAT(l, Catch::Contains("t = 0.05 s / 0.1 s") && Catch::Contains("50.0 %") &&
                    Catch::Contains("5 steps/s") && Catch::Contains("ETA 0:00:10"));
}
