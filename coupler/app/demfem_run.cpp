// demfem_run (also built as `coupler`): runs one scene. It is the coupler process: it reads
// [run] and [coupling], checks the whole scene, creates the shared-memory segment, starts
// dem_server and/or fem_server as child processes with --segment, drives the coupling loop,
// shows progress, and exits with the run's status. --in-process runs the same schemes over
// the solver libraries in this process instead (the reference for the three-process run).
//
// Exit status: 0 done; 1 a solver or the run failed; 2 bad command line or scene; 3 blow-up
// (the diagnosis names step and quantity); 128 + N stopped by signal N (SIGINT: 130).

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>

#include "demfem/coupling/beam_check.hpp"
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

struct Options {
  std::string scene;
  std::string bin_dir;
  std::string output_dir;
  bool quiet = false;
  bool in_process = false;
  int wait_spin_us = 0;
};

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
    doc = scene::Document::load(opt.scene);
    settings = read_coupling_settings(*doc);
    check_solver_sections(*doc);
  } catch (const scene::SceneError& e) {
    std::fprintf(stderr, "demfem run: scene error: %s\n", e.what());
    return kExitUsage;
  }
  const fs::path out_dir =
      opt.output_dir.empty() ? settings.run.output_dir : fs::path(opt.output_dir);
  const bool remote = !opt.in_process;
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
      session = std::make_unique<protocol::CouplerSession>(copt);
      std::vector<std::string> args = {"--scene", opt.scene, "--segment", session->segment_name()};
      if (!opt.output_dir.empty()) {
        args.push_back("--output-dir");
        args.push_back(opt.output_dir);
      }
      std::optional<pid_t> dem_pid, fem_pid;
      std::printf("demfem run: segment %s\n", session->segment_name().c_str());
      if (settings.has_fem) {
        fem_proc = std::make_unique<SolverProcess>("FEM solver", bin / "fem_server", args);
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
    } else {
      link = std::make_unique<LocalLink>(make_local_dem(*doc, settings, out_dir),
                                         make_local_fem(*doc, settings, out_dir));
    }
    CouplingRun loop(*link, settings, out_dir, &SignalGuard::stop_flag());
    loop.set_observer([&](const StepDiagnostics& d, const CouplingSettings& s) {
      progress.update(d.step, s.step_count, d.time, s.run.end_time);
    });
    summary = loop.run();
    progress.finish();
  } catch (const BlowUp& e) {
    progress.finish();
    std::fprintf(stderr, "demfem run: %s\n  output so far is in %s\n", e.what(), out_dir.c_str());
    code = kExitBlowUp;
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
      "them, and exits with the run's status (0 ok, 1 failed, 2 bad input, 3 blow-up, 128+N "
      "signal N)."};
  app.add_option("SCENE", opt.scene, "scene file (TOML)")->required();
  app.add_option("--bin-dir", opt.bin_dir,
                 "folder with dem_server and fem_server (default: this program's folder)");
  app.add_option("--output-dir", opt.output_dir,
                 "folder for the coupler's output (default: run.output_dir of the scene)");
  app.add_flag("--quiet", opt.quiet, "no progress display");
  app.add_option("--wait-spin-us", opt.wait_spin_us,
                 "microseconds the coupler spins before it blocks while waiting for a solver "
                 "(default 0: block at once)")
      ->check(CLI::Range(0, 100000));
  app.add_flag("--in-process", opt.in_process,
               "run the solvers in this process (no servers; same results on the CPU backend)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return kExitUsage;
  }
  return run(opt);
}
