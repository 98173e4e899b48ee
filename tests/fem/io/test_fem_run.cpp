// End to end with the real solver: a standalone dynamic run of a tiny scene writes HDF5 +
// XDMF + CSV that re-read to the solver's own state; an .inp beam deflects exactly as the
// mesher's beam; the fem_server executable's exit codes and messages.
#include <catch2/catch.hpp>

#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

#include "demfem/fem/fem_output.hpp"
#include "demfem/fem/fem_scene.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/fem/modal_run.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem;
using namespace demfem::fem;

namespace {

using demfem::test::read_text;
using demfem::test::TempDir;

const std::string kMeshDir = std::string(DEMFEM_SOURCE_DIR) + "/cases/meshes";

FemScene scene_from(const std::string& text) {
  const auto doc = scene::Document::parse(text, kMeshDir + "/test_scene.toml");
  return read_fem_scene(doc.root().required_table("fem"));
}

// A cantilever 1 x 0.1 x 0.1 m, clamped at x = 0, 1 kPa on its top (z = 0.1).
const std::string kLoads = R"(
[[fem.clamps]]
nodes = "CLAMPED"
[[fem.pressures]]
surface = "TOP"
magnitude = 1e3
)";

const std::string kTinyDynamic = R"([run]
end_time = 1e-3
output_interval = 5e-4
[fem]
analysis = "dynamic"
dt = 1e-4
mesh = { box = { lo = [0, 0, 0], hi = [0.4, 0.1, 0.1], cells = [4, 1, 1] } }
materials = [{ name = "steel", youngs_modulus = 2.1e11, poisson_ratio = 0.3, density = 7850 }]
[[fem.clamps]]
nodes = "x <= 0"
[[fem.nodal_loads]]
nodes = "x >= 0.4"
force = [0, 0, -100]
amplitude = { type = "table", points = [[0, 0], [5e-4, 1]] }
)";

