#pragma once
// The FEM engine as a protocol backend: what fem_server serves to the coupler. Header-only
// on purpose: demfem::fem does not depend on demfem::protocol, so only a target that links
// both (the fem_server executable, a test) compiles this adapter.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <cstdio>
#include <iostream>
#include <type_traits>

#include "demfem/fem/fem_monitor.hpp"
#include "demfem/fem/fem_output.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/fem/modal_solver.hpp"
#include "demfem/fem/rigid_solver.hpp"
#include "demfem/io/checkpoint_file.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem/io/output_schedule.hpp"
#include "demfem/protocol/protocol.hpp"

namespace demfem::fem {

// What distinguishes the solvers of demfem's FEM backends for their protocol adapter: the
// name in Hello, the kind recorded in a checkpoint (docs/backends.md) and the largest
// displacement of the step diagnostic.
inline const char* backend_kind(const FemSolver&) {
  return "fem";
}
inline const char* backend_kind(const ModalSolver&) {
  return "modal";
}
inline const char* backend_kind(const RigidSolver&) {
  return "rigid";
}
inline std::string backend_label(const FemSolver&) {
  return "demfem-fem 0.1 (cpu)";
}
inline std::string backend_label(const ModalSolver& s) {
  return "demfem-modal 0.1 (" + std::to_string(s.mode_count()) + " modes" +
         (s.settings().static_correction ? " + static correction)" : ")");
}
inline std::string backend_label(const RigidSolver&) {
  return "demfem-rigid 0.1 (rigid body)";
}
/// Largest nodal |u| (FEM: every node; the reduced models: the interface nodes).
inline double step_max_displacement(const FemSolver& s) {
  const auto u = s.displacements();
  double umax = 0.0;
  for (std::size_t i = 0; i + 2 < u.size(); i += 3)
    umax = std::max(umax, std::sqrt(u[i] * u[i] + u[i + 1] * u[i + 1] + u[i + 2] * u[i + 2]));
  return umax;
}
inline double step_max_displacement(const ModalSolver& s) {
  return s.max_interface_displacement();
}
inline double step_max_displacement(const RigidSolver& s) {
  return s.max_interface_displacement();
}
/// A note about a state restored from another backend's checkpoint (stderr).
inline std::string restore_note(const FemSolver&) {
  return {};
}
inline std::string restore_note(const ModalSolver& s) {
  return s.restore_report();
}
inline std::string restore_note(const RigidSolver&) {
  return {};
}

/// @brief Whether a checkpoint written by the backend `from` can be restored by `to`, and why
/// not (empty = it can). The full FEM and the modal backend share the full state (fem.h5's
/// group "fem": the modal backend writes its reconstruction there); the rigid body has six
/// coordinates of its own; an external program's file is its own format.
inline std::string checkpoint_swap_refusal(const std::string& from, const std::string& to) {
  if (from == to) return {};
  const bool full_from = from == "fem" || from == "modal", full_to = to == "fem" || to == "modal";
  if (full_from && full_to) return {};
  if (from == "external" || to == "external")
    return "an external program's checkpoint part is in its own format, which demfem's backends "
           "cannot read, and demfem's state is one an external program cannot take over";
  if (to == "rigid")
    return "the rigid-body backend has six coordinates; the deformed state of the " + from +
           " backend has no rigid-body equivalent (its interface would jump)";
  return "the rigid-body backend's state is a rigid motion on springs, not a displacement of the "
         "clamped structure that the " +
         to + " backend models";
}

/// @brief protocol::SolverBackend around a FemSolver (FemBackend), a ModalSolver
/// (ModalBackend) or a RigidSolver (RigidBackend).
///
/// step(): takes the interface forces from buffers.forces(cmd.buffer); runs a static solve
/// when cmd.flags has kStepStatic, else one Bossak step of cmd.dt; writes the interface
/// positions, velocities and accelerations into the same buffer. StepResult values:
/// [0] max nodal |u| (m), [1] kinetic energy (J), [2] strain energy (J), [3] solver time (s).
/// Optional output: a FemOutput step for every multiple k * `output_interval`, of the state at
/// the coupling step end nearest to it and labelled with it (io::OutputSchedule; none from
/// step() when the interval is 0); the caller writes the start and end states with
/// write_initial_output() and write_final_output().
///
/// Iterated steps (implicit coupling, docs/protocol.md): the save point is the solver's state
/// in memory (u, v, a, forces, time: FemSolver::save_state; the full FEM only) with the output step
/// size; a step with kStepIterate writes its output only when accepted (accept_step()).
template <class Solver>
class StructureBackend final : public protocol::SolverBackend {
 public:
  explicit StructureBackend(Solver& solver, FemOutput* output = nullptr,
                            double output_interval = 0.0)
      : solver_(solver), output_(output), schedule_(output_interval) {}

