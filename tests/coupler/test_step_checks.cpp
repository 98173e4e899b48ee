// The coupling run's parts that are plain functions of their input: the per-step blow-up checks
// (step_checks.hpp: which quantity stops the run, with what message), the interface work and
// drift every scheme accounts with (schemes/coupling_scheme.hpp), and the dataset names of the
// schemes' history in a checkpoint (schemes/scheme_state.hpp), which checkpoints written by
// earlier versions hold under these names.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "schemes/coupling_scheme.hpp"
#include "schemes/scheme_state.hpp"
#include "step_checks.hpp"

using namespace demfem::coupling;

namespace {

// Two interface nodes at rest at the reference, no forces.
SchemeState two_nodes() {
  return SchemeState({0.0, 0.0, 0.0, 1.0, 0.0, 0.0});
}

StepDiagnostics step_seven() {
  StepDiagnostics d;
  d.step = 7;
  d.time = 8e-4;
  return d;
}

}  // namespace

TEST_CASE("step checks: a step within every bound passes", "[coupling][checks]") {
  CouplingSettings s;
  s.scheme = Scheme::just_in_time;
  s.max_overlap = 1e-3;
  s.max_energy_error = 1.0;
  SchemeState st = two_nodes();
  StepDiagnostics d = step_seven();
  d.max_overlap = 5e-4;
  d.energy_error = -0.5;
  CHECK_FALSE(blow_up_of(d, st, s).has_value());
}

TEST_CASE("step checks: a non-finite interface force names the node and component",
          "[coupling][checks]") {
  CouplingSettings s;
  SchemeState st = two_nodes();
  st.dem_force[4] = std::numeric_limits<double>::quiet_NaN();  // node 1, component y
  const auto b = blow_up_of(step_seven(), st, s);
  REQUIRE(b.has_value());
  CHECK(b->quantity() == "interface force");
  CHECK(b->step() == 7);
  const std::string what = b->what();
  CHECK(what.find("blow-up at coupling step 7 (t = 0.0008 s)") == 0);
  CHECK(what.find("interface force of node 1 (component 1) is not finite") != std::string::npos);
}

TEST_CASE("step checks: the arrays are checked before the scalars, forces first",
          "[coupling][checks]") {
  CouplingSettings s;
  SchemeState st = two_nodes();
  st.dem_end[0] = INFINITY;
  st.positions[3] = INFINITY;
  StepDiagnostics d = step_seven();
  d.kinetic_energy = std::numeric_limits<double>::quiet_NaN();
  auto b = blow_up_of(d, st, s);
  REQUIRE(b.has_value());
  CHECK(b->quantity() == "FEM interface position");
  st = two_nodes();
  b = blow_up_of(d, st, s);
  REQUIRE(b.has_value());
  CHECK(b->quantity() == "kinetic_energy");
}

TEST_CASE("step checks: overlap and energy error beyond coupling.blowup's bounds",
          "[coupling][checks]") {
  CouplingSettings s;
  s.scheme = Scheme::predictive;
  s.max_overlap = 1e-3;
  s.max_energy_error = 0.1;
  const SchemeState st = two_nodes();
  StepDiagnostics d = step_seven();
  d.max_overlap = 2e-3;
  auto b = blow_up_of(d, st, s);
  REQUIRE(b.has_value());
  CHECK(b->quantity() == "max_overlap");
  CHECK(b->value() == 2e-3);
  CHECK(b->bound() == 1e-3);
  CHECK(std::string(b->what()).find("coupling.blowup.max_overlap = 0.001 m") != std::string::npos);
  d.max_overlap = 0.0;
  d.energy_error = -0.2;  // |W_dem - W_fem|: either sign
  b = blow_up_of(d, st, s);
  REQUIRE(b.has_value());
  CHECK(b->quantity() == "energy_error");
  CHECK(b->value() == -0.2);
  // one_way_static: the DEM's mesh never moves, its side of the work is zero by construction.
  s.scheme = Scheme::one_way_static;
  CHECK_FALSE(blow_up_of(d, st, s).has_value());
}

TEST_CASE("interface work is trapezoidal, the drift the largest node distance",
          "[coupling][checks]") {
  // Forces from (0, 0, 2) to (0, 0, 4) N over a displacement of (0, 0, 0.5) m: 1.5 J; the
  // second node does not move.
  const std::vector<double> f0 = {0, 0, 2, 5, 5, 5}, f1 = {0, 0, 4, 5, 5, 5};
  const std::vector<double> x0 = {0, 0, 0, 1, 1, 1}, x1 = {0, 0, 0.5, 1, 1, 1};
  CHECK(trapezoid_work(f0, f1, x0, x1) == 1.5);
  CHECK(trapezoid_work(f1, f0, x1, x0) == -1.5);
  // Node 0 moved 0.5 m, node 1 by (3, 4, 0) m, 5 m: the larger.
  const std::vector<double> a = {0, 0, 0.5, 4, 5, 1};
  CHECK(max_node_distance(a, x0) == 5.0);
  CHECK(max_node_distance(x0, x0) == 0.0);
}

TEST_CASE("the schemes' history keeps the dataset names of earlier checkpoints",
          "[coupling][checks]") {
  SchemeState st = two_nodes();
  const char* expected[] = {
      "scheme/positions", "scheme/velocities",    "scheme/accelerations", "scheme/next_positions",
      "scheme/dem_start", "scheme/dem_end",       "scheme/dem_force",     "scheme/dem_force_prev",
      "scheme/fem_force", "scheme/fem_force_prev"};
  const auto arrays = st.arrays();
  REQUIRE(arrays.size() == std::size(expected));
  for (std::size_t k = 0; k < arrays.size(); ++k) {
    CHECK(std::string(arrays[k].first) == expected[k]);
    CHECK(arrays[k].second->size() == 6);
  }
  CHECK(st.positions == std::vector<double>{0, 0, 0, 1, 0, 0});
  CHECK(st.velocities == std::vector<double>(6, 0.0));
  CHECK(arrays[0].second == &st.positions);
  CHECK(arrays[9].second == &st.fem_force_prev);
}
