// The coupling schemes against test doubles of the two solvers, driven through LocalLink:
// the order of the solver steps, what each solver is given (thesis Algorithm 3, eq. 3.3-3.8),
// the one-way static settle logic, the diagnostics and the blow-up stops.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "demfem/coupling/coupling_run.hpp"

using namespace demfem;
using namespace demfem::coupling;
using protocol::kStepSetKinematics;
using protocol::kStepStatic;

namespace {

constexpr double kWeight = 10.0;    // N per node from the fake DEM
constexpr double kStiffness = 1e4;  // N/m per node in the fake FEM

// Written by both solvers, which may step at the same time (the concurrent scheme).
struct Log {
  std::vector<std::string> calls;  // "dem 3", "fem 3"
  std::mutex mutex;
  void add(std::string call) {
    std::lock_guard<std::mutex> lock(mutex);
    calls.push_back(std::move(call));
  }
};

InterfaceMesh triangle() {
  InterfaceMesh m;
  m.reference_positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  m.triangles = {0, 1, 2};
  return m;
}

// A quasi-static spring per node: u_z = F_z / k; the velocity is the difference quotient and
// the acceleration a constant marker, so that a test can see what is passed on.
class FakeFem : public protocol::SolverBackend {
 public:
  explicit FakeFem(Log& log) : log_(log) {}
  std::string name() const override { return "fake-fem"; }
  std::optional<InterfaceMesh> published_mesh() override { return triangle(); }
  void on_mesh(const InterfaceMesh&) override {}
  StepResult step(const StepCommand& cmd, InterfaceBuffers& buf) override {
    log_.add("fem " + std::to_string(cmd.step));
    commands.push_back(cmd);
    auto f = buf.forces(cmd.buffer);
    forces_seen.emplace_back(f.begin(), f.end());
    const auto ref = buf.reference_mesh().reference_positions;
    double umax = 0;
    for (std::size_t i = 0; i < buf.node_count(); ++i) {
      for (int k = 0; k < 3; ++k) {
        const std::size_t j = 3 * i + k;
        const double u = f[j] / kStiffness;
        const double u_old = buf.positions(cmd.buffer)[j] - ref[j];
        buf.velocities(cmd.buffer)[j] = (u - u_old) / cmd.dt;
        buf.accelerations(cmd.buffer)[j] = 0.25;
        buf.positions(cmd.buffer)[j] = ref[j] + u;
        umax = std::max(umax, std::abs(u));
      }
    }
    StepResult r;
    r.values[0] = umax;
    return r;
  }
  void write_checkpoint(const std::filesystem::path&, std::int64_t) override {}
  void restore_checkpoint(const std::filesystem::path&, std::int64_t) override {}
  // Its state is the buffer's (it has none of its own): nothing to save.
  bool supports_iteration() const override { return iterates; }
  void save_iteration_state() override { log_.add("fem save"); }
  void restore_iteration_state() override { log_.add("fem restore"); }
  void accept_step() override { log_.add("fem accept"); }

  std::vector<StepCommand> commands;
  std::vector<std::vector<double>> forces_seen;
  bool iterates = true;

