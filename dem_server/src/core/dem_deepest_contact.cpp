// DemSystem::deepest_contact: where a blow-up happened. The run's stability guard
// (DemRun::check_stable) knows only the largest overlap over the steps of an advance(); the
// pair kernels keep no argmax (the sphere kernel is a SIMD loop). After the guard has
// stopped a run, this computes every contact once more, on copies of its history, and
// names the deepest one now: a user sees which particles and where, not only that a
// contact overlapped.

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "dem_system_impl.hpp"
#include "demfem/dem/physics/pair.hpp"
#include "demfem/dem/physics/poly_contact.hpp"
#include "demfem/dem/physics/wall_contact.hpp"
#include "polyhedra.hpp"

namespace demfem::dem {

using phys::Vec3;

DeepestContact DemSystem::deepest_contact() const {
  DeepestContact out;
  // const_cast: wall_view() hands out the slots' pointers; every one that a contact writes
  // is pointed at a copy below, so nothing of the system changes
  auto& I = const_cast<Impl&>(*impl_);
  if (I.gpu != nullptr || I.n() == 0) return out;  // the device's list is not on the host
  const auto& st = I.st;
  const phys::ParticleView view = I.particle_view();
  detail::PolyParticles pp = I.poly_particles(view);
  std::vector<double> rot;
  if (I.poly) {  // the rotations of the current orientations (the narrow phase reads them)
    rot.resize(9 * I.n());
    std::vector<double> xprev(3 * I.n()), move(I.n());
    detail::poly_rotations(pp, rot.data(), xprev.data(), move.data(),
                           static_cast<std::int64_t>(I.n()), 1);
    pp.rot = rot.data();
  }
  auto radius = [&](std::int64_t i) {
    return I.poly ? phys::particle_contact_radius(pp, static_cast<int>(i)) : st.radius[i];
  };
  auto consider = [&](double delta, std::int64_t i, std::int64_t j, double rel) {
    if (delta > 0.0 && rel > out.relative)
      out.relative = rel, out.depth = delta, out.particle = i, out.other = j;
  };
  const phys::PeriodicBox* box = I.periodic ? &I.pbox : nullptr;
  const std::int64_t pairs = static_cast<std::int64_t>(I.list.pairs());
  for (std::int64_t k = 0; k < pairs; ++k) {
    const std::int32_t i = I.list.owner[k], j = I.list.partner[k];
    if (!I.frozen.empty() && I.frozen[i] != 0 && I.frozen[j] != 0) continue;  // not computed
    const phys::PairConstants& c =
        I.pair_table[static_cast<std::size_t>(st.material[i]) * I.material_count +
                     st.material[j]];
    Vec3 sh{0, 0, 0}, rh{0, 0, 0}, axis{0, 0, 0}, force, ti, tj;
    int feat[6] = {-1, -1, -1, -1, -1, -1};
    if (I.poly && I.slots.separating_axis.size() == 3 * static_cast<std::size_t>(pairs)) {
      axis = Vec3{I.slots.separating_axis[3 * k], I.slots.separating_axis[3 * k + 1],
                  I.slots.separating_axis[3 * k + 2]};
      std::copy_n(I.slots.closest_features.data() + 6 * k, 6, feat);
    }
    double delta = 0.0;
    if (I.poly) {
      delta = phys::mixed_pair<false>(pp, i, j, c, I.s.dt, false, sh, rh, axis, feat, force, ti,
                                      tj, nullptr, box);
    } else {
      phys::ContactResult r;
      phys::sphere_sphere<false>(view, i, j, c, I.s.dt, sh, rh, r, delta, box);
    }
    consider(delta, i, j, phys::relative_overlap(delta, radius(i), radius(j)));
  }
  if (!I.walls.empty()) {
    detail::WallContactSlots wc = I.wall_contacts;  // the copies the wall contacts write
    phys::WallView wv = I.wall_view();
    wv.wkey = wc.key.data(), wv.wshear = wc.shear.data(), wv.wf = wc.force.data();
    wv.wp = wc.point.data(), wv.wb = wc.weights.data(), wv.wtri = wc.triangle.data();
    wv.wcount = wc.count.data();
    wv.wroll = I.rolling ? wc.rolling_history.data() : nullptr;
    for (std::int64_t i = 0; i < static_cast<std::int64_t>(I.n()); ++i) {
      if (wv.prow[i] == wv.prow[i + 1] && wv.wcount[i] == 0) continue;
      Vec3 f{0, 0, 0}, q{0, 0, 0};
      double wmo = 0.0, fmo = 0.0;
      const phys::PairConstants* row = I.pair_table.data() + st.material[i] * I.material_count;
      if (I.poly && st.shape_id[i] >= 0)
        detail::poly_wall_contacts(pp, wv, i, row, I.s.dt, false, f, q, wmo, fmo);
      else
        phys::wall_contacts<false>(view, wv, i, row, I.s.dt, f, q, wmo, fmo);
      const double rc = radius(i);
      consider(wmo, i, -1, phys::relative_overlap(wmo, rc, rc));
      if (out.particle == i && out.other == -1) {  // the walls its contacts touch
        out.walls.clear();
        for (int s = 0; s < wv.wcount[i]; ++s) {
          const std::int32_t tri = wv.wtri[i * phys::kMaxWallContacts + s];
          const std::int32_t w = tri >= 0 ? wv.tri_wall[tri] : -1;
          const std::string name = w >= 0 ? I.walls.rigid[w].mesh.name : "the coupled mesh";
          if (std::find(out.walls.begin(), out.walls.end(), name) == out.walls.end())
            out.walls.push_back(name);
        }
      }
    }
  }
  return out;
}

}  // namespace demfem::dem
