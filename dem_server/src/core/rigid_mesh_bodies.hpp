#pragma once
// The rigid mesh bodies of a DemSystem: walls moved by the particles' contact forces
// (WallMesh::body). Holds each body's state (physics/rigid_mesh_body.hpp) and its vertices in
// the principal frame; DemSystem::Impl calls the two half kicks and the drift around its
// particle step and places the vertices in its wall store. Steps, loads and placement are the
// shared physics; this class only owns the arrays, in a fixed order (bitwise reproducible).

#include <array>
#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/physics/rigid_mesh_body.hpp"

namespace demfem::io {
class H5File;
}

namespace demfem::dem::detail {

class RigidMeshBodies {
 public:
  /// Adds the body of `mesh` (mesh.body.enabled) under gravity g; returns its index. Throws
  /// std::invalid_argument naming `where` for a mass, inertia or orientation out of range.
  int add(const WallMesh& mesh, const std::array<double, 3>& g, const std::string& where);
  std::size_t size() const { return bodies_.size(); }
  bool empty() const { return bodies_.empty(); }

  /// First half kick with the last step's loads, then the drift over dt.
  void kick_drift(double dt);
  /// Second half kick with the loads just set.
  void kick(double dt);
  /// Loads of body b from the particles' force on its mesh and their torque about the origin.
  void set_loads(int b, const std::array<double, 3>& force, const std::array<double, 3>& torque);
  /// Current positions and velocities of the vertices of body b (3 per vertex).
  void place(int b, double* x, double* v) const;
  RigidBodyState state(int b) const;

  /// The bodies' state, 19 numbers per body (pose, velocities, last loads): what save()
  /// writes and DemSystem::save_state() keeps in memory.
  std::vector<double> pack() const;
  /// Back to a packed state; false if `in` holds another number of bodies.
  bool unpack(std::span<const double> in);
  /// Appends the state to a saved DEM state (dataset "<group>/rigid_bodies", 19 per body).
  void save(io::H5File& f, const std::string& g) const;
  /// Reads it back; a state without bodies or with another count is refused (message names
  /// the file).
  void restore(const io::H5File& f, const std::string& g);

 private:
  std::vector<phys::MeshBody> bodies_;
  std::vector<std::vector<double>> local_;  // body-frame vertices, 3 per vertex
};

}  // namespace demfem::dem::detail