 private:
  Log& log_;
};

// Pushes each node down with a force that decays to kWeight; moves its mesh copy as the
// kinematics say (x + v dt + a dt^2 / 2) when it is given them.
class FakeDem : public protocol::SolverBackend {
 public:
  explicit FakeDem(Log& log) : log_(log) {}
  std::string name() const override { return "fake-dem"; }
  std::optional<InterfaceMesh> published_mesh() override { return std::nullopt; }
  void on_mesh(const InterfaceMesh& m) override { mesh_ = m.reference_positions; }
  StepResult step(const StepCommand& cmd, InterfaceBuffers& buf) override {
    log_.add("dem " + std::to_string(cmd.step));
    if (cmd.step == throw_step) throw std::runtime_error("dem: injected failure");
    commands.push_back(cmd);
    const auto b = cmd.buffer;
    if (cmd.flags & kStepSetKinematics) {
      auto p = buf.positions(b), v = buf.velocities(b), a = buf.accelerations(b);
      given_positions.emplace_back(p.begin(), p.end());
      given_velocities.emplace_back(v.begin(), v.end());
      given_accelerations.emplace_back(a.begin(), a.end());
      for (std::size_t j = 0; j < mesh_.size(); ++j)
        mesh_[j] = p[j] + v[j] * cmd.dt + 0.5 * a[j] * cmd.dt * cmd.dt;
    }
    const double scale = 1.0 + std::pow(0.5, static_cast<double>(cmd.step));
    const auto ref = buf.reference_mesh().reference_positions;
    for (std::size_t j = 0; j < mesh_.size(); ++j) {
      // A contact spring of `stiffness` (0 by default) under the load pushes back on a mesh
      // that moves down: the two-way part of the implicit tests.
      buf.forces(b)[j] = (j % 3 == 2) ? -kWeight * scale - stiffness * (mesh_[j] - ref[j]) : 0.0;
      buf.dem_positions(b)[j] = mesh_[j];
    }
    if (cmd.step == nan_step) buf.forces(b)[4] = std::numeric_limits<double>::quiet_NaN();
    StepResult r;
    r.values[0] = cmd.step == overlap_step ? 1e-3 : 1e-6;        // flexible max overlap
    r.values[1] = std::pow(0.5, static_cast<double>(cmd.step));  // kinetic energy
    r.values[2] = 2e-6;
    return r;
  }
  void write_checkpoint(const std::filesystem::path&, std::int64_t) override {}
  void restore_checkpoint(const std::filesystem::path&, std::int64_t) override {}
  // Stateless between steps when it is given the kinematics (as the implicit scheme does).
  bool supports_iteration() const override { return true; }
  void save_iteration_state() override { log_.add("dem save"); }
  void restore_iteration_state() override { log_.add("dem restore"); }
  void accept_step() override { log_.add("dem accept"); }

  std::vector<StepCommand> commands;
  std::vector<std::vector<double>> given_positions, given_velocities, given_accelerations;
  double stiffness = 0.0;  // N/m per node
  std::int64_t nan_step = -1;
  std::int64_t overlap_step = -1;
  std::int64_t throw_step = -1;

 private:
  Log& log_;
  std::vector<double> mesh_;
};

struct Fixture {
  Log log;
  FakeDem* dem = nullptr;
  FakeFem* fem = nullptr;
  std::unique_ptr<LocalLink> link;
  std::filesystem::path dir;
  CouplingSettings settings;

