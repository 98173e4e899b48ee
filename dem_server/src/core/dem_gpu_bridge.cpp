// DemSystem::Impl and the CUDA backend: the host side of a device step (the views of the
// state and the walls handed to the device; the list the device built, taken over at the end
// of an advance).

#include "dem_system_impl.hpp"

#include <omp.h>

#include <algorithm>

namespace demfem::dem {

void DemSystem::Impl::gpu_wall_kinematics() {
  gpu_vref.assign(vpos.size(), 0.0);
  gpu_vwall.assign(vpos.size() / 3, -1);
  for (std::size_t w = 0; w < walls.size(); ++w) {
    const auto& x0 = walls[w].mesh.vertices;
    std::copy(x0.begin(), x0.end(), gpu_vref.begin() + 3 * walls[w].vbase);
    std::fill_n(gpu_vwall.begin() + walls[w].vbase, x0.size() / 3, static_cast<std::int32_t>(w));
  }
  if (has_flex) std::copy(flex_x.begin(), flex_x.end(), gpu_vref.begin() + 3 * flex.vbase);
}

GpuHostView DemSystem::Impl::gpu_view() {
  GpuHostView v;
  v.n = n();
  v.px = st.px.data(), v.py = st.py.data(), v.pz = st.pz.data();
  v.vx = st.vx.data(), v.vy = st.vy.data(), v.vz = st.vz.data();
  v.wx = st.wx.data(), v.wy = st.wy.data(), v.wz = st.wz.data();
  v.qw = st.qw.data(), v.qx = st.qx.data(), v.qy = st.qy.data(), v.qz = st.qz.data();
  v.fx = st.fx.data(), v.fy = st.fy.data(), v.fz = st.fz.data();
  v.tx = tx.data(), v.ty = ty.data(), v.tz = tz.data();
  v.radius = st.radius.data(), v.mass = st.mass.data(), v.inertia = st.inertia.data();
  v.material = st.material.data();
  v.npairs = nbr.size();
  v.row = row.data(), v.trow = trow.data(), v.tpair = tpair.data(), v.nbr = nbr.data();
  v.shear = slots.shear.data();
  v.rhist = rolling ? slots.rolling_history.data() : nullptr;
  v.bx = bx.data(), v.by = by.data(), v.bz = bz.data();
  v.pc = pc.data();
  v.nmat = nmat;
  v.dt = s.dt;
  for (int k = 0; k < 3; ++k) v.gravity[k] = s.gravity[k];
  v.friction = friction, v.rolling = rolling;
  v.orientation = orientation;
  if (poly) {
    const auto& a = shapes.arrays();
    v.poly = true;
    v.nshapes = a.nv.size(), v.nshape_verts = a.vert.size() / 3;
    v.nshape_faces = a.flen.size(), v.nshape_fverts = a.fvert.size();
    v.nshape_edges = a.edge.size() / 2;
    v.vbase = a.vbase.data(), v.snv = a.nv.data(), v.fbase = a.fbase.data(), v.snf = a.nf.data();
    v.floop = a.floop.data(), v.flen = a.flen.data(), v.fvert = a.fvert.data();
    v.ebase = a.ebase.data(), v.sne = a.ne.data(), v.edge = a.edge.data();
    v.vert = a.vert.data(), v.fnormal = a.fnormal.data(), v.dilation = a.dilation.data();
    v.bound = a.bound.data();
    v.shape_id = st.shape_id.data(), v.scale = st.scale.data();
    v.ix = st.ix.data(), v.iy = st.iy.data(), v.iz = st.iz.data();
    v.ptj = slots.torque_j.data();
    v.paxis = slots.separating_axis.data();
    v.pfeat = slots.closest_features.data();
  }
  if (periodic) v.periodic = true, v.pbox = pbox, v.image = image.data();
  if (!frozen_idx.empty()) {
    v.nfrozen = frozen_idx.size(), v.frozen = frozen.data();
    v.frozen_idx = frozen_idx.data(), v.frozen_hold = frozen_hold.data();
  }
  if (!tri_v.empty()) {
    v.nverts = vpos.size() / 3, v.ntris = tri_v.size() / 3, v.nptri = ptri.size();
    v.vpos = vpos.data(), v.vvel = vvel.data();
    v.tri_v = tri_v.data(), v.tri_e = tri_e.data(), v.tri_mat = tri_mat.data();
    v.tri_wall = tri_wall.data(), v.prow = prow.data(), v.ptri = ptri.data();
    v.wkey = wkey.data(), v.wshear = wshear.data(), v.wf = wf.data(), v.wp = wp.data();
    v.wb = wb.data(), v.wtri = wtri.data(), v.wcount = wcount.data();
    if (walls_moving) {
      v.walls_moving = true;
      v.vbuild = vbuild.data(), v.vref = gpu_vref.data(), v.vwall = gpu_vwall.data();
      v.motion = wall_motions.data(), v.nwalls = wall_motions.size();
      if (has_flex) {
        v.flex_vbase = static_cast<std::size_t>(flex.vbase), v.flex_nodes = flex_x.size() / 3;
        v.flex_v = flex_v.data(), v.flex_a = flex_a.data(), v.flex_force = flex_force.data();
      }
    }
    v.wroll = rolling ? wroll.data() : nullptr;
  }
  return v;
}

void DemSystem::Impl::adopt_device_list() {
  std::size_t npairs = 0, nptri = 0;
  cuda_list_sizes(gpu, &npairs, &nptri);
  const std::size_t np = n();
  row.resize(np + 1), nbr.resize(npairs), bx.resize(np), by.resize(np), bz.resize(np);
  GpuListDownload dl;
  dl.row = row.data(), dl.nbr = nbr.data(), dl.bx = bx.data(), dl.by = by.data();
  dl.bz = bz.data();
  if (!tri_v.empty()) {
    prow.resize(np + 1), ptri.resize(nptri);
    dl.prow = prow.data(), dl.ptri = ptri.data();
    if (walls_moving) dl.vbuild = vbuild.data();
  }
  cuda_download_lists(gpu, dl);
  if (!tri_v.empty() && !walls_moving) vbuild = vpos;
  orow = row, onbr = nbr;  // one level: the candidates are the list
  index_list();
  // the histories come with the state (cuda_download_state), sized as refilter() sizes them
  slots.shear.assign(friction ? 3 * npairs : 0, 0.0);
  slots.rolling_history.assign(rolling ? 3 * npairs : 0, 0.0);
  slots.separating_axis.assign(poly ? 3 * npairs : 0, 0.0);
  slots.closest_features.assign(poly ? 6 * npairs : 0, -1);
  out_disp = 0.0, out_pair = 0.0;
  steps_at_update = steps;
  need_rebuild = false;
}

void DemSystem::Impl::advance_gpu(std::int64_t substeps, ForceMode mode) {
  const double t0 = omp_get_wtime();
  if (has_flex) {
    std::fill(flex_force.begin(), flex_force.end(), 0.0);
    flex_max_ov = 0.0;
  }
  if (n() == 0) {  // nothing for the device: the CPU step moves the walls and the clock
    for (std::int64_t k = 0; k < substeps; ++k)
      friction ? step<true>(k + 1 == substeps, mode, substeps)
               : step<false>(k + 1 == substeps, mode, substeps);
    return;
  }
  if (periodic) check_periods();
  // The state and the list stay on the device from one advance() to the next: they are
  // uploaded when the host changed them (every change of particles, walls or state sets
  // need_rebuild) or the device does not hold them (the first advance(), one that threw).
  const bool changed = need_rebuild || row.size() != n() + 1 || bx.size() != n();
  if (changed) rebuild();
  if (walls_moving) gpu_wall_kinematics();
  auto view = [&] {
    GpuHostView v = gpu_view();
    v.flex_average = mode == ForceMode::average;
    v.flex_inv_substeps = 1.0 / static_cast<double>(substeps);
    return v;
  };
  if (changed || !cuda_resident(gpu, n(), nbr.size())) {
    cuda_upload_state(gpu, view());
    cuda_upload_lists(gpu, view());
  }
  cuda_begin_advance(gpu, view());
  cuda_set_resident(gpu, false);  // until the results are downloaded
  std::int64_t left = substeps;
  double tdet = 0.0;
  bool built_on_device = false;
  while (left > 0) {
    const std::int64_t done = cuda_run_steps(gpu, left, skin, t, flex_tau, cancel);
    for (std::int64_t k = 0; k < done; ++k) t += s.dt, flex_tau += s.dt;  // the device's sums
    steps += done;
    left -= done;
    check_cancel(substeps - left, substeps);
    if (left > 0) {  // drift of the next step done, forces wait for the new list
      const double r0 = omp_get_wtime();
      cuda_build_lists(gpu, skin, rmax);  // on the device, from the device's positions
      ++rebuilds, ++refilters;            // one level: a build is its own refilter
      built_on_device = true;
      tdet += omp_get_wtime() - r0;
      cuda_finish_step(gpu);
      t += s.dt, flex_tau += s.dt;
      ++steps;
      --left;
    }
  }
  if (built_on_device) adopt_device_list();
  cuda_download_state(gpu, view());
  cuda_set_resident(gpu, true);
  max_ov = cuda_max_overlap(gpu);
  adv_max_ov = cuda_advance_max_overlap(gpu);
  adv_max_rel = cuda_advance_max_relative_overlap(gpu);
  if (has_flex) flex_max_ov = cuda_flex_max_overlap(gpu);
  if (walls_moving && tri_v.empty()) update_walls(t, flex_tau);  // no triangle on the device
  // Per-wall force and torque of the last step from its contact slots, in the CPU's order
  // (last = false: the flexible node forces came from the device).
  if (!tri_v.empty()) wall_reduce(false, ForceMode::last_substep, 1);
  timing.detection += tdet;
  timing.forces += omp_get_wtime() - t0 - tdet;  // device steps are not split further
}

}  // namespace demfem::dem
