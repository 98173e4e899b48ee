// [coupling] reading: every error names file, line and key; n_D consistency (eq. 3.2).
#include <catch2/catch.hpp>

#include "demfem/coupling/coupling_settings.hpp"
#include "demfem_test/error_of.hpp"

using namespace demfem;
using coupling::read_coupling_settings;

namespace {

coupling::CouplingSettings read(const std::string& text) {
  return read_coupling_settings(scene::Document::parse(text, "scene.toml"));
}

std::string error_of(const std::string& text) {
  return demfem::test::error_of<scene::SceneError>([&] { read(text); }, "");
}

const char* kRun = "[run]\nend_time = 0.01\n";

}  // namespace

TEST_CASE("coupled scene: n_D, step count and scheme") {
  auto s = read(std::string(kRun) +
                "[dem]\ndt = 1e-6\n[fem]\ndt = 1e-4\n[coupling]\nscheme = \"predictive\"\n"
                "force_averaging = true\n");
  CHECK(s.scheme == coupling::Scheme::predictive);
  CHECK(s.dem_substeps == 100);
  CHECK(s.coupling_dt == 1e-4);
  CHECK(s.step_count == 100);
  CHECK(s.force_mode() == ForceMode::average);
}

TEST_CASE("a non-integer dt_F / dt_D is refused naming both keys and values") {
  const std::string msg = error_of(std::string(kRun) +
                                   "[dem]\ndt = 3e-6\n[fem]\ndt = 1e-4\n[coupling]\n"
                                   "scheme = \"just_in_time\"\n");
  CHECK_THAT(msg, Catch::Contains("fem.dt"));
  CHECK_THAT(msg, Catch::Contains("dem.dt"));
  CHECK_THAT(msg, Catch::Contains("1e-04"));
  CHECK_THAT(msg, Catch::Contains("3e-06"));
  CHECK_THAT(msg, Catch::Contains("scene.toml:"));
  // A DEM step larger than the FEM step gives n_D < 1: refused as well.
  CHECK_THAT(error_of(std::string(kRun) + "[dem]\ndt = 2e-4\n[fem]\ndt = 1e-4\n[coupling]\n"
                                          "scheme = \"just_in_time\"\n"),
             Catch::Contains("integer"));
}

TEST_CASE("n_D within the relative tolerance is accepted; just outside is not") {
  CHECK(coupling::dem_substeps(1e-4, 1e-6 * (1 + 1e-12), "f", "d") == 100);
  CHECK_THROWS_AS(coupling::dem_substeps(1e-4, 1e-6 * (1 + 1e-7), "f", "d"), scene::SceneError);
}

TEST_CASE("[coupling] errors name file, line and key") {
  const std::string base = std::string(kRun) + "[dem]\ndt = 1e-6\n[fem]\ndt = 1e-4\n";
  CHECK_THAT(error_of(base), Catch::Contains("[coupling]"));
  std::string msg = error_of(base + "[coupling]\nscheme = \"staggered\"\n");
  CHECK_THAT(msg, Catch::Contains("coupling.scheme"));
  CHECK_THAT(msg, Catch::Contains("just_in_time"));
  CHECK_THAT(msg, Catch::Contains("implicit"));
  msg = error_of(base + "[coupling]\nscheme = \"predictive\"\nforce_averagin = true\n");
  CHECK_THAT(msg, Catch::Contains("coupling.force_averagin"));
  CHECK_THAT(msg, Catch::Contains("scene.toml:9"));
  msg =
      error_of(base + "[coupling]\nscheme = \"predictive\"\n[coupling.blowup]\nmax_overlap = -1\n");
  CHECK_THAT(msg, Catch::Contains("coupling.blowup.max_overlap"));
  msg = error_of(base + "[coupling]\nscheme = \"predictive\"\n[coupling.settle]\nmin_time = 0\n");
  CHECK_THAT(msg, Catch::Contains("one_way_static"));
  msg =
      error_of(base + "[coupling]\nscheme = \"one_way_static\"\n[coupling.settle]\nmin_time = 1\n");
  CHECK_THAT(msg, Catch::Contains("coupling.settle.min_time"));
  msg = error_of(base + "[coupling]\nscheme = \"one_way_static\"\ndiagnostics_interval = 0\n");
  CHECK_THAT(msg, Catch::Contains("coupling.diagnostics_interval"));
}

