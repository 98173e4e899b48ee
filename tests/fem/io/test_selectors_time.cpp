// Node and face selectors, and the load amplitudes (time functions).
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>

#include "demfem/fem/inp_reader.hpp"
#include "demfem/fem/node_selector.hpp"
#include "demfem/fem/time_function.hpp"

using namespace demfem::fem;

namespace {

Mesh unit_hex() {
  return read_inp(std::filesystem::path(DEMFEM_SOURCE_DIR) / "cases/meshes/unit_hex.inp");
}

}  // namespace

TEST_CASE("node selectors: set names, all, expressions with tolerance") {
  const Mesh m = unit_hex();
  CHECK(select_nodes(m, "BOTTOM").size() == 4);
  CHECK(select_nodes(m, "bottom").size() == 4);  // .inp names are case-insensitive
  CHECK(select_nodes(m, "all").size() == 8);
  CHECK(select_nodes(m, "z <= 0") == std::vector<std::int32_t>{0, 1, 2, 3});
  CHECK(select_nodes(m, "z>=1") == std::vector<std::int32_t>{4, 5, 6, 7});
  CHECK(select_nodes(m, "x <= 1e-9 and y > 0") == std::vector<std::int32_t>{3, 7});
  CHECK(select_nodes(m, "0.5 < x AND z == 1") == std::vector<std::int32_t>{5, 6});
  // Tolerance: 1e-6 of the bounding-box diagonal (sqrt 3) = 1.73e-6.
  CHECK(select_nodes(m, "x <= -1e-6").size() == 4);               // within tolerance of x = 0
  CHECK_THROWS_AS(select_nodes(m, "x <= -1e-5"), SelectorError);  // beyond it: nothing
  CHECK_THROWS_WITH(select_nodes(m, "x < 0"), Catch::Contains("selects no node"));
  CHECK_THROWS_WITH(select_nodes(m, "w <= 0"), Catch::Contains("is not a node set"));
  CHECK_THROWS_WITH(select_nodes(m, "x <= abc"), Catch::Contains("'abc' is not a finite number"));
  CHECK_THROWS_WITH(select_nodes(m, "x <= 0 or y > 0"), Catch::Contains("expected 'and'"));
  CHECK_THROWS_WITH(select_nodes(m, "x = 0"), Catch::Contains("comparison operator"));
  CHECK_THROWS_WITH(select_nodes(m, "x <= nan"), Catch::Contains("not a finite number"));
}

TEST_CASE("face selectors: surface names, exterior, node expressions") {
  const Mesh m = unit_hex();
  CHECK(select_faces(m, "s2surf").size() == 1);
  CHECK(select_faces(m, "exterior").size() == 6);
  const auto top = select_faces(m, "z >= 1");
  REQUIRE(top.size() == 1);
  CHECK(top[0].face == 1);  // S2 of a C3D8 is the face of nodes 5-8
  const auto xmin = select_faces(m, "x <= 0");
  REQUIRE(xmin.size() == 1);
  CHECK(xmin[0].face == 5);  // S6
  CHECK(face_area(m, xmin[0]) == Approx(1.0));
  CHECK_THROWS_WITH(select_faces(m, "x <= 0 and z <= 0"),
                    Catch::Contains("selects no exterior face"));
  CHECK_THROWS_WITH(select_faces(m, "nosuch"), Catch::Contains("is not a surface of the mesh"));
}

TEST_CASE("time functions: constant, table (clamped), sinusoid") {
  CHECK(constant_function(2.5)(100.0) == 2.5);
  const auto f = piecewise_linear_function({{0.0, 0.0}, {1.0, 2.0}, {3.0, -2.0}});
  CHECK(f(-1.0) == 0.0);
  CHECK(f(0.5) == Approx(1.0));
  CHECK(f(1.0) == Approx(2.0));
  CHECK(f(2.0) == Approx(0.0));
  CHECK(f(10.0) == -2.0);
  CHECK_THROWS_WITH(piecewise_linear_function({{0.0, 1.0}, {0.0, 2.0}}),
                    Catch::Contains("increase strictly"));
  CHECK_THROWS(piecewise_linear_function({}));
  const auto s = sinusoid_function(1.0, 0.5, 2.0, 0.0);
  CHECK(s(0.125) == Approx(1.5));  // quarter period of 2 Hz
  CHECK(s(0.375) == Approx(0.5));
  CHECK_THROWS(sinusoid_function(0.0, 1.0, -1.0, 0.0));
}

