#include "demfem/coupling/coupling_run.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <tuple>

#include "coupling_series.hpp"
#include "demfem/coupling/acceleration.hpp"
#include "demfem/coupling/checkpoint.hpp"
#include "demfem/io/atomic_file.hpp"
#include "demfem/io/checkpoint_file.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem/io/output_schedule.hpp"
#include "interface_checks.hpp"
#include "interface_output.hpp"

namespace demfem::coupling {

namespace {

using Clock = std::chrono::steady_clock;

double seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

std::string fmt(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

// Trapezoidal work of node forces that change linearly from f0 to f1 over the node
// displacement x1 - x0 (the same rule on both sides, so their difference is the scheme's).
double trapezoid_work(std::span<const double> f0, std::span<const double> f1,
                      std::span<const double> x0, std::span<const double> x1) {
  double w = 0.0;
  for (std::size_t k = 0; k < x0.size(); ++k) w += 0.5 * (f0[k] + f1[k]) * (x1[k] - x0[k]);
  return w;
}

double max_node_distance(std::span<const double> a, std::span<const double> b) {
  double m = 0.0;
  for (std::size_t i = 0; i + 2 < a.size(); i += 3) {
    const double dx = a[i] - b[i], dy = a[i + 1] - b[i + 1], dz = a[i + 2] - b[i + 2];
    m = std::max(m, std::sqrt(dx * dx + dy * dy + dz * dz));
  }
  return m;
}

// The FEM's published mesh: a node that is not finite would be found by the DEM in its first
// step and blamed on it. `backend`: the FEM's name (Hello).
void check_published_mesh(const InterfaceMesh& mesh, const std::string& backend) {
  const std::ptrdiff_t k = first_non_finite(mesh.reference_positions);
  if (k < 0) return;
  const double* x = &mesh.reference_positions[static_cast<std::size_t>(k - k % 3)];
  throw HandshakeFailed(protocol::Role::fem, "the FEM solver's backend \"" + backend +
                                                 "\" published an interface mesh whose node " +
                                                 std::to_string(k / 3) + " is not finite: (" +
                                                 fmt(x[0]) + ", " + fmt(x[1]) + ", " + fmt(x[2]) +
                                                 ") m; it is refused");
}

void copy(std::span<const double> from, std::span<double> to) {
  std::copy(from.begin(), from.end(), to.begin());
}

}  // namespace

protocol::ErrorKind error_kind_of(const std::exception& e) {
  if (const auto* s = dynamic_cast<const protocol::SolverError*>(&e)) return s->kind();
  if (const auto* b = dynamic_cast<const protocol::BackendError*>(&e)) return b->kind();
  return protocol::ErrorKind::failure;
}

bool is_blow_up_report(const std::string& text) {
  return text.find("not finite") != std::string::npos || text.find("blew up") != std::string::npos;
}

BlowUp::BlowUp(std::int64_t step, double time, std::string quantity, double value, double bound,
               const std::string& text)
    : std::runtime_error(text),
      step_(step),
      time_(time),
      quantity_(std::move(quantity)),
      value_(value),
      bound_(bound) {}

std::size_t nearest_node(const InterfaceMesh& mesh, const std::array<double, 3>& p) {
  std::size_t best = 0;
  double best_d = INFINITY;
  for (std::size_t i = 0; i < mesh.node_count(); ++i) {
    const double* x = &mesh.reference_positions[3 * i];
    const double d = (x[0] - p[0]) * (x[0] - p[0]) + (x[1] - p[1]) * (x[1] - p[1]) +
                     (x[2] - p[2]) * (x[2] - p[2]);
    if (d < best_d) {
      best_d = d;
      best = i;
    }
  }
  return best;
}

CouplingRun::CouplingRun(SolverLink& link, const CouplingSettings& settings,
                         std::filesystem::path output_dir, const std::atomic<bool>* stop)
    : link_(link), settings_(settings), output_dir_(std::move(output_dir)), stop_(stop) {}

std::filesystem::path checkpoint_directory(const CouplingSettings& s,
                                           const std::filesystem::path& output_dir) {
  if (s.checkpoint.directory.empty()) return output_dir / "checkpoints";
  return s.checkpoint.directory.is_absolute() ? s.checkpoint.directory
                                              : output_dir / s.checkpoint.directory;
}

std::vector<std::string> checkpoint_parts(const CouplingSettings& s) {
  std::vector<std::string> parts;
  if (s.has_dem) parts.push_back("dem.h5");
  if (s.has_fem) parts.push_back("fem.h5");
  parts.push_back("coupler.h5");
  return parts;
}

namespace {

const char* role_label(Role role) {
  return role == Role::dem ? "DEM" : "FEM";
}

}  // namespace

RunSummary CouplingRun::run() {
  const CouplingSettings& s = settings_;
  std::filesystem::create_directories(output_dir_);
  std::optional<SeriesFile> csv;
  if (!control_.resume_from) csv.emplace(output_dir_ / "coupling.csv", coupling_columns());
  auto report = [&](const std::string& m) {
    if (control_.report) control_.report(m);
  };

  RunSummary sum;
  auto run_start = Clock::now();  // set again when the steps begin (see below)
  sum.mesh = link_.start();
  const std::size_t n3 = 3 * sum.mesh.node_count();
  check_published_mesh(sum.mesh, link_.name(Role::fem));
  const bool coupled = s.has_dem && s.has_fem;
  InterfaceBuffers& buf = link_.buffers();
  // Buffer 0 for every scheme; the concurrent one gives the FEM buffer 1, so that the two
  // solvers, stepping at the same time, never touch the same array.
  constexpr std::uint32_t b = 0;
  constexpr std::uint32_t b_fem_concurrent = 1;
  if (s.scheme == Scheme::implicit) {
    for (Role role : {Role::dem, Role::fem}) {
      if (link_.supports_iteration(role)) continue;
      throw scene::SceneError(s.scene_file.string() +
                              ": coupling.scheme = \"implicit\" iterates every coupling step, "
                              "which needs solvers that can go back to a step's start; the " +
                              role_label(role) + " solver '" + link_.name(role) +
                              "' cannot (its Hello does not announce the capability "
                              "'iteration', docs/protocol.md): choose an explicit scheme");
    }
  }
  // The implicit scheme's accelerator (its history is part of a checkpoint) and counters.
  std::unique_ptr<Acceleration> accel;
  if (s.scheme == Scheme::implicit) accel = make_acceleration(s.implicit.acceleration, n3);

  // The coupler's own copies: the FEM interface state at t_i (P, V, A), the forces the FEM
  // was last given and the DEM's last forces, for the schemes and the work diagnostics.
  // Everything here is the scheme's history and goes into coupler.h5 of a checkpoint.
  std::vector<double> pos = sum.mesh.reference_positions, vel(n3, 0.0), acc(n3, 0.0);
  std::vector<double> next_pos(n3), dem_start(n3), dem_end(n3);
  std::vector<double> dem_force(n3, 0.0), dem_force_prev(n3, 0.0);
  std::vector<double> fem_force(n3, 0.0), fem_force_prev(n3, 0.0);
  double work_dem = 0.0, work_fem = 0.0;
  bool settled = false;
  std::int64_t csv_rows = 0;

  // Rows reach the disk at least every kFlushInterval of wall time (and at every end of the
  // run, normal or not): a flush per step would cost a system call per step.
  constexpr auto kFlushInterval = std::chrono::milliseconds(500);
  auto last_flush = Clock::now();
  auto write_row = [&](const StepDiagnostics& d) {
    const auto r = row_of(d);
    csv->row(r);
    ++csv_rows;
    if (const auto now = Clock::now(); now - last_flush >= kFlushInterval) {
      csv->flush();
      last_flush = now;
    }
  };
  // The interface (coupling.h5 at the end, the series of coupling.xdmf at the output times):
  // the FEM's positions and velocities as the scheme holds them, the DEM's forces.
  auto interface_state = [&] { return InterfaceState{&sum.mesh, pos, vel, dem_force, dem_end}; };
  auto write_h5 = [&]() {
    write_coupling_h5(output_dir_, interface_state(), scheme_name(s.scheme), sum.steps, sum.time);
  };
  std::optional<InterfaceSeries> series;
  if (n3 > 0) series.emplace(output_dir_, sum.mesh, control_.resume_from.has_value());
  io::OutputSchedule out_schedule(s.run.output_interval);
  std::int64_t last_output_step = -1;  // sum.steps of the last series output
  auto write_output = [&](double label) {
    if (!series) return;
    series->write(interface_state(), label, sum.time);
    last_output_step = sum.steps;
  };

  // ---- checkpoints ------------------------------------------------------------------------
  const CheckpointSettings& cps = s.checkpoint;
  const auto cp_dir = checkpoint_directory(s, output_dir_);
  std::optional<std::filesystem::path> last_cp;  // the newest committed checkpoint
  std::int64_t last_cp_step = -1;
  auto last_cp_wall = Clock::now();
  const std::vector<std::string> parts = checkpoint_parts(s);

  auto save_coupler = [&](const std::filesystem::path& file, std::int64_t steps) {
    io::write_checkpoint_file(file, steps, [&](io::H5File& h5) {
      h5.set_attribute("/", "scheme", std::string(scheme_name(s.scheme)));
      h5.set_attribute("/", "node_count", static_cast<std::int64_t>(n3 / 3));
      h5.set_attribute("/", "time", sum.time);
      h5.set_attribute("/", "work_dem", work_dem);
      h5.set_attribute("/", "work_fem", work_fem);
      h5.set_attribute("/", "settled", static_cast<std::int64_t>(settled));
      h5.set_attribute("/", "csv_rows", csv_rows);
      h5.set_attribute("/", "output_next", out_schedule.next());
      h5.set_attribute("/", "output_last_step", last_output_step);
      // Wall times of the whole run so far: earlier sessions (a resumed run) and this one.
      h5.set_attribute("/", "wall_total", sum.earlier.total + seconds(run_start, Clock::now()));
      h5.set_attribute("/", "wall_dem", sum.earlier.dem + sum.wall_dem);
      h5.set_attribute("/", "wall_fem", sum.earlier.fem + sum.wall_fem);
      h5.set_attribute("/", "wall_coupling", sum.earlier.coupling + sum.wall_coupling);
      if (!control_.scene_hash.empty()) h5.set_attribute("/", "scene_hash", control_.scene_hash);
      if (link_.has(Role::fem)) {
        h5.set_attribute("/", "fem_backend",
                         control_.fem_backend.empty() ? std::string("fem") : control_.fem_backend);
        h5.set_attribute("/", "fem_backend_name", link_.name(Role::fem));
      }
      if (link_.has(Role::dem) && !control_.dem_backend.empty()) {
        h5.set_attribute("/", "dem_backend", control_.dem_backend);
        h5.set_attribute("/", "dem_backend_name", link_.name(Role::dem));
      }
      h5.set_attribute("/", "output_dir", std::filesystem::absolute(output_dir_).string());
      const auto last = row_of(sum.last);
      h5.write("last_diagnostics", std::span<const double>(last), {last.size()});
      h5.create_group("scheme");
      const std::pair<const char*, const std::vector<double>*> arrays[] = {
          {"scheme/positions", &pos},       {"scheme/velocities", &vel},
          {"scheme/accelerations", &acc},   {"scheme/next_positions", &next_pos},
          {"scheme/dem_start", &dem_start}, {"scheme/dem_end", &dem_end},
          {"scheme/dem_force", &dem_force}, {"scheme/dem_force_prev", &dem_force_prev},
          {"scheme/fem_force", &fem_force}, {"scheme/fem_force_prev", &fem_force_prev}};
      for (const auto& [name, v] : arrays) h5.write(name, std::span<const double>(*v), {v->size()});
      h5.set_attribute("/", "iterations", sum.iterations);
      h5.set_attribute("/", "max_iterations", sum.max_iterations);
      h5.set_attribute("/", "unconverged_steps", sum.unconverged_steps);
      if (accel) accel->save(h5, "acceleration");
      if (n3 > 0) {
        // The interface buffer as the solvers left it (the schemes rewrite it before every
        // read, but a restored run starts from exactly the same bytes).
        h5.create_group("buffer");
        h5.write("buffer/positions", std::span<const double>(buf.positions(b)), {n3});
        h5.write("buffer/velocities", std::span<const double>(buf.velocities(b)), {n3});
        h5.write("buffer/accelerations", std::span<const double>(buf.accelerations(b)), {n3});
        h5.write("buffer/forces", std::span<const double>(buf.forces(b)), {n3});
        h5.write("buffer/dem_positions", std::span<const double>(buf.dem_positions(b)), {n3});
        if (s.scheme == Scheme::concurrent) {  // the FEM's buffer
          const std::uint32_t f = b_fem_concurrent;
          h5.create_group("buffer1");
          h5.write("buffer1/positions", std::span<const double>(buf.positions(f)), {n3});
          h5.write("buffer1/velocities", std::span<const double>(buf.velocities(f)), {n3});
          h5.write("buffer1/accelerations", std::span<const double>(buf.accelerations(f)), {n3});
          h5.write("buffer1/forces", std::span<const double>(buf.forces(f)), {n3});
        }
      }
    });
  };
  // `resume`: the checkpoint of --resume (its wall times are the earlier sessions'), not a
  // rollback within this session (whose wall times go on counting).
  auto load_coupler = [&](const std::filesystem::path& file, std::int64_t steps, bool resume) {
    const io::H5File h5 = io::open_checkpoint_file(file, steps);
    auto need = [&](bool ok, const std::string& what) {
      if (!ok) throw std::runtime_error(file.string() + ": " + what);
    };
    need(h5.attribute_string("/", "scheme") == scheme_name(s.scheme),
         "attribute 'scheme' is '" + h5.attribute_string("/", "scheme") + "', the scene's is '" +
             scheme_name(s.scheme) +
             "' (coupling.scheme changed: the scheme's history cannot "
             "be carried over; resume with the scheme it was taken with)");
    const std::int64_t nodes = h5.attribute_int64("/", "node_count");
    need(nodes == static_cast<std::int64_t>(n3 / 3),
         "the checkpoint's interface has " + std::to_string(nodes) + " nodes, this scene's " +
             std::to_string(n3 / 3) +
             " (the FEM mesh or fem.interface_surface changed): its state cannot be continued "
             "with this scene");
    sum.time = h5.attribute_double("/", "time");
    work_dem = h5.attribute_double("/", "work_dem");
    work_fem = h5.attribute_double("/", "work_fem");
    settled = h5.attribute_int64("/", "settled") != 0;
    csv_rows = h5.attribute_int64("/", "csv_rows");
    if (resume) {
      sum.earlier.dem = h5.attribute_double("/", "wall_dem");
      sum.earlier.fem = h5.attribute_double("/", "wall_fem");
      sum.earlier.coupling = h5.attribute_double("/", "wall_coupling");
      // Checkpoints of older versions lack the total: the parts are a lower bound of it.
      sum.earlier.total = h5.has_attribute("/", "wall_total")
                              ? h5.attribute_double("/", "wall_total")
                              : sum.earlier.dem + sum.earlier.fem + sum.earlier.coupling;
    }
    const auto last = h5.read_doubles("last_diagnostics");
    need(last.size() == coupling_columns().size(),
         "dataset 'last_diagnostics' has " + std::to_string(last.size()) +
             " values, coupling.csv " + std::to_string(coupling_columns().size()) +
             " columns (a checkpoint of an older demfem, whose series had other columns: start "
             "the run afresh)");
    sum.last = diagnostics_of(last);
    const std::pair<const char*, std::vector<double>*> arrays[] = {
        {"scheme/positions", &pos},       {"scheme/velocities", &vel},
        {"scheme/accelerations", &acc},   {"scheme/next_positions", &next_pos},
        {"scheme/dem_start", &dem_start}, {"scheme/dem_end", &dem_end},
        {"scheme/dem_force", &dem_force}, {"scheme/dem_force_prev", &dem_force_prev},
        {"scheme/fem_force", &fem_force}, {"scheme/fem_force_prev", &fem_force_prev}};
    for (const auto& [name, v] : arrays) {
      auto data = h5.read_doubles(name);
      need(data.size() == n3, std::string("dataset '") + name + "' has " +
                                  std::to_string(data.size()) + " values, expected " +
                                  std::to_string(n3));
      *v = std::move(data);
    }
    if (n3 > 0) {
      const std::pair<const char*, std::span<double>> bufs[] = {
          {"buffer/positions", buf.positions(b)},
          {"buffer/velocities", buf.velocities(b)},
          {"buffer/accelerations", buf.accelerations(b)},
          {"buffer/forces", buf.forces(b)},
          {"buffer/dem_positions", buf.dem_positions(b)}};
      for (const auto& [name, to] : bufs) {
        const auto data = h5.read_doubles(name);
        need(data.size() == n3, std::string("dataset '") + name + "' has the wrong size");
        copy(data, to);
      }
      if (s.scheme == Scheme::concurrent) {
        const std::uint32_t f = b_fem_concurrent;
        const std::pair<const char*, std::span<double>> bufs1[] = {
            {"buffer1/positions", buf.positions(f)},
            {"buffer1/velocities", buf.velocities(f)},
            {"buffer1/accelerations", buf.accelerations(f)},
            {"buffer1/forces", buf.forces(f)}};
        for (const auto& [name, to] : bufs1) {
          const auto data = h5.read_doubles(name);
          need(data.size() == n3, std::string("dataset '") + name + "' has the wrong size");
          copy(data, to);
        }
      }
    }
    sum.iterations = h5.attribute_int64("/", "iterations");
    sum.max_iterations = h5.attribute_int64("/", "max_iterations");
    sum.unconverged_steps = h5.attribute_int64("/", "unconverged_steps");
    if (accel) accel->load(h5, "acceleration");
    sum.steps = steps;
    // The interface series: the outputs taken so far, and none of states after the checkpoint
    // (written before the attributes existed: the outputs up to its time were taken).
    if (h5.has_attribute("/", "output_next")) {
      out_schedule.set_next(h5.attribute_int64("/", "output_next"));
      last_output_step = h5.attribute_int64("/", "output_last_step");
    } else {
      out_schedule.skip_to_after(sum.time);
      last_output_step = -1;
    }
    if (series) {
      series->rollback(sum.time);
      if (series->last_state_time() == sum.time) last_output_step = steps;
    }
  };

  // Writes the checkpoint after `steps` coupling steps; a solver failing here is a
  // SolverFailure like one failing in a step.
  auto take_checkpoint = [&](std::int64_t steps) {
    const auto t0 = Clock::now();
    const auto folder = cp_dir / checkpoint_folder_name(steps);
    std::filesystem::remove_all(folder);  // an uncommitted or rolled-back one
    std::filesystem::create_directories(folder);
    csv->flush();
    for (Role role : {Role::dem, Role::fem}) {
      if (!link_.has(role)) continue;
      const auto file = folder / (role == Role::dem ? "dem.h5" : "fem.h5");
      try {
        link_.checkpoint(role, file, steps);
      } catch (const std::exception& e) {
        throw SolverFailure(
            role, steps, sum.time,
            std::string("the ") + role_label(role) + " solver failed writing checkpoint " +
                file.string() + ": " + e.what(),
            dynamic_cast<const protocol::PeerDied*>(&e) != nullptr, error_kind_of(e));
      }
    }
    save_coupler(folder / "coupler.h5", steps);
    commit_checkpoint(folder, steps, sum.time, scheme_name(s.scheme), parts);
    last_cp = folder;
    last_cp_step = steps;
    prune_checkpoints(cp_dir, cps.keep);
    last_cp_wall = Clock::now();
    ++stats_.checkpoints;
    stats_.checkpoint_wall += seconds(t0, last_cp_wall);
  };
  auto checkpoint_due = [&](std::int64_t steps) {
    if (!cps.enabled || steps == last_cp_step || steps >= s.step_count) return false;
    if (cps.every_steps > 0 && steps % cps.every_steps == 0) return true;
    if (cps.every_sim_time > 0.0) {
      const double t = static_cast<double>(steps) * s.coupling_dt;
      const double t_last =
          static_cast<double>(std::max<std::int64_t>(last_cp_step, 0)) * s.coupling_dt;
      if (std::floor(t / cps.every_sim_time + 1e-9) >
          std::floor(t_last / cps.every_sim_time + 1e-9))
        return true;
    }
    return cps.every_wall_time > 0.0 && seconds(last_cp_wall, Clock::now()) >= cps.every_wall_time;
  };
  // Every process back to the checkpoint in `folder`: both solvers, the coupler's scheme
  // history and the CSV rows. Returns the step to continue from.
  auto restore_from = [&](const std::filesystem::path& folder, bool resume) {
    const CheckpointManifest m = verify_checkpoint(folder, parts);
    // The coupler's part first: its interface check names a changed mesh more plainly than
    // the solvers' own refusals would.
    load_coupler(folder / "coupler.h5", m.step, resume);
    for (Role role : {Role::dem, Role::fem}) {
      if (!link_.has(role)) continue;
      link_.restore(role, folder / (role == Role::dem ? "dem.h5" : "fem.h5"), m.step);
    }
    csv.reset();
    csv.emplace(output_dir_ / "coupling.csv", static_cast<std::size_t>(csv_rows));
    last_cp = folder;
    last_cp_step = m.step;
    last_cp_wall = Clock::now();
    return m.step;
  };

  // A solver that fails or dies inside a step: name it, the step and the time.
  auto solver_failure = [&](Role role, const StepCommand& cmd, const std::exception& e,
                            std::optional<protocol::ErrorKind> kind = std::nullopt) {
    // Named with the backend's own name (its Hello): an outside program is blamed by name.
    const std::string what = e.what();
    std::ostringstream m;
    m << "the " << role_label(role) << " solver failed in coupling step " << cmd.step
      << " (t = " << fmt(cmd.time) << " s): "
      << (what.rfind("its backend \"", 0) == 0 ? "" : "its backend \"" + link_.name(role) + "\": ")
      << what;
    return SolverFailure(role, cmd.step, cmd.time, m.str(),
                         dynamic_cast<const protocol::PeerDied*>(&e) != nullptr,
                         kind.value_or(error_kind_of(e)));
  };
  auto send = [&](Role role, const StepCommand& cmd) {
    try {
      link_.send_step(role, cmd);
      if (control_.after_send) control_.after_send(role, cmd.step);
    } catch (const std::exception& e) {
      throw solver_failure(role, cmd, e);
    }
  };
  auto wait = [&](Role role, const StepCommand& cmd) {
    StepResult r;
    try {
      r = link_.wait_step_done(role);
    } catch (const std::exception& e) {
      throw solver_failure(role, cmd, e);
    }
    if (n3 > 0) {
      if (const std::string bad = role == Role::fem ? non_finite_fem_kinematics(buf, cmd.buffer)
                                                    : non_finite_dem_output(buf, cmd.buffer);
          !bad.empty()) {
        // The solver's own blow-up (exit status 3), as if it had refused the state itself.
        throw solver_failure(role, cmd,
                             std::runtime_error("its backend \"" + link_.name(role) + "\": " + bad),
                             protocol::ErrorKind::blow_up);
      }
    }
    return r;
  };
  // The outcome of a DEM step (forces and mesh positions in buffer `bb`) and of a FEM step.
  auto dem_done = [&](const StepResult& r, std::uint32_t bb, StepDiagnostics& d) {
    d.max_overlap = r.values[0];
    d.kinetic_energy = r.values[1];
    d.dem_max_overlap = r.values[2];
    d.wall_dem_compute += r.compute_seconds;
    if (n3 > 0) {
      copy(buf.forces(bb), dem_force);
      copy(buf.dem_positions(bb), dem_end);
    }
  };
  auto fem_done = [&](const StepResult& r, StepDiagnostics& d) {
    d.fem_max_displacement = r.values[0];
    d.wall_fem_compute += r.compute_seconds;
  };
  auto dem_step = [&](const StepCommand& cmd, StepDiagnostics& d) {
    const auto t0 = Clock::now();
    send(Role::dem, cmd);
    const StepResult r = wait(Role::dem, cmd);
    d.wall_dem += seconds(t0, Clock::now());
    dem_done(r, cmd.buffer, d);
  };
  auto fem_step = [&](const StepCommand& cmd, StepDiagnostics& d) {
    const auto t0 = Clock::now();
    send(Role::fem, cmd);
    const StepResult r = wait(Role::fem, cmd);
    d.wall_fem += seconds(t0, Clock::now());
    fem_done(r, d);
  };
  auto fail = [&](const StepDiagnostics& d, const std::string& quantity, double value, double bound,
                  const std::string& why) {
    write_row(d);
    csv->flush();
    sum.last = d;
    std::ostringstream m;
    m << "blow-up at coupling step " << d.step << " (t = " << fmt(d.time) << " s): " << why;
    throw BlowUp(d.step, d.time, quantity, value, bound, m.str());
  };
  auto check = [&](StepDiagnostics& d) {
    const std::pair<const char*, std::span<const double>> arrays[] = {
        {"interface force", dem_force},
        {"FEM interface position", pos},
        {"DEM interface position", dem_end}};
    for (const auto& [what, v] : arrays) {
      if (auto k = first_non_finite(v); k >= 0) {
        fail(d, what, v[k], 0.0,
             std::string(what) + " of node " + std::to_string(k / 3) + " (component " +
                 std::to_string(k % 3) + ") is not finite (" + fmt(v[k]) + ")");
      }
    }
    const std::pair<const char*, double> scalars[] = {
        {"max_overlap", d.max_overlap},         {"kinetic_energy", d.kinetic_energy},
        {"dem_max_overlap", d.dem_max_overlap}, {"fem_max_displacement", d.fem_max_displacement},
        {"energy_error", d.energy_error},       {"drift", d.drift}};
    for (const auto& [what, v] : scalars) {
      if (!std::isfinite(v)) fail(d, what, v, 0.0, std::string(what) + " is not finite");
    }
    if (d.max_overlap > s.max_overlap) {
      fail(d, "max_overlap", d.max_overlap, s.max_overlap,
           "particle-interface overlap " + fmt(d.max_overlap) +
               " m exceeds coupling.blowup.max_overlap = " + fmt(s.max_overlap) + " m");
    }
    if (s.scheme != Scheme::one_way_static && std::abs(d.energy_error) > s.max_energy_error) {
      fail(d, "energy_error", d.energy_error, s.max_energy_error,
           "interface energy error |W_dem - W_fem| = " + fmt(std::abs(d.energy_error)) +
               " J exceeds coupling.blowup.max_energy_error = " + fmt(s.max_energy_error) + " J");
    }
  };

  // The wall time of a step spent waiting for the solvers: in the concurrent scheme their
  // steps overlap, and the FEM's (from the common send to its reply) covers both.
  auto solver_wall = [&](const StepDiagnostics& d) {
    return s.scheme == Scheme::concurrent ? std::max(d.wall_dem, d.wall_fem)
                                          : d.wall_dem + d.wall_fem;
  };

  // The implicit scheme (docs/coupling.md): the step from t_i to t_i+1 is iterated as a
  // Dirichlet-Neumann fixed point on the interface displacement at t_i+1. Iteration k gives
  // the DEM the displacement u^k (its mesh moves linearly in time from the accepted P_i to
  // X + u^k, eq. 3.5-3.7 with the iterate for P_i+1), the DEM's forces F^k drive the FEM step,
  // whose displacement u~^k = H(u^k) closes the loop. u^0 is the FEM's own extrapolation
  // P_i + dt V_i + dt^2/2 A_i; later ones come from the accelerator. Both solvers keep the
  // step's start in memory and go back to it for every new iteration (kStepIterate,
  // kStepRedo); the last iteration's states are the accepted ones.
  const std::vector<double>& ref = sum.mesh.reference_positions;
  std::vector<double> u_in(n3), u_out(n3), u_next(n3), force_before(n3), fem_vel(n3), fem_acc(n3);
  std::string nonconvergence;  // set by a step that did not converge and must stop the run
  auto implicit_step = [&](StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d) {
    const ImplicitSettings& im = s.implicit;
    const double dt = s.coupling_dt;
    for (std::size_t k = 0; k < n3; ++k)
      u_in[k] = pos[k] + dt * vel[k] + 0.5 * dt * dt * acc[k] - ref[k];
    force_before = dem_force_prev;  // F^{-1}: the last step's (preCICE's first measure)
    dem_start = pos;
    dem_cmd.flags |= protocol::kStepSetKinematics | protocol::kStepIterate;
    fem_cmd.flags |= protocol::kStepIterate;
    std::int64_t it = 0;
    bool converged = false;
    for (;;) {
      if (it > 0) {
        dem_cmd.flags |= protocol::kStepRedo;
        fem_cmd.flags |= protocol::kStepRedo;
      }
      copy(pos, buf.positions(b));
      auto v = buf.velocities(b);
      for (std::size_t k = 0; k < n3; ++k) v[k] = (ref[k] + u_in[k] - pos[k]) / dt;
      std::fill(buf.accelerations(b).begin(), buf.accelerations(b).end(), 0.0);
      dem_step(dem_cmd, d);
      fem_force = dem_force;  // the FEM reads them in the buffer, where the DEM left them
      fem_step(fem_cmd, d);
      copy(buf.positions(b), next_pos);
      copy(buf.velocities(b), fem_vel);
      copy(buf.accelerations(b), fem_acc);
      for (std::size_t k = 0; k < n3; ++k) u_out[k] = next_pos[k] - ref[k];
      double abs_u = 0.0, abs_f = 0.0;
      d.residual_displacement = relative_change(u_out, u_in, &abs_u);
      d.residual_force = relative_change(dem_force, force_before, &abs_f);
      ++it;
      converged = (d.residual_displacement <= im.displacement_tolerance ||
                   abs_u <= im.displacement_abs_tolerance) &&
                  (d.residual_force <= im.force_tolerance || abs_f <= im.force_abs_tolerance);
      if (converged || it >= im.max_iterations) break;
      force_before = dem_force;
      accel->next(u_in, u_out, u_next);
      u_in.swap(u_next);
    }
    accel->end_step(u_in, u_out);
    vel = fem_vel;
    acc = fem_acc;
    d.iterations = it;
    d.converged = converged;
    sum.iterations += it;
    sum.max_iterations = std::max(sum.max_iterations, it);
    if (!converged) {
      std::ostringstream m;
      m << "coupling step " << d.step << " (t = " << fmt(d.time) << " s) did not converge in " << it
        << " iterations (coupling.max_iterations): relative residuals "
        << fmt(d.residual_displacement)
        << " (displacement, coupling.displacement_tolerance = " << fmt(im.displacement_tolerance)
        << ") and " << fmt(d.residual_force)
        << " (force, coupling.force_tolerance = " << fmt(im.force_tolerance) << ")";
      if (im.on_nonconvergence == NonConvergence::stop) {
        nonconvergence = m.str() +
                         "; coupling.on_nonconvergence = \"stop\" (raise max_iterations, lower "
                         "the coupling step, or set \"accept\" to go on with a warning)";
      } else {
        // Counted in the summary and marked in coupling.csv (converged = 0); the first few are
        // also reported, not every one of a long run.
        constexpr std::int64_t kReported = 5;
        if (++sum.unconverged_steps <= kReported) {
          report("warning: " + m.str() + "; accepted (coupling.on_nonconvergence = \"accept\")" +
                 (sum.unconverged_steps == kReported
                      ? "; further unconverged steps are counted, not reported"
                      : ""));
        }
      }
    }
  };

  // One coupling step i (0-based); returns true when the run is complete (settled).
  auto one_step = [&](std::int64_t i) {
    const auto step_start = Clock::now();
    StepDiagnostics d;
    d.step = i;
    const double t = static_cast<double>(i) * s.coupling_dt;
    d.time = static_cast<double>(i + 1) * s.coupling_dt;
    StepCommand dem_cmd;
    dem_cmd.step = i;
    dem_cmd.time = t;
    dem_cmd.dt = s.coupling_dt;
    dem_cmd.substeps = s.dem_substeps;
    dem_cmd.buffer = b;
    dem_cmd.force_mode = s.force_mode();
    StepCommand fem_cmd = dem_cmd;
    fem_cmd.substeps = 1;

    switch (s.scheme) {
      case Scheme::dem_only: {
        // The DEM alone advances in slices; the last one is cut to end at run.end_time.
        const double left = (s.run.end_time - t) / s.dem_dt;
        const std::int64_t n = std::llround(left);
        if (std::abs(left - static_cast<double>(n)) <= 1e-6 && n < dem_cmd.substeps) {
          dem_cmd.substeps = std::max<std::int64_t>(1, n);
          dem_cmd.dt = static_cast<double>(dem_cmd.substeps) * s.dem_dt;
          d.time = t + dem_cmd.dt;
        }
        dem_step(dem_cmd, d);
        break;
      }
      case Scheme::fem_only:
        if (s.fem_static) fem_cmd.flags |= protocol::kStepStatic;
        fem_step(fem_cmd, d);
        if (n3 > 0) copy(buf.positions(b), pos);
        break;
      case Scheme::one_way_static: {
        // The DEM mesh stays at the reference (no kinematics are sent).
        if (i == 0) dem_start = pos;
        dem_step(dem_cmd, d);
        const bool last = i + 1 == s.step_count;
        const bool ke_ok = s.settle_kinetic_energy > 0.0 &&
                           d.time >= s.settle_min_time * (1.0 - 1e-12) &&
                           d.kinetic_energy <= s.settle_kinetic_energy;
        if (ke_ok || (last && s.settle_kinetic_energy == 0.0)) {
          settled = true;
          copy(dem_force, buf.forces(b));
          fem_force = dem_force;
          fem_cmd.flags |= protocol::kStepStatic;
          fem_step(fem_cmd, d);
          copy(buf.positions(b), next_pos);
          // A slowly applied load does W = F.u / 2 (the strain energy); the DEM's mesh did
          // not move, so its side is zero by construction (not a scheme error).
          work_fem = trapezoid_work(fem_force_prev, fem_force, pos, next_pos);
          pos = next_pos;
        }
        break;
      }
      case Scheme::just_in_time: {
        // Algorithm 3: the DEM moves the mesh from the FEM's state at t_i (x + v tau +
        // a tau^2/2) for n_D substeps; its forces then drive one FEM step.
        copy(pos, buf.positions(b));
        copy(vel, buf.velocities(b));
        copy(acc, buf.accelerations(b));
        dem_start = pos;
        dem_cmd.flags |= protocol::kStepSetKinematics;
        dem_step(dem_cmd, d);
        // The DEM adapter left its forces in the buffer; the FEM reads them there.
        fem_force = dem_force;
        fem_step(fem_cmd, d);
        copy(buf.positions(b), next_pos);
        copy(buf.velocities(b), vel);
        copy(buf.accelerations(b), acc);
        break;
      }
      case Scheme::predictive: {
        // eq. 3.4-3.7: the FEM steps first with the last DEM forces; the DEM then moves the
        // mesh from P_i with V = (P_{i+1} - P_i) / dt_F and A = 0, ending where the FEM is.
        fem_force = dem_force_prev;
        copy(fem_force, buf.forces(b));
        fem_step(fem_cmd, d);
        copy(buf.positions(b), next_pos);
        const double inv_dt = 1.0 / s.coupling_dt;
        auto v = buf.velocities(b);
        for (std::size_t k = 0; k < n3; ++k) v[k] = (next_pos[k] - pos[k]) * inv_dt;
        copy(pos, buf.positions(b));
        std::fill(buf.accelerations(b).begin(), buf.accelerations(b).end(), 0.0);
        dem_start = pos;
        dem_cmd.flags |= protocol::kStepSetKinematics;
        dem_step(dem_cmd, d);
        break;
      }
      case Scheme::concurrent: {
        // Both at once, each from the other's data at t_i: the DEM moves the mesh from the
        // FEM's state at t_i (x + v tau + a tau^2/2, as just-in-time) in buffer 0, while the
        // FEM advances with the DEM's last forces (F_i, as predictive) in buffer 1.
        copy(pos, buf.positions(b));
        copy(vel, buf.velocities(b));
        copy(acc, buf.accelerations(b));
        dem_start = pos;
        dem_cmd.flags |= protocol::kStepSetKinematics;
        fem_force = dem_force_prev;
        fem_cmd.buffer = b_fem_concurrent;
        copy(fem_force, buf.forces(fem_cmd.buffer));
        const auto t0 = Clock::now();
        send(Role::dem, dem_cmd);
        try {
          send(Role::fem, fem_cmd);
        } catch (...) {
          try {
            (void)link_.wait_step_done(Role::dem);  // the DEM's reply must not stay behind
          } catch (...) {
          }
          throw;
        }
        StepResult rd;
        try {
          rd = wait(Role::dem, dem_cmd);
        } catch (...) {
          try {
            (void)link_.wait_step_done(Role::fem);  // as above: its reply is drained
          } catch (...) {
          }
          throw;
        }
        d.wall_dem = seconds(t0, Clock::now());
        const StepResult rf = wait(Role::fem, fem_cmd);
        d.wall_fem = seconds(t0, Clock::now());
        dem_done(rd, b, d);
        fem_done(rf, d);
        copy(buf.positions(fem_cmd.buffer), next_pos);
        copy(buf.velocities(fem_cmd.buffer), vel);
        copy(buf.accelerations(fem_cmd.buffer), acc);
        break;
      }
      case Scheme::implicit:
        implicit_step(dem_cmd, fem_cmd, d);
        break;
    }

    if (coupled && s.scheme != Scheme::one_way_static) {
      work_dem += trapezoid_work(dem_force_prev, dem_force, dem_start, dem_end);
      work_fem += trapezoid_work(fem_force_prev, fem_force, pos, next_pos);
      d.drift = max_node_distance(dem_end, next_pos);
      pos = next_pos;
    } else if (s.scheme == Scheme::one_way_static) {
      d.drift = settled ? 0.0 : max_node_distance(dem_end, pos);
    }
    if (coupled) {
      dem_force_prev = dem_force;
      fem_force_prev = fem_force;
    }
    d.work_dem = work_dem;
    d.work_fem = work_fem;
    d.energy_error = work_dem - work_fem;
    for (std::size_t k = 2; k < n3; k += 3) d.force_sum_z += dem_force[k];
    check(d);
    if (!nonconvergence.empty()) {  // coupling.on_nonconvergence = "stop": exit status 3
      const std::string why = std::move(nonconvergence);
      nonconvergence.clear();
      write_row(d);
      csv->flush();
      sum.last = d;
      throw BlowUp(d.step, d.time, "iterations", static_cast<double>(d.iterations),
                   static_cast<double>(s.implicit.max_iterations), why);
    }
    d.wall_coupling = std::max(0.0, seconds(step_start, Clock::now()) - solver_wall(d));
    sum.steps = i + 1;
    sum.time = d.time;
    if (out_schedule.due(sum.time, s.coupling_dt))
      write_output(out_schedule.take(sum.time, s.coupling_dt));
    sum.wall_dem += d.wall_dem;
    sum.wall_fem += d.wall_fem;
    const bool row_due = (i + 1) % s.diagnostics_interval == 0 || i + 1 == s.step_count || settled;
    if (row_due) write_row(d);
    // The row's own write is part of the coupler's time; account it to the totals.
    d.wall_coupling = std::max(0.0, seconds(step_start, Clock::now()) - solver_wall(d));
    sum.wall_coupling += d.wall_coupling;
    sum.last = d;
    if (observer_) observer_(d, s);
    return settled;
  };

  // A solver died: restart it, roll every process back to the last committed checkpoint.
  // At most max_retries restarts per checkpoint step; then RecoveryExhausted.
  std::map<std::int64_t, std::int64_t> tries;
  std::string failures;
  auto recover = [&](const SolverFailure& first) -> std::int64_t {
    const auto t0 = Clock::now();
    Role role = first.role();
    std::string why = first.what();
    for (;;) {
      const std::int64_t n = ++tries[last_cp_step];
      failures += "\n  " + why;
      if (n > cps.max_retries) {
        throw RecoveryExhausted(role, first.step(), first.time(),
                                "the " + std::string(role_label(role)) + " solver kept failing: " +
                                    std::to_string(cps.max_retries) + " restarts from checkpoint " +
                                    last_cp->string() + " (step " + std::to_string(last_cp_step) +
                                    ") did not get past it (checkpoint.max_retries = " +
                                    std::to_string(cps.max_retries) + "); failures:" + failures);
      }
      report("the " + std::string(role_label(role)) + " solver failed (" + why + "); restart " +
             std::to_string(n) + " of " + std::to_string(cps.max_retries) +
             ", rolling back to checkpoint " + last_cp->string());
      try {
        control_.restart_solver(role);
        const std::int64_t at = restore_from(*last_cp, false);
        ++stats_.recoveries;
        stats_.recovery_wall += seconds(t0, Clock::now());
        report("recovered: every process is back at step " + std::to_string(at) + " (t = " +
               fmt(sum.time) + " s), " + fmt(seconds(t0, Clock::now())) + " s after the failure");
        return at;
      } catch (const protocol::PeerDied& e) {
        role = e.role();
        why = e.what();
      }
      if (stop_ && stop_->load()) throw Interrupted("stopped by a signal during recovery");
    }
  };

  run_start = Clock::now();  // wall_total: from the first step (or restore) to the last
  try {
    std::int64_t i = 0;
    if (!control_.resume_from) {  // the reference state: output 0
      write_output(out_schedule.label(0.0, s.coupling_dt));
      out_schedule.skip_to_after(0.0);
    }
    if (control_.resume_from) {
      try {
        i = restore_from(*control_.resume_from, true);
      } catch (const protocol::PeerDied&) {
        throw;  // a solver died while restoring: not the checkpoint's fault
      } catch (const protocol::SolverError& e) {
        throw ResumeRefused("checkpoint " + control_.resume_from->string() +
                            " cannot be resumed: " + e.what());
      } catch (const protocol::ProtocolError&) {
        throw;
      } catch (const std::exception& e) {
        throw ResumeRefused("checkpoint " + control_.resume_from->string() +
                            " cannot be resumed: " + e.what());
      }
      stats_.resumed_from = i;
      if (cps.enabled) discard_checkpoints_after(cp_dir, i);
      report("resumed from checkpoint " + control_.resume_from->string() + " (step " +
             std::to_string(i) + ", t = " + fmt(sum.time) + " s)");
    } else if (cps.enabled) {
      discard_checkpoints_after(cp_dir, -1);  // an older run's, its series are being replaced
      take_checkpoint(0);
    }
    // The steps, then (with [checkpoint]) a last checkpoint of the end state, so that a
    // finished run can be continued with a later run.end_time; a solver that dies on the way
    // is recovered in either.
    for (bool done = false; !done;) {
      if (control_.check_output_folder) control_.check_output_folder();
      if (stop_ && stop_->load()) {
        throw Interrupted("stopped by a signal before coupling step " + std::to_string(i) +
                          " (t = " + fmt(static_cast<double>(i) * s.coupling_dt) + " s)");
      }
      try {
        if (i >= s.step_count || settled) {
          if (cps.enabled && last_cp_step != sum.steps) take_checkpoint(sum.steps);
          done = true;
        } else {
          using Request = RunControl::CheckpointRequest;
          const Request asked =
              control_.checkpoint_request ? control_.checkpoint_request() : Request::none;
          const bool stop_after = asked == Request::stop && control_.stop;
          if (asked != Request::none) {
            const std::string at = "step " + std::to_string(i) +
                                   " (t = " + fmt(static_cast<double>(i) * s.coupling_dt) + " s)";
            if (!cps.enabled) {
              report("a checkpoint was asked for at " + at +
                     ", but the scene has no [checkpoint]: none written" +
                     (stop_after ? "; stopping, nothing to resume from" : ""));
            } else {
              if (last_cp_step != i) take_checkpoint(i);
              report("checkpoint of " + at + " written on request (" + last_cp->string() +
                     (stop_after ? "); stopping: `--resume` continues from it" : ")"));
            }
            if (stop_after) {
              control_.stop();
              continue;  // the stop check at the top ends the run
            }
          }
          if (checkpoint_due(i)) take_checkpoint(i);
          if (!one_step(i)) ++i;
        }
      } catch (const SolverFailure& e) {
        // Only a dead (or silent) solver is restarted: an error it reported, such as a
        // blow-up refusal, would repeat from the checkpoint.
        if (!control_.restart_solver || !last_cp || !e.died() || (stop_ && stop_->load())) throw;
        i = recover(e);
      }
    }
    if (s.scheme == Scheme::one_way_static && !settled) {
      throw std::runtime_error(
          "one_way_static: the DEM did not settle by run.end_time = " + fmt(s.run.end_time) +
          " s (kinetic energy " + fmt(sum.last.kinetic_energy) +
          " J > coupling.settle.kinetic_energy = " + fmt(s.settle_kinetic_energy) +
          " J); raise run.end_time (and --resume from the last checkpoint) or the threshold");
    }
  } catch (const OutputFolderLost&) {
    throw;  // the folder may be another run's now: nothing more is written there
  } catch (...) {
    sum.wall_total = seconds(run_start, Clock::now());
    try {
      if (csv) csv->flush();
      write_h5();
      // Not into the series: a resumed run continues from the checkpoint, and the series
      // must hold what the uninterrupted run's does (as the solvers' end states).
    } catch (...) {
      // The original error matters more than a failed final file.
    }
    throw;
  }
  csv->flush();
  sum.wall_total = seconds(run_start, Clock::now());
  sum.settled = settled;
  sum.positions = pos;
  sum.forces = dem_force;
  write_h5();
  if (last_output_step != sum.steps) write_output(out_schedule.label(sum.time, s.coupling_dt));
  return sum;
}

}  // namespace demfem::coupling
