// DemSystem state: save() / restore() to HDF5 (checkpoints, loaded beds) and the in-memory
// copies the coupler takes within a coupling step (save_state() / restore_state()).

#include "dem_system_impl.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "demfem/io/h5_file.hpp"

namespace demfem::dem {

using detail::bad;
using detail::kMaxWallContacts;

namespace {
template <class T>
std::vector<std::int64_t> to64(const std::vector<T>& v) {
  return {v.begin(), v.end()};
}
template <class T>
std::vector<T> from64(const std::vector<std::int64_t>& v) {
  std::vector<T> o(v.size());
  for (std::size_t k = 0; k < v.size(); ++k) o[k] = static_cast<T>(v[k]);
  return o;
}
}  // namespace

// Every double array of the saved state with its dataset name: one list serves save() and
// restore(), so the two cannot drift apart. ImplT is Impl or const Impl.
template <class ImplT>
auto double_arrays(ImplT& I) {
  using Vec =
      std::conditional_t<std::is_const_v<ImplT>, const std::vector<double>, std::vector<double>>;
  auto& st = I.st;
  return std::array<std::pair<const char*, Vec*>, 39>{{{"px", &st.px},
                                                       {"py", &st.py},
                                                       {"pz", &st.pz},
                                                       {"vx", &st.vx},
                                                       {"vy", &st.vy},
                                                       {"vz", &st.vz},
                                                       {"wx", &st.wx},
                                                       {"wy", &st.wy},
                                                       {"wz", &st.wz},
                                                       {"qw", &st.qw},
                                                       {"qx", &st.qx},
                                                       {"qy", &st.qy},
                                                       {"qz", &st.qz},
                                                       {"fx", &st.fx},
                                                       {"fy", &st.fy},
                                                       {"fz", &st.fz},
                                                       {"radius", &st.radius},
                                                       {"mass", &st.mass},
                                                       {"inertia", &st.inertia},
                                                       {"tx", &I.tx},
                                                       {"ty", &I.ty},
                                                       {"tz", &I.tz},
                                                       {"shear", &I.slots.shear},
                                                       {"rhist", &I.slots.rolling_history},
                                                       {"wroll", &I.wall_contacts.rolling_history},
                                                       {"bx", &I.list.update_x},
                                                       {"by", &I.list.update_y},
                                                       {"bz", &I.list.update_z},
                                                       {"wshear", &I.wall_contacts.shear},
                                                       {"vpos", &I.walls.vertex_x},
                                                       {"vbuild", &I.walls.vertex_x_at_build},
                                                       {"flex_x", &I.walls.flexible_x0},
                                                       {"flex_v", &I.walls.flexible_v0},
                                                       {"flex_a", &I.walls.flexible_a0},
                                                       {"flex_force", &I.walls.flexible_force},
                                                       {"scale", &st.scale},
                                                       {"ix", &st.ix},
                                                       {"iy", &st.iy},
                                                       {"iz", &st.iz}}};
}

namespace {
// The shape table: per shape its vertex and triangle counts, the concatenated vertices and
// triangles, dilation, volume and principal moments, and the names (one per line).
void save_shapes(const detail::ShapeTable& t, io::H5File& f, const std::string& g) {
  std::vector<std::int64_t> nv, ntri, tri;
  std::vector<double> vert, par;
  std::string names;
  for (std::size_t k = 0; k < t.size(); ++k) {
    const PolyhedronShape& s = t.shape(static_cast<std::int32_t>(k));
    nv.push_back(static_cast<std::int64_t>(s.vertices.size() / 3));
    ntri.push_back(static_cast<std::int64_t>(s.triangles.size() / 3));
    vert.insert(vert.end(), s.vertices.begin(), s.vertices.end());
    tri.insert(tri.end(), s.triangles.begin(), s.triangles.end());
    par.insert(par.end(), {s.dilation, s.volume, s.inertia[0], s.inertia[1], s.inertia[2]});
    names += s.name + "\n";
  }
  f.write(g + "shape_nv", std::span<const std::int64_t>(nv));
  f.write(g + "shape_ntri", std::span<const std::int64_t>(ntri));
  f.write(g + "shape_vertices", std::span<const double>(vert));
  f.write(g + "shape_triangles", std::span<const std::int64_t>(tri));
  f.write(g + "shape_params", std::span<const double>(par));
  f.set_attribute(g + "shape_nv", "names", names);
}

}  // namespace

std::vector<PolyhedronShape> read_state_shapes(const io::H5File& f, const std::string& group) {
  const std::string g = group + "/";
  std::vector<PolyhedronShape> out;
  if (!f.exists(g + "shape_nv")) return out;
  const auto nv = f.read_int64(g + "shape_nv"), ntri = f.read_int64(g + "shape_ntri");
  const auto vert = f.read_doubles(g + "shape_vertices");
  const auto tri = f.read_int64(g + "shape_triangles");
  const auto par = f.read_doubles(g + "shape_params");
  const std::string names = f.attribute_string(g + "shape_nv", "names");
  auto inconsistent = [&](const std::string& what) {
    throw std::invalid_argument("DemSystem: restore: inconsistent shape table in " +
                                f.path().string() + ":/" + g + what);
  };
  if (ntri.size() != nv.size() || par.size() != 5 * nv.size())
    inconsistent("shape_nv, shape_ntri and shape_params have " + std::to_string(nv.size()) +
                 ", " + std::to_string(ntri.size()) + " and " + std::to_string(par.size()) +
                 " values (accepted: n, n and 5 n)");
  std::size_t v0 = 0, t0 = 0, name0 = 0;
  for (std::size_t k = 0; k < nv.size(); ++k) {
    PolyhedronShape s;
    const std::size_t e = names.find('\n', name0);
    s.name = names.substr(name0, e == std::string::npos ? std::string::npos : e - name0);
    name0 = e == std::string::npos ? names.size() : e + 1;
    // counts beyond what the arrays hold (negative ones included) are refused before any
    // index is formed from them
    if (nv[k] < 0 || ntri[k] < 0 || static_cast<std::uint64_t>(nv[k]) > (vert.size() - v0) / 3 ||
        static_cast<std::uint64_t>(ntri[k]) > (tri.size() - t0) / 3)
      inconsistent("shape_nv[" + std::to_string(k) + "] = " + std::to_string(nv[k]) +
                   ", shape_ntri[" + std::to_string(k) + "] = " + std::to_string(ntri[k]) +
                   " exceed shape_vertices and shape_triangles");
    const auto vn = static_cast<std::size_t>(3 * nv[k]), tn = static_cast<std::size_t>(3 * ntri[k]);
    s.vertices.assign(vert.begin() + v0, vert.begin() + v0 + vn);
    for (std::size_t m = 0; m < tn; ++m) {
      if (tri[t0 + m] < 0 || tri[t0 + m] >= nv[k])
        inconsistent("shape_triangles[" + std::to_string(t0 + m) + "] = " +
                     std::to_string(tri[t0 + m]) + " is not a vertex of shape " +
                     std::to_string(k) + " (accepted 0 .. " + std::to_string(nv[k] - 1) + ")");
      s.triangles.push_back(static_cast<std::int32_t>(tri[t0 + m]));
    }
    s.dilation = par[5 * k], s.volume = par[5 * k + 1];
    s.inertia = {par[5 * k + 2], par[5 * k + 3], par[5 * k + 4]};
    v0 += vn, t0 += tn;
    out.push_back(std::move(s));
  }
  return out;
}

namespace {
// The force-limited walls' drift state: time and rate, 2 per wall.
template <class ImplT>  // DemSystem::Impl (a private type: deduced)
std::vector<double> pack_drift(const ImplT& I) {
  std::vector<double> d;
  for (std::size_t w = 0; w < I.walls.drift_time.size(); ++w)
    d.insert(d.end(), {I.walls.drift_time[w], I.walls.drift_rate[w]});
  return d;
}
template <class ImplT>
void unpack_drift(ImplT& I, const std::vector<double>& d) {
  if (d.size() != 2 * I.walls.drift_time.size()) return;
  for (std::size_t w = 0; w < I.walls.drift_time.size(); ++w)
    I.walls.drift_time[w] = d[2 * w], I.walls.drift_rate[w] = d[2 * w + 1];
}

// Replaces the table by the state's (a state without one keeps the system's).
void restore_shapes(detail::ShapeTable& t, const io::H5File& f, const std::string& g) {
  if (!f.exists(g + "shape_nv")) return;
  t.clear();
  for (const auto& s : read_state_shapes(f, g.substr(0, g.size() - 1))) t.add(s);
}
}  // namespace

namespace {
// The pair list as a saved state holds it: the pairs that carry a spring (tangential or
// rolling history), each row in the order of j. restore() rebuilds the list from the
// positions and takes the springs from these rows, so the list's other entries (neighbours
// within the skin, which depend on when the list was last built or refiltered, and a
// restarted process refilters with its own adaptive skin) are not state: two runs that agree
// in every particle and contact write the same arrays.
// Systems with polyhedra also keep the pairs whose narrow-phase caches are warm, with the
// caches of every kept pair ("sepaxis", "features"): the narrow phase of a pair starts from
// them (GJK's simplex, the axis's support pair), and a cold start can round a contact
// otherwise, so a restored run without them parts from the uninterrupted one at round-off.
// Which non-touching pairs hold an axis depends on the list's history (as their springs do
// not): two runs equal in every particle and contact may then write different pairs.
struct PairsWithSprings {
  std::vector<std::int64_t> row, nbr;
  std::vector<double> shear, rhist;
  bool caches = false;             ///< the system has polyhedra: axis and feat are written
  std::vector<double> axis;        ///< 3 per kept pair
  std::vector<std::int64_t> feat;  ///< 6 per kept pair
};
template <class ImplT>  // DemSystem::Impl (a private type: deduced)
PairsWithSprings pairs_with_springs(const ImplT& I) {
  PairsWithSprings out;
  const std::size_t n = I.list.row.empty() ? 0 : I.list.row.size() - 1;
  out.row.assign(I.list.row.empty() ? 0 : n + 1, 0);
  // without friction no pair has a spring (and no shear array): without polyhedra no pair is
  // state
  const bool friction = I.slots.shear.size() == 3 * I.list.partner.size();
  out.caches = I.poly && I.slots.separating_axis.size() == 3 * I.list.partner.size() &&
               I.slots.closest_features.size() == 6 * I.list.partner.size();
  if (!friction && !out.caches) return out;
  const bool rolling = friction && I.slots.rolling_history.size() == I.slots.shear.size();
  std::vector<std::pair<std::int32_t, std::size_t>> kept;  // (j, pair index)
  auto spring = [](const std::vector<double>& h, std::size_t k) {
    return h[3 * k] != 0.0 || h[3 * k + 1] != 0.0 || h[3 * k + 2] != 0.0;
  };
  // a pair whose caches are not cold: features set (it touched at its last pass) or an axis
  // (it was proven apart along it, or touched)
  auto warm = [&](std::size_t k) {
    if (!out.caches) return false;
    const double* a = I.slots.separating_axis.data() + 3 * k;
    return I.slots.closest_features[6 * k] >= 0 || a[0] != 0.0 || a[1] != 0.0 || a[2] != 0.0;
  };
  for (std::size_t i = 0; i < n; ++i) {
    kept.clear();
    for (auto k = static_cast<std::size_t>(I.list.row[i]);
         k < static_cast<std::size_t>(I.list.row[i + 1]); ++k)
      if ((friction && spring(I.slots.shear, k)) ||
          (rolling && spring(I.slots.rolling_history, k)) || warm(k))
        kept.emplace_back(I.list.partner[k], k);
    std::sort(kept.begin(), kept.end());
    for (const auto& [j, k] : kept) {
      out.nbr.push_back(j);
      // a frictionless system's kept pairs get zero springs (restore checks 3 per pair)
      for (int d = 0; d < 3; ++d) out.shear.push_back(friction ? I.slots.shear[3 * k + d] : 0.0);
      if (out.caches) {
        for (int d = 0; d < 3; ++d) out.axis.push_back(I.slots.separating_axis[3 * k + d]);
        for (int d = 0; d < 6; ++d) out.feat.push_back(I.slots.closest_features[6 * k + d]);
      }
      if (rolling)
        out.rhist.insert(out.rhist.end(), I.slots.rolling_history.begin() + std::ptrdiff_t(3 * k),
                         I.slots.rolling_history.begin() + std::ptrdiff_t(3 * k + 3));
    }
    out.row[i + 1] = static_cast<std::int64_t>(out.nbr.size());
  }
  return out;
}
}  // namespace

namespace {
// The arrays of a saved state that other arrays are indexed by (and the lengths of those
// indexed per particle), checked before any step or refilter reads through them: a damaged or
// forged file is refused with the dataset named, never read out of bounds. `at` is
// "<file>:/<group>/"; `nverts` the system's wall vertex count before the restore.
template <class ImplT>
void check_state_indices(const ImplT& I, std::size_t nverts, const std::string& at) {
  const auto& st = I.st;
  const std::size_t n = st.px.size();
  auto refuse = [&](const std::string& dataset, const std::string& what) {
    bad("restore: " + at + dataset + " " + what);
  };
  auto entry = [](std::string dataset, auto k) {  // "nbr[7]"
    dataset += '[';
    dataset += std::to_string(k);
    dataset += ']';
    return dataset;
  };
  auto per_particle = [&](const char* name, std::size_t size, bool may_be_empty = false) {
    if (size != n && !(may_be_empty && size == 0))
      refuse(name, "has " + std::to_string(size) + " values, not one per particle (" +
                       std::to_string(n) + ", the length of px)");
  };
  for (const auto* v : {&st.py, &st.pz, &st.vx, &st.vy, &st.vz, &st.wx, &st.wy, &st.wz, &st.qw,
                        &st.qx, &st.qy, &st.qz, &st.fx, &st.fy, &st.fz, &st.radius, &st.mass,
                        &st.inertia, &I.tx, &I.ty, &I.tz})
    if (v->size() != n) per_particle("(a per-particle array)", v->size());
  per_particle("material", st.material.size());
  per_particle("shape", st.shape.size());
  // the list's build positions: all three or none (a state saved before the first build)
  for (const auto* v : {&I.list.update_x, &I.list.update_y, &I.list.update_z})
    per_particle("bx/by/bz", v->size(), true);
  if (I.list.update_x.size() != I.list.update_y.size() ||
      I.list.update_x.size() != I.list.update_z.size())
    refuse("bx/by/bz", "have " + std::to_string(I.list.update_x.size()) + ", " +
                           std::to_string(I.list.update_y.size()) + " and " +
                           std::to_string(I.list.update_z.size()) +
                           " values: all three one per particle, or all three empty");
  if (I.walls.vertex_x.size() != nverts)
    refuse("vpos", "has " + std::to_string(I.walls.vertex_x.size() / 3) +
                       " wall vertices, this system " + std::to_string(nverts / 3) +
                       " (the state of other walls)");
  // the pair rows: a prefix sum over the particles, each row's partners j > i ascending (the
  // order of the list's merge in refilter)
  const auto& row = I.list.row;
  const auto& nbr = I.list.partner;
  if (row.size() != n + 1)
    refuse("row", "has " + std::to_string(row.size()) + " values, not particles + 1 (" +
                      std::to_string(n + 1) + ")");
  if (row[0] != 0) refuse("row", "starts at " + std::to_string(row[0]) + ", not 0");
  for (std::size_t i = 0; i < n; ++i)
    if (row[i + 1] < row[i] || row[i + 1] > static_cast<std::int64_t>(nbr.size()))
      refuse(entry("row", i + 1), "= " + std::to_string(row[i + 1]) + " is not in [" +
                                      entry("row", i) + " = " + std::to_string(row[i]) + ", " +
                                      std::to_string(nbr.size()) +
                                      "] (the pair rows must rise monotonically to the length "
                                      "of nbr)");
  if (row[n] != static_cast<std::int64_t>(nbr.size()))
    refuse("row", "ends at " + std::to_string(row[n]) + ", nbr holds " +
                      std::to_string(nbr.size()) + " pairs");
  for (std::size_t i = 0; i < n; ++i)
    for (std::int64_t k = row[i]; k < row[i + 1]; ++k) {
      const std::int64_t lo = k > row[i] ? std::int64_t{nbr[k - 1]} : std::int64_t(i);
      if (nbr[k] <= lo || nbr[k] >= static_cast<std::int64_t>(n))
        refuse(entry("nbr", k), "= " + std::to_string(nbr[k]) + " (a partner of particle " +
                                    std::to_string(i) + ") is not in [" +
                                    std::to_string(lo + 1) + ", " + std::to_string(n) +
                                    "): partners are particles after i, ascending within a row");
    }
  if (I.slots.shear.size() != 3 * nbr.size())
    refuse("shear", "has " + std::to_string(I.slots.shear.size()) +
                        " values, not 3 per pair of nbr (" + std::to_string(3 * nbr.size()) + ")");
  const bool walls = !I.walls.triangle_wall.empty();
  for (std::size_t i = 0; i < I.wall_contacts.count.size(); ++i)
    if (I.wall_contacts.count[i] > (walls ? kMaxWallContacts : 0))
      refuse(entry("wcount", i), "= " + std::to_string(int(I.wall_contacts.count[i])) +
                                     " wall contacts, accepted 0 .. " +
                                     std::to_string(walls ? kMaxWallContacts : 0) +
                                     (walls ? "" : " (this system has no wall triangles)"));
}
}  // namespace

namespace {
// The narrow-phase caches of the restored pairs ("sepaxis", "features": pairs_with_springs),
// checked before any step reads them: a feature indexes a core's vertices (GJK's warm start,
// narrow_phase.hpp gjk_distance: even entries the vertices of i, odd ones those of j; a sphere
// is a point core of one vertex), and an axis is a unit vector or zero (convex_contact proves
// a separation along it). A state written before the caches were saved has neither: the
// caches start cold (as a list rebuilt from scratch).
template <class ImplT>
void restore_pair_caches(ImplT& I, const io::H5File& f, const std::string& g) {
  const std::string at = f.path().string() + ":/" + g;
  auto refuse = [&](const std::string& dataset, const std::string& what) {
    bad("restore: " + at + dataset + " " + what);
  };
  I.slots.separating_axis.clear(), I.slots.closest_features.clear();
  const bool has_axis = f.exists(g + "sepaxis"), has_feat = f.exists(g + "features");
  if (!has_axis && !has_feat) return;
  if (has_axis != has_feat)
    refuse(has_axis ? "features" : "sepaxis", "is missing (saved with " +
                                                  std::string(has_axis ? "sepaxis" : "features") +
                                                  ": the narrow-phase caches come together)");
  const auto axis = f.read_doubles(g + "sepaxis");
  const auto feat = f.read_int64(g + "features");
  const std::size_t np = I.list.partner.size(), n = I.st.px.size();
  if (axis.size() != 3 * np)
    refuse("sepaxis", "has " + std::to_string(axis.size()) + " values, not 3 per pair of nbr (" +
                          std::to_string(3 * np) + ")");
  if (feat.size() != 6 * np)
    refuse("features", "has " + std::to_string(feat.size()) + " values, not 6 per pair of nbr (" +
                           std::to_string(6 * np) + ")");
  auto vertices = [&](std::size_t i) -> std::int64_t {  // of particle i's core
    const std::int32_t id = I.st.shape_id[i];
    return id < 0 ? 1 : static_cast<std::int64_t>(I.shapes.shape(id).vertices.size() / 3);
  };
  for (std::size_t i = 0; i < n; ++i)
    for (auto k = static_cast<std::size_t>(I.list.row[i]);
         k < static_cast<std::size_t>(I.list.row[i + 1]); ++k) {
      const double* a = axis.data() + 3 * k;
      const double a2 = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
      if (!std::isfinite(a2) || !(a2 == 0.0 || std::abs(a2 - 1.0) < 1e-6))
        refuse("sepaxis[" + std::to_string(3 * k) + " .. " + std::to_string(3 * k + 2) + "]",
               "(pair " + std::to_string(k) + ") is not a unit axis or zero (|a|^2 = " +
                   std::to_string(a2) + ", accepted 0 or 1 +- 1e-6)");
      const std::size_t j = static_cast<std::size_t>(I.list.partner[k]);
      for (int m = 0; m < 6; ++m) {
        const std::size_t owner = m % 2 == 0 ? i : j;
        const std::int64_t nv = vertices(owner), v = feat[6 * k + m];
        if (v < -1 || v >= nv)
          refuse("features[" + std::to_string(6 * k + m) + "]",
                 "= " + std::to_string(v) + " (pair " + std::to_string(k) +
                     ", a vertex of particle " + std::to_string(owner) + ") is not in -1 .. " +
                     std::to_string(nv - 1) + " (-1: none, else a vertex of its core)");
      }
    }
  I.slots.separating_axis = axis;
  I.slots.closest_features = from64<std::int32_t>(feat);
}
}  // namespace

void DemSystem::save(io::H5File& f, const std::string& group) const {
  const auto& I = *impl_;
  const auto& st = I.st;
  f.create_group(group);
  const std::string g = group + "/";
  f.set_attribute(group, "time", I.t);
  f.set_attribute(group, "steps", static_cast<std::int64_t>(I.steps));
  f.set_attribute(group, "flex_tau", I.walls.flexible_tau);
  f.set_attribute(group, "max_overlap", I.max_overlap);
  f.set_attribute(group, "flex_max_overlap", I.walls.flexible_max_overlap);
  f.set_attribute(group, "format", std::string("demfem-dem-state-1"));
  const PairsWithSprings pairs = pairs_with_springs(I);
  for (const auto& [name, v] : double_arrays(I)) {
    if (std::strcmp(name, "shear") == 0)
      f.write(g + name, std::span<const double>(pairs.shear));
    else if (std::strcmp(name, "rhist") == 0)
      f.write(g + name, std::span<const double>(pairs.rhist));
    else
      f.write(g + name, std::span<const double>(*v));
  }
  f.write(g + "material", std::span<const std::int64_t>(to64(st.material)));
  f.write(g + "shape", std::span<const std::uint8_t>(st.shape));
  f.write(g + "shape_id", std::span<const std::int64_t>(to64(st.shape_id)));
  save_shapes(I.shapes, f, g);
  f.write(g + "row", std::span<const std::int64_t>(pairs.row));
  f.write(g + "nbr", std::span<const std::int64_t>(pairs.nbr));
  if (pairs.caches) {
    f.write(g + "sepaxis", std::span<const double>(pairs.axis));
    f.write(g + "features", std::span<const std::int64_t>(pairs.feat));
  }
  f.write(g + "wkey", std::span<const std::int64_t>(I.wall_contacts.key));
  f.write(g + "wcount", std::span<const std::uint8_t>(I.wall_contacts.count));
  I.walls.bodies.save(f, g);
  if (I.walls.force_limited) f.write(g + "wall_drift", std::span<const double>(pack_drift(I)));
  if (!I.frozen.empty()) f.write(g + "frozen", std::span<const std::uint8_t>(I.frozen));
  if (I.periodic) {
    f.write(g + "image", std::span<const std::int64_t>(to64(I.image)));
    const PeriodicRange& r = I.s.periodic;
    const std::vector<double> range{double(r.on[0]), double(r.on[1]), double(r.on[2]),
                                    r.lo[0],         r.lo[1],         r.lo[2],
                                    r.hi[0],         r.hi[1],         r.hi[2]};
    f.write(g + "periodic", std::span<const double>(range));
  }
}

PeriodicRange read_state_periodic(const io::H5File& f, const std::string& group) {
  PeriodicRange r;
  const std::string name = group + "/periodic";
  if (!f.exists(name)) return r;
  const auto v = f.read_doubles(name);
  if (v.size() != 9)
    bad("read_state_periodic: " + f.path().string() + ":/" + name + " has " +
        std::to_string(v.size()) + " values, not 9 (on, lo, hi per direction)");
  for (int d = 0; d < 3; ++d) {
    r.on[d] = v[d] != 0.0;
    r.lo[d] = v[3 + d], r.hi[d] = v[6 + d];
    if (r.on[d] && !(r.hi[d] > r.lo[d]))
      bad("read_state_periodic: " + f.path().string() + ":/" + name + " has an empty range");
  }
  return r;
}

namespace {
// Arrays of save() that a state copy within one coupling step leaves out: the particle
// properties do not change there, and the build positions are reset by the rebuild that
// follows restore_state().
bool constant_within_step(const char* name) {
  for (const char* c : {"radius", "mass", "inertia", "bx", "by", "bz"})
    if (std::strcmp(name, c) == 0) return true;
  return false;
}
}  // namespace

void DemSystem::save_state(DemStateCopy& c) const {
  const auto& I = *impl_;
  c.time = I.t;
  c.steps = I.steps;
  c.flex_tau = I.walls.flexible_tau;
  c.max_overlap = I.max_overlap;
  c.flex_max_overlap = I.walls.flexible_max_overlap;
  c.particles = I.n();
  const auto arrays = double_arrays(I);
  c.arrays.resize(arrays.size());
  for (std::size_t k = 0; k < arrays.size(); ++k) {
    if (constant_within_step(arrays[k].first)) continue;
    c.arrays[k].assign(arrays[k].second->begin(), arrays[k].second->end());
  }
  c.row.assign(I.list.row.begin(), I.list.row.end());
  c.nbr.assign(I.list.partner.begin(), I.list.partner.end());
  // the narrow phase's warm starts, in the order of nbr as the springs (the rebuild after
  // restore_state() carries both over)
  c.axis = I.slots.separating_axis;
  c.features = I.slots.closest_features;
  c.wkey.assign(I.wall_contacts.key.begin(), I.wall_contacts.key.end());
  c.wcount.assign(I.wall_contacts.count.begin(), I.wall_contacts.count.end());
  c.bodies = I.walls.bodies.pack();
  c.drift = pack_drift(I);
  c.frozen = I.frozen;
  c.image = I.image;
}

void DemSystem::restore_state(const DemStateCopy& c) {
  auto& I = *impl_;
  if (c.steps < 0 || c.particles != I.n()) {
    throw std::logic_error("DemSystem::restore_state: " +
                           (c.steps < 0 ? std::string("nothing was saved")
                                        : "the state copy has " + std::to_string(c.particles) +
                                              " particles, the system " + std::to_string(I.n())));
  }
  I.t = c.time;
  I.steps = c.steps;
  I.walls.flexible_tau = c.flex_tau;
  I.max_overlap = c.max_overlap;
  I.walls.flexible_max_overlap = c.flex_max_overlap;
  const auto arrays = double_arrays(I);
  for (std::size_t k = 0; k < arrays.size(); ++k) {
    if (constant_within_step(arrays[k].first)) continue;
    arrays[k].second->assign(c.arrays[k].begin(), c.arrays[k].end());
  }
  I.list.row.assign(c.row.begin(), c.row.end());
  I.list.partner.assign(c.nbr.begin(), c.nbr.end());
  I.slots.separating_axis = c.axis;
  I.slots.closest_features = c.features;
  I.wall_contacts.key.assign(c.wkey.begin(), c.wkey.end());
  I.wall_contacts.count.assign(c.wcount.begin(), c.wcount.end());
  if (!I.walls.bodies.unpack(c.bodies))
    throw std::logic_error(
        "DemSystem::restore_state: the state copy holds another number of "
        "rigid bodies");
  unpack_drift(I, c.drift);
  I.frozen = c.frozen;
  I.image = c.image;
  I.refresh_frozen();
  // As restore(): the list is rebuilt from the restored positions and springs.
  I.list.update_x.clear(), I.list.update_y.clear(), I.list.update_z.clear();
  I.refresh_particle_derived();
  I.list.must_build = true;
}

void DemSystem::restore(const io::H5File& f, const std::string& group) {
  auto& I = *impl_;
  auto& st = I.st;
  const std::string g = group + "/";
  if (!f.exists(group)) bad("restore: group '" + group + "' not found in " + f.path().string());
  const std::size_t nwalls = I.walls.rigid.size();
  const std::size_t nverts = I.walls.vertex_x.size();
  I.t = f.attribute_double(group, "time");
  I.steps = f.attribute_int64(group, "steps");
  I.walls.flexible_tau = f.attribute_double(group, "flex_tau");
  I.max_overlap = f.attribute_double(group, "max_overlap");
  I.walls.flexible_max_overlap = f.attribute_double(group, "flex_max_overlap");
  for (const auto& [name, v] : double_arrays(I)) {
    // the rolling histories are absent in states written before the rolling spring model:
    // they then start at zero (checked against the pair list below)
    // so are the polyhedron arrays in states written before them (all spheres: set below)
    const bool optional = std::strcmp(name, "rhist") == 0 || std::strcmp(name, "wroll") == 0 ||
                          std::strcmp(name, "scale") == 0 || std::strcmp(name, "ix") == 0 ||
                          std::strcmp(name, "iy") == 0 || std::strcmp(name, "iz") == 0;
    *v = optional && !f.exists(g + name) ? std::vector<double>{} : f.read_doubles(g + name);
  }
  if (f.exists(g + "shape_id")) {
    st.shape_id = from64<std::int32_t>(f.read_int64(g + "shape_id"));
  } else {
    st.shape_id.assign(st.px.size(), -1);
    st.scale.assign(st.px.size(), 1.0);
    st.ix = st.iy = st.iz = st.inertia;
  }
  restore_shapes(I.shapes, f, g);
  st.material = from64<std::int32_t>(f.read_int64(g + "material"));
  st.shape = f.read_uint8(g + "shape");
  I.list.row = f.read_int64(g + "row");
  I.list.partner = from64<std::int32_t>(f.read_int64(g + "nbr"));
  I.wall_contacts.key = f.read_int64(g + "wkey");
  I.wall_contacts.count = f.read_uint8(g + "wcount");
  try {
    I.walls.bodies.restore(f, g);
  } catch (const std::invalid_argument& e) {
    bad(std::string("restore: ") + e.what());
  }
  if (I.list.row.empty()) I.list.row.assign(st.px.size() + 1, 0);  // saved before the first step
  check_state_indices(I, nverts, f.path().string() + ":/" + g);
  // force-limited walls: their drift as saved (a state of another scene's walls, or of one
  // without such walls, leaves them at their start)
  I.walls.reset_drift();
  if (I.walls.force_limited && f.exists(g + "wall_drift")) {
    const auto d = f.read_doubles(g + "wall_drift");
    if (d.size() != 2 * nwalls)
      bad("restore: wall_drift in '" + group + "' of " + f.path().string() + " has " +
          std::to_string(d.size()) + " values, not 2 per wall (" + std::to_string(nwalls) + ")");
    unpack_drift(I, d);
  }
  const std::size_t n = st.px.size();
  I.frozen = f.exists(g + "frozen") ? f.read_uint8(g + "frozen") : std::vector<std::uint8_t>{};
  if (!I.frozen.empty() && I.frozen.size() != n)
    bad("restore: frozen in '" + group + "' of " + f.path().string() + " has " +
        std::to_string(I.frozen.size()) + " entries, not one per particle (" + std::to_string(n) +
        ")");
  // periodic: the image counters as saved (a state saved without periods starts at zero)
  I.image.clear();
  if (I.periodic) {
    if (f.exists(g + "image")) I.image = from64<std::int32_t>(f.read_int64(g + "image"));
    if (I.image.empty()) I.image.assign(3 * n, 0);
    if (I.image.size() != 3 * n)
      bad("restore: image in '" + group + "' of " + f.path().string() + " has " +
          std::to_string(I.image.size()) + " entries, not 3 per particle (" + std::to_string(n) +
          ")");
  }
  if (I.walls.vertex_x.size() != (I.walls.vertex_x_at_build.size()) ||
      (nwalls > 0 && I.walls.vertex_x.size() < 3))
    bad("restore: wall vertex data in '" + group + "' does not match the walls of this system");
  for (std::size_t i = 0; i < n; ++i)
    if (st.material[i] < 0 || static_cast<std::size_t>(st.material[i]) >= I.material_count)
      bad("restore: particle material index out of range in '" + group + "'");
  if (st.shape_id.size() != n || st.scale.size() != n || st.ix.size() != n || st.iy.size() != n ||
      st.iz.size() != n)
    bad("restore: polyhedron arrays in '" + group + "' of " + f.path().string() +
        " do not match the particle count");
  for (std::size_t i = 0; i < n; ++i)
    if (st.shape[i] != static_cast<std::uint8_t>(ParticleShape::sphere) &&
        st.shape[i] != static_cast<std::uint8_t>(ParticleShape::polyhedron))
      bad("restore: " + f.path().string() + ":/" + g + "shape[" + std::to_string(i) + "] = " +
          std::to_string(int(st.shape[i])) + " is not a particle shape kind (accepted " +
          std::to_string(int(ParticleShape::sphere)) + ": sphere, " +
          std::to_string(int(ParticleShape::polyhedron)) + ": polyhedron)");
  for (std::size_t i = 0; i < n; ++i)
    if (st.shape_id[i] >= static_cast<std::int32_t>(I.shapes.size()) ||
        (st.shape_id[i] >= 0) !=
            (st.shape[i] == static_cast<std::uint8_t>(ParticleShape::polyhedron)))
      bad("restore: particle " + std::to_string(i) + " in '" + group + "' of " + f.path().string() +
          " refers to a shape the state does not hold");
  restore_pair_caches(I, f, g);  // indexes the shapes of the particles checked above
  // the orientation update keeps unit quaternions unit (physics/integrator.hpp), it does not
  // normalise arbitrary ones
  if (st.qw.size() == n && st.qx.size() == n && st.qy.size() == n && st.qz.size() == n)
    for (std::size_t i = 0; i < n; ++i) {
      const double q2 =
          st.qw[i] * st.qw[i] + st.qx[i] * st.qx[i] + st.qy[i] * st.qy[i] + st.qz[i] * st.qz[i];
      if (!(std::abs(q2 - 1.0) < 1e-6))
        bad("restore: orientation of particle " + std::to_string(i) + " in '" + group + "' of " +
            f.path().string() + " is not a unit quaternion (|q|^2 = " + std::to_string(q2) +
            ", accepted 1 +- 1e-6)");
    }
  auto& wc = I.wall_contacts;
  wc.force.assign(3 * kMaxWallContacts * n, 0.0), wc.point.assign(3 * kMaxWallContacts * n, 0.0),
      wc.weights.assign(3 * kMaxWallContacts * n, 0.0), wc.triangle.assign(kMaxWallContacts * n, 0);
  I.refresh_particle_derived();
  // The neighbour list is rebuilt from the restored positions; the restored rows carry the
  // springs. Forces of the pairs do not depend on which non-touching pairs the list holds,
  // so the continuation is bitwise identical to an uninterrupted run.
  if (!I.rolling) {
    I.slots.rolling_history.clear(), wc.rolling_history.clear();
  } else {
    if (I.slots.rolling_history.empty())
      I.slots.rolling_history.assign(3 * I.list.partner.size(), 0.0);
    if (wc.rolling_history.empty()) wc.rolling_history.assign(3 * kMaxWallContacts * n, 0.0);
    if (I.slots.rolling_history.size() != 3 * I.list.partner.size() ||
        wc.rolling_history.size() != 3 * kMaxWallContacts * n)
      bad("restore: rolling history sizes in '" + group + "' of " + f.path().string() +
          " do not match the pair list and particles");
  }
  if (wc.count.size() != n || wc.key.size() != kMaxWallContacts * n ||
      wc.shear.size() != 3 * kMaxWallContacts * n || I.list.row.size() != n + 1)
    bad("restore: inconsistent array sizes in '" + group + "' of " + f.path().string());
  I.refresh_frozen();  // held at their saved poses
  I.list.must_build = true;
}

void DemSystem::reset_clock() {
  auto& I = *impl_;
  I.t = 0.0;
  I.steps = 0;
  I.walls.reset_drift();  // the walls' motions start again
  I.walls.update(I.t, I.walls.flexible_tau);
}

}  // namespace demfem::dem
