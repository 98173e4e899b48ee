// demfem_run (also built as `coupler`): runs one scene. It is the coupler process: it reads
// [run] and [coupling], checks the whole scene, creates the shared-memory segment, starts
// dem_server and/or fem_server as child processes with --segment, drives the coupling loop,
// shows progress, and exits with the run's status. --in-process runs the same schemes over
// the solver libraries in this process instead (the reference for the three-process run).
//
// Exit status: 0 done; 1 a solver or the run failed; 2 bad command line or scene; 3 blow-up
// (the diagnosis names step and quantity); 4 a solver kept dying after checkpoint.max_retries
// restarts from the same checkpoint; 128 + N stopped by signal N (SIGINT: 130).

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>

#include "demfem/coupling/beam_check.hpp"
#include "demfem/coupling/checkpoint.hpp"
#include "demfem/coupling/coupling_run.hpp"
#include "demfem/coupling/coupling_settings.hpp"
#include "demfem/coupling/local_solvers.hpp"
#include "demfem/coupling/progress.hpp"
#include "demfem/coupling/solver_link.hpp"
#include "demfem/coupling/supervisor.hpp"
#include "demfem/io/atomic_file.hpp"

namespace fs = std::filesystem;
using namespace demfem;
using namespace demfem::coupling;

namespace {

constexpr int kExitFailed = 1;
constexpr int kExitUsage = 2;
constexpr int kExitBlowUp = 3;
constexpr int kExitRecoveryExhausted = 4;

struct Options {
  std::string scene;
  std::string bin_dir;
  std::string output_dir;
  bool quiet = false;
  bool in_process = false;
  int wait_spin_us = 0;
  bool resume = false;
  std::string resume_from;  // empty: the latest valid checkpoint
  std::string debug_kill;   // ROLE:STEP[:always], fault injection for tests
  std::vector<std::string> sets;  // --set KEY=VALUE, passed on to the solvers
  bool check = false;             // --check: read and check the scene, start nothing
};

// --debug-kill dem:17, fem:5:always, coupler:30 (docs/reliability.md). Testing only.
struct DebugKill {
  std::string role;
  std::int64_t step = -1;
  bool always = false;
  bool stop = false;
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
    } else {
      throw std::invalid_argument(text);
    }
    rest = rest.substr(0, c2);
  }
  std::size_t used = 0;
  k.step = std::stoll(rest, &used);
  if (used != rest.size() || k.step < 0 ||
      (k.role != "dem" && k.role != "fem" && k.role != "coupler")) {
    throw std::invalid_argument(text);
  }
  return k;
}

fs::path self_dir() {
  std::error_code ec;
  const auto exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::current_path() : exe.parent_path();
}

void print_timing(const RunSummary& s, bool remote) {
  const double total = s.wall_total > 0 ? s.wall_total : 1.0;
  std::printf(
      "wall time: total %.3f s; DEM %.3f s (%.1f %%), FEM %.3f s (%.1f %%), coupling %.4f s "
      "(%.2f %%)%s\n",
      s.wall_total, s.wall_dem, 100 * s.wall_dem / total, s.wall_fem, 100 * s.wall_fem / total,
      s.wall_coupling, 100 * s.wall_coupling / total,
      remote ? "; DEM/FEM times include the IPC round trip" : "");
}

void write_timing(const fs::path& dir, const RunSummary& s) {
  char text[512];
  std::snprintf(text, sizeof(text),
                "steps,time,wall_total,wall_dem,wall_fem,wall_coupling,coupling_share\n"
                "%lld,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n",
                static_cast<long long>(s.steps), s.time, s.wall_total, s.wall_dem, s.wall_fem,
                s.wall_coupling, s.wall_total > 0 ? s.wall_coupling / s.wall_total : 0.0);
  io::write_file_atomic(dir / "timing.csv", text);
}

