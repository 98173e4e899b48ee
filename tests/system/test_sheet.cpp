// The steel sheet under grain flow (thesis ch. 5) as a user runs it: `demfem run
// cases/sheet_ci.toml` in a fresh folder prepares the fill (cases/sheet_fill_ci.toml), runs
// the coupled case, and its [[post]] steps write the plots, the report and the static check.
// Also: the prepare step's reuse and staleness rule, [[post]] failures, and the static check
// against a FEM-only run whose time-mean answer is known.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "demfem/io/h5_file.hpp"
#include "demfem_test/box_scene.hpp"
#include "demfem_test/demfem_run.hpp"
#include "demfem_test/run_output.hpp"
#include "demfem_test/steel_strip.hpp"
#include "demfem_test/temp_dir.hpp"

namespace fs = std::filesystem;

namespace {

using demfem::test::have_matplotlib;
using demfem::test::kBin;
using demfem::test::kCases;
using demfem::test::run_demfem;
using Result = demfem::test::Ended;
using demfem::test::is_png;
using demfem::test::read_csv;
using demfem::test::read_text;
using demfem::test::TempDir;

// Column `name` of a CSV written by the run (header row first).
std::vector<double> column(const std::vector<std::vector<std::string>>& rows,
                           const std::string& name) {
  std::vector<double> v;
  REQUIRE_NOTHROW(v = demfem::test::csv_column(rows, name));
  return v;
}

// A box of 60 spheres resting on its floor; the fill writes its state, the use loads it.
const std::string kSmallDem = [] {
  demfem::test::BoxScene b;
  b.end_time.clear();
  b.box_hi = "[0.03, 0.03, 0.05]";
  return b.text();
}();

}  // namespace

