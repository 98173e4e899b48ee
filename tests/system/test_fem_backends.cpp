// The FEM backends in coupled runs (docs/backends.md):
//  * the modal-reduced backend (10 modes + static correction) follows the full FEM's interface
//    displacement on the dynamic beam within 1 % (in process, the same code the servers run);
//  * a run checkpointed with fem_server and resumed with --fem-backend modal (three processes)
//    continues with the interface kinematics continuous to 1e-9 m and ends within 1 % of the
//    full-FEM run; the checkpoint records the backend, and a swap to the rigid body is refused;
//  * the rigid-body backend runs the beam case and its statics match rigid-body theory.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <regex>

#include "demfem/io/h5_file.hpp"
#include "demfem_test/coupled_history.hpp"
#include "demfem_test/launch.hpp"
#include "demfem_test/run_output.hpp"
#include "demfem_test/temp_dir.hpp"

namespace fs = std::filesystem;
using namespace demfem;

namespace {

const std::string kSource = DEMFEM_SOURCE_DIR;
const std::string kRun = std::string(DEMFEM_BINARY_DIR) + "/bin/demfem_run";

double max_abs(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = std::max(m, std::abs(x));
  return m;
}

/// Displacements of the top-face (interface) nodes in fem_NNNNNN.h5 of a run's output.
std::vector<double> top_displacement(const fs::path& out, int step) {
  char name[32];
  std::snprintf(name, sizeof name, "fem_%06d.h5", step);
  const io::H5File mesh(out / "fem_mesh.h5", io::H5File::Mode::read);
  const auto xyz = mesh.read_doubles("nodes");
  const auto u = io::H5File(out / name, io::H5File::Mode::read).read_doubles("displacement");
  std::vector<double> top;
  for (std::size_t n = 0; 3 * n + 2 < xyz.size(); ++n)
    if (xyz[3 * n + 2] > 0.1 - 1e-9) top.insert(top.end(), {u[3 * n], u[3 * n + 1], u[3 * n + 2]});
  return top;
}

}  // namespace

TEST_CASE(
    "modal backend: the coupled dynamic beam's interface displacement within 1 % of the "
    "full FEM with 10 modes",
    "[backends]") {
  test::TempDir dir("modal_accuracy");
  const std::string scene = kSource + "/cases/beam_dynamic_ci.toml";
  const auto full = test::coupled_history(scene, {}, dir.path / "full").u;
  const auto modal =
      test::coupled_history(scene, {"fem.backend=\"modal\"", "fem.modal={ modes = 10 }"},
                            dir.path / "modal")
          .u;
  REQUIRE(full.size() == 50);
  REQUIRE(modal.size() == full.size());
  double d = 0, u = 0;
  for (std::size_t s = 0; s < full.size(); ++s) {
    for (std::size_t k = 0; k < full[s].size(); ++k)
      d = std::max(d, std::abs(modal[s][k] - full[s][k]));
    u = std::max(u, max_abs(full[s]));
  }
  std::printf(
      "modal backend, 10 modes: interface displacement within %.3e m of the full FEM's "
      "(largest %.3e m): %.4f %%\n",
      d, u, 100 * d / u);
  CHECK(d < 0.01 * u);
}

