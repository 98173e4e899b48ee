#include "launch/run_solvers.hpp"

#include <cmath>
#include <csignal>
#include <cstdio>
#include <utility>

#include "demfem/coupling/local_solvers.hpp"
#include "launch/external_backend.hpp"

namespace demfem::coupling::launch {

using protocol::Role;

RunSolvers::RunSolvers(const LaunchOptions& opt, const CheckedRun& run)
    : opt_(opt), run_(run), debug_kill_(run.debug_kill) {}

protocol::CouplerOptions RunSolvers::coupler_options() const {
  const CouplingSettings& settings = run_.settings;
  // The coupler waits for StepDone while a solver computes. By default it blocks at once
  // (futex): a spinning coupler would take CPU time from the solver it waits for on a
  // machine with few cores, and the blocking round trip costs only a few microseconds.
  protocol::CouplerOptions copt;
  copt.wait.spin = std::chrono::microseconds(opt_.wait_spin_us);
  copt.peer_timeout = std::chrono::milliseconds(
      static_cast<std::int64_t>(std::ceil(1000.0 * settings.run.peer_timeout)));
  copt.reply_timeout = std::chrono::milliseconds(
      static_cast<std::int64_t>(std::ceil(1000.0 * settings.checkpoint.reply_timeout)));
  copt.hello_timeout =
      std::chrono::milliseconds(static_cast<std::int64_t>(std::ceil(1000.0 * opt_.hello_timeout)));
  // dem_server runs dem.settle_time before it attaches, which may take hours: then a
  // solver may take as long as it lives (a dead one is still found within 0.1 s), unless
  // the user gave --hello-timeout.
  if (settings.dem_settle_time > 0.0 && !opt_.hello_timeout_given) {
    copt.hello_timeout = std::chrono::milliseconds(0);
    if (!opt_.quiet)
      std::printf(
          "demfem run: dem.settle_time = %g s runs before the DEM attaches: no limit "
          "on the time to attach (--hello-timeout sets one)\n",
          settings.dem_settle_time);
  }
  // After Ctrl-C / SIGTERM (forwarded to the solvers) a solver that has not ended within
  // copt.stop_grace is not waited for any longer.
  copt.stop = &SignalGuard::stop_flag();
  return copt;
}

// An outside program gets the arguments of demfem's own solver of its role (as the FEM's:
// --resume when resumed), absolute paths (it runs in the scene's folder), the same
// supervision and restarts (external_backend.hpp).
std::unique_ptr<SolverProcess> RunSolvers::start_one(Role role,
                                                     const std::optional<ExternalCommand>& external,
                                                     const std::vector<std::string>& args,
                                                     const std::vector<std::string>& fem_args) {
  std::unique_ptr<SolverProcess> proc;
  if (external) {
    proc = make_external_process(*external, fem_args, run_.out_dir, run_.bin);
    (role == Role::dem ? dem_program_ : fem_program_) = external->label();
    const pid_t pid = proc->start();
    std::printf("demfem run: started the %s (pid %d)\n", program(role).c_str(),
                static_cast<int>(pid));
  } else if (role == Role::fem) {
    proc = std::make_unique<SolverProcess>("FEM solver", run_.bin / "fem_server", fem_args);
    proc->set_own_session(opt_.solver_sessions);
    const pid_t pid = proc->start();
    std::printf("demfem run: started fem_server (pid %d) with the %s backend\n",
                static_cast<int>(pid), run_.settings.fem_backend.c_str());
  } else {
    proc = std::make_unique<SolverProcess>("DEM solver", run_.bin / "dem_server", args);
    proc->set_own_session(opt_.solver_sessions);
    const pid_t pid = proc->start();
    std::printf("demfem run: started dem_server (pid %d)\n", static_cast<int>(pid));
  }
  return proc;
}

void RunSolvers::start_processes(const std::optional<ResumePoint>& resume, RunControl& control) {
  session_ = std::make_unique<protocol::CouplerSession>(coupler_options());
  std::vector<std::string> args = {"--scene", opt_.scene, "--segment", session_->segment_name()};
  for (const auto& s : opt_.sets) args.insert(args.end(), {"--set", s});
  for (const auto& s : run_.computed_sets) args.insert(args.end(), {"--set", s});
  if (!opt_.output_dir.empty()) {
    args.push_back("--output-dir");
    args.push_back(opt_.output_dir);
  }
  std::vector<std::string> fem_args = args;
  // A resumed FEM continues its output series (the coupler then restores it).
  if (opt_.resume) fem_args.push_back("--resume");
  std::printf("demfem run: segment %s\n", session_->segment_name().c_str());
  // Every process reads the same scene: the overrides of --fem-backend and --dem-backend
  // go to all.
  for (const auto& [section, kind] :
       {std::pair{"fem", &opt_.fem_backend}, std::pair{"dem", &opt_.dem_backend}}) {
    if (kind->empty()) continue;
    for (auto* a : {&args, &fem_args})
      a->insert(a->end(), {"--set", std::string(section) + ".backend=\"" + *kind + "\""});
  }
  if (run_.settings.has_fem) fem_proc_ = start_one(Role::fem, run_.external_fem, args, fem_args);
  if (run_.settings.has_dem) dem_proc_ = start_one(Role::dem, run_.external_dem, args, fem_args);
  std::fflush(stdout);
  std::optional<pid_t> dem_pid, fem_pid;
  if (dem_proc_) dem_pid = dem_proc_->pid();
  if (fem_proc_) fem_pid = fem_proc_->pid();
  auto remote_link = std::make_unique<RemoteLink>(*session_, dem_pid, fem_pid);
  describe_processes(*remote_link, resume);
  if (dem_proc_ && run_.external_dem) {
    // An external DEM may be an MPI job: its shared-memory files go once it has ended
    // (mpi_job_files.hpp says why the launcher does it).
    remote_link->on_hello([this](Role role, pid_t pid) {
      if (role == Role::dem) note_external_dem_hello(pid);
    });
    dem_proc_->set_after_end([this] {
      for (const auto& name : dem_mpi_jobs_.remove_left())
        std::fprintf(stderr, "demfem run: removed /dev/shm/%s, left by the ended MPI job of %s\n",
                     name.c_str(), dem_program_.c_str());
    });
  }
  link_ = std::move(remote_link);
  // A solver that died is started again and attached to the same segment; the run then
  // rolls back to the last committed checkpoint (CouplingRun).
  control.restart_solver = [this](Role role) { restart(role); };
  if (debug_kill_) {
    control.after_send = [this](Role role, std::int64_t step) {
      debug_kill_after_send(role, step);
    };
  }
}

void RunSolvers::describe_processes(RemoteLink& link, const std::optional<ResumePoint>& resume) {
  if (dem_proc_ && run_.external_dem) {
    link.describe(Role::dem,
                  "the " + dem_program_ + " (pid " + std::to_string(dem_proc_->pid()) + ")");
  }
  if (!fem_proc_) return;
  link.describe(Role::fem, (run_.external_fem ? "the " : "") + fem_program_ + " (pid " +
                               std::to_string(fem_proc_->pid()) + ")");
  // The interface the FEM must report: the checkpoint's when resuming, else the scene's
  // for demfem's own backends (an external program's is its own).
  if (resume && resume->fem_interface_nodes) {
    link.expect_fem_interface(static_cast<std::size_t>(*resume->fem_interface_nodes),
                              "the checkpoint " + resume->checkpoint.string() + " being resumed");
  } else if (run_.sections.fem_interface_nodes > 0 && !run_.external_fem) {
    link.expect_fem_interface(run_.sections.fem_interface_nodes,
                              "the interface of " + opt_.scene + " (fem.interface_surface)");
  }
}

void RunSolvers::note_external_dem_hello(pid_t pid) {
  dem_hello_pid_ = pid;
  dem_mpi_jobs_.note_rank(pid);
}

void RunSolvers::restart(Role role) {
  SolverProcess* p = process(role);
  // A wrapper that started the solver (mpirun: the Hello came from rank 0, another pid) is
  // ending its job itself when a rank died (the other ranks, its shared-memory files):
  // killed at once, it would leave them. It gets a moment to finish first.
  // (Only a process that said its Hello: the session keeps the last Hello, which for a
  // process that never said one is its predecessor's.)
  if (role == Role::dem) {
    if (dem_hello_pid_ > 0 && dem_hello_pid_ != p->pid())
      p->wait_for(std::chrono::milliseconds(3000));
    dem_hello_pid_ = 0;  // until the restarted process says its Hello
  }
  // The protocol gave it up (gone, or heartbeat stale: stopped or hung): a hung process
  // would never answer again, so it is killed rather than asked to leave.
  p->signal(SIGKILL);
  const int c = p->stop(std::chrono::milliseconds(1000));
  std::fprintf(stderr, "demfem run: the %s (pid %d) ended with status %d%s; restarting it\n",
               p->label().c_str(), static_cast<int>(p->pid()), c,
               c > 128 ? (" (signal " + std::to_string(c - 128) + ")").c_str() : "");
  session_->reset_peer(role);
  // The FEM and an external DEM continue their output series (the SDK's --resume).
  if (role == Role::fem || run_.external_dem) p->add_argument("--resume");
  const pid_t pid = p->start();
  std::printf("demfem run: started %s (pid %d)\n", program(role).c_str(), static_cast<int>(pid));
  std::fflush(stdout);
  session_->wait_hello(role, pid);
  if (role == Role::dem && run_.external_dem) note_external_dem_hello(session_->peer(role).pid);
  try {
    session_->reattach(role);
  } catch (const protocol::PeerDied&) {
    throw;
  } catch (const protocol::ProtocolError& e) {
    // A restarted process that is not the structure that was running (another interface
    // size): named, and not restarted again.
    throw HandshakeFailed(role, "the restarted " + program(role) + " (pid " + std::to_string(pid) +
                                    ") was refused: " + e.what());
  }
}

void RunSolvers::debug_kill_after_send(Role role, std::int64_t step) {
  DebugKill& k = *debug_kill_;
  if (step != k.step || (k.fired && !k.always)) return;
  if (k.role == "job") {
    if (role != Role::dem) return;
    k.fired = true;
    std::fprintf(stderr, "demfem run: --debug-kill: signal %d to every process in step %lld\n",
                 k.job_signal, static_cast<long long>(step));
    for (SolverProcess* p : {dem_proc_.get(), fem_proc_.get()})
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
  SolverProcess* p = process(role);
  std::fprintf(stderr, "demfem run: --debug-kill: %s to the %s in step %lld\n",
               k.stop ? "SIGSTOP" : "SIGKILL", p->label().c_str(), static_cast<long long>(step));
  ::kill(p->pid(), k.stop ? SIGSTOP : SIGKILL);
}

void RunSolvers::start_in_process(RunControl& control) {
  if (debug_kill_) {
    control.after_send = [this](Role, std::int64_t step) {
      if (step != debug_kill_->step || debug_kill_->fired) return;
      debug_kill_->fired = true;
      std::fflush(stdout);
      ::raise(debug_kill_->job_signal != 0 ? debug_kill_->job_signal : SIGKILL);
    };
  }
  auto dem = make_local_dem(*run_.doc, run_.settings, run_.out_dir);
  // Ctrl-C stops a long DEM step within one substep, as in dem_server.
  if (dem) dem->set_cancel_flag(&SignalGuard::stop_flag());
  link_ = std::make_unique<LocalLink>(
      std::move(dem), make_local_fem(*run_.doc, run_.settings, run_.out_dir, opt_.resume));
}

void RunSolvers::close_link() {
  link_.reset();
  session_.reset();  // removes the segments
}

}  // namespace demfem::coupling::launch
