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

#include "demfem/fem/fem_monitor.hpp"
#include "demfem/fem/fem_output.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/io/checkpoint_file.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem/io/output_schedule.hpp"
#include "demfem/protocol/protocol.hpp"

namespace demfem::fem {

/// @brief protocol::SolverBackend around a FemSolver.
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
/// in memory (u, v, a, forces, time: FemSolver::save_state) with the output step size; a step
/// with kStepIterate writes its output only when accepted (accept_step()).
class FemBackend final : public protocol::SolverBackend {
 public:
  explicit FemBackend(FemSolver& solver, FemOutput* output = nullptr, double output_interval = 0.0)
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

  /// The end state, unless the last output is of it (or no step was taken).
  void write_final_output() {
    if (!output_ || solver_.step_count() == 0 || last_output_step_ == solver_.step_count()) return;
    FemFields f = gather_fields(solver_);
    f.time = schedule_.label(output_clock(), step_dt_);
    f.state_time = solver_.time();
    output_->write(f);
    last_output_step_ = solver_.step_count();
  }

  /// [fem.monitor]: sampled after every step, kept in checkpoints (may be null).
  void set_monitor(FemMonitor* monitor) { monitor_ = monitor; }

  std::string name() const override { return "demfem-fem 0.1 (cpu)"; }

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
        throw std::runtime_error("fem: step " + std::to_string(cmd.step) +
                                 ": interface force is not finite");
      }
    }
    solver_.set_interface_forces(forces);
    if (cmd.flags & protocol::kStepStatic) {
      solver_.solve_static();
    } else {
      if (!(cmd.dt > 0.0) || !std::isfinite(cmd.dt)) {
        throw std::runtime_error("fem: step " + std::to_string(cmd.step) + ": dt must be > 0");
      }
      solver_.advance(cmd.dt);
      step_dt_ = cmd.dt;
    }
    solver_.interface_kinematics(buffers.positions(cmd.buffer), buffers.velocities(cmd.buffer),
                                 buffers.accelerations(cmd.buffer));
    const auto u = solver_.displacements();
    double umax = 0.0;
    for (std::size_t i = 0; i + 2 < u.size(); i += 3) {
      umax = std::max(umax, std::sqrt(u[i] * u[i] + u[i + 1] * u[i + 1] + u[i + 2] * u[i + 2]));
    }
    if (!std::isfinite(umax)) {
      throw std::runtime_error("fem: step " + std::to_string(cmd.step) +
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
      if (monitor_) monitor_->sample(solver_, forces);
    }
    return r;
  }

  bool supports_iteration() const override { return true; }
  void save_iteration_state() override {
    accept_step();
    solver_.save_state(save_point_);
    save_point_dt_ = step_dt_;
  }
  void restore_iteration_state() override {
    held_back_ = false;
    solver_.restore_state(save_point_);
    step_dt_ = save_point_dt_;
  }
  void accept_step() override {
    if (!held_back_) return;
    held_back_ = false;
    maybe_write_output();
    if (monitor_) monitor_->sample(solver_, held_forces_);
  }

  /// The solver state under group "fem" of an HDF5 file, written under a temporary name and
  /// renamed when complete; attribute "step" on "/" records the coupling step.
  void write_checkpoint(const std::filesystem::path& file, std::int64_t step) override {
    io::write_checkpoint_file(file, step, [this](io::H5File& h5) {
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
    });
  }

  void restore_checkpoint(const std::filesystem::path& file, std::int64_t step) override {
    held_back_ = false;  // a held-back step is not part of the restored state
    const io::H5File h5 = io::open_checkpoint_file(file, step);
    solver_.restore(h5, "fem");
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
    // Output of states after the checkpoint is rewritten by the continuation.
    if (output_) {
      output_->rollback(solver_.time());
      // The series may keep an output of the restored state itself (the end state of a
      // finished run, written after its final checkpoint): it is not written again.
      if (output_->last_state_time() == solver_.time()) last_output_step_ = solver_.step_count();
    }
  }

 private:
  /// The FEM clock for output: step count x dt (not the running sum of dt).
  double output_clock() const { return static_cast<double>(solver_.step_count()) * step_dt_; }

  void maybe_write_output() {
    if (!output_ || !(step_dt_ > 0.0)) return;
    const double t = output_clock();
    if (!schedule_.due(t, step_dt_)) return;
    FemFields f = gather_fields(solver_);
    f.time = schedule_.take(t, step_dt_);
    f.state_time = solver_.time();
    output_->write(f);
    last_output_step_ = solver_.step_count();
  }

  FemSolver& solver_;
  FemOutput* output_;
  FemMonitor* monitor_ = nullptr;
  io::OutputSchedule schedule_;
  double step_dt_ = 0.0;                ///< dt of the dynamic steps (the coupling step), s
  std::int64_t last_output_step_ = -1;  ///< solver step count of the last output
  FemStateCopy save_point_;             ///< save_iteration_state()
  double save_point_dt_ = 0.0;
  bool held_back_ = false;  ///< an iterated step whose output waits for accept_step()
  std::vector<double> held_forces_;  ///< the forces of the held-back step (for the monitor)
};

}  // namespace demfem::fem
