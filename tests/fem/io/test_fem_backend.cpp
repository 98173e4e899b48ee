// FemBackend (the protocol adapter) on in-process interface buffers: forces in, kinematics
// out, equal to driving the solver directly; checkpoint/restore gives a bitwise-identical
// continuation; bad input is refused.
#ifdef DEMFEM_HAVE_PROTOCOL
#include <catch2/catch.hpp>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include "demfem/fem/fem_backend.hpp"
#include "demfem/fem/fem_scene.hpp"

using namespace demfem;
using namespace demfem::fem;

namespace {

FemProblem plate_problem() {
  const auto doc = scene::Document::parse(R"([fem]
mesh = { box = { lo = [0, 0, 0], hi = [0.4, 0.1, 0.05], cells = [4, 1, 1] } }
materials = [{ name = "steel", youngs_modulus = 2.1e11, poisson_ratio = 0.3, density = 7850 }]
interface_surface = "zmax"
[[fem.clamps]]
nodes = "x <= 0"
)",
                                          "backend.toml");
  return read_fem_scene(doc.root().required_table("fem")).problem;
}

/// In-process bulk arrays laid out as the segment's: [buffer][positions, velocities,
/// accelerations, forces, dem_positions][3n].
struct LocalBuffers {
  std::vector<double> reference;
  std::vector<std::int32_t> triangles;
  std::vector<double> arrays;
  protocol::InterfaceBuffers buffers;
  explicit LocalBuffers(const InterfaceMesh& m)
      : reference(m.reference_positions),
        triangles(m.triangles),
        arrays(2 * 5 * 3 * m.node_count(), 0.0) {
    buffers.bind(m.node_count(), m.triangle_count(), reference.data(), triangles.data(),
                 arrays.data());
  }
};

std::vector<double> downward(std::size_t nodes, double fz) {
  std::vector<double> f(3 * nodes, 0.0);
  for (std::size_t i = 0; i < nodes; ++i) f[3 * i + 2] = fz;
  return f;
}

}  // namespace

TEST_CASE("FemBackend: static step = direct solve, kinematics written into the buffer") {
  FemSolver solver(plate_problem());
  FemBackend backend(solver);
  const auto mesh = backend.published_mesh();
  REQUIRE(mesh);
  REQUIRE(mesh->node_count() > 0);
  LocalBuffers local(*mesh);
  const auto f = downward(mesh->node_count(), -50.0);
  std::copy(f.begin(), f.end(), local.buffers.forces(1).begin());
  protocol::StepCommand cmd;
  cmd.buffer = 1;
  cmd.flags = protocol::kStepStatic;
  const auto r = backend.step(cmd, local.buffers);

  FemSolver direct(plate_problem());
  direct.set_interface_forces(f);
  direct.solve_static();
  std::vector<double> pos(f.size()), vel(f.size()), acc(f.size());
  direct.interface_kinematics(pos, vel, acc);
  const auto got = local.buffers.positions(1);
  CHECK(std::vector<double>(got.begin(), got.end()) == pos);
  // Buffer 0 untouched.
  const auto other = local.buffers.positions(0);
  CHECK(std::all_of(other.begin(), other.end(), [](double v) { return v == 0.0; }));
  const auto u = direct.displacements();
  double umax = 0.0;
  for (std::size_t i = 0; i < u.size(); i += 3) {
    umax = std::max(umax, std::sqrt(u[i] * u[i] + u[i + 1] * u[i + 1] + u[i + 2] * u[i + 2]));
  }
  CHECK(umax > 0.0);
  CHECK(r.values[0] == umax);
}

