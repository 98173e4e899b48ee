// DemSystem::Impl: one time step on the CPU: half kick and drift, wall kinematics, list
// update, the force pass (pair forces into per-pair slots, gathered in a fixed order, then
// the second half kick) and the wall loads.

#include "dem_system_impl.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "demfem/dem/physics/geometry.hpp"
#include "demfem/dem/physics/step_integrator.hpp"
#include "multiversion.hpp"

namespace demfem::dem {

using detail::OverlapMax;
using phys::Vec3;

namespace {

// The wall contacts of one particle, not inlined into the gather: most particles have none,
// and inlined, their code (a 1.6 kB stack frame, many live values) made the gather's slot
// sums spill and every particle pay its prologue.
template <bool Friction>
[[gnu::noinline]] void wall_contacts_apart(const phys::ParticleView& p, const phys::WallView& w,
                                           std::int64_t i, const phys::PairConstants* pc_row,
                                           double dt, Vec3& f, Vec3& q, double& mo, double& fmo) {
  phys::wall_contacts<Friction>(p, w, i, pc_row, dt, f, q, mo, fmo);
}

// ---------------------------------------------------------------------------------------
// Pair forces over a range of the flat pair list, one pair per SIMD lane: the contact law
// (physics/pair.hpp, contact.hpp) has no data-dependent branch, so the loop vectorises.
// On x86-64 (GCC/Clang, not under nvcc) the loop is compiled for the baseline (SSE2), for
// AVX2 and, with GCC, for x86-64-v4 (AVX-512: 32 vector registers, so the long law spills
// less; measured 7-12 % faster than AVX2 on a Xeon with both), and the loader picks the clone
// the CPU supports. Without FMA contraction every clone rounds each operation as the scalar
// code does (IEEE +, -, *, /, sqrt), so the clones give bitwise identical results (checked:
// a build without clones gives the same bits).
struct PairKernelArgs {
  phys::ParticleView view;
  const std::int32_t* pi;  // i of each pair
  const std::int32_t* pj;  // j of each pair
  const std::int32_t* mat;
  const phys::PairConstants* pc;  // table (nmat x nmat) or, when uniform, the one entry
  std::size_t nmat;
  double dt;
  double* shear;  // 3 per pair
  double* pf;     // 3 per pair
  double* pt;     // 3 per pair (Friction)
  double* pr;     // 3 per pair (Rolling)
  double* rhist;  // 3 per pair (Rolling): rolling-torque history
  const phys::PeriodicBox* box;  // Periodic: the periods (j at its image nearest to i)
};

template <bool Friction, bool Rolling, bool Uniform, bool Periodic = false>
[[gnu::always_inline]] inline OverlapMax pair_loop(const PairKernelArgs& a, std::int64_t begin,
                                                   std::int64_t end) {
  double mo = 0.0, mr = 0.0;
  const phys::ParticleView view = a.view;
  const std::int32_t* pi = a.pi;
  const std::int32_t* pj = a.pj;
  double* shear = a.shear;
  double* pf = a.pf;
  double* pt = a.pt;
  double* pr = a.pr;
  double* rhist = a.rhist;
  const double dt = a.dt;
  const phys::PeriodicBox* box = a.box;
#pragma omp simd reduction(max : mo, mr)
  for (std::int64_t p = begin; p < end; ++p) {
    const std::int32_t i = pi[p], j = pj[p];
    const phys::PairConstants& c =
        Uniform ? a.pc[0] : a.pc[static_cast<std::size_t>(a.mat[i]) * a.nmat + a.mat[j]];
    Vec3 sh{0, 0, 0};
    if constexpr (Friction) sh = Vec3{shear[3 * p], shear[3 * p + 1], shear[3 * p + 2]};
    Vec3 rh{0, 0, 0};
    if constexpr (Rolling) rh = Vec3{rhist[3 * p], rhist[3 * p + 1], rhist[3 * p + 2]};
    phys::ContactResult r;
    double delta;
    phys::sphere_sphere_select<Friction, Rolling, Periodic>(view, i, j, c, dt, sh, rh, r, delta,
                                                            box);
    mo = mo > delta ? mo : delta;
    const double rel = phys::relative_overlap(delta, view.radius[i], view.radius[j]);
    mr = mr > rel ? mr : rel;
    pf[3 * p] = r.force.x, pf[3 * p + 1] = r.force.y, pf[3 * p + 2] = r.force.z;
    if constexpr (Friction) {
      shear[3 * p] = sh.x, shear[3 * p + 1] = sh.y, shear[3 * p + 2] = sh.z;
      pt[3 * p] = r.torque.x, pt[3 * p + 1] = r.torque.y, pt[3 * p + 2] = r.torque.z;
      if constexpr (Rolling) {
        pr[3 * p] = r.roll.x, pr[3 * p + 1] = r.roll.y, pr[3 * p + 2] = r.roll.z;
        rhist[3 * p] = rh.x, rhist[3 * p + 1] = rh.y, rhist[3 * p + 2] = rh.z;
      }
    }
  }
  return OverlapMax{mo, mr};
}

#define DEMFEM_PAIR_KERNEL(F, R, U, P)                                                   \
  DEMFEM_CLONES OverlapMax pair_kernel_##F##R##U##P(const PairKernelArgs& a, std::int64_t b, \
                                                    std::int64_t e) {                        \
    return pair_loop<F != 0, R != 0, U != 0, P != 0>(a, b, e);                               \
  }
DEMFEM_PAIR_KERNEL(0, 0, 0, 0)
DEMFEM_PAIR_KERNEL(0, 0, 1, 0)
DEMFEM_PAIR_KERNEL(1, 0, 0, 0)
DEMFEM_PAIR_KERNEL(1, 0, 1, 0)
DEMFEM_PAIR_KERNEL(1, 1, 0, 0)
DEMFEM_PAIR_KERNEL(1, 1, 1, 0)
// periodic systems (one material table lookup per pair: no uniform variant)
DEMFEM_PAIR_KERNEL(0, 0, 0, 1)
DEMFEM_PAIR_KERNEL(1, 0, 0, 1)
DEMFEM_PAIR_KERNEL(1, 1, 0, 1)
#undef DEMFEM_PAIR_KERNEL

using PairKernel = OverlapMax (*)(const PairKernelArgs&, std::int64_t, std::int64_t);
PairKernel pick_pair_kernel(bool friction, bool rolling, bool uniform, bool periodic) {
  if (periodic) {
    if (!friction) return pair_kernel_0001;
    return rolling ? pair_kernel_1101 : pair_kernel_1001;
  }
  if (!friction) return uniform ? pair_kernel_0010 : pair_kernel_0000;
  if (!rolling) return uniform ? pair_kernel_1010 : pair_kernel_1000;
  return uniform ? pair_kernel_1110 : pair_kernel_1100;
}

}  // namespace

