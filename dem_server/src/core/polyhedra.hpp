#pragma once
// The CPU backend's loops for systems with dilated polyhedra (DemSystem::Impl calls them when
// some particle is not a sphere; spheres alone keep their vectorised path untouched): pair
// forces over a range of the pair list, a particle's wall contacts, and the kick + drift with
// the rigid-body rotation. The physics is in physics/poly_contact.hpp, narrow_phase.hpp and
// rigid_body.hpp, shared with the CUDA backend.

#include <cstdint>

#include "demfem/dem/physics/poly_contact.hpp"
#include "demfem/dem/physics/step_integrator.hpp"

namespace demfem::dem::detail {

/// The largest overlap of a range of contacts: in m, and against each contact's own radii
/// (phys::relative_overlap), which the run's stability guard judges.
struct OverlapMax {
  double abs = 0.0, rel = 0.0;
};

/// Particle arrays of a mixed system (host pointers): the shared physics view.
using PolyParticles = phys::PolyView;

/// The pair list and its per-pair slots.
struct PolyPairs {
  const std::int32_t *pi, *pj;  ///< i and j of each pair
  const std::int32_t* material;
  const phys::PairConstants* pc;  ///< nmat x nmat
  std::size_t nmat;
  double dt;
  bool friction, rolling;
  double* shear;        ///< 3 per pair (friction)
  double* rhist;        ///< 3 per pair (rolling, sphere pairs only)
  double* pf;           ///< 3 per pair: force on i
  double* pt;           ///< 3 per pair: torque on i
  double* ptj;          ///< 3 per pair: torque on j
  double* paxis;        ///< 3 per pair: separating-axis cache (unit, i -> j, or zero)
  std::int32_t* pfeat;  ///< 6 per pair: closest-feature cache (GJK warm start)
  /// Per pair: the separation of the two bodies proven at an earlier pass, less the motion
  /// since (m; negative: none). A pair whose proof still exceeds the motion of this step
  /// (pmove of i and j) gives what the narrow phase would (no contact, caches unchanged):
  /// it is not computed. The proof is the gap of the bounding spheres or along the cached
  /// separating axis (phys::mixed_pair's `slack`), less a rounding margin.
  double* pslack;
  const double* pmove;  ///< per particle: how far any point of its core moved since the last pass
  /// Per particle, or null: a pair of two frozen particles (DemSystem::freeze) is not
  /// computed (zero force and torques in its slots, its spring kept).
  const std::uint8_t* frozen = nullptr;
  /// Periodic systems: the periods (each pair's j at its image nearest to i), else null.
  const phys::PeriodicBox* box = nullptr;
};

/// The rotation matrices of the polyhedra (9 per particle, rotation(q); spheres untouched),
/// for PolyView::rot; beforehand, `move` gets a bound of how far any point of each core moved
/// since the last call (|x - xprev| + s r_bound |R - R_prev|_F, from the matrices the narrow
/// phase uses), and xprev the positions.
void poly_rotations(const PolyParticles& p, double* rot, double* xprev, double* move,
                    std::int64_t n, int threads);

/// Forces of the pairs [begin, end) into their slots; returns their largest overlap.
OverlapMax poly_pair_forces(const PolyParticles& p, const PolyPairs& a, std::int64_t begin,
                        std::int64_t end);

/// Wall contacts of polyhedron i (adds to f and q, fills its wall slots).
void poly_wall_contacts(const PolyParticles& p, const phys::WallView& w, std::int64_t i,
                        const phys::PairConstants* pc_row, double dt, bool friction, phys::Vec3& f,
                        phys::Vec3& q, double& mo, double& fmo);

/// Arrays of the kick + drift of a mixed system.
struct PolyDrift {
  std::int64_t n;
  double dt;
  int threads;
  phys::MotionArrays motion;
  const double *bx, *by, *bz;  ///< positions at the last list update (null: none)
  const std::uint8_t* frozen = nullptr;  ///< per particle, or null: frozen ones are not moved
};

/// First half kick (last forces and torques), drift, rotation (spheres: the exact rotation of
/// ω Δt; polyhedra: NO_SQUISH); returns the largest displacement since the last list update
/// (1e300 without one).
double poly_kick_drift(const PolyDrift& d);

}  // namespace demfem::dem::detail
