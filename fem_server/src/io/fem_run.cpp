#include <chrono>
#include <cmath>
#include <cstdio>
#include <ostream>

#include "demfem/fem/fem_output.hpp"
#include "demfem/fem/modal_run.hpp"
#include "demfem/io/output_schedule.hpp"

namespace demfem::fem {

namespace {

double max_norm3(const std::vector<double>& v) {
  double m = 0.0;
  for (std::size_t i = 0; i + 2 < v.size(); i += 3) {
    m = std::max(m, std::sqrt(v[i] * v[i] + v[i + 1] * v[i + 1] + v[i + 2] * v[i + 2]));
  }
  return m;
}

/// The time loop of a standalone run, for every solver of a FEM backend.
template <class Solver>
FemRunSummary run_solver(Solver& solver, const FemScene& scene, double end_time,
                         double output_interval, const std::filesystem::path& dir,
                         const std::string& name, std::ostream* progress) {
  using clock = std::chrono::steady_clock;
  const auto start = clock::now();
  FemRunSummary summary;
  std::unique_ptr<FemOutput> out;
  if (scene.output.enabled) {
    out = std::make_unique<FemOutput>(dir, name, scene.problem.mesh, scene.output);
  }
  auto write = [&] {
    if (out) {
      out->write(gather_fields(solver));
      ++summary.outputs;
    }
  };

  if (scene.analysis == Analysis::static_analysis) {
    solver.solve_static();
    write();
  } else {
    const double dt = scene.dt;
    if (!(end_time / dt <= scene::kMaxFemSteps)) {
      throw scene::SceneError(
          scene.dt_location + ": run.end_time / dt = " + std::to_string(end_time / dt) +
          " steps, more than the " + std::to_string(scene::kMaxFemSteps) + " a run may take");
    }
    const double interval = scene.output.interval > 0.0 ? scene.output.interval : output_interval;
    // The step count that reaches end_time; the 1e-9 keeps an end_time that is a multiple of
    // dt (up to round-off) from taking one step too many.
    const auto steps = static_cast<std::int64_t>(std::ceil(end_time / dt - 1e-9));
    // Output k is the state at the step end nearest to k * interval, labelled k * interval;
    // the clock is the step count x dt, not the running sum of dt (io::OutputSchedule).
    io::OutputSchedule schedule(interval);
    auto write_labelled = [&](double label) {
      if (!out) return;
      FemFields f = gather_fields(solver);
      f.time = label;
      f.state_time = solver.time();
      out->write(f);
      ++summary.outputs;
    };
    write_labelled(schedule.label(0.0, dt));  // initial state
    schedule.skip_to_after(0.0);
    auto last_report = clock::now();
    bool written_last = true;
    for (std::int64_t s = 0; s < steps; ++s) {
      solver.advance(dt);
      written_last = false;
      const double t = static_cast<double>(s + 1) * dt;
      if (schedule.due(t, dt)) {
        write_labelled(schedule.take(t, dt));
        written_last = true;
      }
      if (progress && clock::now() - last_report > std::chrono::seconds(2)) {
        last_report = clock::now();
        const double wall = std::chrono::duration<double>(last_report - start).count();
        const double rate = static_cast<double>(s + 1) / wall;
        char line[200];
        std::snprintf(line, sizeof line,
                      "fem: t = %.6g s of %.6g s (%.1f%%), %.1f steps/s, ETA %.0f s\n",
                      solver.time(), end_time, 100.0 * solver.time() / end_time, rate,
                      static_cast<double>(steps - s - 1) / rate);
        *progress << line << std::flush;
      }
    }
    if (!written_last) write_labelled(schedule.label(static_cast<double>(steps) * dt, dt));
    summary.steps = steps;
  }
  summary.end_time = solver.time();
  summary.max_displacement = max_norm3(solver.displacements());
  summary.wall_seconds = std::chrono::duration<double>(clock::now() - start).count();
  if (progress) {
    char line[240];
    std::snprintf(line, sizeof line,
                  "fem: done, %s (%s backend), t = %.6g s, %lld steps, max |u| = %.6g m, %zu "
                  "outputs, %.2f s\n",
                  analysis_name(scene.analysis), backend_kind_name(scene.backend), summary.end_time,
                  static_cast<long long>(summary.steps), summary.max_displacement, summary.outputs,
                  summary.wall_seconds);
    *progress << line << std::flush;
  }
  return summary;
}

}  // namespace

FemRunSummary run_fem_standalone(const FemScene& scene, double end_time, double output_interval,
                                 const std::filesystem::path& dir, const std::string& name,
                                 std::ostream* progress) {
  if (scene.analysis == Analysis::modal) {
    const auto t0 = std::chrono::steady_clock::now();
    const ModalRunSummary m = run_modal_analysis(scene, dir, progress);
    FemRunSummary summary;
    summary.outputs = m.frequencies_hz.size();
    summary.wall_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return summary;
  }
  if (scene.analysis == Analysis::dynamic && !(scene.dt > 0.0)) {
    throw scene::SceneError(scene.dt_location +
                            ": is required (> 0 s) for a dynamic FEM run without a coupler");
  }
  switch (scene.backend) {
    case FemBackendKind::modal: {
      ModalSolver solver(scene.problem, scene.modal);
      return run_solver(solver, scene, end_time, output_interval, dir, name, progress);
    }
    case FemBackendKind::rigid: {
      RigidSolver solver(scene.problem, scene.rigid);
      return run_solver(solver, scene, end_time, output_interval, dir, name, progress);
    }
    case FemBackendKind::external:
      throw std::invalid_argument(
          "fem.backend = \"external\": the structure is modelled by the program of "
          "fem.command, which fem_server cannot run; run the scene with demfem run");
    case FemBackendKind::fem:
      break;
  }
  FemSolver solver(scene.problem);
  return run_solver(solver, scene, end_time, output_interval, dir, name, progress);
}

}  // namespace demfem::fem
