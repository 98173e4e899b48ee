// DemSystem::Impl and the CUDA backend: the host side of a device step (the views of the
// state and the walls handed to the device; the list the device built, taken over at the end
// of an advance).

#include "dem_system_impl.hpp"

#include <omp.h>

#include <algorithm>

namespace demfem::dem {

void DemSystem::Impl::gpu_wall_kinematics() {
  gpu_vertex_ref.assign(walls.vertex_x.size(), 0.0);
  gpu_vertex_wall.assign(walls.vertex_x.size() / 3, -1);
  for (std::size_t w = 0; w < walls.rigid.size(); ++w) {
    const auto& x0 = walls.rigid[w].mesh.vertices;
    std::copy(x0.begin(), x0.end(), gpu_vertex_ref.begin() + 3 * walls.rigid[w].first_vertex);
    const bool by_loads = walls.rigid[w].body >= 0 || walls.rigid[w].mesh.motion.max_force > 0.0;
    std::fill_n(gpu_vertex_wall.begin() + walls.rigid[w].first_vertex, x0.size() / 3,
                by_loads ? kVertexPlacedByHost : static_cast<std::int32_t>(w));
  }
  if (walls.has_flexible)
    std::copy(walls.flexible_x0.begin(), walls.flexible_x0.end(),
              gpu_vertex_ref.begin() + 3 * walls.flexible.first_vertex);
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
  v.npairs = list.pairs();
  v.row = list.row.data(), v.trow = list.transposed_row.data();
  v.tpair = list.transposed_pair.data(), v.nbr = list.partner.data();
  v.shear = slots.shear.data();
  v.rhist = rolling ? slots.rolling_history.data() : nullptr;
  v.bx = list.update_x.data(), v.by = list.update_y.data(), v.bz = list.update_z.data();
  v.pc = pair_table.data();
  v.nmat = material_count;
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
  if (!walls.empty()) {
    v.nverts = walls.vertex_x.size() / 3, v.ntris = walls.triangle_vertices.size() / 3,
    v.nptri = walls.candidate_triangle.size();
    v.vpos = walls.vertex_x.data(), v.vvel = walls.vertex_v.data();
    v.tri_v = walls.triangle_vertices.data(), v.tri_e = walls.triangle_edges.data(),
    v.tri_mat = walls.triangle_material.data();
    v.tri_wall = walls.triangle_wall.data(), v.prow = walls.candidate_row.data(),
    v.ptri = walls.candidate_triangle.data();
    v.wkey = wall_contacts.key.data(), v.wshear = wall_contacts.shear.data(),
    v.wf = wall_contacts.force.data(), v.wp = wall_contacts.point.data();
    v.wb = wall_contacts.weights.data(), v.wtri = wall_contacts.triangle.data(),
    v.wcount = wall_contacts.count.data();
    if (walls.moving) {
      v.walls_moving = true;
      v.vbuild = walls.vertex_x_at_build.data(), v.vref = gpu_vertex_ref.data(),
      v.vwall = gpu_vertex_wall.data();
      v.motion = walls.motions.data(), v.nwalls = walls.motions.size();
      if (walls.has_flexible) {
        v.flex_vbase = static_cast<std::size_t>(walls.flexible.first_vertex),
        v.flex_nodes = walls.flexible_x0.size() / 3;
        v.flex_v = walls.flexible_v0.data(), v.flex_a = walls.flexible_a0.data(),
        v.flex_force = walls.flexible_force.data();
      }
    }
    v.wroll = rolling ? wall_contacts.rolling_history.data() : nullptr;
  }
  return v;
}

void DemSystem::Impl::adopt_device_list() {
  std::size_t npairs = 0, nptri = 0;
  cuda_list_sizes(gpu, &npairs, &nptri);
  const std::size_t np = n();
  auto& L = list;
  L.row.resize(np + 1), L.partner.resize(npairs);
  L.update_x.resize(np), L.update_y.resize(np), L.update_z.resize(np);
  GpuListDownload dl;
  dl.row = L.row.data(), dl.nbr = L.partner.data(), dl.bx = L.update_x.data();
  dl.by = L.update_y.data(), dl.bz = L.update_z.data();
  if (!walls.empty()) {
    walls.candidate_row.resize(np + 1), walls.candidate_triangle.resize(nptri);
    dl.prow = walls.candidate_row.data(), dl.ptri = walls.candidate_triangle.data();
    if (walls.moving) dl.vbuild = walls.vertex_x_at_build.data();
  }
  cuda_download_lists(gpu, dl);
  if (!walls.empty() && !walls.moving) walls.vertex_x_at_build = walls.vertex_x;
  L.candidate_row = L.row,
  L.candidate_partner = L.partner;  // one level: the candidates are the list
  index_list();
  // the histories come with the state (cuda_download_state), sized as refilter() sizes them
  slots.shear.assign(friction ? 3 * npairs : 0, 0.0);
  slots.rolling_history.assign(rolling ? 3 * npairs : 0, 0.0);
  slots.separating_axis.assign(poly ? 3 * npairs : 0, 0.0);
  slots.closest_features.assign(poly ? 6 * npairs : 0, -1);
  L.build_disp = 0.0, L.build_pair_disp = 0.0;
  L.steps_at_update = steps;
  L.must_build = false;
}

// Before a device step: the walls moved by their loads advanced over it as the CPU step
// advances them (first half kick and drift of the bodies, the limited drift), all walls placed
// at its end time, and the vertices sent to the device (it keeps those of these walls).
void DemSystem::Impl::gpu_place_walls_by_loads() {
  if (!walls.bodies.empty()) walls.bodies.kick_drift(s.dt);
  if (walls.force_limited) walls.advance_drift(t + s.dt, s.dt);
  walls.update(t + s.dt, walls.flexible_tau + s.dt);
  cuda_upload_wall_vertices(gpu, gpu_view());
}

// After a device step: its wall loads summed from its contact slots in the CPU's order
// (WallStore::reduce; the flexible node forces stay the device's), then the CPU step's
// reaction to them.
void DemSystem::Impl::gpu_walls_follow_loads() {
  cuda_download_wall_contacts(gpu, gpu_view());
  walls.reduce(wall_contacts, n(), false, ForceMode::last_substep, 1);
  walls_follow_loads();
}

void DemSystem::Impl::advance_gpu(std::int64_t substeps, ForceMode mode) {
  const double t0 = omp_get_wtime();
  if (walls.has_flexible) {
    std::fill(walls.flexible_force.begin(), walls.flexible_force.end(), 0.0);
    walls.flexible_max_overlap = 0.0;
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
  // list.must_build) or the device does not hold them (the first advance(), one that threw).
  const bool changed =
      list.must_build || list.row.size() != n() + 1 || !list.has_update_positions(n());
  if (changed) rebuild();
  if (walls.moving) gpu_wall_kinematics();
  auto view = [&] {
    GpuHostView v = gpu_view();
    v.flex_average = mode == ForceMode::average;
    v.flex_inv_substeps = 1.0 / static_cast<double>(substeps);
    return v;
  };
  if (changed || !cuda_resident(gpu, n(), list.partner.size())) {
    cuda_upload_state(gpu, view());
    cuda_upload_lists(gpu, view());
  }
  cuda_begin_advance(gpu, view());
  cuda_set_resident(gpu, false);  // until the results are downloaded
  std::int64_t left = substeps;
  double tdet = 0.0;
  bool built_on_device = false;
  // walls moved by their loads: one step per run (correct first; a device reduction and
  // body step would keep the batches)
  const bool by_loads = walls_move_by_loads() && !walls.empty();
  while (left > 0) {
    if (by_loads) gpu_place_walls_by_loads();
    const std::int64_t asked = by_loads ? 1 : left;
    const std::int64_t done = cuda_run_steps(gpu, asked, list.skin, t, walls.flexible_tau, cancel);
    for (std::int64_t k = 0; k < done; ++k)
      t += s.dt, walls.flexible_tau += s.dt;  // the device's sums
    steps += done;
    left -= done;
    if (by_loads && done == asked) gpu_walls_follow_loads();
    check_cancel(substeps - left, substeps);
    // A run ends early for a list build (the drift of the next step done, its forces wait for
    // the new list) or at its batch cap (nothing pending: the loop runs on).
    if (left > 0 && cuda_build_pending(gpu)) {
      const double r0 = omp_get_wtime();
      cuda_build_lists(gpu, list.skin, rmax);  // on the device, from the device's positions
      ++list.builds, ++list.refilters;         // one level: a build is its own refilter
      built_on_device = true;
      tdet += omp_get_wtime() - r0;
      cuda_finish_step(gpu);
      t += s.dt, walls.flexible_tau += s.dt;
      ++steps;
      --left;
      if (by_loads) gpu_walls_follow_loads();
    }
  }
  if (built_on_device) adopt_device_list();
  cuda_download_state(gpu, view());
  cuda_set_resident(gpu, true);
  max_overlap = cuda_max_overlap(gpu);
  advance_max_overlap = cuda_advance_max_overlap(gpu);
  advance_max_relative_overlap = cuda_advance_max_relative_overlap(gpu);
  if (walls.has_flexible) walls.flexible_max_overlap = cuda_flex_max_overlap(gpu);
  if (walls.moving && walls.empty())
    walls.update(t, walls.flexible_tau);  // no triangle on the device
  // Per-wall force and torque of the last step from its contact slots, in the CPU's order
  // (last = false: the flexible node forces came from the device).
  if (!walls.empty()) walls.reduce(wall_contacts, n(), false, ForceMode::last_substep, 1);
  timing.detection += tdet;
  timing.forces += omp_get_wtime() - t0 - tdet;  // device steps are not split further
}

}  // namespace demfem::dem
