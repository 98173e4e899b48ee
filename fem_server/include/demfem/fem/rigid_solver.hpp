#pragma once
// The structure as one rigid body on springs and supports: the engine of the rigid-body
// backend (fem.backend = "rigid", docs/backends.md), a cheap stand-in for parameter studies.
//
// Six coordinates x = (d, theta): the displacement of a reference point r0 (the centre of
// mass unless fem.rigid.reference_point says otherwise) and a small rotation about it, so a
// material point X moves by u = d + theta x (X - r0), linear like the FEM. Its mass and
// inertia are the FEM mass matrix projected on these six motions, M_r = G^T M G (exact for
// the consistent and the lumped mass of every element type); loads likewise (F_r = G^T F:
// self weight, pressures, nodal loads and interface forces, with their moments about r0).
// Springs k (N/m per axis) and dashpots c at points p add G_p^T diag(k) G_p and
// G_p^T diag(c) G_p; fixed DOFs of the reference point are removed. The mesh's clamps are
// not used (the springs and fixed DOFs stand for the supports). The coordinates are
// integrated by FemSolver's Bossak-Newmark step with Rayleigh damping cm M_r + ck K_r
// (ReducedBossak).

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "demfem/fem/fem_problem.hpp"
#include "demfem/interface/interface_mesh.hpp"

namespace demfem::io {
class H5File;
}

namespace demfem::fem {

struct RigidSpring {
  std::array<double, 3> point{};      ///< m
  std::array<double, 3> stiffness{};  ///< N/m along x, y, z
  std::array<double, 3> damping{};    ///< N s/m along x, y, z
};

/// @brief [fem.rigid] of a scene.
struct RigidSettings {
  std::vector<RigidSpring> springs;
  /// Held DOFs of the reference point: x, y, z, rotations about x, y, z.
  std::array<bool, 6> fixed{};
  bool has_reference_point = false;
  std::array<double, 3> reference_point{};  ///< m (default: the centre of mass)
};

class RigidSolver {
 public:
  /// Throws FemModelError when the body has no mass, or every DOF is fixed.
  RigidSolver(FemProblem problem, RigidSettings settings);
  ~RigidSolver();
  RigidSolver(RigidSolver&&) noexcept;
  RigidSolver& operator=(RigidSolver&&) noexcept;

  const FemProblem& problem() const;
  const InterfaceMesh& interface_mesh() const;
  double mass() const;                           ///< kg
  std::array<double, 3> centre_of_mass() const;  ///< m
  /// 3 x 3 inertia tensor about the centre of mass, kg m^2 (row-major).
  std::array<double, 9> inertia() const;
  std::array<double, 3> reference_point() const;

  void set_interface_forces(std::span<const double> forces);
  /// K_r x = F_r; throws FemModelError when the springs and fixed DOFs leave a motion free.
  void solve_static();
  void advance(double dt);
  double time() const;
  std::int64_t step_count() const;

  /// The six coordinates (d, theta) with fixed ones zero; and their rates.
  std::array<double, 6> coordinates() const;
  std::array<double, 6> rates() const;

  void interface_kinematics(std::span<double> positions, std::span<double> velocities,
                            std::span<double> accelerations) const;
  double max_interface_displacement() const;
  /// Rigid motion of every mesh node (3 per node).
  std::vector<double> displacements() const;
  std::vector<double> velocities() const;
  std::vector<double> accelerations() const;
  double kinetic_energy() const;
  double strain_energy() const;  ///< of the springs

  void save(io::H5File& file, const std::string& group) const;
  /// Only from a rigid-body state of the same body (its mass and reference point).
  void restore(const io::H5File& file, const std::string& group);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace demfem::fem