TEST_CASE("single-solver scenes") {
  auto dem = read(std::string(kRun) + "[dem]\ndt = 1e-5\n");
  CHECK(dem.scheme == coupling::Scheme::dem_only);
  CHECK(dem.dem_substeps == 100);  // slices of 1 ms
  CHECK(dem.step_count == 10);
  auto fem = read(std::string(kRun) + "[fem]\ndt = 1e-3\n");
  CHECK(fem.scheme == coupling::Scheme::fem_only);
  CHECK(fem.step_count == 10);
  CHECK_THAT(error_of(kRun), Catch::Contains("neither"));
}

TEST_CASE("steps_to_reach rounds a near multiple and covers a remainder") {
  CHECK(coupling::steps_to_reach(0.3, 0.1) == 3);
  CHECK(coupling::steps_to_reach(0.35, 0.1) == 4);
  CHECK(coupling::steps_to_reach(1e-4, 1e-4) == 1);
}

TEST_CASE("step counts beyond the stated limits are refused upfront, naming the keys") {
  // end_time = 1e300 once overflowed to "1 coupling steps"; dem.dt = 1e-20 was accepted and
  // then never finished (issue 19, defect 5).
  std::string msg = error_of(
      "[run]\nend_time = 1e300\n[dem]\ndt = 1e-6\n[fem]\ndt = 1e-4\n[coupling]\n"
      "scheme = \"just_in_time\"\n");
  CHECK_THAT(msg, Catch::Contains("scene.toml:2:12: key 'run.end_time' = 1e+300 s"));
  CHECK_THAT(msg, Catch::Contains("key 'fem.dt' = 1e-04 s"));
  CHECK_THAT(msg, Catch::Contains("coupling steps; at most 1e+09 are accepted"));
  msg = error_of(std::string(kRun) +
                 "[dem]\ndt = 1e-20\n[fem]\ndt = 1e-4\n[coupling]\nscheme = \"just_in_time\"\n");
  CHECK_THAT(msg, Catch::Contains("key 'dem.dt' = 1e-20 s"));
  CHECK_THAT(msg, Catch::Contains("key 'fem.dt'"));
  CHECK_THAT(msg, Catch::Contains("DEM substeps per coupling step; at most 1e+09"));
  // The DEM alone: the total count of DEM steps is bounded (1e12), and no slice overflows.
  msg = error_of(std::string(kRun) + "[dem]\ndt = 1e-20\n");
  CHECK_THAT(msg, Catch::Contains("key 'run.end_time' = 0.01 s and"));
  CHECK_THAT(msg, Catch::Contains("key 'dem.dt' = 1e-20 s make 1e+18 DEM steps; at most 1e+12"));
  msg = error_of("[run]\nend_time = 1e300\n[dem]\ndt = 1e-300\n");
  CHECK_THAT(msg, Catch::Contains("DEM steps; at most 1e+12"));
  // The FEM alone.
  msg = error_of("[run]\nend_time = 1e6\n[fem]\ndt = 1e-4\n");
  CHECK_THAT(msg, Catch::Contains("make 1e+10 coupling steps"));
  // At the limits: accepted.
  auto s = read("[run]\nend_time = 1e5\n[fem]\ndt = 1e-4\n");
  CHECK(s.step_count == coupling::kMaxCouplingSteps);
  s = read("[run]\nend_time = 1e3\n[dem]\ndt = 1e-6\n");
  CHECK(s.step_count == 1'000'000);  // slices of 1 ms
  CHECK(coupling::steps_to_reach(1e300, 1e-300) == INT64_MAX);
}