  /// The reference state (output 0, at t = 0) of a new series.
  void write_initial_output() {
    if (!output_) return;
    FemFields f = gather_fields(solver_);
    f.time = schedule_.label(output_clock(), step_dt_);
    f.state_time = solver_.time();
    schedule_.skip_to_after(output_clock());
    output_->write(f);
    last_output_step_ = solver_.step_count();
  }

  /// The end state, unless the last output is of it (or no step was taken). After a static
  /// solve (kStepStatic) that no scheduled output took: the static solution, labelled with the
  /// end of the coupling step whose forces it carries.
  void write_final_output() {
    if (!output_) return;
    if (static_pending_) {
      write_static_output(schedule_.label(static_time_, static_dt_));
      return;
    }
    if (solver_.step_count() == 0 || last_output_step_ == solver_.step_count()) return;
    FemFields f = gather_fields(solver_);
    f.time = schedule_.label(output_clock(), step_dt_);
    f.state_time = solver_.time();
    output_->write(f);
    last_output_step_ = solver_.step_count();
  }

  /// [fem.monitor]: sampled after every step, kept in checkpoints (may be null). The full
  /// FEM only: the monitor reads the whole displacement field every step, which the reduced
  /// models do not hold (the scene reader refuses [fem.monitor] with them).
  void set_monitor(FemMonitor* monitor) requires std::is_same_v<Solver, FemSolver> {
    monitor_ = monitor;
  }

  std::string name() const override { return backend_label(solver_); }

  std::optional<InterfaceMesh> published_mesh() override { return solver_.interface_mesh(); }

  void on_mesh(const InterfaceMesh&) override {}  // the FEM owns the mesh

  protocol::StepResult step(const protocol::StepCommand& cmd,
                            protocol::InterfaceBuffers& buffers) override {
    const std::size_t n = 3 * solver_.interface_mesh().node_count();
    if (buffers.node_count() * 3 != n) {
      throw std::runtime_error("fem: interface buffers have " +
                               std::to_string(buffers.node_count()) + " nodes, the mesh " +
                               std::to_string(n / 3));
    }
    const auto forces = buffers.forces(cmd.buffer);
    for (double f : forces) {
      if (!std::isfinite(f)) {
        throw protocol::BackendError(
            protocol::ErrorKind::blow_up,
            "fem: step " + std::to_string(cmd.step) + ": interface force is not finite");
      }
    }
    solver_.set_interface_forces(forces);
    if (!(cmd.flags & protocol::kStepStatic) && (!(cmd.dt > 0.0) || !std::isfinite(cmd.dt))) {
      throw std::runtime_error("fem: step " + std::to_string(cmd.step) + ": dt must be > 0");
    }
    try {
      if (cmd.flags & protocol::kStepStatic) {
        solver_.solve_static();
        // The solution carries the forces of the coupling step's end (the solver's clock
        // does not move in a static solve): its output is labelled with that time.
        static_time_ = cmd.time + (cmd.dt > 0.0 && std::isfinite(cmd.dt) ? cmd.dt : 0.0);
        static_dt_ = cmd.dt > 0.0 && std::isfinite(cmd.dt) ? cmd.dt : 0.0;
        static_pending_ = true;
      } else {
        solver_.advance(cmd.dt);
        step_dt_ = cmd.dt;
        static_pending_ = false;
      }
    } catch (const FemModelError& e) {
      // A model the solver cannot solve (a mechanism, a displacement larger than the model):
      // bad input found late, not a failure of the run (the coupler exits with status 2).
      throw protocol::BackendError(protocol::ErrorKind::bad_input, e.what());
    }
    solver_.interface_kinematics(buffers.positions(cmd.buffer), buffers.velocities(cmd.buffer),
                                 buffers.accelerations(cmd.buffer));
    const double umax = step_max_displacement(solver_);
    if (!std::isfinite(umax)) {
      throw protocol::BackendError(protocol::ErrorKind::blow_up,
                                   "fem: step " + std::to_string(cmd.step) +
                                       ": displacement is not finite (the structure blew up)");
    }
    protocol::StepResult r;
    r.values[0] = umax;
    r.values[1] = solver_.kinetic_energy();
    r.values[2] = solver_.strain_energy();
    r.values[3] = solver_.time();
    if (cmd.flags & protocol::kStepIterate) {
      // The output and the monitor's sample wait until the step is accepted; by then the
      // buffer holds the next step's forces, so the monitor gets a copy of these.
      held_back_ = true;
      if (monitor_) held_forces_.assign(forces.begin(), forces.end());
    } else {
      maybe_write_output();
      if constexpr (std::is_same_v<Solver, FemSolver>)
        if (monitor_) monitor_->sample(solver_, forces);
    }
    return r;
  }