  explicit Fixture(Scheme scheme, std::int64_t steps = 4) {
    auto d = std::make_unique<FakeDem>(log);
    auto f = std::make_unique<FakeFem>(log);
    dem = d.get();
    fem = f.get();
    link = std::make_unique<LocalLink>(std::move(d), std::move(f));
    dir = std::filesystem::temp_directory_path() /
          ("demfem-test-schemes-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    settings.has_dem = settings.has_fem = true;
    settings.scheme = scheme;
    settings.dem_dt = 1e-5;
    settings.fem_dt = settings.coupling_dt = 1e-3;
    settings.dem_substeps = 100;
    settings.step_count = steps;
    settings.run.end_time = 1e-3 * static_cast<double>(steps);
  }
  ~Fixture() { std::filesystem::remove_all(dir); }
  RunSummary run() {
    CouplingRun r(*link, settings, dir);
    return r.run();
  }
  std::size_t csv_rows() const {
    std::ifstream in(dir / "coupling.csv");
    std::string line;
    std::size_t n = 0;
    while (std::getline(in, line)) ++n;
    return n - 1;
  }
  static inline int counter = 0;
};

}  // namespace

TEST_CASE("just-in-time: DEM then FEM, DEM given the FEM state at t_i") {
  Fixture fx(Scheme::just_in_time, 3);
  fx.run();
  CHECK(fx.log.calls ==
        std::vector<std::string>{"dem 0", "fem 0", "dem 1", "fem 1", "dem 2", "fem 2"});
  REQUIRE(fx.dem->given_positions.size() == 3);
  for (const auto& c : fx.dem->commands) {
    CHECK(c.flags == kStepSetKinematics);
    CHECK(c.substeps == 100);
    CHECK(c.force_mode == ForceMode::last_substep);
  }
  for (const auto& c : fx.fem->commands) CHECK(c.flags == 0);
  // Step 0 starts from the reference at rest.
  CHECK(fx.dem->given_positions[0][2] == 0.0);
  CHECK(fx.dem->given_velocities[0][2] == 0.0);
  CHECK(fx.dem->given_accelerations[0][2] == 0.0);
  // Step 1: the FEM's state at t_1, acceleration included (Algorithm 3, line 8).
  const double u1 = -kWeight * 2.0 / kStiffness;  // FEM 0 got the DEM 0 force (scale 2)
  CHECK(fx.dem->given_positions[1][2] == Approx(u1).epsilon(1e-14));
  CHECK(fx.dem->given_velocities[1][2] == Approx(u1 / 1e-3).epsilon(1e-12));
  CHECK(fx.dem->given_accelerations[1][2] == 0.25);
  // The FEM of step i gets the DEM force of the same step (eq. 3.3).
  CHECK(fx.fem->forces_seen[1][2] == Approx(-kWeight * 1.5));
}

TEST_CASE("predictive: FEM first with the last forces, DEM from P_i with V = dP/dt, A = 0") {
  Fixture fx(Scheme::predictive, 3);
  fx.settings.force_averaging = true;
  auto sum = fx.run();
  CHECK(fx.log.calls ==
        std::vector<std::string>{"fem 0", "dem 0", "fem 1", "dem 1", "fem 2", "dem 2"});
  // FEM 0 sees no force yet, FEM 1 the DEM 0 force (scale 2), FEM 2 the DEM 1 force.
  CHECK(fx.fem->forces_seen[0][2] == 0.0);
  CHECK(fx.fem->forces_seen[1][2] == Approx(-2.0 * kWeight));
  CHECK(fx.fem->forces_seen[2][2] == Approx(-1.5 * kWeight));
  for (const auto& c : fx.dem->commands) CHECK(c.force_mode == ForceMode::average);
  // DEM 2 starts at P_2 (from FEM 1) and moves to P_3 (from FEM 2): eq. 3.5-3.7.
  const double p2 = -2.0 * kWeight / kStiffness, p3 = -1.5 * kWeight / kStiffness;
  CHECK(fx.dem->given_positions[2][2] == Approx(p2).epsilon(1e-14));
  CHECK(fx.dem->given_velocities[2][2] == Approx((p3 - p2) / 1e-3).epsilon(1e-12));
  CHECK(fx.dem->given_accelerations[2][2] == 0.0);
  // So the DEM copy ends where the FEM is: no drift (up to round-off).
  CHECK(sum.last.drift < 1e-15);
}

TEST_CASE("just-in-time drift and interface work are measured") {
  Fixture fx(Scheme::just_in_time, 3);
  auto sum = fx.run();
  // DEM 2 moves from P_2 with V_2 and A = 0.25 for dt; the FEM lands on P_3 instead.
  CHECK(sum.last.drift > 0.0);
  CHECK(std::isfinite(sum.last.work_dem));
  CHECK(sum.last.energy_error == sum.last.work_dem - sum.last.work_fem);
  // FEM work by the trapezoidal rule, by hand: steps 0..2 apply forces 2, 1.5, 1.25 (x -W)
  // and move the three nodes to u = F / k.
  const double f[] = {0.0, -2.0 * kWeight, -1.5 * kWeight, -1.25 * kWeight};
  double w = 0.0;
  for (int i = 1; i <= 3; ++i) w += 3 * 0.5 * (f[i - 1] + f[i]) * (f[i] - f[i - 1]) / kStiffness;
  CHECK(sum.last.work_fem == Approx(w).epsilon(1e-12));
  CHECK(fx.csv_rows() == 3);
}

TEST_CASE("one-way static: DEM on the fixed mesh until settled, then one static FEM solve") {
  Fixture fx(Scheme::one_way_static, 20);
  fx.settings.settle_min_time = 3e-3;       // not before the end of step 2
  fx.settings.settle_kinetic_energy = 0.1;  // 0.5^step <= 0.1 from step 4
  auto sum = fx.run();
  CHECK(sum.settled);
  CHECK(sum.steps == 5);
  REQUIRE(fx.fem->commands.size() == 1);
  CHECK(fx.fem->commands[0].flags == kStepStatic);
  CHECK(fx.fem->commands[0].step == 4);
  for (const auto& c : fx.dem->commands) CHECK(c.flags == 0);  // mesh stays fixed
  CHECK(fx.dem->given_positions.empty());
  CHECK(fx.fem->forces_seen[0][2] == Approx(-kWeight * (1 + std::pow(0.5, 4))));
  const double u = -kWeight * (1 + std::pow(0.5, 4)) / kStiffness;
  CHECK(sum.positions[2] == Approx(u));
}

TEST_CASE("one-way static that does not settle by end_time stops with a clear error") {
  Fixture fx(Scheme::one_way_static, 3);
  fx.settings.settle_kinetic_energy = 1e-9;
  CHECK_THROWS_WITH(fx.run(), Catch::Contains("did not settle") &&
                                  Catch::Contains("coupling.settle.kinetic_energy"));
  CHECK(fx.fem->commands.empty());
}

TEST_CASE("one-way static without a criterion settles at run.end_time") {
  Fixture fx(Scheme::one_way_static, 3);
  auto sum = fx.run();
  CHECK(sum.settled);
  CHECK(fx.dem->commands.size() == 3);
  CHECK(fx.fem->commands.size() == 1);
}

TEST_CASE("a NaN force stops the run naming the step and the quantity; the CSV stays") {
  // The DEM's blow-up (exit status 3), named with its backend and the node, found before the
  // FEM is given the force (it would otherwise be blamed for the motion it causes; issue 36:
  // an external DEM's forces are checked as an external FEM's kinematics are).
  Fixture fx(Scheme::just_in_time, 6);
  fx.dem->nan_step = 3;
  try {
    fx.run();
    FAIL("no blow-up");
  } catch (const SolverFailure& e) {
    CHECK(e.role() == protocol::Role::dem);
    CHECK(e.step() == 3);
    CHECK(e.kind() == protocol::ErrorKind::blow_up);
    CHECK_THAT(e.what(), Catch::Contains("step 3") && Catch::Contains("fake-dem") &&
                             Catch::Contains("force it wrote for interface node 1"));
  }
  CHECK(fx.csv_rows() == 3);  // steps 0..2; the bad step is the DEM's, as for the FEM's
  CHECK(std::filesystem::exists(fx.dir / "coupling.csv"));
  CHECK(fx.log.calls.back() == "dem 3");  // the FEM was not given the NaN force
}

TEST_CASE("an overlap beyond the bound stops the run") {
  Fixture fx(Scheme::predictive, 6);
  fx.dem->overlap_step = 2;
  fx.settings.max_overlap = 5e-4;
  CHECK_THROWS_MATCHES(fx.run(), BlowUp, Catch::Matchers::Predicate<BlowUp>([](const BlowUp& e) {
                         return e.step() == 2 && e.quantity() == "max_overlap" &&
                                std::string(e.what()).find("coupling.blowup.max_overlap") !=
                                    std::string::npos;
                       }));
}

TEST_CASE("an energy error beyond the bound stops the run") {
  Fixture fx(Scheme::just_in_time, 6);
  fx.settings.max_energy_error = 1e-12;
  CHECK_THROWS_MATCHES(fx.run(), BlowUp, Catch::Matchers::Predicate<BlowUp>([](const BlowUp& e) {
                         return e.quantity() == "energy_error" && e.step() >= 0;
                       }));
}

TEST_CASE("the stop flag ends the run between steps") {
  Fixture fx(Scheme::just_in_time, 6);
  std::atomic<bool> stop{false};
  CouplingRun r(*fx.link, fx.settings, fx.dir, &stop);
  r.set_observer([&](const StepDiagnostics& d, const CouplingSettings&) {
    if (d.step == 1) stop = true;
  });
  CHECK_THROWS_AS(r.run(), Interrupted);
  CHECK(fx.log.calls.size() == 4);
}

TEST_CASE("a solver failure names the solver, the step and the cause") {
  Fixture fx(Scheme::just_in_time, 6);
  fx.dem->throw_step = 2;
  try {
    fx.run();
    FAIL("no failure");
  } catch (const SolverFailure& e) {
    CHECK(e.step() == 2);
    CHECK(e.role() == protocol::Role::dem);
    CHECK_THAT(e.what(), Catch::Contains("DEM solver failed in coupling step 2") &&
                             Catch::Contains("injected failure"));
  }
  CHECK(fx.csv_rows() == 2);  // steps 0 and 1 are on disk
}

TEST_CASE("DEM alone: slices of n substeps, the last one cut to end at run.end_time") {
  Log log;
  auto dem = std::make_unique<FakeDem>(log);
  FakeDem* d = dem.get();
  LocalLink link(std::move(dem), nullptr);
  CouplingSettings s;
  s.has_dem = true;
  s.scheme = Scheme::dem_only;
  s.dem_dt = 1e-5;
  s.dem_substeps = 100;
  s.coupling_dt = 1e-3;
  s.run.end_time = 0.0125;
  s.step_count = steps_to_reach(s.run.end_time, s.coupling_dt);
  const auto dir = std::filesystem::temp_directory_path() /
                   ("demfem-test-dem-only-" + std::to_string(::getpid()));
  CouplingRun run(link, s, dir);
  const auto sum = run.run();
  std::filesystem::remove_all(dir);
  REQUIRE(d->commands.size() == 13);
  CHECK(d->commands[11].substeps == 100);
  CHECK(d->commands.back().substeps == 50);
  CHECK(d->commands.back().dt == Approx(5e-4).epsilon(1e-12));
  CHECK(d->commands.back().flags == 0);
  CHECK(sum.time == Approx(0.0125).epsilon(1e-12));
}

TEST_CASE("concurrent: both solvers step together, each from the other's data at t_i") {
  Fixture fx(Scheme::concurrent, 3);
  auto sum = fx.run();
  REQUIRE(fx.dem->commands.size() == 3);
  REQUIRE(fx.fem->commands.size() == 3);
  for (std::size_t i = 0; i < 3; ++i) {
    // Two buffers: the DEM reads kinematics from 0 and writes forces there, the FEM reads
    // forces from 1 and writes kinematics there.
    CHECK(fx.dem->commands[i].buffer == 0);
    CHECK(fx.fem->commands[i].buffer == 1);
    CHECK(fx.dem->commands[i].flags == kStepSetKinematics);
    CHECK(fx.fem->commands[i].flags == 0);
  }
  // FEM i gets the DEM's forces of step i - 1 (F_i; none at step 0), as predictive does.
  CHECK(fx.fem->forces_seen[0][2] == 0.0);
  CHECK(fx.fem->forces_seen[1][2] == Approx(-2.0 * kWeight));
  CHECK(fx.fem->forces_seen[2][2] == Approx(-1.5 * kWeight));
  // DEM i gets the FEM's state at t_i, as just-in-time does: P_2 from FEM 1.
  const double p2 = -2.0 * kWeight / kStiffness;
  CHECK(fx.dem->given_positions[2][2] == Approx(p2).epsilon(1e-14));
  CHECK(fx.dem->given_accelerations[2][2] == 0.25);
  CHECK(std::isfinite(sum.last.energy_error));
  CHECK(fx.csv_rows() == 3);
}

TEST_CASE("concurrent: the in-process link runs the two at once, with the same bits") {
  // Run twice: every result bitwise equal (the solvers write different buffers).
  std::vector<double> first;
  for (int run = 0; run < 2; ++run) {
    Fixture fx(Scheme::concurrent, 5);
    fx.dem->stiffness = 0.5 * kStiffness;
    const auto sum = fx.run();
    std::vector<double> all = sum.positions;
    all.insert(all.end(), sum.forces.begin(), sum.forces.end());
    all.push_back(sum.last.work_dem);
    all.push_back(sum.last.work_fem);
    if (run == 0) {
      first = all;
    } else {
      CHECK(all == first);
    }
  }
}

TEST_CASE("implicit: a stiff two-way step converges to the fixed point, iterating in memory") {
  // H(u) = (-W s - k_c u) / k with k_c = 3 k: plain iteration diverges (factor -3).
  for (auto kind : {AccelerationKind::aitken, AccelerationKind::iqn_ils}) {
    INFO(acceleration_name(kind));
    Fixture fx(Scheme::implicit, 4);
    fx.dem->stiffness = 3.0 * kStiffness;
    fx.settings.implicit.acceleration.kind = kind;
    fx.settings.implicit.displacement_tolerance = 1e-10;
    fx.settings.implicit.force_tolerance = 1e-10;
    const auto sum = fx.run();
    CHECK(sum.steps == 4);
    CHECK(sum.unconverged_steps == 0);
    CHECK(sum.iterations > 4);
    // The last step's fixed point, u = -W s / (k + k_c) with s = 1 + 0.5^3.
    const double u = -kWeight * (1.0 + 0.125) / (4.0 * kStiffness);
    for (std::size_t n = 0; n < 3; ++n) CHECK(sum.positions[3 * n + 2] == Approx(u).epsilon(1e-9));
    CHECK(sum.last.converged);
    CHECK(sum.last.residual_displacement <= 1e-10);
    // The flags: the first try of a step saves (kStepIterate), the others restore (+ kStepRedo).
    std::int64_t step = -1;
    for (const auto& c : fx.dem->commands) {
      const bool first = c.step != step;
      step = c.step;
      CHECK((c.flags & protocol::kStepIterate) != 0);
      CHECK((c.flags & protocol::kStepSetKinematics) != 0);
      CHECK(((c.flags & protocol::kStepRedo) != 0) == !first);
    }
    // save / restore / accept through the gate, as serve() does: per step one save, a restore
    // per further iteration, and the step accepted before the next one's save.
    const auto count = [&](const std::string& what) {
      return std::count(fx.log.calls.begin(), fx.log.calls.end(), what);
    };
    CHECK(count("dem save") == 4);
    CHECK(count("fem save") == 4);
    CHECK(count("dem restore") == static_cast<long>(sum.iterations - 4));
    CHECK(count("dem accept") == 3);
    fx.link->shutdown();  // the last step is accepted at the end, as serve() does on Shutdown
    CHECK(count("dem accept") == 4);
    CHECK(count("fem accept") == 4);
    // The DEM's mesh moves linearly from P_i to the iterate: A = 0 (eq. 3.7).
    for (const auto& a : fx.dem->given_accelerations) CHECK(a[2] == 0.0);
    // The DEM's copy ends where the accepted FEM state is, within the tolerance.
    CHECK(sum.last.drift < 1e-9 * std::abs(u));
  }
}

TEST_CASE("implicit: a step that does not converge stops the run (exit 3) or is counted") {
  SECTION("stop") {
    Fixture fx(Scheme::implicit, 4);
    fx.dem->stiffness = 3.0 * kStiffness;
    fx.settings.implicit.acceleration.kind = AccelerationKind::constant;  // diverges here
    fx.settings.implicit.max_iterations = 5;
    try {
      fx.run();
      FAIL("no stop");
    } catch (const BlowUp& e) {
      CHECK(e.step() == 0);
      CHECK(e.quantity() == "iterations");
      CHECK_THAT(e.what(), Catch::Contains("did not converge in 5 iterations") &&
                               Catch::Contains("coupling.max_iterations") &&
                               Catch::Contains("on_nonconvergence"));
    }
    CHECK(fx.csv_rows() == 1);  // the step's row, with converged = 0
  }
  SECTION("accept") {
    Fixture fx(Scheme::implicit, 4);
    fx.dem->stiffness = 3.0 * kStiffness;
    fx.settings.implicit.acceleration.kind = AccelerationKind::constant;
    fx.settings.implicit.acceleration.initial_relaxation = 1.0;
    fx.settings.implicit.max_iterations = 3;
    fx.settings.implicit.on_nonconvergence = NonConvergence::accept;
    const auto sum = fx.run();
    CHECK(sum.steps == 4);
    CHECK(sum.unconverged_steps == 4);
    CHECK(sum.iterations == 12);
    CHECK(sum.max_iterations == 3);
    CHECK_FALSE(sum.last.converged);
    std::ifstream in(fx.dir / "coupling.csv");
    std::string header;
    std::getline(in, header);
    CHECK_THAT(header,
               Catch::Contains("iterations,residual_displacement,residual_force,converged"));
  }
}

TEST_CASE("implicit: refused at the start when a solver cannot iterate a step") {
  Fixture fx(Scheme::implicit, 2);
  fx.fem->iterates = false;
  CHECK_THROWS_AS(fx.run(), scene::SceneError);
  try {
    Fixture fx2(Scheme::implicit, 2);
    fx2.fem->iterates = false;
    fx2.run();
  } catch (const scene::SceneError& e) {
    CHECK_THAT(e.what(), Catch::Contains("FEM solver 'fake-fem'") && Catch::Contains("implicit") &&
                             Catch::Contains("iteration"));
  }
  CHECK(fx.fem->commands.empty());
}
