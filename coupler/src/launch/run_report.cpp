#include "launch/run_report.hpp"

#include <cstdio>

#include "demfem/coupling/acceleration.hpp"
#include "demfem/coupling/beam_check.hpp"
#include "demfem/interface/exit_status.hpp"
#include "demfem/io/atomic_file.hpp"

namespace demfem::coupling::launch {

void print_run_plan(const LaunchOptions& opt, const CheckedRun& run) {
  const CouplingSettings& settings = run.settings;
  // A clock that starts at a loaded state's time says so: end_time is not the run's length.
  char from[96] = "";
  if (!settings.start_time_where.empty())
    std::snprintf(from, sizeof(from), " from t = %.9g s (the DEM state's time)",
                  settings.start_time);
  std::printf(
      "demfem run: %s: scheme %s, dt_C = %.6g s (n_D = %lld), %lld coupling steps%s to "
      "t = %.6g s%s\n",
      opt.scene.c_str(), scheme_name(settings.scheme), settings.coupling_dt,
      static_cast<long long>(settings.dem_substeps), static_cast<long long>(settings.step_count),
      from, settings.run.end_time, run.remote ? "" : " (in process)");
  std::fflush(stdout);
}

namespace {

void print_scheme_totals(const CouplingSettings& settings, const RunSummary& summary) {
  if (settings.scheme == Scheme::one_way_static) {
    std::printf(
        "demfem run: the DEM settled at t = %.6g s (kinetic energy %.3g J); its forces "
        "(sum %.9g N along z) went into one static FEM solve\n",
        summary.time, summary.last.kinetic_energy, summary.last.force_sum_z);
  }
  if (settings.scheme == Scheme::implicit && summary.steps > 0) {
    std::printf(
        "demfem run: implicit (%s): %lld iterations in %lld steps, %.3g per step, at "
        "most %lld; %lld steps accepted without convergence\n",
        acceleration_name(settings.implicit.acceleration.kind),
        static_cast<long long>(summary.iterations), static_cast<long long>(summary.steps),
        static_cast<double>(summary.iterations) / static_cast<double>(summary.steps),
        static_cast<long long>(summary.max_iterations),
        static_cast<long long>(summary.unconverged_steps));
  }
}

void write_beam_check(const CheckedRun& run, const RunSummary& summary) {
  const CouplingSettings& settings = run.settings;
  const auto r = run_beam_check(*settings.beam_check, *run.doc, summary);
  std::printf("%s", beam_check_table(r, *settings.beam_check).c_str());
  char text[512];
  std::snprintf(text, sizeof(text),
                "load_mass,coupled,fem_pressure,analytical,coupled_load,pressure_load\n"
                "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n",
                settings.beam_check->load_mass, r.coupled, r.fem_pressure, r.analytical,
                r.coupled_load, r.pressure_load);
  io::write_file_atomic(run.out_dir / "beam_check.csv", text);
}

}  // namespace

void report_results(const CheckedRun& run, RunOutcome& outcome) {
  if (!outcome.summary) return;
  const RunSummary& summary = *outcome.summary;
  const CouplingSettings& settings = run.settings;
  std::printf("demfem run: done: %lld coupling steps, t = %.6g s; output in %s\n",
              static_cast<long long>(summary.steps), summary.time, run.out_dir.c_str());
  print_scheme_totals(settings, summary);
  print_timing(summary, run.remote);
  try {
    write_timing(run.out_dir, summary);
    if (settings.beam_check && settings.has_dem && settings.has_fem) write_beam_check(run, summary);
  } catch (const std::exception& e) {
    if (outcome.code == 0) {
      outcome.fail(kExitFailed, e.what());
    } else {
      std::fprintf(stderr, "demfem run: %s\n", e.what());
    }
  }
}

}  // namespace demfem::coupling::launch
