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

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "demfem/coupling/beam_check.hpp"
#include "demfem/coupling/checkpoint.hpp"
#include "demfem/coupling/coupling_run.hpp"
#include "demfem/coupling/coupling_settings.hpp"
#include "demfem/coupling/external_backend.hpp"
#include "demfem/coupling/local_solvers.hpp"
#include "demfem/coupling/output_folder.hpp"
#include "demfem/coupling/progress.hpp"
#include "demfem/coupling/resume_check.hpp"
#include "demfem/coupling/run_record.hpp"
#include "demfem/coupling/scene_steps.hpp"
#include "demfem/coupling/solver_link.hpp"
#include "demfem/coupling/supervisor.hpp"
#include "demfem/dem/omp_wait.hpp"
#include "demfem/fem/fem_backend.hpp"
#include "demfem/fem/fem_scene.hpp"
#include "demfem/fem/modal_run.hpp"
#include "demfem/interface/exit_status.hpp"
#include "demfem/io/atomic_file.hpp"
#include "demfem/io/folder_lock.hpp"
#include "demfem/io/h5_file.hpp"

namespace fs = std::filesystem;
using namespace demfem;
using namespace demfem::coupling;

namespace {

struct Options {
  std::string scene;
  std::string bin_dir;
  std::string output_dir;
  bool quiet = false;
  bool in_process = false;
  bool no_post = false;
  int wait_spin_us = 0;
  bool solver_sessions = false;
  bool resume = false;
  std::string resume_from;        // empty: the latest valid checkpoint
  std::string debug_kill;         // ROLE:STEP[:always], fault injection for tests
  std::vector<std::string> sets;  // --set KEY=VALUE, passed on to the solvers
  bool check = false;             // --check: read and check the scene, start nothing
  double hello_timeout = 300.0;   // s: a started solver that has not said Hello is killed
  bool hello_timeout_given = false;
  std::string fem_backend;        // --fem-backend: overrides fem.backend ("" = the scene's)
  std::string dem_backend;        // --dem-backend: overrides dem.backend ("" = the scene's)
};

// --debug-kill dem:17, fem:5:always, coupler:30, job:12:usr2 (docs/reliability.md). Testing
// only. ROLE job: the signal (SIGUSR1/SIGUSR2, a checkpoint request) goes to every process of
// the run, the launcher and both solvers, as Slurm's --signal sends it to a job's processes.
struct DebugKill {
  std::string role;
  std::int64_t step = -1;
  bool always = false;
  bool stop = false;
  int job_signal = 0;
  bool fired = false;
};

std::optional<DebugKill> parse_debug_kill(const std::string& text) {
  if (text.empty()) return std::nullopt;
  DebugKill k;
  const auto c1 = text.find(':');
  if (c1 == std::string::npos) throw std::invalid_argument(text);
  k.role = text.substr(0, c1);
  std::string rest = text.substr(c1 + 1);
  if (const auto c2 = rest.find(':'); c2 != std::string::npos) {
    const std::string how = rest.substr(c2 + 1);
    if (how == "always") {
      k.always = true;
    } else if (how == "stop") {
      k.stop = true;  // SIGSTOP: a hung process, found by its stale heartbeat
    } else if (how == "usr1" || how == "usr2") {
      k.job_signal = how == "usr1" ? SIGUSR1 : SIGUSR2;
    } else {
      throw std::invalid_argument(text);
    }
    rest = rest.substr(0, c2);
  }
  std::size_t used = 0;
  k.step = std::stoll(rest, &used);
  if (used != rest.size() || k.step < 0 ||
      (k.role != "dem" && k.role != "fem" && k.role != "coupler" && k.role != "job") ||
      ((k.role == "job") != (k.job_signal != 0))) {
    throw std::invalid_argument(text);
  }
  return k;
}

fs::path self_dir() {
  std::error_code ec;
  const auto exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::current_path() : exe.parent_path();
}

int run(const Options& opt, const std::vector<std::string>& command_line) {
  // ---- the scene: everything is checked before any process starts -----------------------
  std::optional<scene::Document> doc;
  CouplingSettings settings;
  SolverSections sections;
  std::vector<PostStep> post_steps;
  const fs::path bin = opt.bin_dir.empty() ? self_dir() : fs::path(opt.bin_dir);
  try {
    std::vector<scene::Override> overrides;
    for (const auto& s : opt.sets) overrides.push_back(scene::Override::parse(s));
    for (const auto& [section, kind] :
         {std::pair{"fem", &opt.fem_backend}, std::pair{"dem", &opt.dem_backend}}) {
      if (kind->empty()) continue;
      if (!scene::Document::load(opt.scene, overrides).root().table(section)) {
        std::fprintf(stderr, "demfem run: --%s-backend %s: %s has no [%s] section\n", section,
                     kind->c_str(), opt.scene.c_str(), section);
        return kExitBadInput;
      }
      overrides.push_back(scene::Override::parse(std::string(section) + ".backend=\"" + *kind +
                                                 "\""));
    }
    doc = scene::Document::load(opt.scene, overrides);
    settings = read_coupling_settings(*doc);
    post_steps = read_post_steps(*doc, bin);
    // A [dem.load] scene = ... whose state is missing or stale: that scene runs first, so
    // that the check of the solver sections (which builds the particles) finds the state.
    // With --check a missing state is not made: the prepare scene is checked instead (and
    // this scene's particles are set up without it).
    if (const int c = run_prepare_scenes(*doc, bin, opt.quiet, opt.in_process, opt.check))
      return c;
    sections = check_solver_sections(*doc, settings.run.seed);
  } catch (const scene::SceneError& e) {
    std::fprintf(stderr, "demfem run: scene error: %s\n", e.what());
    return kExitBadInput;
  }
  // External backends (fem.command, dem.command): resolved before anything starts.
  std::optional<ExternalCommand> external, external_dem;
  for (const auto& [role, ext] : {std::pair{protocol::Role::fem, &external},
                                  std::pair{protocol::Role::dem, &external_dem}}) {
    const bool dem = role == protocol::Role::dem;
    if (!(dem ? settings.dem_external() : settings.fem_external())) continue;
    if (opt.in_process) {
      std::fprintf(stderr,
                   "demfem run: --in-process runs demfem's own %s backends only; %s.backend = "
                   "\"external\" starts the program of %s.command in its own process\n",
                   dem ? "DEM" : "FEM", dem ? "dem" : "fem", dem ? "dem" : "fem");
      return kExitBadInput;
    }
    try {
      *ext = resolve_external_command(settings, role);
    } catch (const scene::SceneError& e) {
      std::fprintf(stderr, "demfem run: scene error: %s\n", e.what());
      return kExitBadInput;
    }
  }
  if (!sections.dem_unapplied_keys.empty()) {
    std::string keys;
    for (const auto& k : sections.dem_unapplied_keys) keys += (keys.empty() ? "" : ", ") + k;
    std::fprintf(stderr,
                 "demfem run: note: dem.backend = \"external\": demfem reads only dem.backend, "
                 "command, dt and settle_time; [dem] %s are the external program's to read or "
                 "ignore (dem_server's particles, output and sensors do not run)\n",
                 keys.c_str());
  }
  if (opt.check) {
    std::printf("demfem run: %s: the scene is valid\n", opt.scene.c_str());
    return 0;
  }
  if (settings.fem_modal && opt.resume) {
    std::fprintf(stderr,
                 "demfem run: --resume: fem.analysis = \"modal\" takes no time steps and no "
                 "checkpoints; run it afresh\n");
    return kExitBadInput;
  }
  const fs::path out_dir =
      opt.output_dir.empty() ? settings.run.output_dir : fs::path(opt.output_dir);
  const bool remote = !opt.in_process;
  std::optional<DebugKill> debug_kill;
  try {
    debug_kill = parse_debug_kill(opt.debug_kill);
  } catch (const std::exception&) {
    std::fprintf(stderr,
                 "demfem run: --debug-kill '%s': expected ROLE:STEP[:always|:stop] with ROLE dem, "
                 "fem or coupler, or job:STEP:usr1|usr2, and STEP >= 0\n",
                 opt.debug_kill.c_str());
    return kExitBadInput;
  }
  if (!remote && debug_kill && debug_kill->role != "coupler" && debug_kill->role != "job") {
    std::fprintf(stderr,
                 "demfem run: --debug-kill %s needs solver processes (not with --in-process)\n",
                 opt.debug_kill.c_str());
    return kExitBadInput;
  }
  // The solver executables, before the output folder is touched: one that cannot be started
  // is reported now, not after the other solver has started and set up.
  if (remote) {
    for (const auto& [needed, name] :
         {std::pair{settings.has_fem && !external, "fem_server"},
          std::pair{settings.has_dem && !external_dem, "dem_server"}}) {
      const fs::path exe = bin / name;
      std::error_code ec;
      if (needed && (!fs::is_regular_file(exe, ec) || ::access(exe.c_str(), X_OK) != 0)) {
        std::fprintf(stderr,
                     "demfem run: cannot start the solver %s: it is missing or not executable "
                     "(build it, or give the folder that holds it with --bin-dir; --in-process "
                     "needs no solver executables)\n",
                     exe.c_str());
        return kExitBadInput;
      }
    }
  }
  // --resume without a [checkpoint] section: nothing was ever checkpointed.
  if (opt.resume && opt.resume_from.empty() && !settings.checkpoint.enabled) {
    std::fprintf(stderr,
                 "demfem run: --resume: %s has no [checkpoint] section, so its runs take no "
                 "checkpoints to resume from; add one (docs/scenes.md, [checkpoint]) and run "
                 "afresh, or name a checkpoint folder: --resume DIR\n",
                 opt.scene.c_str());
    return kExitBadInput;
  }

  // ---- the output folder: this run's alone --------------------------------------------
  // Two runs writing one folder corrupt it silently; the lock refuses the second. Solvers
  // restarted by this run are its children and take no lock.
  const fs::path cp_dir =
      settings.checkpoint.enabled ? checkpoint_directory(settings, out_dir) : fs::path();
  std::vector<io::FolderLock> locks;
  try {
    const std::string what = "demfem run " + opt.scene + " (started " + utc_now() + ")";
    locks.emplace_back(out_dir, what);
    if (!cp_dir.empty()) {
      if (inside(cp_dir, out_dir)) {
        fs::create_directories(cp_dir);
      } else {
        locks.emplace_back(cp_dir, what);
      }
    }
  } catch (const io::FolderBusy& e) {
    std::fprintf(stderr,
                 "demfem run: %s; two runs in one folder would corrupt each other's files: wait "
                 "for it to end, or give this run another folder (--output-dir, run.output_dir, "
                 "checkpoint.directory)\n",
                 e.what());
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::fprintf(stderr,
                 "demfem run: %s; choose a writable folder (--output-dir, run.output_dir, "
                 "checkpoint.directory)\n",
                 e.what());
    return kExitBadInput;
  }
  if (const auto prev = read_run_status(out_dir); prev && recorded_run_alive(*prev)) {
    // Its lock file was removed (the folder deleted and made again, a clean-up of dot files):
    // the lock above is a new one, but the run is still writing here.
    std::fprintf(stderr,
                 "demfem run: %s is in use by process %d (run.json: running since %s, and the "
                 "process is alive; its lock file %s was removed or replaced while it runs); two "
                 "runs in one folder would corrupt each other's files: wait for it to end (or "
                 "stop it), or give this run another folder (--output-dir, run.output_dir)\n",
                 out_dir.c_str(), static_cast<int>(prev->pid), prev->start_time.c_str(),
                 (out_dir / io::FolderLock::kFileName).c_str());
    return kExitBadInput;
  } else if (prev && prev->status == "running") {
    std::fprintf(stderr,
                 "demfem run: note: the previous run in %s (pid %d, started %s) ended without "
                 "writing its end to run.json: it was killed or crashed\n",
                 out_dir.c_str(), static_cast<int>(prev->pid), prev->start_time.c_str());
  }

  RunRecord record;
  record.scene = fs::absolute(opt.scene);
  record.overrides = opt.sets;
  record.scene_hash = scene_hash(opt.scene, record.overrides);
  record.output_dir = fs::absolute(out_dir);
  if (!cp_dir.empty()) record.checkpoint_dir = fs::absolute(cp_dir);
  record.in_process = !remote;
  record.command_line = command_line;
  {
    char host[256] = {};
    ::gethostname(host, sizeof(host) - 1);
    record.host = host;
  }
  record.pid = ::getpid();
  record.dem_backend = sections.dem_backend;
  if (settings.dem_external()) record.dem_command = settings.dem_command;
  if (settings.has_fem) {
    record.fem_backend = settings.fem_backend;
    record.fem_command = settings.fem_command;
  }
  record.dem_threads = sections.dem_threads;
  if (const char* omp = std::getenv("OMP_NUM_THREADS")) record.omp_num_threads = omp;
  record.hardware_threads = std::thread::hardware_concurrency();
  record.start_time = utc_now();
  record.end_time_simulated = settings.run.end_time;
  record.step_count = settings.step_count;

  // --resume: the checkpoint to start from, verified before any process starts.
  RunControl control;
  control.fem_backend = settings.has_fem ? settings.fem_backend : std::string();
  control.dem_backend = settings.has_dem ? settings.dem_backend : std::string();
  std::optional<std::int64_t> resume_nodes;  // the checkpoint's interface size
  control.report = [](const std::string& m) {
    std::fprintf(stderr, "demfem run: %s\n", m.c_str());
  };
  control.scene_hash = record.scene_hash;
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
  // The folder locks are checked now and then while the run goes on: a folder deleted under a
  // running run (and perhaps made again by another) is no longer this run's to write.
  auto last_lock_check = std::chrono::steady_clock::now();
  control.check_output_folder = [&locks, &last_lock_check] {
    const auto now = std::chrono::steady_clock::now();
    if (now - last_lock_check < std::chrono::seconds(1)) return;
    last_lock_check = now;
    for (const auto& lock : locks) {
      if (lock.intact()) continue;
      throw OutputFolderLost(
          (lock.folder() / io::FolderLock::kFileName).string() +
          " was removed or replaced while this run was writing " + lock.folder().string() +
          " (the folder was deleted?); another run may be writing there now, so this one "
          "stops and writes nothing more there. Its output is incomplete: run it again into a "
          "folder of its own");
    }
  };
  if (opt.resume) {
    const auto parts = checkpoint_parts(settings);
    if (!opt.resume_from.empty()) {
      const fs::path from = opt.resume_from;
      std::error_code ec;
      if (!fs::exists(from, ec)) {
        std::fprintf(stderr,
                     "demfem run: --resume %s: no such folder; give a checkpoint folder "
                     "(<checkpoint directory>/step-NNNNNN), or --resume alone for the latest\n",
                     from.c_str());
        return kExitBadInput;
      }
      if (!fs::is_directory(from, ec)) {
        std::fprintf(stderr,
                     "demfem run: --resume %s: is a file, not a checkpoint folder "
                     "(<checkpoint directory>/step-NNNNNN with manifest.json)\n",
                     from.c_str());
        return kExitBadInput;
      }
      try {
        (void)verify_checkpoint(from, parts);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "demfem run: --resume %s: not a valid checkpoint: %s\n", from.c_str(),
                     e.what());
        return kExitBadInput;
      }
      control.resume_from = from;
    } else {
      if (!fs::exists(cp_dir)) {
        std::fprintf(stderr,
                     "demfem run: --resume: the checkpoint folder %s does not exist (no run of "
                     "this scene has written to %s yet?)\n",
                     cp_dir.c_str(), out_dir.c_str());
        return kExitBadInput;
      }
      control.resume_from = latest_valid_checkpoint(cp_dir, parts, control.report);
      if (!control.resume_from) {
        std::fprintf(stderr, "demfem run: --resume: no valid checkpoint in %s\n", cp_dir.c_str());
        return kExitBadInput;
      }
    }
    if (const auto code =
            prepare_resume(*control.resume_from, settings, sections, out_dir, record)) {
      return *code;
    }
    try {
      const io::H5File cp(*control.resume_from / "coupler.h5", io::H5File::Mode::read);
      if (settings.has_fem) resume_nodes = cp.attribute_int64("/", "node_count");
    } catch (const std::exception&) {
      // unreadable coupler.h5: the restore names the file and the reason
    }
    // demfem's own backends: the scene's interface must be the checkpoint's, checked before
    // any process starts (an external code's is checked when it says Hello).
    if (resume_nodes && sections.fem_interface_nodes > 0 && !external &&
        static_cast<std::size_t>(*resume_nodes) != sections.fem_interface_nodes) {
      std::fprintf(stderr,
                   "demfem run: --resume: checkpoint %s cannot be resumed: the checkpoint's "
                   "interface has %lld nodes, this scene's %zu (the FEM mesh or "
                   "fem.interface_surface changed): its state cannot be continued with this "
                   "scene\n",
                   control.resume_from->c_str(), static_cast<long long>(*resume_nodes),
                   sections.fem_interface_nodes);
      return kExitBadInput;
    }
    record.resumed_from = fs::absolute(*control.resume_from).string();
    const std::string folder = control.resume_from->filename().string();
    if (folder.rfind("step-", 0) == 0) record.resumed_step = std::atoll(folder.c_str() + 5);
  } else {
    // A fresh start: files of an earlier run with other output settings would stay and look
    // like this run's.
    try {
      record.cleared = clear_owned_outputs(out_dir);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "demfem run: %s\n", e.what());
      return kExitBadInput;
    }
    if (!record.cleared.empty()) {
      std::fprintf(stderr, "demfem run: removed %zu files of an earlier run in %s\n",
                   record.cleared.size(), out_dir.c_str());
    }
  }
  // From here on a signal ends the run through its handler (and is written into run.json);
  // after the run record, one only sets the flag: the process exits as the record says.
  SignalGuard signals(SignalGuard::Scope::process);
  try {
    write_run_record(out_dir, record);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "demfem run: %s; choose a writable output folder\n", e.what());
    return kExitBadInput;
  }
  if (settings.fem_modal) {
    // Natural frequencies: no solver process and no time steps; the launcher computes them.
    int code = 0;
    try {
      const fem::FemScene fs = fem::read_fem_scene(*doc->root().table("fem"));
      for (const auto& note : fs.notes) std::fprintf(stderr, "fem: note: %s\n", note.c_str());
      (void)fem::run_modal_analysis(fs, out_dir, opt.quiet ? nullptr : &std::cout);
      record.status = "completed";
    } catch (const std::exception& e) {
      std::fprintf(stderr, "demfem run: modal analysis: %s\n", e.what());
      code = dynamic_cast<const fem::FemModelError*>(&e) ||
                     dynamic_cast<const std::invalid_argument*>(&e)
                 ? kExitBadInput
                 : kExitFailed;
      record.status = "failed";
      record.reason = e.what();
    }
    record.exit_code = code;
    record.end_time = utc_now();
    record.steps_done = 0;
    record.time_reached = 0.0;
    write_run_record(out_dir, record);
    return code;
  }
  std::printf(
      "demfem run: %s: scheme %s, dt_C = %.6g s (n_D = %lld), %lld coupling steps to "
      "t = %.6g s%s\n",
      opt.scene.c_str(), scheme_name(settings.scheme), settings.coupling_dt,
      static_cast<long long>(settings.dem_substeps), static_cast<long long>(settings.step_count),
      settings.run.end_time, remote ? "" : " (in process)");
  std::fflush(stdout);

  const bool terminal = ::isatty(STDOUT_FILENO) == 1;
  Progress progress(stdout, terminal, opt.quiet);

  std::unique_ptr<protocol::CouplerSession> session;
  std::unique_ptr<SolverProcess> dem_proc, fem_proc;
  std::unique_ptr<SolverLink> link;
  std::string fem_program = "fem_server";  // how messages name the FEM process
  std::string dem_program = "dem_server";  // and the DEM process
  int code = 0;
  bool folder_lost = false;  // OutputFolderLost: nothing more is written into the folder
  std::string reason;
  std::optional<RunSummary> summary;
  std::optional<protocol::Role> given_up;  // a solver that died or stopped answering
  std::int64_t steps_done = -1;
  double time_reached = -1.0;
  auto failed = [&](int c, const std::string& text) {
    progress.finish();
    std::fprintf(stderr, "demfem run: %s\n", text.c_str());
    code = c;
    reason = text;
  };
  try {
    if (remote) {
      // The coupler waits for StepDone while a solver computes. By default it blocks at once
      // (futex): a spinning coupler would take CPU time from the solver it waits for on a
      // machine with few cores, and the blocking round trip costs only a few microseconds.
      protocol::CouplerOptions copt;
      copt.wait.spin = std::chrono::microseconds(opt.wait_spin_us);
      copt.peer_timeout = std::chrono::milliseconds(
          static_cast<std::int64_t>(std::ceil(1000.0 * settings.run.peer_timeout)));
      copt.reply_timeout = std::chrono::milliseconds(
          static_cast<std::int64_t>(std::ceil(1000.0 * settings.checkpoint.reply_timeout)));
      copt.hello_timeout = std::chrono::milliseconds(
          static_cast<std::int64_t>(std::ceil(1000.0 * opt.hello_timeout)));
      // dem_server runs dem.settle_time before it attaches, which may take hours: then a
      // solver may take as long as it lives (a dead one is still found within 0.1 s), unless
      // the user gave --hello-timeout.
      if (settings.dem_settle_time > 0.0 && !opt.hello_timeout_given) {
        copt.hello_timeout = std::chrono::milliseconds(0);
        if (!opt.quiet)
          std::printf("demfem run: dem.settle_time = %g s runs before the DEM attaches: no limit "
                      "on the time to attach (--hello-timeout sets one)\n",
                      settings.dem_settle_time);
      }
      // After Ctrl-C / SIGTERM (forwarded to the solvers) a solver that has not ended within
      // copt.stop_grace is not waited for any longer.
      copt.stop = &SignalGuard::stop_flag();
      session = std::make_unique<protocol::CouplerSession>(copt);
      std::vector<std::string> args = {"--scene", opt.scene, "--segment", session->segment_name()};
      for (const auto& s : opt.sets) args.insert(args.end(), {"--set", s});
      if (!opt.output_dir.empty()) {
        args.push_back("--output-dir");
        args.push_back(opt.output_dir);
      }
      std::vector<std::string> fem_args = args;
      // A resumed FEM continues its output series (the coupler then restores it).
      if (opt.resume) fem_args.push_back("--resume");
      std::optional<pid_t> dem_pid, fem_pid;
      std::printf("demfem run: segment %s\n", session->segment_name().c_str());
      // Every process reads the same scene: the overrides of --fem-backend and --dem-backend
      // go to all.
      for (const auto& [section, kind] :
           {std::pair{"fem", &opt.fem_backend}, std::pair{"dem", &opt.dem_backend}}) {
        if (kind->empty()) continue;
        for (auto* a : {&args, &fem_args})
          a->insert(a->end(), {"--set", std::string(section) + ".backend=\"" + *kind + "\""});
      }
      // An outside program: the arguments of demfem's own solver of its role (as the FEM's:
      // --resume when resumed), absolute paths (it runs in the scene's folder), the same
      // supervision and restarts (external_backend.hpp).
      auto start_external = [&](const ExternalCommand& ext, std::unique_ptr<SolverProcess>& proc,
                                std::string& program) {
        proc = make_external_process(ext, fem_args, out_dir, bin);
        program = ext.label();
        const pid_t pid = proc->start();
        std::printf("demfem run: started the %s (pid %d)\n", program.c_str(),
                    static_cast<int>(pid));
        return pid;
      };
      if (settings.has_fem && external) {
        fem_pid = start_external(*external, fem_proc, fem_program);
      } else if (settings.has_fem) {
        fem_proc = std::make_unique<SolverProcess>("FEM solver", bin / "fem_server", fem_args);
        fem_proc->set_own_session(opt.solver_sessions);
        fem_pid = fem_proc->start();
        std::printf("demfem run: started fem_server (pid %d) with the %s backend\n",
                    static_cast<int>(*fem_pid), settings.fem_backend.c_str());
      }
      if (settings.has_dem && external_dem) {
        dem_pid = start_external(*external_dem, dem_proc, dem_program);
      } else if (settings.has_dem) {
        dem_proc = std::make_unique<SolverProcess>("DEM solver", bin / "dem_server", args);
        dem_proc->set_own_session(opt.solver_sessions);
        dem_pid = dem_proc->start();
        std::printf("demfem run: started dem_server (pid %d)\n", static_cast<int>(*dem_pid));
      }
      std::fflush(stdout);
      auto remote_link = std::make_unique<RemoteLink>(*session, dem_pid, fem_pid);
      if (dem_pid && external_dem) {
        remote_link->describe(protocol::Role::dem,
                              "the " + dem_program + " (pid " + std::to_string(*dem_pid) + ")");
      }
      if (fem_pid) {
        remote_link->describe(protocol::Role::fem, (external ? "the " : "") + fem_program +
                                                       " (pid " + std::to_string(*fem_pid) + ")");
        // The interface the FEM must report: the checkpoint's when resuming, else the scene's
        // for demfem's own backends (an external program's is its own).
        if (resume_nodes) {
          remote_link->expect_fem_interface(
              static_cast<std::size_t>(*resume_nodes),
              "the checkpoint " + control.resume_from->string() + " being resumed");
        } else if (sections.fem_interface_nodes > 0 && !external) {
          remote_link->expect_fem_interface(
              sections.fem_interface_nodes,
              "the interface of " + opt.scene + " (fem.interface_surface)");
        }
      }
      link = std::move(remote_link);
      // A solver that died is started again and attached to the same segment; the run then
      // rolls back to the last committed checkpoint (CouplingRun).
      control.restart_solver = [&](protocol::Role role) {
        SolverProcess* p = role == protocol::Role::dem ? dem_proc.get() : fem_proc.get();
        // The protocol gave it up (gone, or heartbeat stale: stopped or hung): a hung process
        // would never answer again, so it is killed rather than asked to leave.
        p->signal(SIGKILL);
        const int c = p->stop(std::chrono::milliseconds(1000));
        std::fprintf(stderr, "demfem run: the %s (pid %d) ended with status %d%s; restarting it\n",
                     p->label().c_str(), static_cast<int>(p->pid()), c,
                     c > 128 ? (" (signal " + std::to_string(c - 128) + ")").c_str() : "");
        session->reset_peer(role);
        // The FEM and an external DEM continue their output series (the SDK's --resume).
        if (role == protocol::Role::fem || external_dem) p->add_argument("--resume");
        const pid_t pid = p->start();
        std::printf("demfem run: started %s (pid %d)\n",
                    role == protocol::Role::dem ? dem_program.c_str() : fem_program.c_str(),
                    static_cast<int>(pid));
        std::fflush(stdout);
        session->wait_hello(role, pid);
        try {
          session->reattach(role);
        } catch (const protocol::PeerDied&) {
          throw;
        } catch (const protocol::ProtocolError& e) {
          // A restarted process that is not the structure that was running (another interface
          // size): named, and not restarted again.
          throw HandshakeFailed(
              role, "the restarted " + (role == protocol::Role::dem ? dem_program : fem_program) +
                        " (pid " + std::to_string(pid) + ") was refused: " + e.what());
        }
      };
      if (debug_kill) {
        control.after_send = [&](protocol::Role role, std::int64_t step) {
          DebugKill& k = *debug_kill;
          if (step != k.step || (k.fired && !k.always)) return;
          if (k.role == "job") {
            if (role != protocol::Role::dem) return;
            k.fired = true;
            std::fprintf(stderr,
                         "demfem run: --debug-kill: signal %d to every process in step %lld\n",
                         k.job_signal, static_cast<long long>(step));
            for (SolverProcess* p : {dem_proc.get(), fem_proc.get()})
              if (p) ::kill(p->pid(), k.job_signal);
            ::raise(k.job_signal);
            return;
          }
          if (k.role == "coupler") {
            std::fflush(stdout);
            ::raise(SIGKILL);
          }
          if (k.role != protocol::role_name(role)) return;
          k.fired = true;
          SolverProcess* p = role == protocol::Role::dem ? dem_proc.get() : fem_proc.get();
          std::fprintf(stderr, "demfem run: --debug-kill: %s to the %s in step %lld\n",
                       k.stop ? "SIGSTOP" : "SIGKILL", p->label().c_str(),
                       static_cast<long long>(step));
          ::kill(p->pid(), k.stop ? SIGSTOP : SIGKILL);
        };
      }
    } else {
      if (debug_kill) {
        control.after_send = [&](protocol::Role, std::int64_t step) {
          if (step != debug_kill->step || debug_kill->fired) return;
          debug_kill->fired = true;
          std::fflush(stdout);
          ::raise(debug_kill->job_signal != 0 ? debug_kill->job_signal : SIGKILL);
        };
      }
      auto dem = make_local_dem(*doc, settings, out_dir);
      // Ctrl-C stops a long DEM step within one substep, as in dem_server.
      if (dem) dem->set_cancel_flag(&SignalGuard::stop_flag());
      link = std::make_unique<LocalLink>(std::move(dem),
                                         make_local_fem(*doc, settings, out_dir, opt.resume));
    }
    CouplingRun loop(*link, settings, out_dir, &SignalGuard::stop_flag());
    loop.set_control(control);
    loop.set_observer([&](const StepDiagnostics& d, const CouplingSettings& s) {
      steps_done = d.step + 1;
      time_reached = d.time;
      progress.update(d.step, s.step_count, d.time, s.run.end_time);
    });
    summary = loop.run();
    progress.finish();
    const RecoveryStats& rs = loop.recovery_stats();
    if (rs.checkpoints > 0 || rs.recoveries > 0) {
      std::printf("demfem run: %lld checkpoints (%.3f s), %lld recoveries (%.3f s)\n",
                  static_cast<long long>(rs.checkpoints), rs.checkpoint_wall,
                  static_cast<long long>(rs.recoveries), rs.recovery_wall);
    }
  } catch (const BlowUp& e) {
    failed(kExitBlowUp, std::string(e.what()) + "\n  output so far is in " + out_dir.string());
  } catch (const RecoveryExhausted& e) {
    given_up = e.role();
    failed(kExitRecoveryExhausted,
           std::string(e.what()) + "\n  output so far is in " + out_dir.string());
  } catch (const SolverFailure& e) {
    // The solver says what kind of error it found (protocol::ErrorKind): a model that cannot
    // be solved (a mechanism, displacements larger than the model) is bad input, found late;
    // a non-finite or unstable state is a blow-up. Errors of a solver that does not classify
    // them are blow-ups when their text says so ("... is not finite", "blew up").
    if (e.died()) given_up = e.role();
    if (SignalGuard::stop_flag().load()) {
      failed(128 + SignalGuard::signal_number(), "stopped by signal " +
                                                     std::to_string(SignalGuard::signal_number()) +
                                                     " (" + e.what() + ")");
    } else if (e.kind() == protocol::ErrorKind::bad_input) {
      failed(kExitBadInput,
             "bad model: " + std::string(e.what()) +
                 "\n  (found by the solver after the run started; output so far is in " +
                 out_dir.string() + ")");
    } else if (e.kind() == protocol::ErrorKind::blow_up ||
               (e.kind() == protocol::ErrorKind::failure && is_blow_up_report(e.what()))) {
      failed(kExitBlowUp,
             "blow-up: " + std::string(e.what()) + "\n  output so far is in " + out_dir.string());
    } else {
      failed(kExitFailed, std::string(e.what()) + "\n  output so far is in " + out_dir.string());
    }
  } catch (const OutputFolderLost& e) {
    failed(kExitFailed, e.what());
    folder_lost = true;
  } catch (const Interrupted& e) {
    failed(128 + SignalGuard::signal_number(), e.what());
  } catch (const ResumeRefused& e) {
    failed(kExitBadInput, e.what());
  } catch (const InterfaceMismatch& e) {
    failed(kExitBadInput, e.what());
  } catch (const HandshakeFailed& e) {
    failed(kExitFailed, e.what());
  } catch (const scene::SceneError& e) {
    failed(kExitBadInput, std::string("scene error: ") + e.what());
  } catch (const protocol::PeerDied& e) {
    // Only the start (Hello, mesh exchange) lets it through unwrapped: a solver that ended
    // before it attached, or never attached.
    SolverProcess* p = e.role() == protocol::Role::dem ? dem_proc.get() : fem_proc.get();
    const std::string name = e.role() == protocol::Role::dem ? dem_program : fem_program;
    if (SignalGuard::stop_flag().load()) {
      failed(128 + SignalGuard::signal_number(), "stopped by signal " +
                                                     std::to_string(SignalGuard::signal_number()) +
                                                     " (" + e.what() + ")");
    } else if (p && !p->wait_for(std::chrono::milliseconds(1000)) && p->running()) {
      // (A process seen gone may not be reapable for a moment: the wait tells a death from
      // a hang.)
      p->signal(SIGKILL);
      const int c = p->stop(std::chrono::milliseconds(1000));
      char limit[32];
      std::snprintf(limit, sizeof(limit), "%g", opt.hello_timeout);
      failed(kExitFailed, "the " + p->label() + " (" + name + ", pid " + std::to_string(p->pid()) +
                              ") did not attach within " + limit +
                              " s (--hello-timeout); it was killed (status " + std::to_string(c) +
                              "). " + e.what());
    } else if (p) {
      const int c = p->exit_code().value_or(-1);
      failed(c == kExitBadInput ? kExitBadInput : kExitFailed,
             "the " + p->label() + " (" + name + ", pid " + std::to_string(p->pid()) +
                 ") ended with status " + std::to_string(c) +
                 " before it attached; its message is above (" + e.what() + ")");
    } else {
      failed(kExitFailed, e.what());
    }
  } catch (const protocol::BackendError& e) {
    // In process, a solver's set-up found it (the FEM's model check before the first step).
    if (e.kind() == protocol::ErrorKind::bad_input) {
      failed(kExitBadInput, std::string("bad model: ") + e.what());
    } else {
      failed(e.kind() == protocol::ErrorKind::blow_up ? kExitBlowUp : kExitFailed, e.what());
    }
  } catch (const std::exception& e) {
    if (SignalGuard::stop_flag().load()) {
      failed(128 + SignalGuard::signal_number(), "stopped by signal " +
                                                     std::to_string(SignalGuard::signal_number()) +
                                                     " (" + e.what() + ")");
    } else {
      failed(kExitFailed, e.what());
    }
  }

  // ---- end the solvers: Shutdown, then wait, then signals ---------------------------------
  // After a stop signal the solvers were sent SIGTERM already: no Shutdown, a short grace.
  // A lost folder: the solvers are stopped as by a signal, so that they write no end state
  // there. In process, the adapters are told so after a stop signal too: a solver process
  // stopped by SIGTERM writes none, and an end-state snapshot beyond the last checkpoint
  // would stay in the output series of a `--resume` (an extra fem_NNNNNN.h5).
  const bool stopping = SignalGuard::stop_flag().load() || folder_lost;
  if (folder_lost) {
    for (auto* p : {dem_proc.get(), fem_proc.get()})
      if (p) p->signal(SIGTERM);
  }
  if (auto* local = dynamic_cast<LocalLink*>(link.get()); local && stopping) {
    for (auto role : {protocol::Role::dem, protocol::Role::fem})
      drop_end_state(local->backend(role));
  }
  // A solver given up as dead or silent (no reply within reply_timeout) is killed at once: a
  // hung one would answer neither Shutdown nor SIGTERM, and waiting on both costs seconds.
  if (SolverProcess* p = !given_up                          ? nullptr
                         : *given_up == protocol::Role::dem ? dem_proc.get()
                                                            : fem_proc.get();
      p && p->running()) {
    p->signal(SIGKILL);
    std::fprintf(stderr, "demfem run: the %s (pid %d) is not answering: killed\n",
                 p->label().c_str(), static_cast<int>(p->pid()));
  }
  if (link && !stopping) {
    SignalGuard::solvers_ending();  // a Ctrl-C now must not cut their end state short
    link->shutdown();
  }
  for (auto* p : {dem_proc.get(), fem_proc.get()}) {
    if (!p) continue;
    const int c = p->stop(std::chrono::milliseconds(stopping ? 1000 : 3000));
    if (c != 0 && code == 0 && SignalGuard::stop_flag().load()) {
      // A stop signal after the last step (a terminal's Ctrl-C reaches the solvers too): the
      // steps are done, the end state is not written; --resume writes it from the last
      // checkpoint. Interrupted, as a stop earlier would be, not failed.
      failed(128 + SignalGuard::signal_number(),
             "stopped by signal " + std::to_string(SignalGuard::signal_number()) +
                 " as the run ended: the " + p->label() + " ended with status " +
                 std::to_string(c) + " before its end state was written");
    } else if (c != 0 && code == 0) {
      failed(kExitFailed, "the " + p->label() + " exited with status " + std::to_string(c));
    }
  }
  link.reset();
  session.reset();  // removes the segments

  if (summary) {
    std::printf("demfem run: done: %lld coupling steps, t = %.6g s; output in %s\n",
                static_cast<long long>(summary->steps), summary->time, out_dir.c_str());
    if (settings.scheme == Scheme::one_way_static) {
      std::printf(
          "demfem run: the DEM settled at t = %.6g s (kinetic energy %.3g J); its forces "
          "(sum %.9g N along z) went into one static FEM solve\n",
          summary->time, summary->last.kinetic_energy, summary->last.force_sum_z);
    }
    if (settings.scheme == Scheme::implicit && summary->steps > 0) {
      std::printf(
          "demfem run: implicit (%s): %lld iterations in %lld steps, %.3g per step, at "
          "most %lld; %lld steps accepted without convergence\n",
          acceleration_name(settings.implicit.acceleration.kind),
          static_cast<long long>(summary->iterations), static_cast<long long>(summary->steps),
          static_cast<double>(summary->iterations) / static_cast<double>(summary->steps),
          static_cast<long long>(summary->max_iterations),
          static_cast<long long>(summary->unconverged_steps));
    }
    print_timing(*summary, remote);
    try {
      write_timing(out_dir, *summary);
      if (settings.beam_check && settings.has_dem && settings.has_fem) {
        const auto r = run_beam_check(*settings.beam_check, *doc, *summary);
        std::printf("%s", beam_check_table(r, *settings.beam_check).c_str());
        char text[512];
        std::snprintf(text, sizeof(text),
                      "load_mass,coupled,fem_pressure,analytical,coupled_load,pressure_load\n"
                      "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n",
                      settings.beam_check->load_mass, r.coupled, r.fem_pressure, r.analytical,
                      r.coupled_load, r.pressure_load);
        io::write_file_atomic(out_dir / "beam_check.csv", text);
      }
    } catch (const std::exception& e) {
      if (code == 0) {
        failed(kExitFailed, e.what());
      } else {
        std::fprintf(stderr, "demfem run: %s\n", e.what());
      }
    }
  }
  // [[post]]: plots and reports of a run that ended well.
  if (code == 0 && summary && !opt.no_post && !post_steps.empty()) {
    std::fflush(stdout);
    if (run_post_steps(post_steps, out_dir, opt.scene, bin) != 0) {
      code = kExitFailed;
      reason = "a [[post]] step failed";
    }
  }

  // ---- the run record: how it ended ---------------------------------------------------------
  record.exit_code = code;
  record.end_time = utc_now();
  if (summary) {
    steps_done = summary->steps;
    time_reached = summary->time;
  }
  record.steps_done = steps_done;
  record.time_reached = time_reached;
  if (code == 0) {
    record.status = "completed";
  } else if (code > 128 && SignalGuard::stop_flag().load()) {
    record.status = "interrupted";
    record.signal = SignalGuard::signal_number();
    record.reason = reason;
  } else {
    record.status = "failed";
    record.reason = reason;
  }
  try {
    // A lost folder's run.json is another run's now (or gone): it is left alone.
    if (!folder_lost) write_run_record(out_dir, record);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "demfem run: %s\n", e.what());
    if (code == 0) code = kExitFailed;
  }
  std::fflush(stdout);
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  demfem::dem::ensure_omp_wait_policy(argv);  // first: it may re-execute the program
  Options opt;
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
