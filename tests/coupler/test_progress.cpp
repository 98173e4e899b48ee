#include <catch2/catch.hpp>

#include "launch/progress.hpp"

TEST_CASE("progress line: time, percentage, rate and ETA") {
  // 50 of 100 steps in 10 s: 5 steps/s, 50 left -> 10 s.
  const auto l = demfem::coupling::Progress::line(49, 100, 0.05, 0.1, 10.0);
  CHECK_THAT(l, Catch::Contains("t = 0.05 s / 0.1 s") && Catch::Contains("50.0 %") &&
                    Catch::Contains("5 steps/s") && Catch::Contains("ETA 0:00:10"));
}

TEST_CASE("progress line of a resumed run: the rate counts this session's steps only") {
  // Resumed at step 900 of 1000: steps 900..949 (50 steps) in 10 s are 5 steps/s, and the 50
  // left take 10 s. Counting the 900 steps of earlier sessions would say 95 steps/s, ETA 0:00:01.
  const auto l = demfem::coupling::Progress::line(949, 1000, 0.949, 1.0, 10.0, 900);
  CHECK_THAT(l, Catch::Contains("95.0 %") && Catch::Contains(" 5 steps/s") &&
                    Catch::Contains("ETA 0:00:10"));
}