int run(const Options& opt) {
  // ---- the scene: everything is checked before any process starts -----------------------
  std::optional<scene::Document> doc;
  CouplingSettings settings;
  try {
    std::vector<scene::Override> overrides;
    for (const auto& s : opt.sets) overrides.push_back(scene::Override::parse(s));
    doc = scene::Document::load(opt.scene, overrides);
    settings = read_coupling_settings(*doc);
    check_solver_sections(*doc);
  } catch (const scene::SceneError& e) {
    std::fprintf(stderr, "demfem run: scene error: %s\n", e.what());
    return kExitUsage;
  }
  if (opt.check) {
    std::printf("demfem run: %s: the scene is valid\n", opt.scene.c_str());
    return 0;
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
                 "fem or coupler and STEP >= 0\n",
                 opt.debug_kill.c_str());
    return kExitUsage;
  }
  // --resume: the checkpoint to start from, verified before any process starts.
  RunControl control;
  control.report = [](const std::string& m) {
    std::fprintf(stderr, "demfem run: %s\n", m.c_str());
  };
  if (opt.resume) {
    const fs::path dir = checkpoint_directory(settings, out_dir);
    const auto parts = checkpoint_parts(settings);
    if (!opt.resume_from.empty()) {
      try {
        (void)verify_checkpoint(opt.resume_from, parts);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "demfem run: --resume %s: not a valid checkpoint: %s\n",
                     opt.resume_from.c_str(), e.what());
        return kExitUsage;
      }
      control.resume_from = fs::path(opt.resume_from);
    } else {
      control.resume_from = latest_valid_checkpoint(dir, parts, control.report);
      if (!control.resume_from) {
        std::fprintf(stderr, "demfem run: --resume: no valid checkpoint in %s\n", dir.c_str());
        return kExitUsage;
      }
    }
  }
  std::printf(
      "demfem run: %s: scheme %s, dt_C = %.6g s (n_D = %lld), %lld coupling steps to "
      "t = %.6g s%s\n",
      opt.scene.c_str(), scheme_name(settings.scheme), settings.coupling_dt,
      static_cast<long long>(settings.dem_substeps), static_cast<long long>(settings.step_count),
      settings.run.end_time, remote ? "" : " (in process)");
  std::fflush(stdout);

  SignalGuard signals;
  const bool terminal = ::isatty(STDOUT_FILENO) == 1;
  Progress progress(stdout, terminal, opt.quiet);

  std::unique_ptr<protocol::CouplerSession> session;
  std::unique_ptr<SolverProcess> dem_proc, fem_proc;
  std::unique_ptr<SolverLink> link;
  const fs::path bin = opt.bin_dir.empty() ? self_dir() : fs::path(opt.bin_dir);
  int code = 0;
  std::optional<RunSummary> summary;
  try {
    if (remote) {
      // The coupler waits for StepDone while a solver computes. By default it blocks at once
      // (futex): a spinning coupler would take CPU time from the solver it waits for on a
      // machine with few cores, and the blocking round trip costs only a few microseconds.
      protocol::CouplerOptions copt;
      copt.wait.spin = std::chrono::microseconds(opt.wait_spin_us);
      copt.reply_timeout = std::chrono::milliseconds(
          static_cast<std::int64_t>(std::ceil(1000.0 * settings.checkpoint.reply_timeout)));
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
      if (settings.has_fem) {
        fem_proc = std::make_unique<SolverProcess>("FEM solver", bin / "fem_server", fem_args);
        fem_pid = fem_proc->start();
        std::printf("demfem run: started fem_server (pid %d)\n", static_cast<int>(*fem_pid));
      }
      if (settings.has_dem) {
        dem_proc = std::make_unique<SolverProcess>("DEM solver", bin / "dem_server", args);
        dem_pid = dem_proc->start();
        std::printf("demfem run: started dem_server (pid %d)\n", static_cast<int>(*dem_pid));
      }
      std::fflush(stdout);
      link = std::make_unique<RemoteLink>(*session, dem_pid, fem_pid);
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
        if (role == protocol::Role::fem) p->add_argument("--resume");
        const pid_t pid = p->start();
        std::printf("demfem run: started %s (pid %d)\n",
                    role == protocol::Role::dem ? "dem_server" : "fem_server",
                    static_cast<int>(pid));
        std::fflush(stdout);
        session->wait_hello(role, pid);
        session->reattach(role);
      };
      if (debug_kill) {
        control.after_send = [&](protocol::Role role, std::int64_t step) {
          DebugKill& k = *debug_kill;
          if (step != k.step || (k.fired && !k.always)) return;
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
      if (debug_kill && debug_kill->role != "coupler") {
        std::fprintf(stderr,
                     "demfem run: --debug-kill %s needs solver processes (not with "
                     "--in-process)\n",
                     opt.debug_kill.c_str());
        return kExitUsage;
      }
      if (debug_kill) {
        control.after_send = [&](protocol::Role, std::int64_t step) {
          if (step != debug_kill->step) return;
          std::fflush(stdout);
          ::raise(SIGKILL);
        };
      }
      link = std::make_unique<LocalLink>(make_local_dem(*doc, settings, out_dir),
                                         make_local_fem(*doc, settings, out_dir, opt.resume));
    }
    CouplingRun loop(*link, settings, out_dir, &SignalGuard::stop_flag());
    loop.set_control(control);
    loop.set_observer([&](const StepDiagnostics& d, const CouplingSettings& s) {
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
    progress.finish();
    std::fprintf(stderr, "demfem run: %s\n  output so far is in %s\n", e.what(), out_dir.c_str());
    code = kExitBlowUp;
  } catch (const RecoveryExhausted& e) {
    progress.finish();
    std::fprintf(stderr, "demfem run: %s\n  output so far is in %s\n", e.what(), out_dir.c_str());
    code = kExitRecoveryExhausted;
  } catch (const SolverFailure& e) {
    progress.finish();
    // The adapters refuse non-finite numbers themselves ("... is not finite (the DEM blew
    // up ...)"): that is a blow-up found one step earlier, and exits as one.
    const bool blow_up = std::string(e.what()).find("not finite") != std::string::npos;
    if (SignalGuard::stop_flag().load()) {
      std::fprintf(stderr, "demfem run: stopped by signal %d (%s)\n", SignalGuard::signal_number(),
                   e.what());
      code = 128 + SignalGuard::signal_number();
    } else {
      std::fprintf(stderr, "demfem run: %s%s\n  output so far is in %s\n",
                   blow_up ? "blow-up: " : "", e.what(), out_dir.c_str());
      code = blow_up ? kExitBlowUp : kExitFailed;
    }
  } catch (const Interrupted& e) {
    progress.finish();
    std::fprintf(stderr, "demfem run: %s\n", e.what());
    code = 128 + SignalGuard::signal_number();
  } catch (const scene::SceneError& e) {
    progress.finish();
    std::fprintf(stderr, "demfem run: scene error: %s\n", e.what());
    code = kExitUsage;
  } catch (const std::exception& e) {
    progress.finish();
    if (SignalGuard::stop_flag().load()) {
      std::fprintf(stderr, "demfem run: stopped by signal %d (%s)\n", SignalGuard::signal_number(),
                   e.what());
      code = 128 + SignalGuard::signal_number();
    } else {
      std::fprintf(stderr, "demfem run: %s\n", e.what());
      code = kExitFailed;
    }
  }

  // ---- end the solvers: Shutdown, then wait, then signals ---------------------------------
  if (link) link->shutdown();
  for (auto* p : {dem_proc.get(), fem_proc.get()}) {
    if (!p) continue;
    const int c = p->stop(std::chrono::milliseconds(3000));
    if (c != 0 && code == 0) {
      std::fprintf(stderr, "demfem run: the %s exited with status %d\n", p->label().c_str(), c);
      code = kExitFailed;
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
      std::fprintf(stderr, "demfem run: %s\n", e.what());
      if (code == 0) code = kExitFailed;
    }
  }
  std::fflush(stdout);
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  Options opt;
  CLI::App app{
      "Runs a demfem scene: starts dem_server and/or fem_server as the scene needs, couples "
      "them, and exits with the run's status (0 ok, 1 failed, 2 bad input, 3 blow-up, 4 a solver "
      "kept dying, "
      "128+N signal N)."};
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
               "(0 valid, 2 not)");
  app.add_option("--wait-spin-us", opt.wait_spin_us,
                 "microseconds the coupler spins before it blocks while waiting for a solver "
                 "(default 0: block at once)")
      ->check(CLI::Range(0, 100000));
  app.add_flag("--in-process", opt.in_process,
               "run the solvers in this process (no servers; same results on the CPU backend)");
  auto* resume = app.add_option("--resume", opt.resume_from,
                                "continue from a committed checkpoint: the given folder, or "
                                "without a value the latest valid one in the checkpoint folder")
                     ->expected(0, 1);
  app.add_option("--debug-kill", opt.debug_kill,
                 "testing only: SIGKILL (or with :stop SIGSTOP) a process at a coupling step, "
                 "ROLE:STEP[:always|:stop] with ROLE dem, fem or coupler (docs/reliability.md)");
  try {
    app.parse(argc, argv);
    opt.resume = resume->count() > 0;
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return kExitUsage;
  }
  return run(opt);
}
