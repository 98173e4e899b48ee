// demfem_run (also built as `coupler`): runs one scene. It is the coupler process: it reads
// [run] and [coupling], checks the whole scene, creates the shared-memory segment, starts
// dem_server and/or fem_server as child processes with --segment, drives the coupling loop,
// shows progress, and exits with the run's status. --in-process runs the same schemes over
// the solver libraries in this process instead (the reference for the three-process run).
//
// Exit status: 0 done; 1 a solver or the run failed (also: a solver that did not attach
// within --hello-timeout); 2 bad command line, scene or checkpoint to resume, output folder in
// use by another run or not writable; 3 blow-up (the diagnosis names step and quantity, or a
// solver reported a non-finite or unstable state); 4 a solver kept dying after
// checkpoint.max_retries restarts from the same checkpoint; 128 + N stopped by signal N
// (SIGINT: 130, SIGTERM: 143; SIGUSR2: 140 after its checkpoint). SIGUSR1 asks for a
// checkpoint at the next coupling-step boundary and the run goes on; SIGUSR2 for one and then
// a stop (`--resume` continues from it). Every run that got its output folder leaves run.json
// there (run_record.hpp) saying how it ended.
//
// This file holds the command line and run(), the order of the launcher's parts; the parts
// are in coupler/src/launch/ (docs/architecture.md, "The launcher").

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>
#include <exception>
#include <optional>
#include <string>
#include <vector>

#include "demfem/coupling/coupling_run.hpp"
#include "demfem/dem/omp_wait.hpp"
#include "demfem/interface/exit_status.hpp"
#include "launch/exit_map.hpp"
#include "launch/launch_options.hpp"
#include "launch/modal_analysis.hpp"
#include "launch/preflight.hpp"
#include "launch/progress.hpp"
#include "launch/resume_point.hpp"
#include "launch/run_folder.hpp"
#include "launch/run_outcome.hpp"
#include "launch/run_report.hpp"
#include "launch/run_solvers.hpp"
#include "launch/scene_steps.hpp"
#include "launch/shutdown.hpp"
#include "launch/supervisor.hpp"

using namespace demfem;
using namespace demfem::coupling;
using namespace demfem::coupling::launch;

namespace {

// How the coupling loop reaches the launcher: messages, the checkpoint requests of SIGUSR1 and
// SIGUSR2, the folder lock check, what checkpoints record.
RunControl make_run_control(const CheckedRun& checked, RunFolder& folder) {
  RunControl control;
  control.fem_backend = checked.settings.has_fem ? checked.settings.fem_backend : std::string();
  control.dem_backend = checked.settings.has_dem ? checked.settings.dem_backend : std::string();
  control.report = [](const std::string& m) {
    std::fprintf(stderr, "demfem run: %s\n", m.c_str());
  };
  control.scene_hash = folder.record().scene_hash;
  control.checkpoint_request = [] {
    using Request = RunControl::CheckpointRequest;
    switch (SignalGuard::take_checkpoint_request()) {
      case SIGUSR1:
        return Request::go_on;
      case SIGUSR2:
        return Request::stop;
      default:
        return Request::none;
    }
  };
  control.stop = [] { SignalGuard::request_stop(SIGUSR2); };
  // The folder locks are checked now and then while the run goes on.
  control.check_output_folder = [&folder] { folder.check_lock(); };
  return control;
}

// The launcher's parts in the order a run goes through them (docs/architecture.md,
// "The launcher").
int run(const LaunchOptions& opt, const std::vector<std::string>& command_line) {
  // ---- pre-flight: the scene and the command line, checked before anything starts --------
  CheckedRun checked;
  if (const auto code = check_before_start(opt, checked)) return *code;

  // ---- the run folder: this run's alone; --resume's checkpoint, or a fresh start ---------
  RunFolder folder;
  if (const auto code = folder.claim(opt, checked, command_line)) return *code;
  RunControl control = make_run_control(checked, folder);
  std::optional<ResumePoint> resume;
  if (opt.resume) {
    if (const auto code = find_resume_point(opt, checked, folder, control.report, resume))
      return *code;
    control.resume_from = resume->checkpoint;
  } else if (const auto code = folder.clear_earlier_outputs()) {
    return *code;
  }
  // From here on a signal ends the run through its handler (and is written into run.json);
  // after the run record, one only sets the flag: the process exits as the record says.
  SignalGuard signals(SignalGuard::Scope::process);
  if (const auto code = folder.record_start()) return *code;
  if (checked.settings.fem_modal) return run_modal_analysis(opt, checked, folder);
  print_run_plan(opt, checked);

  // ---- the solvers and the coupling loop -------------------------------------------------
  Progress progress(stdout, ::isatty(STDOUT_FILENO) == 1, opt.quiet);
  RunOutcome outcome(progress);
  RunSolvers solvers(opt, checked);
  try {
    if (checked.remote) {
      solvers.start_processes(resume, control);
    } else {
      solvers.start_in_process(control);
    }
    CouplingRun loop(*solvers.link(), checked.settings, checked.out_dir, &SignalGuard::stop_flag());
    loop.set_control(control);
    loop.set_observer([&](const StepDiagnostics& d, const CouplingSettings& s) {
      outcome.steps_done = d.step + 1;
      outcome.time_reached = d.time;
      progress.update(d.step, s.step_count, d.time, s.run.end_time);
    });
    outcome.summary = loop.run();
    progress.finish();
    const RecoveryStats& rs = loop.recovery_stats();
    if (rs.checkpoints > 0 || rs.recoveries > 0) {
      std::printf("demfem run: %lld checkpoints (%.3f s), %lld recoveries (%.3f s)\n",
                  static_cast<long long>(rs.checkpoints), rs.checkpoint_wall,
                  static_cast<long long>(rs.recoveries), rs.recovery_wall);
    }
  } catch (...) {
    fail_with_exit_status(std::current_exception(), solvers, checked.out_dir, opt.hello_timeout,
                          outcome);
  }

  // ---- the end: the solvers, the results, [[post]], the run record ----------------------
  end_solvers(solvers, outcome);
  report_results(checked, outcome);
  // [[post]]: plots and reports of a run that ended well.
  if (outcome.code == 0 && outcome.summary && !opt.no_post && !checked.post_steps.empty()) {
    std::fflush(stdout);
    if (run_post_steps(checked.post_steps, checked.out_dir, opt.scene, checked.bin) != 0) {
      outcome.code = kExitFailed;
      outcome.reason = "a [[post]] step failed";
    }
  }
  return outcome.record_end(folder);
}

}  // namespace