template <bool Friction, bool Poly>
void DemSystem::Impl::forces_and_kick() {
  const std::int64_t sn = static_cast<std::int64_t>(n());
  PairKernelArgs a{};
  a.view = particle_view();
  a.pi = list.owner.data();
  a.pj = list.partner.data();
  a.mat = st.material.data();
  a.pc =
      uniform_mat >= 0 ? pair_table.data() + uniform_mat * (material_count + 1) : pair_table.data();
  a.nmat = material_count;
  a.dt = s.dt;
  a.shear = slots.shear.data();
  a.pf = slots.force.data();
  a.pt = slots.torque.data();
  a.pr = slots.rolling_torque.data();
  a.rhist = slots.rolling_history.data();
  a.box = periodic ? &pbox : nullptr;
  // a periodic system's kernels look the pair constants up per pair (a.pc the whole table)
  if (periodic) a.pc = pair_table.data();
  const PairKernel kern =
      pick_pair_kernel(Friction, Friction && rolling, uniform_mat >= 0, periodic);
  detail::PolyParticles pp{};
  detail::PolyPairs pa{};
  if constexpr (Poly) {
    pp = poly_particles(a.view);
    // the separation proofs of the last pass hold when it was this step's predecessor and
    // the list has not been updated since (a build or refilter renumbers the pairs)
    const bool proven = proofs.step == steps && list.steps_at_update < steps &&
                        proofs.separation_left.size() == list.pairs() &&
                        proofs.rotation.size() == 9 * n() && proofs.position.size() == 3 * n();
    if (!proven) proofs.separation_left.assign(list.pairs(), -1.0);
    proofs.rotation.resize(9 * n());
    proofs.position.resize(3 * n());
    proofs.core_motion.resize(n());
    detail::poly_rotations(pp, proofs.rotation.data(), proofs.position.data(),
                           proofs.core_motion.data(), sn, nt());
    pp.rot = proofs.rotation.data();
    pa = detail::PolyPairs{list.owner.data(),
                           list.partner.data(),
                           st.material.data(),
                           pair_table.data(),
                           material_count,
                           s.dt,
                           Friction,
                           rolling,
                           slots.shear.data(),
                           slots.rolling_history.data(),
                           slots.force.data(),
                           slots.torque.data(),
                           slots.torque_j.data(),
                           slots.separating_axis.data(),
                           slots.closest_features.data(),
                           proofs.separation_left.data(),
                           proofs.core_motion.data()};
    if (!frozen_idx.empty()) pa.frozen = frozen.data();
    if (periodic) pa.box = &pbox;
  }

  const double g[3] = {s.gravity[0], s.gravity[1], s.gravity[2]};
  const phys::MotionArrays motion = motion_arrays();
  const bool walls_on = !walls.empty();
  const phys::WallView wv = wall_view();
  const phys::ParticleView& view = a.view;
  const double* PF = slots.force.data();
  const double* PT = slots.torque.data();
  const double* PR = slots.rolling_torque.data();
  const double* PTJ = slots.torque_j.data();
  const bool roll = rolling;
  auto gather = [&](std::int64_t i, double& mo, double& mr, double& fmo) {
    double fx = 0, fy = 0, fz = 0;
    double qx = 0, qy = 0, qz = 0;
    const double ri = st.radius[i];
    // own row (pairs i < j) in row order, then the transposed pairs (j < i) in order
    // x + (-1 y) is x - y exactly: the sums are those of a loop over each part
    for (std::int64_t k = list.gather_row[i]; k < list.gather_row[i + 1]; ++k) {
      const std::int64_t p = list.gather_pair[k];
      const double sg = list.gather_sign[k];
      fx += sg * PF[3 * p], fy += sg * PF[3 * p + 1], fz += sg * PF[3 * p + 2];
      if constexpr (Poly) {
        const double* T = sg > 0.0 ? PT : PTJ;
        qx += T[3 * p], qy += T[3 * p + 1], qz += T[3 * p + 2];
      } else if constexpr (Friction) {
        qx += ri * PT[3 * p], qy += ri * PT[3 * p + 1], qz += ri * PT[3 * p + 2];
        if (roll) qx += sg * PR[3 * p], qy += sg * PR[3 * p + 1], qz += sg * PR[3 * p + 2];
      }
    }
    if (walls_on && (wv.prow[i] != wv.prow[i + 1] || wv.wcount[i] != 0)) {
      Vec3 f{fx, fy, fz}, q{qx, qy, qz};
      double wmo = 0.0;  // this particle's deepest wall contact
      double rc = ri;    // and its contact radius
      if (Poly && st.shape_id[i] >= 0) {
        detail::poly_wall_contacts(pp, wv, i, pair_table.data() + st.material[i] * material_count,
                                   s.dt, Friction, f, q, wmo, fmo);
        rc = phys::particle_contact_radius(pp, static_cast<int>(i));
      } else {
        wall_contacts_apart<Friction>(
            view, wv, i, pair_table.data() + st.material[i] * material_count, s.dt, f, q, wmo, fmo);
      }
      mo = std::max(mo, wmo);
      mr = std::max(mr, phys::relative_overlap(wmo, rc, rc));
      fx = f.x, fy = f.y, fz = f.z;
      qx = q.x, qy = q.y, qz = q.z;
    }
    // spheres among polyhedra always spin: a pair torque may come from a polyhedron
    phys::finish_kick(motion, i, Vec3{fx, fy, fz}, Vec3{qx, qy, qz}, g[0], g[1], g[2], s.dt,
                      Poly || Friction);
  };
  constexpr std::int64_t kBlock = 256;  // particles per block: ~1500 pairs, ~150 kB of slots
  const int T = nt();
  balance.ensure(T, sn);
  for (auto& queue : balance.waiting) queue.clear();
  double mo = 0.0, mr = 0.0, fmo = 0.0;
  int active = T;
#pragma omp parallel num_threads(T) reduction(max : mo, mr, fmo)
  {
    const int k = omp_get_thread_num(), nth = omp_get_num_threads();
    // fewer threads than asked (a nested region, a thread limit): equal ranges
    if (k == 0) active = nth;
    const double start = omp_get_wtime();
    const std::int64_t lo = nth == T ? balance.split[k] : sn * k / nth;
    const std::int64_t hi = nth == T ? balance.split[k + 1] : sn * (k + 1) / nth;
    const std::int64_t* trow = list.transposed_row.data();
    const std::int32_t* towner = list.transposed_owner.data();
    auto waits = [&](std::int64_t i) { return trow[i] < trow[i + 1] && towner[trow[i]] < lo; };
    std::vector<std::int64_t>& waiting = balance.waiting[k];
    for (std::int64_t b0 = lo; b0 < hi; b0 += kBlock) {
      const std::int64_t b1 = std::min(hi, b0 + kBlock);
      const OverlapMax m = [&] {
        if constexpr (Poly)
          return detail::poly_pair_forces(pp, pa, list.row[b0], list.row[b1]);
        else
          return kern(a, list.row[b0], list.row[b1]);
      }();
      mo = std::max(mo, m.abs), mr = std::max(mr, m.rel);
      for (std::int64_t i = b0; i < b1; ++i)
        if (waits(i))
          waiting.push_back(i);
        else
          gather(i, mo, mr, fmo);
    }
    balance.busy[k] = omp_get_wtime() - start;
#pragma omp barrier
    // the waiting particles of all threads, shared out evenly (each gather is independent)
    std::int64_t total = 0;
    for (const auto& queue : balance.waiting) total += static_cast<std::int64_t>(queue.size());
    const std::int64_t w0 = total * k / nth, w1 = total * (k + 1) / nth;
    std::int64_t base = 0;
    for (std::size_t th = 0; th < balance.waiting.size() && base < w1; ++th) {
      const auto& queue = balance.waiting[th];
      const std::int64_t len = static_cast<std::int64_t>(queue.size());
      for (std::int64_t m = std::max(w0, base); m < std::min(w1, base + len); ++m)
        gather(queue[m - base], mo, mr, fmo);
      base += len;
    }
  }
  if (active == T) balance.adapt();
  if constexpr (Poly) proofs.step = steps + 1;
  max_overlap = mo;
  advance_max_overlap = std::max(advance_max_overlap, mo);
  advance_max_relative_overlap = std::max(advance_max_relative_overlap, mr);
  walls.flexible_max_overlap = std::max(walls.flexible_max_overlap, fmo);
}

