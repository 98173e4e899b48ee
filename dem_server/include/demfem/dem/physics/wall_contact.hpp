#pragma once
// Contacts of one sphere with the triangles of all walls (rigid and flexible), shared by
// both backends. Each contact is counted once across neighbouring triangles:
//   * a face contact always counts;
//   * an edge contact counts unless a triangle having that edge touches with its face, and
//     once per edge id;
//   * a vertex contact counts unless a triangle with that vertex touches with its face or an
//     edge with that vertex touches, and once per vertex id.
// The tangential history is kept in up to kMaxWallContacts slots per particle keyed by
// (feature type, feature id); a new contact takes the spring of the slot with its key. The
// rolling-torque history (wroll, present only when some pair has rolling resistance) is kept
// in the same slots and carried with the same key.

#include <cstdint>

#include "demfem/dem/physics/geometry.hpp"
#include "demfem/dem/physics/pair.hpp"
#include "demfem/dem/physics/wall_motion.hpp"

namespace demfem::dem::phys {

constexpr int kMaxWallContacts = 8;     // slots per particle; a sphere rarely touches more
constexpr int kMaxWallCandidates = 16;  // touching triangles examined per particle
constexpr int kFeatureShift = 60;       // key = type << 60 | id (0 face, 1 edge, 2 vertex)

/// Triangle store and per-particle slots (host or device pointers).
struct WallView {
  const double* vpos;            ///< 3 per vertex, current positions
  const double* vvel;            ///< 3 per vertex, current velocities
  const std::int32_t* tri_v;     ///< 3 vertex ids per triangle
  const std::int32_t* tri_e;     ///< 3 unique edge ids per triangle (ab, bc, ca)
  const std::int32_t* tri_mat;   ///< wall material per triangle
  const std::int32_t* tri_wall;  ///< wall index per triangle, -1 = flexible mesh
  const std::int64_t* prow;      ///< candidate triangles of particle i: ptri[prow[i]..prow[i+1])
  const std::int32_t* ptri;
  std::int64_t* wkey;    ///< kMaxWallContacts per particle
  double* wshear;        ///< 3 per slot
  double* wf;            ///< 3 per slot: force on the particle
  double* wp;            ///< 3 per slot: contact point
  double* wb;            ///< 3 per slot: barycentric weights of the contact point
  std::int32_t* wtri;    ///< triangle per slot
  std::uint8_t* wcount;  ///< used slots per particle