int main(int argc, char** argv) {
  demfem::dem::ensure_omp_wait_policy(argv);  // first: it may re-execute the program
  launch::LaunchOptions opt;
  CLI::App app{
      "Runs a demfem scene: starts dem_server and/or fem_server as the scene needs, couples "
      "them, and exits with the run's status (0 ok, 1 failed, 2 bad input, 3 blow-up, 4 a solver "
      "kept dying, "
      "128+N signal N). SIGUSR1: a checkpoint at the next coupling step, then on; SIGUSR2: a "
      "checkpoint, then stop (140)."};
  app.add_option("SCENE", opt.scene, "scene file (TOML)")->required();
  app.add_option("--bin-dir", opt.bin_dir,
                 "folder with dem_server and fem_server (default: this program's folder)");
  app.add_option("--output-dir", opt.output_dir,
                 "folder for the coupler's output (default: run.output_dir of the scene)");
  app.add_flag("--quiet", opt.quiet, "no progress display");
  app.add_option("--set", opt.sets,
                 "KEY=VALUE: set a scene key after reading the scene, in every process; KEY "
                 "dotted with array indices (dem.pairs[0].friction), VALUE in TOML (0.3, "
                 "'\"cuda\"', [0, 0, -9.81]); repeatable, the last wins (docs/scenes.md)")
      ->allow_extra_args(false);
  app.add_flag("--check", opt.check,
               "read and check the scene (with --set) as a run would, start nothing, and exit "
               "(0 valid, 2 not); a prepared state ([dem.load] scene) that is missing is not "
               "made: its scene is checked with its overrides");
  app.add_option("--wait-spin-us", opt.wait_spin_us,
                 "microseconds the coupler spins before it blocks while waiting for a solver "
                 "(default 0: block at once)")
      ->check(CLI::Range(0, 100000));
  app.add_flag("--solver-sessions", opt.solver_sessions,
               "start each solver in a session of its own (setsid), so that under Linux's "
               "autogroup scheduling each gets a CPU share of its own (the concurrent scheme "
               "needs both cores while other sessions are busy); signals to the launcher's "
               "process group then reach only the launcher, which forwards SIGTERM "
               "(docs/coupling.md)");
  app.add_flag("--no-post", opt.no_post, "skip the scene's [[post]] steps (plots, reports)");
  app.add_flag("--in-process", opt.in_process,
               "run the solvers in this process (no servers; same results on the CPU backend)");
  auto* resume = app.add_option("--resume", opt.resume_from,
                                "continue from a committed checkpoint: the given folder, or "
                                "without a value the latest valid one in the checkpoint folder")
                     ->expected(0, 1);
  app.add_option("--fem-backend", opt.fem_backend,
                 "the FEM backend of this run, overriding fem.backend: fem (full FEM), modal "
                 "(first N modes + static correction), rigid (one rigid body on springs) or "
                 "external (fem.command); with --resume it continues a checkpoint of another "
                 "backend where the state maps (docs/backends.md)")
      ->check(CLI::IsMember({"fem", "modal", "rigid", "external"}));
  app.add_option("--dem-backend", opt.dem_backend,
                 "the DEM backend of this run, overriding dem.backend: cpu or cuda (dem_server) "
                 "or external (the program of dem.command, on the SDK's DEM side; "
                 "docs/backends.md)")
      ->check(CLI::IsMember({"cpu", "cuda", "external"}));
  app.add_option("--hello-timeout", opt.hello_timeout,
                 "seconds a started solver may take to attach (its Hello) before it is killed "
                 "and the run stops with status 1 (default 300; raise it for models whose "
                 "set-up takes longer; without it a scene with dem.settle_time has no limit, "
                 "the settling running before the DEM attaches)")
      ->check(CLI::Range(0.1, 1e6));
  app.add_option("--debug-kill", opt.debug_kill,
                 "testing only: SIGKILL (or with :stop SIGSTOP) a process at a coupling step, "
                 "ROLE:STEP[:always|:stop] with ROLE dem, fem or coupler; or job:STEP:usr1|usr2, "
                 "a checkpoint request to every process (docs/reliability.md)");
  try {
    app.parse(argc, argv);
    opt.hello_timeout_given = app.count("--hello-timeout") > 0;
    opt.resume = resume->count() > 0;
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return kExitBadInput;
  }
  return run(opt, std::vector<std::string>(argv, argv + argc));
}