phys::ParticleView DemSystem::Impl::particle_view() const {
  return phys::ParticleView{st.px.data(), st.py.data(),     st.pz.data(),  st.vx.data(),
                            st.vy.data(), st.vz.data(),     st.wx.data(),  st.wy.data(),
                            st.wz.data(), st.radius.data(), st.mass.data()};
}

detail::PolyParticles DemSystem::Impl::poly_particles(const phys::ParticleView& view) const {
  return detail::PolyParticles{view,
                               st.qw.data(),
                               st.qx.data(),
                               st.qy.data(),
                               st.qz.data(),
                               st.ix.data(),
                               st.iy.data(),
                               st.iz.data(),
                               st.inertia.data(),
                               st.scale.data(),
                               st.shape_id.data(),
                               shapes.view()};
}

phys::MotionArrays DemSystem::Impl::motion_arrays() {
  const bool rigid = poly;  // the principal moments and shapes exist in systems with polyhedra
  return phys::MotionArrays{st.px.data(),
                            st.py.data(),
                            st.pz.data(),
                            st.vx.data(),
                            st.vy.data(),
                            st.vz.data(),
                            st.wx.data(),
                            st.wy.data(),
                            st.wz.data(),
                            st.qw.data(),
                            st.qx.data(),
                            st.qy.data(),
                            st.qz.data(),
                            st.fx.data(),
                            st.fy.data(),
                            st.fz.data(),
                            tx.data(),
                            ty.data(),
                            tz.data(),
                            st.mass.data(),
                            st.inertia.data(),
                            rigid ? st.ix.data() : nullptr,
                            rigid ? st.iy.data() : nullptr,
                            rigid ? st.iz.data() : nullptr,
                            rigid ? st.shape_id.data() : nullptr};
}

