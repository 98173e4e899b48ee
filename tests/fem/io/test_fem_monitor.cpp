// [fem.monitor]: probes find their nodes, the series has a row per interval with the probe
// displacements and the interface force sum, the window mean is the dt-weighted mean, and a
// rollback to a checkpoint gives the same files as the uninterrupted run.
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "demfem/fem/fem_monitor.hpp"
#include "demfem/fem/fem_scene.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem_test/error_of.hpp"
#include "demfem_test/steel_strip.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem;
using namespace demfem::fem;
using demfem::test::read_text;
using demfem::test::TempDir;

namespace {

const std::string kStrip = test::steel_strip_fem() + R"([fem.monitor]
interval = 5e-4
mean_window = [0.001, 0.003]
[[fem.monitor.probes]]
name = "tip"
point = [0.1004, 0.0098, 0.0001]
[[fem.monitor.probes]]
name = "mid"
point = [0.05, 0.01, 0.0]
)";

FemScene strip(const std::string& text = kStrip) {
  const auto doc = scene::Document::parse(text, "strip.toml");
  return read_fem_scene(doc.root().required_table("fem"));
}

// A step of the strip under a downward force on the interface nodes at the tip.
void step(FemSolver& s, std::vector<double>& f, FemMonitor& m) {
  const auto& mesh = s.interface_mesh();
  f.assign(3 * mesh.node_count(), 0.0);
  for (std::size_t i = 0; i < mesh.node_count(); ++i)
    if (mesh.reference_positions[3 * i] > 0.0999) f[3 * i + 2] = -0.01 * (1.0 + s.time() * 100);
  s.set_interface_forces(f);
  s.advance(1e-4);
  m.sample(s, f);
}

}  // namespace

TEST_CASE("fem.monitor: probes, series and window mean", "[fem][monitor]") {
  TempDir dir("monitor");
  FemScene sc = strip();
  REQUIRE(sc.monitor.probes.size() == 2);
  // The nearest node: (0.1, 0.01, 0), 0.4, 0.2 and 0.1 mm away in x, y and z.
  const auto& tip = sc.monitor.probes[0];
  CHECK(sc.problem.mesh.nodes[tip.node][0] == Approx(0.1));
  CHECK(sc.problem.mesh.nodes[tip.node][1] == Approx(0.01));
  CHECK(tip.distance == Approx(std::sqrt(0.21e-6)).epsilon(1e-9));
  FemSolver s(std::move(sc.problem));
  FemMonitor m(dir.path, sc.monitor);
  std::vector<double> f;
  double sum_u = 0.0, sum_f = 0.0;
  for (int k = 0; k < 40; ++k) {
    step(s, f, m);
    const double t = s.time();
    if (t > 0.001 + 1e-12 && t <= 0.003 + 1e-12) {
      sum_u += 1e-4 * s.displacements()[3 * std::size_t(tip.node) + 2];
      double fz = 0.0;
      for (std::size_t i = 2; i < f.size(); i += 3) fz += f[i];
      sum_f += 1e-4 * fz;
    }
  }
  // Rows: the first step, then each multiple of 0.5 ms up to 4 ms.
  std::istringstream csv(read_text(m.csv_path()));
  std::string line;
  std::getline(csv, line);
  CHECK(line == "time,tip_ux,tip_uy,tip_uz,mid_ux,mid_uy,mid_uz,force_x,force_y,force_z");
  std::vector<double> times;
  while (std::getline(csv, line)) times.push_back(std::stod(line));
  REQUIRE(times.size() == 9);
  CHECK(times[0] == Approx(1e-4));
  CHECK(times[1] == Approx(5e-4));
  CHECK(times.back() == Approx(4e-3));
  // The mean file: 20 steps of 1e-4 s in (1 ms, 3 ms].
  io::H5File h5(m.mean_path(), io::H5File::Mode::read);
  CHECK(h5.attribute_int64("/", "steps") == 20);
  CHECK(h5.attribute_double("/", "duration") == Approx(2e-3).epsilon(1e-9));
  const auto u = h5.read_doubles("displacement");
  CHECK(u[3 * std::size_t(tip.node) + 2] == Approx(sum_u / 2e-3).epsilon(1e-12));
  const auto fm = h5.read_doubles("interface_force");
  double fz = 0.0;
  for (std::size_t i = 2; i < fm.size(); i += 3) fz += fm[i];
  CHECK(fz == Approx(sum_f / 2e-3).epsilon(1e-12));
  CHECK(u[3 * std::size_t(tip.node) + 2] < 0.0);
}