TEST_CASE("concurrent and implicit schemes; the implicit keys and their ranges") {
  const std::string base = std::string(kRun) + "[dem]\ndt = 1e-6\n[fem]\ndt = 1e-4\n[coupling]\n";
  CHECK(read(base + "scheme = \"concurrent\"\n").scheme == coupling::Scheme::concurrent);
  // Defaults (docs/coupling.md): IQN-ILS, 50 iterations, stop when not converged.
  auto s = read(base + "scheme = \"implicit\"\n");
  CHECK(s.scheme == coupling::Scheme::implicit);
  CHECK(s.implicit.acceleration.kind == coupling::AccelerationKind::iqn_ils);
  CHECK(s.implicit.max_iterations == 50);
  CHECK(s.implicit.on_nonconvergence == coupling::NonConvergence::stop);
  s = read(base +
           "scheme = \"implicit\"\nacceleration = \"aitken\"\nmax_iterations = 7\n"
           "displacement_tolerance = 1e-5\nforce_tolerance = 2e-3\n"
           "displacement_abs_tolerance = 1e-12\nforce_abs_tolerance = 1e-6\n"
           "initial_relaxation = 0.25\non_nonconvergence = \"accept\"\n");
  CHECK(s.implicit.acceleration.kind == coupling::AccelerationKind::aitken);
  CHECK(s.implicit.max_iterations == 7);
  CHECK(s.implicit.displacement_tolerance == 1e-5);
  CHECK(s.implicit.force_tolerance == 2e-3);
  CHECK(s.implicit.displacement_abs_tolerance == 1e-12);
  CHECK(s.implicit.force_abs_tolerance == 1e-6);
  CHECK(s.implicit.acceleration.initial_relaxation == 0.25);
  CHECK(s.implicit.on_nonconvergence == coupling::NonConvergence::accept);
  s = read(base + "scheme = \"implicit\"\nreuse_steps = 0\nmax_columns = 12\nqr_filter = 0\n");
  CHECK(s.implicit.acceleration.reuse_steps == 0);
  CHECK(s.implicit.acceleration.max_columns == 12);
  CHECK(s.implicit.acceleration.qr_filter == 0.0);

  // Every key names itself and its range (or the scheme it belongs to).
  struct Bad {
    const char* text;
    const char* key;
    const char* says;
  };
  const Bad bad[] = {
      {"scheme = \"implicit\"\nmax_iterations = 0\n", "coupling.max_iterations", "1"},
      {"scheme = \"implicit\"\ndisplacement_tolerance = 0\n", "coupling.displacement_tolerance",
       "> 0"},
      {"scheme = \"implicit\"\nforce_tolerance = -1\n", "coupling.force_tolerance", "> 0"},
      {"scheme = \"implicit\"\ninitial_relaxation = 1.5\n", "coupling.initial_relaxation", "1"},
      {"scheme = \"implicit\"\ninitial_relaxation = 0\n", "coupling.initial_relaxation", "0"},
      {"scheme = \"implicit\"\nacceleration = \"broyden\"\n", "coupling.acceleration", "iqn-ils"},
      {"scheme = \"implicit\"\non_nonconvergence = \"ignore\"\n", "coupling.on_nonconvergence",
       "accept"},
      {"scheme = \"implicit\"\nqr_filter = 1\n", "coupling.qr_filter", "1"},
      {"scheme = \"implicit\"\nacceleration = \"aitken\"\nreuse_steps = 4\n",
       "coupling.reuse_steps", "iqn-ils"},
      {"scheme = \"just_in_time\"\nmax_iterations = 4\n", "coupling.max_iterations", "implicit"},
      {"scheme = \"concurrent\"\nacceleration = \"aitken\"\n", "coupling.acceleration", "implicit"},
  };
  for (const auto& b : bad) {
    INFO(b.text);
    const std::string msg = error_of(base + b.text);
    CHECK_THAT(msg, Catch::Contains(b.key));
    CHECK_THAT(msg, Catch::Contains(b.says));
    CHECK_THAT(msg, Catch::Contains("scene.toml:"));
  }
}
