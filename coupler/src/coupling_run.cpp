#include "demfem/coupling/coupling_run.hpp"

#include <cmath>
#include <string>
#include <utility>

#include "demfem/coupling/checkpoint.hpp"
#include "interface_checks.hpp"
#include "recovery.hpp"
#include "run_checkpoints.hpp"
#include "run_output.hpp"
#include "run_session.hpp"
#include "run_text.hpp"
#include "step_checks.hpp"

namespace demfem::coupling {

namespace {

// The FEM's published mesh: a node that is not finite would be found by the DEM in its first
// step and blamed on it. `backend`: the FEM's name (Hello).
void check_published_mesh(const InterfaceMesh& mesh, const std::string& backend) {
  const std::ptrdiff_t k = first_non_finite(mesh.reference_positions);
  if (k < 0) return;
  const double* x = &mesh.reference_positions[static_cast<std::size_t>(k - k % 3)];
  throw HandshakeFailed(protocol::Role::fem, "the FEM solver's backend \"" + backend +
                                                 "\" published an interface mesh whose node " +
                                                 std::to_string(k / 3) + " is not finite: (" +
                                                 format_number(x[0]) + ", " + format_number(x[1]) +
                                                 ", " + format_number(x[2]) + ") m; it is refused");
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

// Ends the run with `why` after step `d`: its row written and on disk first.
[[noreturn]] void stop_after_step(RunSession& run, const StepDiagnostics& d, const BlowUp& why) {
  run.output.write_row(d);
  run.output.flush();
  run.summary.last = d;
  throw why;
}

// Coupling step i (0-based) by the scheme, checked, accounted and written; returns true when
// the run is complete (settled).
bool coupling_step(RunSession& run, std::int64_t i, const StepObserver& observer) {
  const CouplingSettings& s = run.settings;
  RunSummary& sum = run.summary;
  const auto step_start = RunClock::now();
  StepDiagnostics d;
  d.step = i;
  d.time = s.time_at(i + 1);
  StepCommand dem_cmd;
  dem_cmd.step = i;
  dem_cmd.time = s.time_at(i);
  dem_cmd.dt = s.coupling_dt;
  dem_cmd.substeps = s.dem_substeps;
  dem_cmd.buffer = kSharedBuffer;
  dem_cmd.force_mode = s.force_mode();
  StepCommand fem_cmd = dem_cmd;
  fem_cmd.substeps = 1;
  run.scheme->step(dem_cmd, fem_cmd, d);
  if (const auto blow_up = blow_up_of(d, run.state, s)) stop_after_step(run, d, *blow_up);
  if (std::string why = run.scheme->take_stop_reason(); !why.empty()) {
    // coupling.on_nonconvergence = "stop": exit status 3
    stop_after_step(run, d,
                    BlowUp(d.step, d.time, "iterations", static_cast<double>(d.iterations),
                           static_cast<double>(s.implicit.max_iterations), why));
  }
  auto coupler_wall = [&] {
    return std::max(0.0, seconds_between(step_start, RunClock::now()) - run.scheme->solver_wall(d));
  };
  d.wall_coupling = coupler_wall();
  sum.steps = i + 1;
  sum.time = d.time;
  run.output.write_interface_if_due(run.interface_state(), sum.time, s.coupling_dt, sum.steps);
  sum.wall_dem += d.wall_dem;
  sum.wall_fem += d.wall_fem;
  const bool settled = run.state.settled;
  if ((i + 1) % s.diagnostics_interval == 0 || i + 1 == s.step_count || settled)
    run.output.write_row(d);
  // The row's own write is part of the coupler's time; account it to the totals.
  d.wall_coupling = coupler_wall();
  sum.wall_coupling += d.wall_coupling;
  sum.last = d;
  if (observer) observer(d, s);
  return settled;
}

// The start: a fresh run writes the reference state as output 0 and (with [checkpoint])
// checkpoint 0; a resumed one restores its checkpoint. Returns the first step to run.
std::int64_t start_or_resume(RunSession& run, RunCheckpoints& checkpoints) {
  const CouplingSettings& s = run.settings;
  const auto& resume_from = run.control.resume_from;
  if (!resume_from) {
    run.output.write_initial_interface(run.interface_state(), s.start_time, s.coupling_dt);
    if (s.checkpoint.enabled) {
      discard_checkpoints_after(checkpoints.directory(), -1);  // an older run's: replaced
      checkpoints.take(0);
    }
    return 0;
  }
  std::int64_t i = 0;
  try {
    i = checkpoints.restore(*resume_from, true);
  } catch (const protocol::PeerDied&) {
    throw;  // a solver died while restoring: not the checkpoint's fault
  } catch (const protocol::SolverError& e) {
    throw ResumeRefused("checkpoint " + resume_from->string() + " cannot be resumed: " + e.what());
  } catch (const protocol::ProtocolError&) {
    throw;
  } catch (const std::exception& e) {
    throw ResumeRefused("checkpoint " + resume_from->string() + " cannot be resumed: " + e.what());
  }
  run.stats.resumed_from = i;
  if (s.checkpoint.enabled) discard_checkpoints_after(checkpoints.directory(), i);
  run.report("resumed from checkpoint " + resume_from->string() + " (step " + std::to_string(i) +
             ", t = " + format_number(run.summary.time) + " s)");
  return i;
}

// A checkpoint asked for from outside the run before step i (RunControl::checkpoint_request);
// returns true when the run is to stop after it (RunControl::stop called).
bool serve_checkpoint_request(RunSession& run, RunCheckpoints& checkpoints, std::int64_t i) {
  using Request = RunControl::CheckpointRequest;
  const RunControl& control = run.control;
  const Request asked = control.checkpoint_request ? control.checkpoint_request() : Request::none;
  if (asked == Request::none) return false;
  const bool stop_after = asked == Request::stop && control.stop;
  const std::string at =
      "step " + std::to_string(i) + " (t = " + format_number(run.settings.time_at(i)) + " s)";
  if (!run.settings.checkpoint.enabled) {
    run.report("a checkpoint was asked for at " + at +
               ", but the scene has no [checkpoint]: none written" +
               (stop_after ? "; stopping, nothing to resume from" : ""));
  } else {
    if (checkpoints.last_step() != i) checkpoints.take(i);
    run.report("checkpoint of " + at + " written on request (" + checkpoints.last()->string() +
               (stop_after ? "); stopping: `--resume` continues from it" : ")"));
  }
  if (stop_after) control.stop();
  return stop_after;
}

// Before every step: the output folder still the run's, and no stop asked for.
void check_before_step(const RunSession& run, const std::atomic<bool>* stop, std::int64_t i) {
  if (run.control.check_output_folder) run.control.check_output_folder();
  if (stop && stop->load()) {
    throw Interrupted("stopped by a signal before coupling step " + std::to_string(i) +
                      " (t = " + format_number(run.settings.time_at(i)) + " s)");
  }
}

// one_way_static must have come to rest by the end.
void check_settled(const RunSession& run) {
  const CouplingSettings& s = run.settings;
  if (s.scheme != Scheme::one_way_static || run.state.settled) return;
  throw std::runtime_error(
      "one_way_static: the DEM did not settle by run.end_time = " + format_number(s.run.end_time) +
      " s (kinetic energy " + format_number(run.summary.last.kinetic_energy) +
      " J > coupling.settle.kinetic_energy = " + format_number(s.settle_kinetic_energy) +
      " J); raise run.end_time (and --resume from the last checkpoint) or the threshold");
}

}  // namespace

RunSummary CouplingRun::run() {
  const CouplingSettings& s = settings_;
  std::filesystem::create_directories(output_dir_);
  RunOutput output(output_dir_, control_.resume_from.has_value(), s.run.output_interval);
  InterfaceMesh mesh = link_.start();
  check_published_mesh(mesh, link_.name(Role::fem));
  RunSession run(link_, s, control_, output_dir_, stats_, output, std::move(mesh));
  output.open_interface_series(run.summary.mesh);
  RunCheckpoints checkpoints(run);
  Recovery recovery(run, checkpoints, stop_);
  RunSummary& sum = run.summary;
  run.run_start = RunClock::now();  // wall_total: from the first step (or restore) to the last
  try {
    std::int64_t i = start_or_resume(run, checkpoints);
    // The steps, then (with [checkpoint]) a last checkpoint of the end state, so that a
    // finished run can be continued with a later run.end_time; a solver that dies on the way
    // is recovered in either.
    for (bool done = false; !done;) {
      check_before_step(run, stop_, i);
      try {
        if (i >= s.step_count || run.state.settled) {
          if (s.checkpoint.enabled && checkpoints.last_step() != sum.steps)
            checkpoints.take(sum.steps);
          done = true;
        } else if (!serve_checkpoint_request(run, checkpoints, i)) {
          if (checkpoints.due(i)) checkpoints.take(i);
          if (!coupling_step(run, i, observer_)) ++i;
        }  // else: stopping after the checkpoint asked for; the check above ends the run
      } catch (const SolverFailure& e) {
        if (!recovery.can_recover(e)) throw;
        i = recovery.recover(e);
      }
    }
    check_settled(run);
  } catch (const OutputFolderLost&) {
    throw;  // the folder may be another run's now: nothing more is written there
  } catch (...) {
    sum.wall_total = seconds_between(run.run_start, RunClock::now());
    try {
      output.flush();
      // Not into the series: a resumed run continues from the checkpoint, and the series
      // must hold what the uninterrupted run's does (as the solvers' end states).
      run.write_end_state();
    } catch (...) {
      // The original error matters more than a failed final file.
    }
    throw;
  }
  output.flush();
  sum.wall_total = seconds_between(run.run_start, RunClock::now());
  sum.settled = run.state.settled;
  sum.positions = run.state.positions;
  sum.forces = run.state.dem_force;
  run.write_end_state();
  output.write_final_interface(run.interface_state(), sum.time, s.coupling_dt, sum.steps);
  return sum;
}

}  // namespace demfem::coupling