double DemSystem::Impl::poly_kick_drift() {
  const bool have_build = list.has_update_positions(n());
  detail::PolyDrift d{static_cast<std::int64_t>(n()),
                      s.dt,
                      nt(),
                      motion_arrays(),
                      have_build ? list.update_x.data() : nullptr,
                      have_build ? list.update_y.data() : nullptr,
                      have_build ? list.update_z.data() : nullptr};
  d.frozen = frozen_idx.empty() ? nullptr : frozen.data();
  return detail::poly_kick_drift(d);
}

phys::WallView DemSystem::Impl::wall_view() {
  detail::WallContactSlots& wc = wall_contacts;
  phys::WallView v{walls.vertex_x.data(),
                   walls.vertex_v.data(),
                   walls.triangle_vertices.data(),
                   walls.triangle_edges.data(),
                   walls.triangle_material.data(),
                   walls.triangle_wall.data(),
                   walls.candidate_row.data(),
                   walls.candidate_triangle.data(),
                   wc.key.data(),
                   wc.shear.data(),
                   wc.force.data(),
                   wc.point.data(),
                   wc.weights.data(),
                   wc.triangle.data(),
                   wc.count.data()};
  v.wroll = rolling ? wc.rolling_history.data() : nullptr;
  if (walls.moving && !walls.motions.empty()) v.motion = walls.motions.data(), v.time = t;
  return v;
}