  /// The reduced models (modal, rigid) have no in-memory save point yet: the coupler refuses
  /// implicit coupling with them at the handshake.
  bool supports_iteration() const override { return std::is_same_v<Solver, FemSolver>; }
  void save_iteration_state() override {
    if constexpr (std::is_same_v<Solver, FemSolver>) {
      accept_step();
      solver_.save_state(save_point_);
      save_point_dt_ = step_dt_;
    } else {
      throw std::logic_error(std::string("the ") + backend_kind(solver_) +
                             " backend cannot iterate a coupling step");
    }
  }
  void restore_iteration_state() override {
    if constexpr (std::is_same_v<Solver, FemSolver>) {
      held_back_ = false;
      solver_.restore_state(save_point_);
      step_dt_ = save_point_dt_;
    } else {
      throw std::logic_error(std::string("the ") + backend_kind(solver_) +
                             " backend cannot iterate a coupling step");
    }
  }
  void accept_step() override {
    if (!held_back_) return;
    held_back_ = false;
    maybe_write_output();
    if constexpr (std::is_same_v<Solver, FemSolver>)
      if (monitor_) monitor_->sample(solver_, held_forces_);
  }

  /// The solver state under group "fem" of an HDF5 file, written under a temporary name and
  /// renamed when complete; attribute "step" on "/" records the coupling step.
  void write_checkpoint(const std::filesystem::path& file, std::int64_t step) override {
    io::write_checkpoint_file(file, step, [this](io::H5File& h5) {
      // Which backend wrote the part: a resume with another backend maps the state or says
      // why it cannot (checkpoint_swap_refusal).
      h5.set_attribute("/", "backend", std::string(backend_kind(solver_)));
      h5.set_attribute("/", "backend_name", name());
      h5.create_group("fem");
      solver_.save(h5, "fem");
      if (monitor_) monitor_->save(h5, "fem_monitor");
      // The mesh the state belongs to, so that a resume with a changed mesh is refused before
      // any process starts (demfem_run).
      const auto& mesh = solver_.problem().mesh;
      h5.set_attribute("fem", "mesh_nodes", static_cast<std::int64_t>(mesh.nodes.size()));
      h5.set_attribute("fem", "mesh_elements", static_cast<std::int64_t>(mesh.elements.size()));
      // The output schedule, so that a restored run writes the same states with the same labels.
      const std::int64_t sched[3] = {schedule_.next(), last_output_step_, 0};
      h5.write("fem_output_schedule", std::span<const std::int64_t>(sched));
      const double dt[1] = {step_dt_};
      h5.write("fem_output_step", std::span<const double>(dt));
      if (static_time_ > 0.0 || static_pending_) {  // a static solution and its output
        const double st[3] = {static_time_, static_dt_, static_pending_ ? 1.0 : 0.0};
        h5.write("fem_output_static", std::span<const double>(st));
      }
    });
  }

