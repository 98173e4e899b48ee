#pragma once
// The DEM engine as a protocol backend: what dem_server serves to the coupler. Header-only
// on purpose: demfem::dem does not depend on demfem::protocol, so only a target that links
// both (the dem_server executable, the coupler's in-process link, a test) compiles it.

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "demfem/dem/run/dem_run.hpp"
#include "demfem/io/checkpoint_file.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem/protocol/protocol.hpp"

namespace demfem::dem {

/// @brief protocol::SolverBackend around a DemRun (system + sensors + output).
///
/// on_mesh(): the FEM's surface becomes the flexible mesh, with the scene's
/// dem.interface_material. step(): with kStepSetKinematics, the node positions, velocities
/// and accelerations of buffers(cmd.buffer) become the mesh kinematics; then cmd.substeps
/// steps (cmd.substeps * dem.dt must equal cmd.dt); the node forces (as cmd.force_mode asks)
/// go to buffers.forces(cmd.buffer) and the DEM's node positions to
/// buffers.dem_positions(cmd.buffer). StepResult values: [0] largest overlap with the
/// flexible mesh (m), [1] kinetic energy (J), [2] largest overlap of any contact (m).
/// Sensors and particle output advance with the run.
///
/// Iterated steps (implicit coupling, docs/protocol.md): the save point is the system's state
/// in memory (DemRun::take_save_point); a step with kStepIterate holds back its insertions,
/// sensor samples and snapshots until accept_step().
class DemBackend final : public protocol::SolverBackend {
 public:
  explicit DemBackend(DemRun& run) : run_(run) {}

  std::string name() const override {
    return std::string("demfem-dem 0.1 (") + dem_backend_name(run_.system().settings().backend) +
           ")";
  }

  std::optional<InterfaceMesh> published_mesh() override { return std::nullopt; }

  void on_mesh(const InterfaceMesh& mesh) override {
    if (run_.scene().interface_material < 0) {
      throw std::runtime_error(run_.scene().file +
                               ": [dem] needs 'interface_material' (the wall material of the "
                               "coupled structure's surface) in a coupled scene");
    }
    run_.system().set_flexible_mesh(mesh, run_.scene().interface_material);
    nodes_ = mesh.node_count();
  }

  protocol::StepResult step(const protocol::StepCommand& cmd,
                            protocol::InterfaceBuffers& buffers) override {
    DemSystem& sys = run_.system();
    const double dt = sys.settings().dt;
    if (cmd.substeps < 1) {
      throw std::runtime_error("dem: step " + std::to_string(cmd.step) + ": substeps " +
                               std::to_string(cmd.substeps) + " must be >= 1");
    }
    // The coupling step must be a whole number of DEM steps (eq. 3.2).
    if (std::abs(double(cmd.substeps) * dt - cmd.dt) > 1e-9 * cmd.dt) {
      throw std::runtime_error("dem: step " + std::to_string(cmd.step) + ": " +
                               std::to_string(cmd.substeps) +
                               " substeps of dem.dt = " + std::to_string(dt) +
                               " s do not make the coupling step " + std::to_string(cmd.dt) + " s");
    }
    const bool coupled = sys.has_flexible_mesh();
    if (coupled && buffers.node_count() != nodes_) {
      throw std::runtime_error("dem: interface buffers have " +
                               std::to_string(buffers.node_count()) + " nodes, the mesh " +
                               std::to_string(nodes_));
    }
    if (coupled && (cmd.flags & protocol::kStepSetKinematics)) {
      sys.set_flexible_kinematics(buffers.positions(cmd.buffer), buffers.velocities(cmd.buffer),
                                  buffers.accelerations(cmd.buffer));
    }
    try {
      if (cmd.flags & protocol::kStepIterate) {
        run_.advance_tentative(cmd.substeps, cmd.force_mode);
      } else {
        run_.advance(cmd.substeps, cmd.force_mode);
      }
    } catch (const Unstable& e) {
      // A blow-up, reported as one (the coupler exits with status 3, docs/coupling.md).
      throw protocol::BackendError(
          protocol::ErrorKind::blow_up,
          "dem: step " + std::to_string(cmd.step) + ": the DEM blew up: " + e.what());
    } catch (const scene::SceneError& e) {
      // Something of the scene that only the run can tell (a sensor, an insertion): bad input.
      throw protocol::BackendError(protocol::ErrorKind::bad_input, e.what());
    }
    protocol::StepResult r;
    if (coupled) {
      auto forces = buffers.forces(cmd.buffer);
      sys.flexible_forces(forces);
      for (double f : forces) {
        if (!std::isfinite(f)) {
          throw protocol::BackendError(protocol::ErrorKind::blow_up,
                                       "dem: step " + std::to_string(cmd.step) +
                                           ": an interface force is not finite (the DEM blew up; "
                                           "reduce dem.dt)");
        }
      }
      const auto x = sys.flexible_positions();
      auto out = buffers.dem_positions(cmd.buffer);
      std::copy(x.begin(), x.end(), out.begin());
      r.values[0] = sys.flexible_max_overlap();
    }
    r.values[1] = sys.kinetic_energy();
    r.values[2] = sys.max_overlap();
    if (!std::isfinite(r.values[1])) {
      throw protocol::BackendError(
          protocol::ErrorKind::blow_up,
          "dem: step " + std::to_string(cmd.step) +
              ": kinetic energy is not finite (the DEM blew up; reduce dem.dt)");
    }
    return r;
  }

  /// The state under group "dem" (and "dem_tools") of an HDF5 file, written under a
  /// temporary name and renamed when complete; attribute "step" on "/" records the step.
  void write_checkpoint(const std::filesystem::path& file, std::int64_t step) override {
    // A checkpoint before the first step (the coupler's step-0 checkpoint): start the deferred
    // output now, as the first advance() would (initial sensor samples and snapshot), so the
    // checkpoint counts them and a rollback to it keeps them instead of writing them again
    // at a later time.
    run_.start_deferred_output();
    io::write_checkpoint_file(file, step, [this](io::H5File& h5) { run_.save(h5, "dem"); });
  }

  void restore_checkpoint(const std::filesystem::path& file, std::int64_t step) override {
    run_.restore(io::open_checkpoint_file(file, step), "dem");
  }

  /// A long coupling step (n_D substeps) stops within one substep when the flag is set.
  void set_cancel_flag(const std::atomic<bool>* flag) override { run_.set_cancel_flag(flag); }

  bool supports_iteration() const override { return true; }
  void save_iteration_state() override { run_.take_save_point(); }
  void restore_iteration_state() override { run_.restore_save_point(); }
  void accept_step() override { run_.accept_step(); }

 private:
  DemRun& run_;
  std::size_t nodes_ = 0;
};

}  // namespace demfem::dem