TEST_CASE("swap on resume: fem_server's checkpoint continued by the modal backend", "[backends]") {
  test::TempDir dir("swap");
  const std::string scene = kSource + "/cases/beam_checkpoint_ci.toml";
  const std::vector<std::string> common = {"--quiet",
                                           "--set",
                                           "run.output_interval=1e-4",
                                           "--set",
                                           "checkpoint.keep=10",
                                           "--set",
                                           "dem.output.particles=false"};
  auto run = [&](const fs::path& out, std::vector<std::string> extra) {
    std::vector<std::string> argv = {kRun, scene, "--output-dir", out.string()};
    argv.insert(argv.end(), common.begin(), common.end());
    argv.insert(argv.end(), extra.begin(), extra.end());
    const auto r = test::wait_for(test::launch(dir.path, argv));
    for (const auto& seg : test::segments_of(r.out)) CHECK(!fs::exists("/dev/shm/" + seg));
    return r;
  };
  const fs::path full = dir.path / "full", swapped = dir.path / "swapped";
  const auto a = run(full, {});
  REQUIRE(a.status == 0);
  const fs::path cp = full / "checkpoints" / "step-000020";
  CHECK(
      io::H5File(cp / "coupler.h5", io::H5File::Mode::read).attribute_string("/", "fem_backend") ==
      "fem");
  CHECK(io::H5File(cp / "fem.h5", io::H5File::Mode::read).attribute_string("/", "backend") ==
        "fem");
  const auto b = run(swapped, {"--resume", cp.string(), "--fem-backend", "modal", "--set",
                               "fem.modal={ modes = 20 }"});
  INFO(b.err);
  REQUIRE(b.status == 0);
  CHECK(b.err.find("was taken with the FEM backend \"fem\"") != std::string::npos);
  // The modal backend's own account of the swap: the interface continues within ... m.
  std::smatch m;
  const std::regex cont(
      "interface positions continue within ([0-9.e+-]+) m, velocities within "
      "([0-9.e+-]+) m/s");
  REQUIRE(std::regex_search(b.err, m, cont));
  const double at_swap = std::stod(m[1]);
  std::printf(
      "swap at step 20: interface positions continue within %.3g m, velocities within "
      "%s m/s\n",
      at_swap, m[2].str().c_str());
  CHECK(at_swap <= 1e-9);
  // After the swap, step by step against the uninterrupted full-FEM run.
  const auto u20 = top_displacement(full, 20);
  double first = 0, worst = 0, scale = 0;
  for (int step = 21; step <= 50; ++step) {
    const auto ua = top_displacement(full, step), ub = top_displacement(swapped, step);
    REQUIRE(ua.size() == ub.size());
    double d = 0;
    for (std::size_t k = 0; k < ua.size(); ++k) d = std::max(d, std::abs(ua[k] - ub[k]));
    if (step == 21) first = d;
    worst = std::max(worst, d);
    scale = std::max(scale, max_abs(ua));
  }
  const auto ua = top_displacement(full, 50), ub = top_displacement(swapped, 50);
  double end = 0;
  for (std::size_t k = 0; k < ua.size(); ++k) end = std::max(end, std::abs(ua[k] - ub[k]));
  std::printf(
      "after the swap: step 21 within %.3g m; steps 21-50 within %.3g m (largest "
      "displacement %.3g m); at the end %.3g m = %.4f %% of %.3g m\n",
      first, worst, scale, end, 100 * end / max_abs(ua), max_abs(ua));
  CHECK(u20.size() == ua.size());
  CHECK(first <= 1e-9);
  CHECK(end < 0.01 * max_abs(ua));
  // The swapped run's checkpoints record the modal backend; the rigid body cannot take them.
  const fs::path cp40 = swapped / "checkpoints" / "step-000040";
  CHECK(io::H5File(cp40 / "coupler.h5", io::H5File::Mode::read)
            .attribute_string("/", "fem_backend") == "modal");
  const auto c = run(dir.path / "rigid", {"--resume", cp40.string(), "--fem-backend", "rigid"});
  CHECK(c.status == 2);
  CHECK(c.err.find("the rigid-body backend has six coordinates") != std::string::npos);
  // ... and the full FEM continues the modal backend's checkpoint (its reconstructed state).
  const auto d = run(dir.path / "back", {"--resume", cp40.string(), "--fem-backend", "fem"});
  CHECK(d.status == 0);
  CHECK(d.err.find("fem backend took over the full state written by the modal backend") !=
        std::string::npos);
}

TEST_CASE("rigid-body backend: the beam as a rigid body on four corner springs", "[backends]") {
  // The beam case's spheres on the beam as one rigid body held by four vertical springs at the
  // bottom corners, the other DOFs fixed; one-way static: the settled weight W of the spheres
  // and the body's own weight are carried by the springs: d_z = -(W + m g) / (4 k).
  test::TempDir dir("rigid");
  const double k = 1e8;
  std::string springs = "fem.rigid={ fixed = [\"x\", \"y\", \"rz\"], springs = [";
  for (const char* p : {"[0, 0, 0]", "[1, 0, 0]", "[0, 0.1, 0]", "[1, 0.1, 0]"})
    springs += std::string("{ point = ") + p + ", stiffness = [0, 0, 1e8] },";
  springs.back() = ']';
  springs += " }";
  const std::vector<std::string> argv = {kRun,
                                         kSource + "/cases/beam_fixed_ci.toml",
                                         "--output-dir",
                                         (dir.path / "out").string(),
                                         "--quiet",
                                         "--fem-backend",
                                         "rigid",
                                         "--set",
                                         springs,
                                         "--set",
                                         "fem.gravity=[0, 0, -9.81]"};
  const auto r = test::wait_for(test::launch(dir.path, argv));
  INFO(r.err);
  REQUIRE(r.status == 0);
  const auto rows = test::read_text(dir.path / "out" / "coupling.csv");
  const auto last = rows.substr(rows.rfind('\n', rows.size() - 2) + 1);
  std::vector<double> v;
  std::stringstream ss(last);
  for (std::string cell; std::getline(ss, cell, ',');) v.push_back(std::stod(cell));
  const double w = -v[10], body = 7800.0 * 1.0 * 0.1 * 0.1 * 9.81;  // force_sum_z, beam weight
  const double dz = (w + body) / (4 * k);
  std::printf(
      "rigid backend: settled weight %.6g N + beam %.6g N on 4 x %.0e N/m: |d_z| %.6e m, "
      "theory %.6e m\n",
      w, body, k, v[9], dz);
  CHECK(w == Approx(51.0 * 9.81).epsilon(1e-6));
  CHECK(v[9] == Approx(dz).epsilon(1e-9));
}
