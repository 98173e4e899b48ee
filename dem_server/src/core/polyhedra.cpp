// CPU loops for systems with dilated polyhedra (see polyhedra.hpp).

#include "polyhedra.hpp"

#include "multiversion.hpp"

#include <omp.h>

#include <cmath>

#include "demfem/dem/physics/poly_contact.hpp"
#include "demfem/dem/physics/step_integrator.hpp"

namespace demfem::dem::detail {

using phys::Vec3;

namespace {

template <bool Friction>
OverlapMax pair_range(const PolyParticles& p, const PolyPairs& a, std::int64_t begin,
                      std::int64_t end) {
  double mo = 0.0, mr = 0.0;
  for (std::int64_t k = begin; k < end; ++k) {
    const std::int32_t i = a.pi[k], j = a.pj[k];
    if (a.frozen != nullptr && a.frozen[i] != 0 && a.frozen[j] != 0) {
      // both held: their mutual force moves nothing and cancels in the frozen particles'
      // total (DemSystem::frozen_support), so it is not computed (the spring is kept)
      for (int d = 0; d < 3; ++d) a.pf[3 * k + d] = a.pt[3 * k + d] = a.ptj[3 * k + d] = 0.0;
      continue;
    }
    // still proven apart: the narrow phase would give no contact and keep the caches
    const double left = a.pslack[k] - (a.pmove[i] + a.pmove[j]);
    if (left > 0.0) {
      a.pslack[k] = left;
      for (int d = 0; d < 3; ++d) a.pf[3 * k + d] = a.pt[3 * k + d] = a.ptj[3 * k + d] = 0.0;
      if constexpr (Friction)
        for (int d = 0; d < 3; ++d) a.shear[3 * k + d] = 0.0;
      continue;
    }
    const phys::PairConstants& c =
        a.pc[static_cast<std::size_t>(a.material[i]) * a.nmat + a.material[j]];
    Vec3 sh{0, 0, 0}, rh{0, 0, 0};
    if constexpr (Friction) sh = Vec3{a.shear[3 * k], a.shear[3 * k + 1], a.shear[3 * k + 2]};
    if (a.rolling) rh = Vec3{a.rhist[3 * k], a.rhist[3 * k + 1], a.rhist[3 * k + 2]};
    Vec3 axis{a.paxis[3 * k], a.paxis[3 * k + 1], a.paxis[3 * k + 2]};
    Vec3 force, ti, tj;
    double slack = -1.0;
    const double delta = phys::mixed_pair<Friction>(p, i, j, c, a.dt, a.rolling, sh, rh, axis,
                                                    a.pfeat + 6 * k, force, ti, tj, &slack, a.box);
    a.pslack[k] = slack;
    if (delta > 0.0) {
      mo = mo > delta ? mo : delta;
      const double rel = phys::relative_overlap(delta, phys::particle_contact_radius(p, i),
                                                phys::particle_contact_radius(p, j));
      mr = mr > rel ? mr : rel;
    }
    a.pf[3 * k] = force.x, a.pf[3 * k + 1] = force.y, a.pf[3 * k + 2] = force.z;
    a.pt[3 * k] = ti.x, a.pt[3 * k + 1] = ti.y, a.pt[3 * k + 2] = ti.z;
    a.ptj[3 * k] = tj.x, a.ptj[3 * k + 1] = tj.y, a.ptj[3 * k + 2] = tj.z;
    a.paxis[3 * k] = axis.x, a.paxis[3 * k + 1] = axis.y, a.paxis[3 * k + 2] = axis.z;
    if constexpr (Friction)
      a.shear[3 * k] = sh.x, a.shear[3 * k + 1] = sh.y, a.shear[3 * k + 2] = sh.z;
    if (a.rolling) a.rhist[3 * k] = rh.x, a.rhist[3 * k + 1] = rh.y, a.rhist[3 * k + 2] = rh.z;
  }
  return OverlapMax{mo, mr};
}

}  // namespace

void poly_rotations(const PolyParticles& p, double* rot, double* xprev, double* move,
                    std::int64_t n, int threads) {
#pragma omp parallel for num_threads(threads) schedule(static)
  for (std::int64_t i = 0; i < n; ++i) {
    const double x[3] = {p.p.px[i], p.p.py[i], p.p.pz[i]};
    double d2 = 0.0;
    for (int k = 0; k < 3; ++k) {
      const double e = x[k] - xprev[3 * i + k];
      d2 += e * e;
      xprev[3 * i + k] = x[k];
    }
    double m = std::sqrt(d2);
    if (p.shape_id[i] >= 0) {
      // a core point at r from the centre moves by |x' - x| + |(R' - R) r| at most, and
      // |(R' - R) r| <= |R' - R|_F r_bound s
      const phys::Rot r = phys::rotation(p.qw[i], p.qx[i], p.qy[i], p.qz[i]);
      double e2 = 0.0;
      for (int k = 0; k < 9; ++k) {
        const double e = r.m[k] - rot[9 * i + k];
        e2 += e * e;
        rot[9 * i + k] = r.m[k];
      }
      m += p.scale[i] * p.table.bound[p.shape_id[i]] * std::sqrt(e2);
    }
    move[i] = m * (1.0 + 1e-9);  // the rounding of the bound itself
  }
}

// The narrow phase's loops over vertices and faces gain from the wider instruction sets.
DEMFEM_CLONES OverlapMax poly_pair_forces(const PolyParticles& p, const PolyPairs& a,
                                          std::int64_t begin, std::int64_t end) {
  return a.friction ? pair_range<true>(p, a, begin, end) : pair_range<false>(p, a, begin, end);
}

DEMFEM_CLONES void poly_wall_contacts(const PolyParticles& p, const phys::WallView& w,
                                      std::int64_t i, const phys::PairConstants* pc_row, double dt,
                                      bool friction, Vec3& f, Vec3& q, double& mo, double& fmo) {
  const phys::PolyWallParticle pw = phys::poly_wall_particle(p, static_cast<int>(i));
  if (friction)
    phys::poly_wall_contacts<true>(pw, w, i, pc_row, dt, f, q, mo, fmo);
  else
    phys::poly_wall_contacts<false>(pw, w, i, pc_row, dt, f, q, mo, fmo);
}

double poly_kick_drift(const PolyDrift& d) {
  double m2 = 0.0;
  const bool have_build = d.bx != nullptr;
#pragma omp parallel for num_threads(d.threads) schedule(static) reduction(max : m2)
  for (std::int64_t i = 0; i < d.n; ++i) {
    // a frozen particle is held at rest (hold_frozen): not moved, but its distance from the
    // list's build position still counts. Spheres among polyhedra always spin and turn.
    if (d.frozen == nullptr || d.frozen[i] == 0)
      phys::kick_drift(d.motion, i, d.dt, /*spin=*/true, /*turn=*/true);
    if (have_build) {
      const double d2 = phys::displacement2(d.motion, i, d.bx, d.by, d.bz);
      m2 = m2 > d2 ? m2 : d2;
    }
  }
  return have_build ? std::sqrt(m2) : 1e300;
}

}  // namespace demfem::dem::detail