template <bool Friction>
double DemSystem::Impl::kick_drift() {
  if (poly) return poly_kick_drift();
  const std::int64_t sn = static_cast<std::int64_t>(n());
  const double dt = s.dt, h = 0.5 * s.dt;
  double m2 = 0.0, w2max = 0.0;
  const bool have_build = list.has_update_positions(n());
  const phys::MotionArrays m = motion_arrays();
  const double *Tx = tx.data(), *Ty = ty.data(), *Tz = tz.data();
  const double *Bx = list.update_x.data(), *By = list.update_y.data(), *Bz = list.update_z.data();
  const double *wx = st.wx.data(), *wy = st.wy.data(), *wz = st.wz.data();
  // phys::kick_drift less the turn, which a second loop gives below
#pragma omp parallel for simd num_threads(nt()) schedule(static) reduction(max : m2, w2max)
  for (std::int64_t i = 0; i < sn; ++i) {
    phys::kick_drift_translation(m, i, dt);
    if constexpr (Friction) phys::kick_sphere_spin(m, i, Tx[i], Ty[i], Tz[i], h);
    const double w2 = wx[i] * wx[i] + wy[i] * wy[i] + wz[i] * wz[i];
    w2max = w2max > w2 ? w2max : w2;
    if (have_build) {
      const double d2 = phys::displacement2(m, i, Bx, By, Bz);
      m2 = m2 > d2 ? m2 : d2;
    }
  }
  if (!orientation) return have_build ? std::sqrt(m2) : 1e300;
  double *qw = st.qw.data(), *qx = st.qx.data(), *qy = st.qy.data(), *qz = st.qz.data();
  if (phys::small_rotation(w2max, dt)) {
#pragma omp parallel for simd num_threads(nt()) schedule(static)
    for (std::int64_t i = 0; i < sn; ++i) {
      double q0 = qw[i], q1 = qx[i], q2 = qy[i], q3 = qz[i];  // registers, not memory
      phys::rotate_quaternion_small(q0, q1, q2, q3, wx[i], wy[i], wz[i], dt);
      qw[i] = q0, qx[i] = q1, qy[i] = q2, qz[i] = q3;
    }
  } else {
#pragma omp parallel for num_threads(nt()) schedule(static)
    for (std::int64_t i = 0; i < sn; ++i)
      phys::rotate_quaternion(qw[i], qx[i], qy[i], qz[i], wx[i], wy[i], wz[i], dt);
  }
  return have_build ? std::sqrt(m2) : 1e300;
}

void DemSystem::Impl::refresh_frozen() {
  frozen_idx.clear();
  frozen_hold.clear();
  for (std::size_t i = 0; i < frozen.size(); ++i) {
    if (frozen[i] == 0) continue;
    frozen_idx.push_back(static_cast<std::int64_t>(i));
    frozen_hold.insert(frozen_hold.end(),
                       {st.px[i], st.py[i], st.pz[i], st.qw[i], st.qx[i], st.qy[i], st.qz[i]});
  }
}