int run_command(const std::string& cmd) {
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

TEST_CASE("standalone dynamic run: HDF5/XDMF/CSV re-read equal the solver's own state") {
  TempDir tmp("dyn");
  const FemScene s = scene_from(kTinyDynamic.substr(kTinyDynamic.find("[fem]")));
  const FemRunSummary sum = run_fem_standalone(s, 1e-3, 5e-4, tmp.path, "fem", nullptr);
  CHECK(sum.steps == 10);
  CHECK(sum.outputs == 3);  // t = 0, 5e-4, 1e-3
  CHECK(sum.end_time == Approx(1e-3));

  // Reference: the same problem stepped directly (the solver is deterministic, so equal).
  FemSolver ref(s.problem);
  for (int i = 0; i < 10; ++i) ref.advance(1e-4);
  // The third output (file 2; the initial state is file 0) is labelled with the requested
  // time exactly, and records the time of its state (the solver's running sum of dt).
  io::H5File last(tmp.path / "fem_000002.h5", io::H5File::Mode::read);
  CHECK(last.attribute_double("/", "time") == 1e-3);
  CHECK(last.attribute_double("/", "state_time") == ref.time());
  CHECK(io::H5File(tmp.path / "fem_000001.h5", io::H5File::Mode::read)
            .attribute_double("/", "time") == 5e-4);
  CHECK(last.read_doubles("displacement") == ref.displacements());
  CHECK(last.read_doubles("velocity") == ref.velocities());
  CHECK(last.read_doubles("hex8/von_mises") == ref.element_results().von_mises);
  const double umax = summarize(gather_fields(ref)).max_displacement;
  CHECK(umax > 0.0);
  CHECK(sum.max_displacement == umax);

  // Every dataset the XDMF names exists.
  const std::string xdmf = read_text(tmp.path / "fem.xdmf");
  const std::regex ref_re(R"re(>([^<>:]+\.h5):([^<]+)<)re");
  int refs = 0;
  for (auto it = std::sregex_iterator(xdmf.begin(), xdmf.end(), ref_re);
       it != std::sregex_iterator(); ++it) {
    const auto file = tmp.path / (*it)[1].str();
    REQUIRE(std::filesystem::exists(file));
    CHECK(io::H5File(file, io::H5File::Mode::read).exists((*it)[2].str()));
    ++refs;
  }
  CHECK(refs == 3 * 9);

  // CSV: header + 3 rows; the last row's max displacement is the solver's.
  std::ifstream csv(tmp.path / "fem_series.csv");
  std::string line, lastline;
  int rows = -1;
  while (std::getline(csv, line)) {
    ++rows;
    lastline = line;
  }
  CHECK(rows == 3);
  CHECK(std::stod(lastline.substr(lastline.find(',') + 1)) == Approx(umax).epsilon(1e-15));
}

TEST_CASE("an .inp beam deflects as the mesher's beam (static)") {
  // Same geometry, mesh and loads; the .inp numbers nodes and elements in reverse order
  // and names the clamp and the loaded face by sets. Tolerance 1e-9 relative: the two
  // systems differ only in DOF order (round-off of the factorisation).
  const FemScene inp =
      scene_from("[fem]\nanalysis = \"static\"\nmesh = { file = \"beam_hex.inp\" }\n" + kLoads);
  std::string box = kLoads;
  box = std::regex_replace(box, std::regex("\"CLAMPED\""), "\"x <= 0\"");
  box = std::regex_replace(box, std::regex("\"TOP\""), "\"z >= 0.1\"");
  const FemScene mesher = scene_from(
      "[fem]\nanalysis = \"static\"\n"
      "mesh = { box = { lo = [0, 0, 0], hi = [1, 0.1, 0.1], cells = [10, 2, 2] } }\n"
      "materials = [{ name = \"steel\", youngs_modulus = 2.1e11, poisson_ratio = 0.3, "
      "density = 7850 }]\n" +
      box);
  REQUIRE(inp.problem.mesh.nodes.size() == mesher.problem.mesh.nodes.size());
  REQUIRE(inp.problem.pressures[0].faces.size() == mesher.problem.pressures[0].faces.size());
  FemSolver a(inp.problem);
  FemSolver b(mesher.problem);
  a.solve_static();
  b.solve_static();
  const auto ua = a.displacements();
  const auto ub = b.displacements();
  // Tip deflection: mean u_z of the nodes at x = 1 in each mesh.
  auto tip = [](const Mesh& m, const std::vector<double>& u) {
    double sum = 0.0;
    int n = 0;
    for (std::size_t i = 0; i < m.nodes.size(); ++i) {
      if (m.nodes[i][0] > 1.0 - 1e-9) {
        sum += u[3 * i + 2];
        ++n;
      }
    }
    return sum / n;
  };
  const double wa = tip(inp.problem.mesh, ua);
  const double wb = tip(mesher.problem.mesh, ub);
  CHECK(wa < 0.0);
  CHECK(wa == Approx(wb).epsilon(1e-9));
  // Sanity against Euler-Bernoulli, w = q L^4 / (8 E I) with q = p b: a 10 x 2 x 2 hex8
  // mesh with incompatible modes is within a few percent of it (shear and Poisson effects).
  const double q = 1e3 * 0.1, I = 0.1 * std::pow(0.1, 3) / 12.0;
  CHECK(-wa == Approx(q / (8.0 * 2.1e11 * I)).epsilon(0.05));
  // Node by node, through the labels: node label 1000 + i is mesher node i.
  double worst = 0.0, scale = 0.0;
  for (std::size_t i = 0; i < inp.problem.mesh.nodes.size(); ++i) {
    const auto j = static_cast<std::size_t>(inp.problem.mesh.node_labels[i] - 1000);
    for (int k = 0; k < 3; ++k) {
      worst = std::max(worst, std::abs(ua[3 * i + k] - ub[3 * j + k]));
      scale = std::max(scale, std::abs(ub[3 * j + k]));
    }
  }
  CHECK(worst <= 1e-9 * scale);
}

TEST_CASE("fem_server executable: --help, standalone run, bad scene exits 2 naming file:line:key") {
  const std::string exe = std::string(DEMFEM_BINARY_DIR) + "/bin/fem_server";
  REQUIRE(std::filesystem::exists(exe));
  TempDir tmp("exe");
  const auto log = tmp.path / "log.txt";
  CHECK(run_command(exe + " --help > " + log.string() + " 2>&1") == 0);
  CHECK(read_text(log).find("--segment") != std::string::npos);

  const auto good = tmp.path / "tiny.toml";
  std::ofstream(good) << kTinyDynamic;
  CHECK(run_command(exe + " --scene " + good.string() + " --output-dir " +
                    (tmp.path / "out").string() + " > " + log.string() + " 2>&1") == 0);
  CHECK(read_text(log).find("fem: done, dynamic") != std::string::npos);
  CHECK(std::filesystem::exists(tmp.path / "out/fem.xdmf"));
  CHECK(std::filesystem::exists(tmp.path / "out/fem_000002.h5"));

  const auto bad = tmp.path / "bad.toml";
  std::ofstream(bad) << std::regex_replace(kTinyDynamic, std::regex("dt = 1e-4"), "dt = -1e-4");
  CHECK(run_command(exe + " --scene " + bad.string() + " > " + log.string() + " 2>&1") == 2);
  CHECK_THAT(read_text(log), Catch::Contains("bad.toml:6:6: key 'fem.dt'"));

  const auto nodt = tmp.path / "nodt.toml";
  std::ofstream(nodt) << std::regex_replace(kTinyDynamic, std::regex("dt = 1e-4\n"), "");
  CHECK(run_command(exe + " --scene " + nodt.string() + " --output-dir " +
                    (tmp.path / "out2").string() + " > " + log.string() + " 2>&1") == 2);
  CHECK_THAT(read_text(log), Catch::Contains("key 'fem.dt'") && Catch::Contains("is required"));

  // Issue 19: density 0 in a dynamic run crashed fem_server (SIGSEGV) and, run in process,
  // the launcher (exit 139). Both now refuse the scene before any step: exit 2, key named.
  const auto massless = tmp.path / "massless.toml";
  std::ofstream(massless) << std::regex_replace(kTinyDynamic, std::regex("density = 7850"),
                                                "density = 0");
  CHECK(run_command(exe + " --scene " + massless.string() + " --output-dir " +
                    (tmp.path / "out3").string() + " > " + log.string() + " 2>&1") == 2);
  CHECK_THAT(read_text(log),
             Catch::Contains("key 'fem.materials[0].density'") && Catch::Contains("needs mass"));
  const std::string launcher = std::string(DEMFEM_BINARY_DIR) + "/bin/demfem_run";
  if (std::filesystem::exists(launcher)) {
    CHECK(run_command(launcher + " --in-process --quiet --output-dir " +
                      (tmp.path / "out4").string() + " " + massless.string() + " > " +
                      log.string() + " 2>&1") == 2);
    CHECK_THAT(read_text(log), Catch::Contains("key 'fem.materials[0].density'"));
  }

  CHECK(run_command(exe + " --scene " + (tmp.path / "missing.toml").string() + " > " +
                    log.string() + " 2>&1") == 2);
  CHECK_THAT(read_text(log),
             Catch::Contains("missing.toml: cannot open: no such file; expected a scene file"));
}

TEST_CASE("standalone static runs of a shell .inp and a tet box write their topologies") {
  TempDir tmp("static");
  const FemScene shell = scene_from(R"([fem]
analysis = "static"
mesh = { file = "plate_s4r.inp" }
[[fem.clamps]]
nodes = "EDGE"
[[fem.pressures]]
surface = "TOP"
magnitude = 100
)");
  const FemRunSummary a = run_fem_standalone(shell, 1.0, 0.0, tmp.path / "shell", "fem", nullptr);
  CHECK(a.steps == 0);
  CHECK(a.outputs == 1);
  CHECK(a.max_displacement > 0.0);
  CHECK(read_text(tmp.path / "shell/fem.xdmf").find("TopologyType=\"Quadrilateral\"") !=
        std::string::npos);
  io::H5File h5(tmp.path / "shell/fem_000000.h5", io::H5File::Mode::read);
  CHECK(h5.read_doubles("quad4/von_mises").size() == 2);

  const FemScene tets = scene_from(R"([fem]
analysis = "static"
mesh = { box = { lo = [0, 0, 0], hi = [0.4, 0.1, 0.1], cells = [4, 1, 1], element = "tet4" } }
materials = [{ name = "steel", youngs_modulus = 2.1e11, poisson_ratio = 0.3, density = 7850 }]
[[fem.clamps]]
nodes = "xmin"
[[fem.pressures]]
surface = "xmax"
total_force = -1000
)");
  const FemRunSummary b = run_fem_standalone(tets, 1.0, 0.0, tmp.path / "tet", "fem", nullptr);
  CHECK(b.max_displacement > 0.0);
  io::H5File t5(tmp.path / "tet/fem_000000.h5", io::H5File::Mode::read);
  CHECK(t5.read_doubles("tet4/strain").size() == 9 * 24);  // the strain tensors
  // Static equilibrium: the reactions balance the 1000 N pulled out of the x = 0.4 face.
  const auto r = t5.read_doubles("reaction_force");
  double rx = 0.0;
  for (std::size_t i = 0; i < r.size(); i += 3) rx += r[i];
  CHECK(rx == Approx(-1000.0).epsilon(1e-8));
  CHECK(read_text(tmp.path / "tet/fem.xdmf").find("TopologyType=\"Tetrahedron\"") !=
        std::string::npos);
}

TEST_CASE("modal analysis of a mm-tonne model: effective masses in kg, as the SI model's") {
  // Issue 34, item 14: a deck in mm, tonne, s (steel 7.85e-9 t/mm^3, E in MPa) had its
  // effective masses, in tonnes, labelled kg. The same beam in SI is the reference (a 2:1
  // section: no pair of equal frequencies, whose shapes a solver may mix): the
  // frequencies (Hz in both systems) and the effective masses in kg agree to round-off.
  TempDir dir;
  auto beam = [](const char* hi, const char* e, const char* rho) {
    return std::string("[fem]\nanalysis = \"modal\"\nmesh = { box = { lo = [0, 0, 0], hi = ") + hi +
           ", cells = [10, 1, 1] } }\nmaterials = [{ name = \"steel\", youngs_modulus = " + e +
           ", poisson_ratio = 0.3, density = " + rho +
           " }]\n[fem.modal]\nmodes = 4\n[[fem.clamps]]\nnodes = \"x <= 0\"\n";
  };
  std::ostringstream table_si, table_mm, table_other;
  run_modal_analysis(scene_from(beam("[1, 0.1, 0.05]", "2.1e11", "7850")), dir / "si", &table_si);
  run_modal_analysis(scene_from(beam("[1000, 100, 50]", "2.1e5", "7.85e-9")), dir / "mm",
                     &table_mm);
  // Densities of another system (in-lbf-s: 7.3e-4 for steel; here the SI beam with 1e-7 of its
  // density): not taken for tonnes, not converted, labelled as the model's mass unit.
  run_modal_analysis(scene_from(beam("[1, 0.1, 0.05]", "2.1e11", "7.85e-4")), dir / "other",
                     &table_other);
  CHECK_THAT(table_si.str(), Catch::Contains("eff. mass x, y, z (kg)"));
  CHECK_THAT(table_mm.str(), Catch::Contains("eff. mass x, y, z (kg)"));
  CHECK_THAT(table_other.str(), Catch::Contains("eff. mass x, y, z (the model's mass unit)"));
  auto rows = [](const std::filesystem::path& csv) {
    std::istringstream in(read_text(csv));
    std::string line;
    std::getline(in, line);  // header
    std::vector<std::vector<double>> out;
    while (std::getline(in, line)) {
      std::vector<double> r;
      std::istringstream cells(line);
      for (std::string c; std::getline(cells, c, ',');) r.push_back(std::stod(c));
      out.push_back(r);
    }
    return out;
  };
  const auto si = rows(dir / "si/fem_modes.csv"), mm = rows(dir / "mm/fem_modes.csv"),
             other = rows(dir / "other/fem_modes.csv");
  REQUIRE(other.size() == 4);
  for (std::size_t j = 0; j < 4; ++j)  // effective mass z: 1e-7 of the SI beam's
    CHECK(other[j][10] == Approx(1e-7 * si[j][10]).epsilon(1e-8).margin(1e-9 * 39.25e-7));
  REQUIRE(si.size() == 4);
  REQUIRE(mm.size() == 4);
  double zmass = 0.0;
  for (std::size_t j = 0; j < 4; ++j) {
    CHECK(mm[j][1] == Approx(si[j][1]).epsilon(1e-9));  // frequency, Hz
    // participation (sqrt kg), effective mass (kg) and fraction along x, y, z
    for (std::size_t c = 5; c < 14; ++c)
      CHECK(mm[j][c] == Approx(si[j][c]).epsilon(1e-8).margin(1e-9 * 39.25));
    zmass += si[j][10] + si[j][9];
  }
  CHECK(zmass > 10.0);  // the bending modes carry kilograms of the 39 kg beam
}
