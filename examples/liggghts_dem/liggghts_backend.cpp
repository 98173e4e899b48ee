#include "liggghts_backend.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <thread>

namespace demfem::liggghts {

namespace {

// An order travels as four doubles: the order, then its arguments (a step: dt, substeps,
// 1 for force averaging; attach: the node and triangle counts, followed by the mesh).
using OrderMessage = std::array<double, 4>;

OrderMessage broadcast_order(MPI_Comm world, OrderMessage message) {
  MPI_Request request;
  MPI_Ibcast(message.data(), static_cast<int>(message.size()), MPI_DOUBLE, 0, world, &request);
  // The other ranks wait here while rank 0 waits for the coupler, often for the whole FEM
  // step: a blocking MPI_Bcast would spin a core that the FEM and the coupler need.
  for (int done = 0;;) {
    MPI_Test(&request, &done, MPI_STATUS_IGNORE);
    if (done) return message;
    std::this_thread::sleep_for(std::chrono::microseconds(50));
  }
}

void broadcast_mesh(MPI_Comm world, InterfaceMesh& mesh) {
  MPI_Bcast(mesh.reference_positions.data(), static_cast<int>(mesh.reference_positions.size()),
            MPI_DOUBLE, 0, world);
  MPI_Bcast(mesh.triangles.data(), static_cast<int>(mesh.triangles.size()), MPI_INT32_T, 0,
            world);
}

}  // namespace

LiggghtsBackend::LiggghtsBackend(MPI_Comm world, LiggghtsDomain& domain)
    : world_(world), domain_(domain) {
  MPI_Comm_size(world_, &ranks_);
}

std::string LiggghtsBackend::name() const {
  return "liggghts_dem (LIGGGHTS-PUBLIC 3.8, " + std::to_string(ranks_) + " MPI rank" +
         (ranks_ == 1 ? "" : "s") + ")";
}

void LiggghtsBackend::on_mesh(const InterfaceMesh& mesh) {
  InterfaceMesh copy = mesh;
  broadcast_order(world_, {static_cast<double>(RankOrder::attach),
                           static_cast<double>(mesh.node_count()),
                           static_cast<double>(mesh.triangle_count()), 0.0});
  broadcast_mesh(world_, copy);
  const std::string refusal = domain_.attach(copy);
  if (!refusal.empty()) throw protocol::BackendError(protocol::ErrorKind::bad_input, refusal);
}

protocol::StepResult LiggghtsBackend::step(const protocol::StepCommand& cmd,
                                           protocol::InterfaceBuffers& buffers) {
  const std::size_t values = 3 * domain_.mesh().node_count();
  if (cmd.flags & protocol::kStepSetKinematics) {
    // LIGGGHTS holds the interface as demfem published it; a structure that moves it is
    // refused rather than coupled to a mesh that stays behind.
    const double offset = domain_.mesh_offset(buffers.positions(cmd.buffer).data());
    const auto v = buffers.velocities(cmd.buffer);
    const double speed = std::abs(*std::max_element(
        v.begin(), v.end(), [](double a, double b) { return std::abs(a) < std::abs(b); }));
    if (offset > 0.0 || speed > 0.0) {
      char text[400];
      std::snprintf(text, sizeof text,
                    "coupling step %lld: the structure moved the interface (a node %.3g m from "
                    "its reference position, %.3g m/s), and liggghts_dem keeps LIGGGHTS's "
                    "coupling mesh where demfem published it: use coupling.scheme = "
                    "\"one_way_static\" with it, or dem_server for a two-way coupling",
                    static_cast<long long>(cmd.step), offset, speed);
      throw protocol::BackendError(protocol::ErrorKind::bad_input, text);
    }
  }
  const bool average = cmd.force_mode == ForceMode::average;
  broadcast_order(world_, {static_cast<double>(RankOrder::step), cmd.dt,
                           static_cast<double>(cmd.substeps), average ? 1.0 : 0.0});
  const StepReport report = domain_.advance(cmd.dt, cmd.substeps, average);
  std::copy(report.node_forces.begin(), report.node_forces.end(),
            buffers.forces(cmd.buffer).begin());
  const auto& x = domain_.mesh().reference_positions;
  std::copy(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(values),
            buffers.dem_positions(cmd.buffer).begin());
  protocol::StepResult result;
  result.values[0] = report.max_overlap;
  result.values[1] = report.kinetic_energy;
  result.values[2] = report.max_overlap;
  return result;
}

void LiggghtsBackend::write_checkpoint(const std::filesystem::path& file, std::int64_t step) {
  (void)file;
  throw protocol::BackendError(
      protocol::ErrorKind::bad_input,
      "checkpoint of coupling step " + std::to_string(step) +
          ": liggghts_dem does not write checkpoints (LIGGGHTS's restart files cannot yet be "
          "read back into a user's deck); run the scene without [checkpoint]");
}

void LiggghtsBackend::restore_checkpoint(const std::filesystem::path& file, std::int64_t step) {
  throw protocol::BackendError(protocol::ErrorKind::bad_input,
                               "liggghts_dem cannot restore " + file.string() + " (step " +
                                   std::to_string(step) + "): it writes no checkpoints");
}

void LiggghtsBackend::release_other_ranks() {
  broadcast_order(world_, {static_cast<double>(RankOrder::quit), 0.0, 0.0, 0.0});
}

void serve_other_rank(MPI_Comm world, LiggghtsDomain& domain) {
  for (;;) {
    const OrderMessage order = broadcast_order(world, {});
    switch (static_cast<RankOrder>(static_cast<int>(order[0]))) {
      case RankOrder::attach: {
        InterfaceMesh mesh;
        mesh.reference_positions.resize(3 * static_cast<std::size_t>(order[1]));
        mesh.triangles.resize(3 * static_cast<std::size_t>(order[2]));
        broadcast_mesh(world, mesh);
        domain.attach(mesh);  // rank 0 reports a refusal; this rank waits for quit
        break;
      }
      case RankOrder::step:
        domain.advance(order[1], static_cast<std::int64_t>(order[2]), order[3] != 0.0);
        break;
      case RankOrder::quit:
        return;
    }
  }
}

}  // namespace demfem::liggghts
