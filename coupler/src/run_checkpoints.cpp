#include "run_checkpoints.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "coupling_series.hpp"
#include "demfem/coupling/checkpoint.hpp"
#include "demfem/io/checkpoint_file.hpp"
#include "demfem/io/h5_file.hpp"
#include "run_text.hpp"

namespace demfem::coupling {

RunCheckpoints::RunCheckpoints(RunSession& session)
    : run_(session),
      directory_(checkpoint_directory(session.settings, session.output_dir)),
      parts_(checkpoint_parts(session.settings)) {}

bool RunCheckpoints::due(std::int64_t steps) const {
  const CouplingSettings& s = run_.settings;
  const CheckpointSettings& cps = s.checkpoint;
  if (!cps.enabled || steps == last_step_ || steps >= s.step_count) return false;
  if (cps.every_steps > 0 && steps % cps.every_steps == 0) return true;
  if (cps.every_sim_time > 0.0) {
    const double t = s.time_at(steps);
    const double t_last = s.time_at(std::max<std::int64_t>(last_step_, 0));
    if (std::floor(t / cps.every_sim_time + 1e-9) > std::floor(t_last / cps.every_sim_time + 1e-9))
      return true;
  }
  return cps.every_wall_time > 0.0 &&
         seconds_between(last_wall_, RunClock::now()) >= cps.every_wall_time;
}

void RunCheckpoints::take(std::int64_t steps) {
  const auto t0 = RunClock::now();
  const auto folder = directory_ / checkpoint_folder_name(steps);
  std::filesystem::remove_all(folder);  // an uncommitted or rolled-back one
  std::filesystem::create_directories(folder);
  run_.output.flush();
  for (Role role : {Role::dem, Role::fem}) {
    if (!run_.link.has(role)) continue;
    const auto file = folder / (role == Role::dem ? "dem.h5" : "fem.h5");
    try {
      run_.link.checkpoint(role, file, steps);
    } catch (const std::exception& e) {
      throw SolverFailure(role, steps, run_.summary.time,
                          std::string("the ") + role_label(role) +
                              " solver failed writing checkpoint " + file.string() + ": " +
                              e.what(),
                          dynamic_cast<const protocol::PeerDied*>(&e) != nullptr, error_kind_of(e));
    }
  }
  save_coupler(folder / "coupler.h5", steps);
  commit_checkpoint(folder, steps, run_.summary.time, scheme_name(run_.settings.scheme), parts_);
  last_ = folder;
  last_step_ = steps;
  prune_checkpoints(directory_, run_.settings.checkpoint.keep);
  last_wall_ = RunClock::now();
  ++run_.stats.checkpoints;
  run_.stats.checkpoint_wall += seconds_between(t0, last_wall_);
}

std::int64_t RunCheckpoints::restore(const std::filesystem::path& folder, bool resume) {
  const CheckpointManifest m = verify_checkpoint(folder, parts_);
  // The coupler's part first: its interface check names a changed mesh more plainly than the
  // solvers' own refusals would.
  load_coupler(folder / "coupler.h5", m.step, resume);
  for (Role role : {Role::dem, Role::fem}) {
    if (!run_.link.has(role)) continue;
    run_.link.restore(role, folder / (role == Role::dem ? "dem.h5" : "fem.h5"), m.step);
  }
  run_.output.continue_rows(restored_rows_);
  last_ = folder;
  last_step_ = m.step;
  last_wall_ = RunClock::now();
  return m.step;
}

void RunCheckpoints::save_coupler(const std::filesystem::path& file, std::int64_t steps) const {
  const CouplingSettings& s = run_.settings;
  const RunControl& control = run_.control;
  const RunSummary& sum = run_.summary;
  const SchemeState& st = run_.state;
  SolverLink& link = run_.link;
  io::write_checkpoint_file(file, steps, [&](io::H5File& h5) {
    h5.set_attribute("/", "scheme", std::string(scheme_name(s.scheme)));
    h5.set_attribute("/", "node_count", static_cast<std::int64_t>(run_.n3 / 3));
    h5.set_attribute("/", "time", sum.time);
    h5.set_attribute("/", "start_time", s.start_time);
    h5.set_attribute("/", "work_dem", st.work_dem);
    h5.set_attribute("/", "work_fem", st.work_fem);
    h5.set_attribute("/", "settled", static_cast<std::int64_t>(st.settled));
    h5.set_attribute("/", "csv_rows", run_.output.rows());
    h5.set_attribute("/", "output_next", run_.output.next_output());
    h5.set_attribute("/", "output_last_step", run_.output.last_output_step());
    // Wall times of the whole run so far: earlier sessions (a resumed run) and this one.
    h5.set_attribute("/", "wall_total",
                     sum.earlier.total + seconds_between(run_.run_start, RunClock::now()));
    h5.set_attribute("/", "wall_dem", sum.earlier.dem + sum.wall_dem);
    h5.set_attribute("/", "wall_fem", sum.earlier.fem + sum.wall_fem);
    h5.set_attribute("/", "wall_coupling", sum.earlier.coupling + sum.wall_coupling);
    if (!control.scene_hash.empty()) h5.set_attribute("/", "scene_hash", control.scene_hash);
    if (link.has(Role::fem)) {
      h5.set_attribute("/", "fem_backend",
                       control.fem_backend.empty() ? std::string("fem") : control.fem_backend);
      h5.set_attribute("/", "fem_backend_name", link.name(Role::fem));
    }
    if (link.has(Role::dem) && !control.dem_backend.empty()) {
      h5.set_attribute("/", "dem_backend", control.dem_backend);
      h5.set_attribute("/", "dem_backend_name", link.name(Role::dem));
    }
    h5.set_attribute("/", "output_dir", std::filesystem::absolute(run_.output_dir).string());
    const auto last = row_of(sum.last);
    h5.write("last_diagnostics", std::span<const double>(last), {last.size()});
    h5.create_group("scheme");
    for (const auto& [name, v] : run_.state.arrays())
      h5.write(name, std::span<const double>(*v), {v->size()});
    h5.set_attribute("/", "iterations", sum.iterations);
    h5.set_attribute("/", "max_iterations", sum.max_iterations);
    h5.set_attribute("/", "unconverged_steps", sum.unconverged_steps);
    run_.scheme->save_history(h5);
    save_buffers(h5);
  });
}

void RunCheckpoints::save_buffers(io::H5File& h5) const {
  const std::size_t n3 = run_.n3;
  if (n3 == 0) return;
  // The interface buffer as the solvers left it (the schemes rewrite it before every read,
  // but a restored run starts from exactly the same bytes).
  InterfaceBuffers& buf = run_.link.buffers();
  constexpr std::uint32_t b = kSharedBuffer;
  h5.create_group("buffer");
  h5.write("buffer/positions", std::span<const double>(buf.positions(b)), {n3});
  h5.write("buffer/velocities", std::span<const double>(buf.velocities(b)), {n3});
  h5.write("buffer/accelerations", std::span<const double>(buf.accelerations(b)), {n3});
  h5.write("buffer/forces", std::span<const double>(buf.forces(b)), {n3});
  h5.write("buffer/dem_positions", std::span<const double>(buf.dem_positions(b)), {n3});
  if (run_.settings.scheme != Scheme::concurrent) return;
  constexpr std::uint32_t f = kConcurrentFemBuffer;  // the FEM's buffer
  h5.create_group("buffer1");
  h5.write("buffer1/positions", std::span<const double>(buf.positions(f)), {n3});
  h5.write("buffer1/velocities", std::span<const double>(buf.velocities(f)), {n3});
  h5.write("buffer1/accelerations", std::span<const double>(buf.accelerations(f)), {n3});
  h5.write("buffer1/forces", std::span<const double>(buf.forces(f)), {n3});
}

void RunCheckpoints::load_coupler(const std::filesystem::path& file, std::int64_t steps,
                                  bool resume) {
  const CouplingSettings& s = run_.settings;
  RunSummary& sum = run_.summary;
  SchemeState& st = run_.state;
  const std::size_t n3 = run_.n3;
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
  // The clock's start (a DEM state's time kept, [dem.load] keep_time): the steps' times
  // follow from it. Checkpoints of older versions lack it: their runs started at 0.
  const std::string clock = start_time_mismatch(
      s, h5.has_attribute("/", "start_time") ? h5.attribute_double("/", "start_time") : 0.0);
  need(clock.empty(), clock);
  sum.time = h5.attribute_double("/", "time");
  st.work_dem = h5.attribute_double("/", "work_dem");
  st.work_fem = h5.attribute_double("/", "work_fem");
  st.settled = h5.attribute_int64("/", "settled") != 0;
  const std::int64_t csv_rows = h5.attribute_int64("/", "csv_rows");
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
       "dataset 'last_diagnostics' has " + std::to_string(last.size()) + " values, coupling.csv " +
           std::to_string(coupling_columns().size()) +
           " columns (a checkpoint of an older demfem, whose series had other columns: start "
           "the run afresh)");
  sum.last = diagnostics_of(last);
  for (const auto& [name, v] : st.arrays()) {
    auto data = h5.read_doubles(name);
    need(data.size() == n3, std::string("dataset '") + name + "' has " +
                                std::to_string(data.size()) + " values, expected " +
                                std::to_string(n3));
    *v = std::move(data);
  }
  load_buffers(h5, file);
  sum.iterations = h5.attribute_int64("/", "iterations");
  sum.max_iterations = h5.attribute_int64("/", "max_iterations");
  sum.unconverged_steps = h5.attribute_int64("/", "unconverged_steps");
  run_.scheme->load_history(h5);
  sum.steps = steps;
  // Written before the attributes existed: the outputs up to its time were taken.
  std::optional<std::int64_t> next_output;
  std::int64_t last_output_step = -1;
  if (h5.has_attribute("/", "output_next")) {
    next_output = h5.attribute_int64("/", "output_next");
    last_output_step = h5.attribute_int64("/", "output_last_step");
  }
  run_.output.restore_interface(next_output, last_output_step, sum.time, steps);
  restored_rows_ = csv_rows;  // coupling.csv is cut back once the solvers are restored too
}

