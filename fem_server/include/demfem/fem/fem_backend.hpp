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

#include "demfem/fem/fem_output.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/io/checkpoint_file.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem/protocol/protocol.hpp"

namespace demfem::fem {

/// @brief protocol::SolverBackend around a FemSolver.
///
/// step(): takes the interface forces from buffers.forces(cmd.buffer); runs a static solve
/// when cmd.flags has kStepStatic, else one Bossak step of cmd.dt; writes the interface
/// positions, velocities and accelerations into the same buffer. StepResult values:
/// [0] max nodal |u| (m), [1] kinetic energy (J), [2] strain energy (J), [3] solver time (s).
/// Optional output: a FemOutput written whenever the solver time passes a multiple of
/// `output_interval` (never from step() when it is 0: the caller writes the start and end
/// states).
class FemBackend final : public protocol::SolverBackend {
 public:
  explicit FemBackend(FemSolver& solver, FemOutput* output = nullptr, double output_interval = 0.0)
      : solver_(solver), output_(output), interval_(output_interval) {}

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
    maybe_write_output();
    return r;
  }

  /// The solver state under group "fem" of an HDF5 file, written under a temporary name and
  /// renamed when complete; attribute "step" on "/" records the coupling step.
  void write_checkpoint(const std::filesystem::path& file, std::int64_t step) override {
    io::write_checkpoint_file(file, step, [this](io::H5File& h5) {
      h5.create_group("fem");
      solver_.save(h5, "fem");
      // The mesh the state belongs to, so that a resume with a changed mesh is refused before
      // any process starts (demfem_run).
      const auto& mesh = solver_.problem().mesh;
      h5.set_attribute("fem", "mesh_nodes", static_cast<std::int64_t>(mesh.nodes.size()));
      h5.set_attribute("fem", "mesh_elements", static_cast<std::int64_t>(mesh.elements.size()));
    });
  }

  void restore_checkpoint(const std::filesystem::path& file, std::int64_t step) override {
    solver_.restore(io::open_checkpoint_file(file, step), "fem");
    if (interval_ > 0.0) {
      // The next multiple of the interval after the restored time, as in the original run.
      next_output_ = interval_ * (std::floor(solver_.time() / interval_ + 1e-9) + 1.0);
    }
    // Output written after the checkpoint is rewritten by the continuation.
    if (output_) output_->rollback(solver_.time());
  }

 private:
  void maybe_write_output() {
    if (!output_ || !(interval_ > 0.0)) return;
    if (solver_.time() < next_output_ * (1.0 - 1e-12)) return;
    while (next_output_ <= solver_.time() * (1.0 + 1e-12)) next_output_ += interval_;
    output_->write(solver_);
  }

  FemSolver& solver_;
  FemOutput* output_;
  double interval_;
  double next_output_ = interval_;
};

}  // namespace demfem::fem