TEST_CASE("sheet CI case: demfem run prepares the fill, runs, plots and checks", "[sheet]") {
  if (!have_matplotlib()) {
    WARN("skipped: /usr/bin/python3 has no matplotlib (Debian: python3-matplotlib)");
    return;
  }
  TempDir d("sheet_ci");
  const Result r = run_demfem(d.path, {(kCases / "sheet_ci.toml").string(), "--quiet"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  // The fill was made first, then loaded with its contact history.
  CHECK_THAT(r.out, Catch::Contains("running that scene first"));
  const fs::path fill = d.path / "out/sheet_fill_ci/dem_state.h5";
  REQUIRE(fs::exists(fill));
  demfem::io::H5File state(fill, demfem::io::H5File::Mode::read);
  const auto masses = state.read_doubles("dem/mass");
  double fill_mass = 0.0;
  for (double m : masses) fill_mass += m;
  CHECK(fill_mass == Approx(0.8).margin(0.002));  // 0.8 kg + at most one grain
  CHECK_THAT(r.err, Catch::Contains("with contact history"));
  CHECK_THAT(r.err, Catch::Contains("loaded " + std::to_string(masses.size()) + " particles"));

  const fs::path out = d.path / "out/sheet_ci";
  for (const char* png : {"mass_flow.png", "deflection.png"}) {
    INFO(png);
    CHECK(is_png(out / png));
  }
  for (const char* f : {"particles.xdmf", "fem.xdmf", "coupling.csv", "timing.csv",
                        "sheet_report.txt", "sheet_report.json", "fem_mean.h5"})
    CHECK(fs::exists(out / f));

  // Mass: what crossed the plane under the flaps is part of the fill, and the flow started.
  const auto flow = read_csv(out / "sensor_outflow.csv");
  const auto crossed = column(flow, "mass_crossed");
  REQUIRE(!crossed.empty());
  CHECK(crossed.back() <= fill_mass);
  CHECK(crossed.back() > 0.1 * fill_mass);
  for (std::size_t i = 1; i < crossed.size(); ++i) CHECK(crossed[i] >= crossed[i - 1] - 2e-4);
  const auto rate = column(flow, "mass_flow");
  const auto ft = column(flow, "time");
  // Nothing falls before the flaps open; the peak comes while they open (0-0.2 s) or soon
  // after, as the initial bulk drops.
  CHECK(crossed[0] == 0.0);
  std::size_t peak = 0;
  for (std::size_t i = 0; i < rate.size(); ++i)
    if (rate[i] > rate[peak]) peak = i;
  CHECK(ft[peak] > 0.05);
  CHECK(ft[peak] < 0.35);

  // The sheet: at rest until the first grains arrive (0.36 m of fall: about 0.27 s after the
  // flaps start to open), pushed down during the flow.
  const auto mon = read_csv(out / "fem_monitor.csv");
  const auto t = column(mon, "time"), uz = column(mon, "lmp_uz"), fz = column(mon, "force_z");
  double mean_flow = 0.0, lowest = 0.0;
  std::size_t n_flow = 0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    if (t[i] < 0.2) CHECK(uz[i] == 0.0);
    if (t[i] >= 0.3) mean_flow += uz[i], ++n_flow;
    lowest = std::min(lowest, uz[i]);
  }
  REQUIRE(n_flow > 100);
  mean_flow /= double(n_flow);
  CHECK(mean_flow < -1e-3);  // m: down by more than a millimetre on average
  CHECK(lowest < -5e-3);
  CHECK(lowest > -0.1);  // bounded: no blow-up
  double mean_force = 0.0;
  for (std::size_t i = 0; i < t.size(); ++i)
    if (t[i] >= 0.3) mean_force += fz[i];
  CHECK(mean_force / double(n_flow) < 0.0);

  // The static check ran: the mean deflection follows from the mean load within the scatter
  // that a window of two sheet periods leaves (docs/verification.md).
  const auto sc = read_csv(out / "static_check.csv");
  REQUIRE(sc.size() >= 2);
  CHECK(sc[1][0] == "lmp");
  CHECK(std::abs(std::stod(sc[1][5])) < 0.3);
}

TEST_CASE("prepare scenes: made once, reused, made again when the scene changes", "[sheet]") {
  TempDir d("prepare");
  std::ofstream(d / "fill.toml") << "[run]\nend_time = 0.002\n"
                                 << kSmallDem
                                 << "[[dem.insert]]\nmaterial = \"wheat\"\nlo = [0, 0, 0]\n"
                                    "hi = [0.03, 0.03, 0.03]\ncount = 60\nseed = 2\n"
                                    "distribution = { kind = \"constant\", diameter = 0.004 }\n"
                                    "[dem.output]\nstate = true\nparticles = false\n";
  std::ofstream(d / "use.toml") << "[run]\nend_time = 0.002\n"
                                << kSmallDem
                                << "[dem.load]\nscene = \"fill.toml\"\n"
                                   "[dem.output]\nparticles = false\n";
  const std::string use = (d / "use.toml").string();
  Result r = run_demfem(d.path, {use, "--quiet"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  CHECK_THAT(r.out, Catch::Contains("running that scene first"));
  CHECK(fs::exists(d.path / "out/fill/dem_state.h5"));
  r = run_demfem(d.path, {use, "--quiet", "--in-process"});
  REQUIRE(r.status == 0);
  CHECK_THAT(r.out, !Catch::Contains("running that scene first"));
  // A comment is no change of the scene: the state is reused. Another seed is.
  std::ofstream(d / "fill.toml", std::ios::app) << "# a comment\n";
  r = run_demfem(d.path, {use, "--quiet"});
  REQUIRE(r.status == 0);
  CHECK_THAT(r.out, !Catch::Contains("running that scene first"));
  std::string fill = read_text(d / "fill.toml");
  fill.replace(fill.find("seed = 2"), 8, "seed = 3");
  std::ofstream(d / "fill.toml") << fill;
  r = run_demfem(d.path, {use, "--quiet"});
  REQUIRE(r.status == 0);
  CHECK_THAT(r.out, Catch::Contains("was made by another version of it"));
  // A state that has gone is made again (in process too).
  fs::remove(d.path / "out/fill/dem_state.h5");
  r = run_demfem(d.path, {use, "--quiet", "--in-process"});
  CHECK(r.status == 0);
  CHECK_THAT(r.out, Catch::Contains("does not exist"));
  // A prepare scene with bad input ends the run as bad input (2); nothing else starts.
  std::ofstream(d / "bad.toml") << "[run]\nend_time = 0.002\n"
                                << kSmallDem << "[dem.output]\nstate = true\nbogus = 1\n";
  std::ofstream(d / "use_bad.toml") << "[run]\nend_time = 0.002\n"
                                    << kSmallDem << "[dem.load]\nscene = \"bad.toml\"\n";
  r = run_demfem(d.path, {(d / "use_bad.toml").string(), "--quiet"});
  CHECK(r.status == 2);
  CHECK_THAT(r.err, Catch::Contains("bad.toml") && Catch::Contains("ended with status 2"));
}

TEST_CASE("prepare scenes with overrides: each variant of a bed is made once, in its own folder",
          "[sheet]") {
  // A sweep member's --set run.seed reaches the bed through [dem.load] pass (its insertion
  // takes run.seed); [dem.load] set fixes a key of the bed for every member.
  TempDir d("prepare_overrides");
  std::ofstream(d / "fill.toml") << "[run]\nend_time = 0.002\n"
                                 << kSmallDem
                                 << "[[dem.insert]]\nmaterial = \"wheat\"\nlo = [0, 0, 0]\n"
                                    "hi = [0.03, 0.03, 0.03]\ncount = 60\n"
                                    "distribution = { kind = \"constant\", diameter = 0.004 }\n"
                                    "[dem.output]\nstate = true\nparticles = false\n";
  std::ofstream(d / "use.toml") << "[run]\nend_time = 0.002\n"
                                << kSmallDem
                                << "[dem.load]\nscene = \"fill.toml\"\npass = [\"run.seed\"]\n"
                                   "set = [\"dem.insert[0].count=50\"]\n"
                                   "[dem.output]\nparticles = false\n";
  const std::string use = (d / "use.toml").string();
  // A sweep checks each member first: the bed to come is checked, nothing is made.
  Result c = run_demfem(d.path, {use, "--check", "--set", "run.seed=5"});
  INFO(c.out << c.err);
  CHECK(c.status == 0);
  CHECK_FALSE(fs::exists(d.path / "out/fill"));
  // a bad value for the bed only: found by the check of the bed's scene
  c = run_demfem(d.path, {use, "--check", "--set", "dem.load.set=[\"dem.insert[0].count=-3\"]"});
  CHECK(c.status == 2);
  CHECK_THAT(c.err, Catch::Contains("fill.toml") && Catch::Contains("dem.insert[0].count") &&
                        Catch::Contains("does not pass --check"));
  auto variants = [&] {
    std::vector<fs::path> v;
    if (fs::exists(d.path / "out/fill"))
      for (const auto& e : fs::directory_iterator(d.path / "out/fill"))
        if (e.path().filename().string().rfind("set-", 0) == 0) v.push_back(e.path());
    return v;
  };
  Result r = run_demfem(d.path, {use, "--quiet", "--set", "run.seed=5"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  CHECK_THAT(r.out, Catch::Contains("running that scene first") &&
                        Catch::Contains("--set run.seed=5") &&
                        Catch::Contains("--set dem.insert[0].count=50"));
  REQUIRE(variants().size() == 1);
  CHECK(fs::exists(variants()[0] / "dem_state.h5"));
  CHECK_FALSE(fs::exists(d.path / "out/fill/dem_state.h5"));  // the plain scene's place
  // the same member again (in process too): reused
  r = run_demfem(d.path, {use, "--quiet", "--in-process", "--set", "run.seed=5"});
  REQUIRE(r.status == 0);
  CHECK_THAT(r.out, !Catch::Contains("running that scene first"));
  // another seed: another bed beside it; the first stays current
  r = run_demfem(d.path, {use, "--quiet", "--set", "run.seed=6"});
  REQUIRE(r.status == 0);
  CHECK_THAT(r.out, Catch::Contains("running that scene first"));
  CHECK(variants().size() == 2);
  r = run_demfem(d.path, {use, "--quiet", "--set", "run.seed=5"});
  REQUIRE(r.status == 0);
  CHECK_THAT(r.out, !Catch::Contains("running that scene first"));
  // the fill run by hand with the plain scene does not stand in for a variant
  r = run_demfem(d.path, {(d / "fill.toml").string(), "--quiet"});
  REQUIRE(r.status == 0);
  CHECK(fs::exists(d.path / "out/fill/dem_state.h5"));
  CHECK(variants().size() == 2);
}

TEST_CASE("[[post]] steps: unknown tools are scene errors, a failing tool ends the run with 1",
          "[sheet]") {
  TempDir d("post");
  const std::string base =
      std::string("[run]\nend_time = 0.001\n") + kSmallDem + "[dem.output]\nparticles = false\n";
  std::ofstream(d / "unknown.toml") << base << "[[post]]\ntool = \"no_such_tool\"\n";
  Result r = run_demfem(d.path, {(d / "unknown.toml").string(), "--quiet"});
  CHECK(r.status == 2);
  CHECK_THAT(r.err, Catch::Contains("post[0].tool") && Catch::Contains("no_such_tool"));
  // fem_static_check without a [fem] section fails: the run's output is kept, status 1.
  std::ofstream(d / "fails.toml") << base << "[[post]]\ntool = \"fem_static_check\"\n"
                                  << "args = [\"--scene\", \"{scene}\", \"--output-dir\", "
                                     "\"{output}\"]\n";
  r = run_demfem(d.path, {(d / "fails.toml").string(), "--quiet"});
  CHECK(r.status == 1);
  CHECK_THAT(r.err, Catch::Contains("post step fem_static_check"));
  CHECK(fs::exists(d.path / "out/fails/coupling.csv"));
  r = run_demfem(d.path, {(d / "fails.toml").string(), "--quiet", "--no-post"});
  CHECK(r.status == 0);
}

TEST_CASE("fem_static_check: the time-mean of a damped oscillation is the static solution",
          "[sheet]") {
  // A steel strip 100 x 20 x 1 mm clamped at x = 0, loaded at its tip from t = 0 (a step
  // load): it oscillates about the static deflection (first mode about 80 Hz) and Rayleigh
  // damping (about 5 % of critical there) lets the oscillation die out. Over 0.2-0.4 s its
  // amplitude is below 1e-3 of the static value, so the time-mean displacement equals the
  // static solution under the mean load to about 1e-3 (the bound of K <u> = <F> - M [u'] / T).
  TempDir d("static_check");
  const std::string strip = demfem::test::steel_strip_fem("analysis = \"dynamic\"\n");
  std::ofstream(d / "strip.toml") << "\n[run]\nend_time = 0.4\n" + strip + R"([[fem.nodal_loads]]
nodes = "x >= 0.1"
force = [0.0, 0.0, -0.1]
[fem.damping]
stiffness_factor = 2e-4
[fem.output]
write = false
[fem.monitor]
interval = 1e-3
mean_window = [0.2, 0.4]
[[fem.monitor.probes]]
name = "tip"
point = [0.1, 0.01, 0.0]
[[post]]
tool = "fem_static_check"
args = ["--scene", "{scene}", "--output-dir", "{output}"]
)";
  const Result r = run_demfem(d.path, {(d / "strip.toml").string(), "--quiet"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  const auto rows = read_csv(d.path / "out/strip/static_check.csv");
  REQUIRE(rows.size() == 3);
  CHECK(rows[1][0] == "tip");
  const double mean = std::stod(rows[1][2]), stat = std::stod(rows[1][3]);
  CHECK(stat < -1e-4);  // m: the load bends the strip down
  CHECK(std::abs(std::stod(rows[1][5])) < 1e-3);
  CHECK(std::abs(std::stod(rows[2][5])) < 1e-3);  // whole field
  CHECK(mean == Approx(stat).epsilon(1e-3));
  // The probe series: every 1 ms, the tip going down.
  const auto mon = read_csv(d.path / "out/strip/fem_monitor.csv");
  CHECK(mon.size() == 402);  // header, the first step (t = 1e-4 s), then every 1 ms to 0.4 s
}