TEST_CASE("fem.monitor: a rollback to a checkpoint rewrites the same series and mean",
          "[fem][monitor]") {
  TempDir a("monitor_a"), b("monitor_b");
  FemScene sa = strip(), sb = strip();
  FemSolver whole(std::move(sa.problem)), cut(std::move(sb.problem));
  FemMonitor ma(a.path, sa.monitor), mb(b.path, sb.monitor);
  std::vector<double> f;
  for (int k = 0; k < 40; ++k) step(whole, f, ma);
  // 15 steps (inside the window), a checkpoint, 10 more, back to the checkpoint, 25 more.
  for (int k = 0; k < 15; ++k) step(cut, f, mb);
  {
    io::H5File h5(b / "cp.h5", io::H5File::Mode::create);
    h5.create_group("fem");
    cut.save(h5, "fem");
    mb.save(h5, "fem_monitor");
  }
  for (int k = 0; k < 10; ++k) step(cut, f, mb);
  {
    io::H5File h5(b / "cp.h5", io::H5File::Mode::read);
    cut.restore(h5, "fem");
    mb.restore(h5, "fem_monitor", cut.time());
  }
  for (int k = 0; k < 25; ++k) step(cut, f, mb);
  CHECK(read_text(ma.csv_path()) == read_text(mb.csv_path()));
  io::H5File ha(ma.mean_path(), io::H5File::Mode::read), hb(mb.mean_path(), io::H5File::Mode::read);
  CHECK(ha.read_doubles("displacement") == hb.read_doubles("displacement"));
  CHECK(ha.read_doubles("interface_force") == hb.read_doubles("interface_force"));
}

TEST_CASE("fem.monitor: bad keys name file, line and key", "[fem][monitor]") {
  auto error_of_text = [](const std::string& text) {
    return test::error_of<scene::SceneError>([&] { strip(text); });
  };
  auto error_of = [&](const std::string& extra) {
    return error_of_text(std::string(kStrip) + extra);
  };
  CHECK_THAT(error_of("[[fem.monitor.probes]]\nname = \"tip\"\npoint = [0, 0, 0]\n"),
             Catch::Contains("fem.monitor.probes[2].name") && Catch::Contains("used twice"));
  CHECK_THAT(error_of("[[fem.monitor.probes]]\nname = \"a b\"\npoint = [0, 0, 0]\n"),
             Catch::Contains("fem.monitor.probes[2].name"));
  std::string text = kStrip;
  text.replace(text.find("mean_window = [0.001, 0.003]"), 28, "mean_window = [0.003, 0.001]");
  try {
    strip(text);
    FAIL("a reversed window was accepted");
  } catch (const scene::SceneError& e) {
    CHECK_THAT(e.what(),
               Catch::Contains("fem.monitor.mean_window") && Catch::Contains("strip.toml:"));
  }
  // The reduced backends do not hold the displacement field every step: refused, naming both.
  for (const char* backend : {"modal", "rigid"}) {
    std::string reduced = kStrip;
    reduced.insert(reduced.find("[fem]\n") + 6, std::string("backend = \"") + backend + "\"\n");
    CHECK_THAT(error_of_text(reduced), Catch::Contains("fem.monitor") &&
                                           Catch::Contains("strip.toml:") &&
                                           Catch::Contains(std::string("not \"") + backend));
  }
}