void DemSystem::Impl::hold_frozen() {
  const phys::MotionArrays m = motion_arrays();
  for (std::size_t k = 0; k < frozen_idx.size(); ++k)
    phys::hold_pose(m, frozen_idx[k], frozen_hold.data() + 7 * k);
}

void DemSystem::Impl::rebuild() {
  list.build(list_particles(), rmax);
  list.adapt_inner_skin(steps, fixed_inner_skin(), true);
  // triangles: binned into the particle cells their AABB (grown by rmax + skin) touches
  walls.bin_triangles(list.grid, list.cell, list_particles(), rmax, list.skin);
  walls.vertex_x_at_build = walls.vertex_x;
  list.must_build = false;
  refilter();
}

void DemSystem::Impl::refilter() {
  list.refilter(list_particles(), slots, detail::CarriedHistory{friction, rolling, poly});
  index_list();
}

void DemSystem::Impl::index_list() {
  const std::size_t np = n(), npair = list.pairs();
  list.index(np, nt());
  uniform_mat = np > 0 ? st.material[0] : -1;
  for (std::size_t i = 0; i < np && uniform_mat >= 0; ++i)
    if (st.material[i] != uniform_mat) uniform_mat = -1;
  slots.force.assign(3 * npair, 0.0);
  if (friction || poly)
    slots.torque.assign(3 * npair, 0.0);
  else
    slots.torque.clear();
  if (poly)
    slots.torque_j.assign(3 * npair, 0.0);
  else
    slots.torque_j.clear();
  if (rolling)
    slots.rolling_torque.assign(3 * npair, 0.0);
  else
    slots.rolling_torque.clear();
}

void DemSystem::Impl::walls_follow_loads() {
  if (walls.force_limited) walls.decide_drift();
  if (!walls.bodies.empty()) {
    for (const auto& w : walls.rigid)
      if (w.body >= 0) walls.bodies.set_loads(w.body, w.force, w.torque);
    walls.bodies.kick(s.dt);
  }
}

template <bool Friction>
void DemSystem::Impl::step(bool last, ForceMode mode, std::int64_t substeps) {
  const double t0 = omp_get_wtime();
  const double disp = kick_drift<Friction>();
  if (!frozen_idx.empty()) hold_frozen();
  if (periodic && wrap_positions() && !walls.empty()) list.must_build = true;
  if (!walls.bodies.empty()) walls.bodies.kick_drift(s.dt);
  t += s.dt;
  walls.flexible_tau += s.dt;
  if (walls.force_limited) walls.advance_drift(t, s.dt);
  double wdisp = 0.0;
  if (walls.moving) {
    walls.update(t, walls.flexible_tau);
    wdisp = walls.displacement();
  }
  const double t1 = omp_get_wtime();
  switch (list.next_update(list_particles(), disp, wdisp, steps, fixed_inner_skin())) {
    case detail::NeighbourList::Update::build:
      rebuild();
      break;
    case detail::NeighbourList::Update::refilter:
      refilter();
      break;
    case detail::NeighbourList::Update::none:
      break;
  }
  const double t2 = omp_get_wtime();
  if (poly)
    forces_and_kick<Friction, true>();
  else
    forces_and_kick<Friction>();
  if (!frozen_idx.empty()) hold_frozen();  // their second half kick undone
  // Wall forces and torques are read after advance(): summed at its last step only. The
  // flexible mesh's node forces are summed every substep when they are averaged, and the
  // rigid bodies' loads every substep (they move by them), and so the loads of force-limited
  // walls (their drift goes on by them).
  if (!walls.empty() && (last || (walls.has_flexible && mode == ForceMode::average) ||
                         !walls.bodies.empty() || walls.force_limited))
    walls.reduce(wall_contacts, n(), last, mode, substeps);
  walls_follow_loads();
  ++steps;
  const double t3 = omp_get_wtime();
  timing.integration += t1 - t0;
  timing.detection += t2 - t1;
  timing.forces += t3 - t2;
}

// advance() and the CUDA bridge pick the instance by whether some pair has friction.
template void DemSystem::Impl::step<false>(bool, ForceMode, std::int64_t);
template void DemSystem::Impl::step<true>(bool, ForceMode, std::int64_t);

}  // namespace demfem::dem