TEST_CASE("sleeper load pattern (thesis fig. 6.2) at known times") {
  const auto f = sleeper_load_function({});
  // Reference values follow from the pattern's definition in time_function.hpp (levels from
  // the thesis, 0.03 s ramps, 0.06 s of 100 Hz cycles); tolerance is round-off only.
  CHECK(f(-0.01) == 0.0);
  CHECK(f(0.0) == 0.0);
  CHECK(f(0.015) == Approx(110e3).epsilon(1e-12));  // half way up the first ramp
  CHECK(f(0.0299999) == Approx(220e3).epsilon(1e-5));
  CHECK(f(0.03) == Approx(4.4e3).epsilon(1e-12));     // cycles start at the minimum
  CHECK(f(0.035) == Approx(44e3).epsilon(1e-12));     // half a 100 Hz period later: maximum
  CHECK(f(0.0325) == Approx(24.2e3).epsilon(1e-12));  // quarter period: the mean
  CHECK(f(0.085) == Approx(44e3).epsilon(1e-12));     // sixth maximum
  CHECK(f(0.09) == Approx(0.0).margin(1e-9));         // second ramp starts from zero
  CHECK(f(0.105) == Approx(110e3).epsilon(1e-12));
  CHECK(f(0.12) == Approx(220e3).epsilon(1e-12));  // held at the peak afterwards
  CHECK(f(5.0) == 220e3);
  // Time scale 10 (the thesis' production choice) stretches the whole pattern.
  SleeperLoadPattern slow;
  slow.time_scale = 10.0;
  CHECK(slow.duration() == Approx(1.2));
  const auto g = sleeper_load_function(slow);
  CHECK(g(0.15) == Approx(110e3).epsilon(1e-12));
  CHECK(g(0.35) == Approx(44e3).epsilon(1e-12));
  // Six full cycles: count the maxima (44 kN) on a fine grid of the cyclic phase.
  int maxima = 0;
  double prev2 = f(0.03), prev = f(0.03 + 1e-5);
  for (double t = 0.03 + 2e-5; t < 0.09; t += 1e-5) {
    const double v = f(t);
    if (prev > prev2 && prev >= v) ++maxima;
    prev2 = prev;
    prev = v;
  }
  CHECK(maxima == 6);
  // A finite unloading (0.01 s from 220 to 4.4 kN): linear, then the same cycles and second
  // ramp 0.01 s later; the pattern lasts 0.13 s.
  SleeperLoadPattern unload;
  unload.unload_duration = 0.01;
  CHECK(unload.duration() == Approx(0.13));
  const auto u = sleeper_load_function(unload);
  CHECK(u(0.0299999) == Approx(220e3).epsilon(1e-5));
  CHECK(u(0.035) == Approx(112.2e3).epsilon(1e-12));  // half way down
  CHECK(u(0.04) == Approx(4.4e3).epsilon(1e-12));     // the cycles start at the minimum
  for (double t : {0.0325, 0.045, 0.07, 0.095, 0.1, 0.115, 0.2})
    CHECK(u(t + 0.01) == Approx(f(t)).epsilon(1e-12));
  SleeperLoadPattern bad;
  bad.unload_duration = -1e-3;
  CHECK_THROWS(sleeper_load_function(bad));
  bad = {};
  bad.cycle_min = 50e3;
  CHECK_THROWS(sleeper_load_function(bad));
  bad = {};
  bad.time_scale = 0.0;
  CHECK_THROWS(sleeper_load_function(bad));
}