  void restore_checkpoint(const std::filesystem::path& file, std::int64_t step) override {
    held_back_ = false;  // a held-back step is not part of the restored state
    const io::H5File h5 = io::open_checkpoint_file(file, step);
    // Parts written before the attribute existed are the full FEM's.
    const std::string from =
        h5.has_attribute("/", "backend") ? h5.attribute_string("/", "backend") : "fem";
    const std::string refusal = checkpoint_swap_refusal(from, backend_kind(solver_));
    if (!refusal.empty())
      throw std::runtime_error(file.string() + " was written by the " + from + " backend; the " +
                               backend_kind(solver_) + " backend cannot continue it: " + refusal);
    solver_.restore(h5, "fem");
    if (from != backend_kind(solver_)) {
      std::string note = restore_note(solver_);
      if (note.empty())
        note = "the full state written by the " + from + " backend" +
               (from == "modal" ? " (reconstructed from its modes and static correction)" : "");
      std::cerr << "fem: note: " << backend_kind(solver_) << " backend took over " << note << "\n";
    }
    if (monitor_) monitor_->restore(h5, "fem_monitor", solver_.time());
    if (h5.exists("fem_output_schedule")) {
      const auto sched = h5.read_int64("fem_output_schedule");
      const auto dt = h5.read_doubles("fem_output_step");
      if (sched.size() != 3 || dt.size() != 1) {
        throw std::runtime_error(file.string() + ": fem_output_schedule is malformed");
      }
      schedule_.set_next(sched[0]);
      last_output_step_ = sched[1];
      step_dt_ = dt[0];
    } else {  // written by an older version: the outputs up to the restored time were taken
      schedule_.skip_to_after(solver_.time());
      last_output_step_ = -1;
    }
    static_time_ = static_dt_ = 0.0;
    static_pending_ = false;
    if (h5.exists("fem_output_static")) {
      const auto st = h5.read_doubles("fem_output_static");
      if (st.size() != 3)
        throw std::runtime_error(file.string() + ": fem_output_static is malformed");
      static_time_ = st[0];
      static_dt_ = st[1];
      static_pending_ = st[2] != 0.0;
    }
    // Output of states after the checkpoint is rewritten by the continuation (a static
    // solution applies at its own time, which the solver's clock does not reach).
    if (output_) {
      output_->rollback(std::max(solver_.time(), static_time_));
      if (static_pending_ && output_->last_state_time() == static_time_) static_pending_ = false;
      // The series may keep an output of the restored state itself (the end state of a
      // finished run, written after its final checkpoint): it is not written again.
      if (output_->last_state_time() == solver_.time()) last_output_step_ = solver_.step_count();
    }
  }

 private:
  /// The FEM clock for output: step count x dt (not the running sum of dt).
  double output_clock() const { return static_cast<double>(solver_.step_count()) * step_dt_; }

  void maybe_write_output() {
    if (!output_) return;
    if (static_pending_) {  // a static solve: written when an output is due, else at the end
      if (static_dt_ > 0.0 && schedule_.due(static_time_, static_dt_))
        write_static_output(schedule_.take(static_time_, static_dt_));
      return;
    }
    if (!(step_dt_ > 0.0)) return;
    const double t = output_clock();
    if (!schedule_.due(t, step_dt_)) return;
    FemFields f = gather_fields(solver_);
    f.time = schedule_.take(t, step_dt_);
    f.state_time = solver_.time();
    output_->write(f);
    last_output_step_ = solver_.step_count();
  }

  void write_static_output(double label) {
    FemFields f = gather_fields(solver_);
    f.time = label;
    f.state_time = static_time_;
    output_->write(f);
    static_pending_ = false;
    last_output_step_ = solver_.step_count();
  }

  Solver& solver_;
  FemOutput* output_;
  FemMonitor* monitor_ = nullptr;
  io::OutputSchedule schedule_;
  double step_dt_ = 0.0;                ///< dt of the dynamic steps (the coupling step), s
  std::int64_t last_output_step_ = -1;  ///< solver step count of the last output
  FemStateCopy save_point_;             ///< save_iteration_state()
  double save_point_dt_ = 0.0;
  double static_time_ = 0.0;         ///< the time the last static solution applies at, s
  double static_dt_ = 0.0;           ///< the coupling step of that static solve, s
  bool static_pending_ = false;      ///< a static solution that no output holds yet
  bool held_back_ = false;           ///< an iterated step whose output waits for accept_step()
  std::vector<double> held_forces_;  ///< the forces of the held-back step (for the monitor)
};

using FemBackend = StructureBackend<FemSolver>;
using ModalBackend = StructureBackend<ModalSolver>;
using RigidBackend = StructureBackend<RigidSolver>;

}  // namespace demfem::fem
