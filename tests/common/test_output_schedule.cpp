#include <catch2/catch.hpp>

#include <cmath>
#include <cstdint>
#include <vector>

#include "demfem/io/output_schedule.hpp"

using demfem::io::decimal_time;
using demfem::io::format_time;
using demfem::io::OutputSchedule;

TEST_CASE("output times are the requested decimals, not products carrying rounding",
          "[output_schedule]") {
  CHECK(3 * 0.1 != 0.3);  // why the rounding exists
  CHECK(decimal_time(3 * 0.1) == 0.3);
  CHECK(decimal_time(2500 * 2e-6) == 0.005);
  CHECK(decimal_time(21 * 1e-4) == decimal_time(1050 * 2e-6));  // FEM and DEM clocks agree
  CHECK(decimal_time(0.0) == 0.0);
  OutputSchedule s(0.1);
  CHECK(s.nominal(3) == 0.3);
  CHECK(s.nominal(7) == 0.7);
  CHECK(format_time(0.3) == "0.3");
  CHECK(format_time(0.0005) == "0.0005");
  CHECK(format_time(0.0) == "0");
}

TEST_CASE("a commensurate interval is taken at the step that reaches it, labelled exactly",
          "[output_schedule]") {
  // dem.dt = 2e-6, output every 5e-4 s (250 steps): the running sum of dt reaches
  // 0.0004999999999999991 at step 250, the product 250 * 2e-6 is what the solver passes.
  const double dt = 2e-6;
  OutputSchedule s(5e-4);
  std::vector<std::int64_t> steps;
  std::vector<double> labels;
  CHECK(s.take(0.0, dt) == 0.0);  // the initial state is output 0
  for (std::int64_t n = 1; n <= 1000; ++n) {
    const double t = static_cast<double>(n) * dt;
    if (s.due(t, dt)) {
      steps.push_back(n);
      labels.push_back(s.take(t, dt));
    }
  }
  CHECK(steps == std::vector<std::int64_t>{250, 500, 750, 1000});
  CHECK(labels == std::vector<double>{0.0005, 0.001, 0.0015, 0.002});
  CHECK(s.next() == 5);
}

TEST_CASE("an incommensurate interval takes the nearest step end, ties to the later one",
          "[output_schedule]") {
  const double step = 1e-4;  // a coupling step
  OutputSchedule s(0.00105);
  s.take(0.0, step);
  std::vector<std::int64_t> at;
  std::vector<double> labels;
  for (std::int64_t n = 1; n <= 40; ++n) {
    const double t = static_cast<double>(n) * step;
    if (s.due(t, step)) {
      at.push_back(n);
      labels.push_back(s.take(t, step));
    }
  }
  // 0.00105 lies half way between steps 10 and 11 (tie: 11); 0.0021 is step 21; 0.00315 ties
  // again (32); |state time - label| <= step / 2 throughout.
  CHECK(at == std::vector<std::int64_t>{11, 21, 32});
  CHECK(labels == std::vector<double>{0.00105, 0.0021, 0.00315});
  for (std::size_t i = 0; i < at.size(); ++i) {
    CHECK(std::abs(static_cast<double>(at[i]) * step - labels[i]) <= 0.5 * step * (1 + 1e-9));
  }
}

TEST_CASE("outputs shorter than a step: one snapshot per step, labelled with the latest",
          "[output_schedule]") {
  OutputSchedule s(1e-5);
  s.take(0.0, 1e-4);
  CHECK(s.due(1e-4, 1e-4));
  // The window of the state at 1e-4 is [0.5e-4, 1.5e-4): outputs 1..14 all fall to it.
  CHECK(s.take(1e-4, 1e-4) == decimal_time(14 * 1e-5));
  CHECK(s.next() == 15);
  CHECK_FALSE(s.due(1e-4, 1e-4));
}

TEST_CASE("labels of unscheduled states and resuming", "[output_schedule]") {
  OutputSchedule s(0.1);
  CHECK(s.label(0.05, 1e-3) == 0.05);          // a settled start between outputs
  CHECK(s.label(0.2999999999, 1e-3) == 0.3);   // within half a step of 0.3
  CHECK(s.label(25000 * 2e-6, 2e-6) == 0.05);  // an end state, decimal
  OutputSchedule none;
  CHECK_FALSE(none.active());
  CHECK_FALSE(none.due(1.0, 1e-3));
  CHECK(none.label(3 * 0.1, 1e-3) == 0.3);
  s.skip_to_after(0.3);
  CHECK(s.next() == 4);
  s.skip_to_after(0.29);
  CHECK(s.next() == 3);
  s.skip_to_after(0.0);
  CHECK(s.next() == 1);
}

TEST_CASE("an interval below the resolution of the times: every step, labelled with its time",
          "[output_schedule]") {
  // Issue 19 (QA): run.output_interval = 1e-300 hung the run in take() (neighbouring nominal
  // times are equal, the index saturates, and the correction loops never ended).
  for (const double interval : {1e-300, 1e-20}) {
    INFO("interval " << interval);
    OutputSchedule s(interval);
    s.take(0.0, 1e-4);
    for (int i = 1; i <= 3; ++i) {
      const double t = i * 1e-4;
      REQUIRE(s.due(t, 1e-4));
      const double label = s.take(t, 1e-4);
      CHECK(std::abs(label - t) <= 0.5e-4);
    }
    s.skip_to_after(0.5);  // returns
  }
}