  double* wroll = nullptr;  ///< 3 per slot: rolling-torque history (null: no pair rolls)
  /// Motions of the rigid walls (index = tri_wall) and the time of the step, for the spin of a
  /// rotating wall; null: no wall moves.
  const RigidMotion* motion = nullptr;
  double time = 0.0;
};

/// Adds the wall contact forces and torques of particle i to f and q; fills its slots;
/// raises mo (largest overlap) and fmo (largest overlap with the flexible mesh).
template <bool Friction>
DEMFEM_HD void wall_contacts(const ParticleView& p, const WallView& w, std::int64_t i,
                             const PairConstants* pc_row, double dt, Vec3& f, Vec3& q, double& mo,
                             double& fmo) {
  if (w.prow[i] == w.prow[i + 1] && w.wcount[i] == 0) return;  // no wall nearby
  // The touching candidates, one array per field: a ClosestPoint copied whole into an array
  // of structs was stored in 8-byte pieces and read back in 16-byte ones, and each such
  // read waited for the stores to retire (store forwarding fails): a fifth of the time of
  // this function, measured.
  double cpx[kMaxWallCandidates], cpy[kMaxWallCandidates], cpz[kMaxWallCandidates];
  double cu[kMaxWallCandidates], cv[kMaxWallCandidates], cw[kMaxWallCandidates];
  int cfeat[kMaxWallCandidates];
  std::int32_t ctri[kMaxWallCandidates];
  std::int64_t ckey[kMaxWallCandidates];
  int nc = 0;
  const Vec3 x{p.px[i], p.py[i], p.pz[i]};
  const double ri = p.radius[i];
  const double* v = w.vpos;
  for (std::int64_t k = w.prow[i]; k < w.prow[i + 1]; ++k) {
    const std::int32_t tri = w.ptri[k];
    const std::int32_t* tv = w.tri_v + 3 * tri;
    const ClosestPoint c =
        closest_point_triangle(x, Vec3{v[3 * tv[0]], v[3 * tv[0] + 1], v[3 * tv[0] + 2]},
                               Vec3{v[3 * tv[1]], v[3 * tv[1] + 1], v[3 * tv[1] + 2]},
                               Vec3{v[3 * tv[2]], v[3 * tv[2] + 1], v[3 * tv[2] + 2]});
    if (norm2(x - c.point) >= ri * ri || nc == kMaxWallCandidates) continue;
    std::int64_t key;
    if (c.feature == kFace)
      key = tri;
    else if (c.feature <= kEdgeCA)
      key = (std::int64_t{1} << kFeatureShift) | w.tri_e[3 * tri + c.feature - 1];
    else
      key = (std::int64_t{2} << kFeatureShift) | tv[c.feature - kVertexA];
    cpx[nc] = c.point.x, cpy[nc] = c.point.y, cpz[nc] = c.point.z;
    cu[nc] = c.u, cv[nc] = c.v, cw[nc] = c.w;
    cfeat[nc] = c.feature;
    ctri[nc] = tri;
    ckey[nc] = key;
    ++nc;
  }
  bool keep[kMaxWallCandidates];
  for (int a = 0; a < nc; ++a) {
    keep[a] = true;
    const std::int64_t type = ckey[a] >> kFeatureShift;
    if (type == 0) continue;
    const std::int64_t fid = ckey[a] & ((std::int64_t{1} << kFeatureShift) - 1);
    for (int b = 0; b < nc && keep[a]; ++b) {
      if (b == a) continue;
      const std::int64_t tb = ckey[b] >> kFeatureShift;
      if (ckey[b] == ckey[a] && b < a) keep[a] = false;
      if (type == 1 && tb == 0) {
        for (int e = 0; e < 3; ++e)
          if (w.tri_e[3 * ctri[b] + e] == fid) keep[a] = false;
      } else if (type == 2 && tb == 0) {
        for (int e = 0; e < 3; ++e)
          if (w.tri_v[3 * ctri[b] + e] == fid) keep[a] = false;
      } else if (type == 2 && tb == 1) {
        const int fe = cfeat[b] - 1;
        const std::int32_t* tv = w.tri_v + 3 * ctri[b];
        if (tv[fe] == fid || tv[(fe + 1) % 3] == fid) keep[a] = false;
      }
    }
  }
  std::int64_t* key = w.wkey + kMaxWallContacts * i;
  double* shr = w.wshear + 3 * kMaxWallContacts * i;
  std::int64_t okey[kMaxWallContacts];
  double osh[3 * kMaxWallContacts];
  double* rol = w.wroll ? w.wroll + 3 * kMaxWallContacts * i : nullptr;
  double orl[3 * kMaxWallContacts];
  const int oc = w.wcount[i];
  if constexpr (Friction) {
    for (int o = 0; o < oc; ++o) {
      okey[o] = key[o];
      osh[3 * o] = shr[3 * o], osh[3 * o + 1] = shr[3 * o + 1], osh[3 * o + 2] = shr[3 * o + 2];
      if (rol)
        orl[3 * o] = rol[3 * o], orl[3 * o + 1] = rol[3 * o + 1], orl[3 * o + 2] = rol[3 * o + 2];
    }
  }
  int cnt = 0;
  for (int a = 0; a < nc && cnt < kMaxWallContacts; ++a) {
    if (!keep[a]) continue;
    const std::int32_t tri = ctri[a];
    const std::int32_t* tv = w.tri_v + 3 * tri;
    const double* vv = w.vvel;
    // wall velocity at the contact point: barycentric interpolation of the vertex velocities
    // (exact for rigid motion and for the linear velocity field of a flexible triangle)
    const Vec3 vw = cu[a] * Vec3{vv[3 * tv[0]], vv[3 * tv[0] + 1], vv[3 * tv[0] + 2]} +
                    cv[a] * Vec3{vv[3 * tv[1]], vv[3 * tv[1] + 1], vv[3 * tv[1] + 2]} +
                    cw[a] * Vec3{vv[3 * tv[2]], vv[3 * tv[2] + 1], vv[3 * tv[2] + 2]};
    Vec3 sh{0, 0, 0}, rh{0, 0, 0};
    if constexpr (Friction)
      for (int o = 0; o < oc; ++o)
        if (okey[o] == ckey[a]) {
          sh = Vec3{osh[3 * o], osh[3 * o + 1], osh[3 * o + 2]};
          if (rol) rh = Vec3{orl[3 * o], orl[3 * o + 1], orl[3 * o + 2]};
        }
    ContactResult r{};
    double delta = 0.0;
    const std::int32_t wall = w.tri_wall[tri];
    const Vec3 ww =
        w.motion != nullptr && wall >= 0 ? rigid_spin(w.motion[wall], w.time) : Vec3{0, 0, 0};
    const Vec3 point{cpx[a], cpy[a], cpz[a]};
    if (!sphere_wall<Friction>(p, static_cast<int>(i), point, vw, ww, pc_row[w.tri_mat[tri]], dt,
                               sh, rh, r, delta))
      continue;
    f = f + r.force;
    if constexpr (Friction) {
      q = q + ri * r.torque + r.roll;
      shr[3 * cnt] = sh.x, shr[3 * cnt + 1] = sh.y, shr[3 * cnt + 2] = sh.z;
      if (rol) rol[3 * cnt] = rh.x, rol[3 * cnt + 1] = rh.y, rol[3 * cnt + 2] = rh.z;
    }
    key[cnt] = ckey[a];
    const std::int64_t slot = kMaxWallContacts * i + cnt;
    w.wf[3 * slot] = r.force.x, w.wf[3 * slot + 1] = r.force.y, w.wf[3 * slot + 2] = r.force.z;
    w.wp[3 * slot] = point.x, w.wp[3 * slot + 1] = point.y, w.wp[3 * slot + 2] = point.z;
    w.wb[3 * slot] = cu[a], w.wb[3 * slot + 1] = cv[a], w.wb[3 * slot + 2] = cw[a];
    w.wtri[slot] = tri;
    mo = mo > delta ? mo : delta;
    if (w.tri_wall[tri] < 0) fmo = fmo > delta ? fmo : delta;
    ++cnt;
  }
  w.wcount[i] = static_cast<std::uint8_t>(cnt);
}

}  // namespace demfem::dem::phys