void RunCheckpoints::load_buffers(const io::H5File& h5, const std::filesystem::path& file) {
  const std::size_t n3 = run_.n3;
  if (n3 == 0) return;
  InterfaceBuffers& buf = run_.link.buffers();
  auto read_into = [&](const char* name, std::span<double> to) {
    const auto data = h5.read_doubles(name);
    if (data.size() != n3)
      throw std::runtime_error(file.string() + ": dataset '" + name + "' has the wrong size");
    std::ranges::copy(data, to.begin());
  };
  constexpr std::uint32_t b = kSharedBuffer;
  read_into("buffer/positions", buf.positions(b));
  read_into("buffer/velocities", buf.velocities(b));
  read_into("buffer/accelerations", buf.accelerations(b));
  read_into("buffer/forces", buf.forces(b));
  read_into("buffer/dem_positions", buf.dem_positions(b));
  if (run_.settings.scheme != Scheme::concurrent) return;
  constexpr std::uint32_t f = kConcurrentFemBuffer;
  read_into("buffer1/positions", buf.positions(f));
  read_into("buffer1/velocities", buf.velocities(f));
  read_into("buffer1/accelerations", buf.accelerations(f));
  read_into("buffer1/forces", buf.forces(f));
}

}  // namespace demfem::coupling