TEST_CASE("FemBackend: the static solution is written, at the time it applies (issue 34, 10)") {
  // One-way static coupling: the reference state at t = 0, then one static solve with the
  // forces of the coupling step that ends at 0.021 s. Reference: the solver's own field
  // (bitwise) and that time. Before the fix only the t = 0 state was written.
  const auto dir =
      std::filesystem::temp_directory_path() / ("demfem_fem_static_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  FemSolver solver(plate_problem());
  {
    FemOutput output(dir, "fem", solver.problem().mesh);
    FemBackend backend(solver, &output, 0.0);
    backend.write_initial_output();
    LocalBuffers local(*backend.published_mesh());
    const auto f = downward(local.buffers.node_count(), -50.0);
    std::copy(f.begin(), f.end(), local.buffers.forces(0).begin());
    protocol::StepCommand cmd;
    cmd.step = 20;
    cmd.time = 0.020;
    cmd.dt = 1e-3;
    cmd.flags = protocol::kStepStatic;
    backend.step(cmd, local.buffers);
    backend.write_checkpoint(dir / "fem.h5", 21);
    backend.write_final_output();
    REQUIRE(output.steps() == 2);
    CHECK(output.last_state_time() == 0.021);
    // A restore of the checkpoint taken after the solve keeps the static output and does not
    // write it twice.
    backend.restore_checkpoint(dir / "fem.h5", 21);
    backend.write_final_output();
    CHECK(output.steps() == 2);
  }
  io::H5File h5(dir / "fem_000001.h5", io::H5File::Mode::read);
  CHECK(h5.attribute_double("/", "time") == 0.021);
  const auto u = h5.read_doubles("displacement");
  const auto expected = solver.displacements();
  CHECK(u == std::vector<double>(expected.begin(), expected.end()));
  double umax = 0.0;
  for (std::size_t i = 0; i + 2 < u.size(); i += 3)
    umax = std::max(umax, std::sqrt(u[i] * u[i] + u[i + 1] * u[i + 1] + u[i + 2] * u[i + 2]));
  CHECK(umax > 0.0);
  std::ifstream csv(dir / "fem_series.csv");
  std::string header, row0, row1, extra;
  std::getline(csv, header);
  std::getline(csv, row0);
  std::getline(csv, row1);
  CHECK_FALSE(std::getline(csv, extra));
  const auto comma = row1.find(',');
  CHECK(std::stod(row1.substr(0, comma)) == 0.021);
  CHECK(std::stod(row1.substr(comma + 1)) == umax);
  std::filesystem::remove_all(dir);
}

TEST_CASE("FemBackend: checkpoint/restore continues bitwise identically, bad input refused") {
  const auto dir =
      std::filesystem::temp_directory_path() / ("demfem_fem_backend_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  FemSolver solver(plate_problem());
  FemBackend backend(solver);
  LocalBuffers local(*backend.published_mesh());
  const auto f = downward(local.buffers.node_count(), -20.0);
  std::copy(f.begin(), f.end(), local.buffers.forces(0).begin());
  protocol::StepCommand cmd;
  cmd.dt = 1e-4;
  backend.step(cmd, local.buffers);
  backend.write_checkpoint(dir / "fem.h5", 1);
  CHECK_FALSE(std::filesystem::exists(dir / "fem.h5.part"));
  cmd.step = 1;
  backend.step(cmd, local.buffers);
  const auto p = local.buffers.positions(0);
  const std::vector<double> first(p.begin(), p.end());
  const auto a = local.buffers.accelerations(0);
  const std::vector<double> first_acc(a.begin(), a.end());

  backend.restore_checkpoint(dir / "fem.h5", 1);
  backend.step(cmd, local.buffers);
  CHECK(std::vector<double>(p.begin(), p.end()) == first);
  CHECK(std::vector<double>(a.begin(), a.end()) == first_acc);

  CHECK_THROWS_WITH(backend.restore_checkpoint(dir / "fem.h5", 7),
                    Catch::Contains("checkpoint is of step 1, asked to restore step 7"));
  cmd.dt = -1.0;
  CHECK_THROWS_WITH(backend.step(cmd, local.buffers), Catch::Contains("dt must be > 0"));
  cmd.dt = 1e-4;
  local.buffers.forces(0)[0] = std::nan("");
  CHECK_THROWS_WITH(backend.step(cmd, local.buffers), Catch::Contains("not finite"));
  std::filesystem::remove_all(dir);
}
TEST_CASE("FemBackend: iterated steps leave the results and output of plain steps") {
  // Implicit coupling: each step tried three times through the IterationGate (save point in
  // memory, restore on redo), the last try with the forces the plain run uses. Reference: the
  // plain run. Tolerance: none (bitwise kinematics, the same output series, text for text).
  const auto base =
      std::filesystem::temp_directory_path() / ("demfem_fem_iter_" + std::to_string(::getpid()));
  std::vector<std::vector<double>> runs;
  for (const bool iterated : {false, true}) {
    const auto dir = base / (iterated ? "iterated" : "plain");
    std::filesystem::remove_all(dir);
    FemSolver solver(plate_problem());
    FemOutput output(dir, "fem", solver.problem().mesh);
    FemBackend backend(solver, &output, 5e-4);  // an output every 5 steps
    backend.write_initial_output();
    protocol::IterationGate gate;
    LocalBuffers local(*backend.published_mesh());
    std::vector<double> kin;
    for (std::int64_t k = 0; k < 12; ++k) {
      protocol::StepCommand cmd;
      cmd.step = k;
      cmd.dt = 1e-4;
      for (int t = 0; t < (iterated ? 3 : 1); ++t) {
        cmd.flags = iterated ? protocol::kStepIterate | (t > 0 ? protocol::kStepRedo : 0u) : 0u;
        const double fz = (iterated && t == 1) ? 500.0 : -20.0 * static_cast<double>(k + 1);
        const auto f = downward(local.buffers.node_count(), fz);
        std::copy(f.begin(), f.end(), local.buffers.forces(0).begin());
        gate.step(backend, cmd, local.buffers);
      }
      for (auto a : {local.buffers.positions(0), local.buffers.velocities(0),
                     local.buffers.accelerations(0)})
        kin.insert(kin.end(), a.begin(), a.end());
    }
    gate.accept(backend);  // as on Shutdown
    backend.write_final_output();
    runs.push_back(kin);
    CHECK(output.steps() == 4);  // t = 0, 0.5, 1.0 ms and the end state
  }
  CHECK(runs[0] == runs[1]);
  for (const char* file : {"fem.xdmf", "fem_series.csv"}) {
    INFO(file);
    std::ifstream a(base / "plain" / file), b(base / "iterated" / file);
    const std::string ta((std::istreambuf_iterator<char>(a)), {}),
        tb((std::istreambuf_iterator<char>(b)), {});
    CHECK(ta.size() > 50);
    CHECK(ta == tb);
  }
  std::filesystem::remove_all(base);
}
#endif
