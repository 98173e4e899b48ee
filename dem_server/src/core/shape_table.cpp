// Shape table: validation of a dilated convex polyhedron and its faces as polygons.

#include "shape_table.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>

namespace demfem::dem::detail {

namespace {

[[noreturn]] void bad(const std::string& where, const std::string& what) {
  throw std::invalid_argument("DemSystem: add_shape('" + where + "'): " + what);
}

struct V3 {
  double x, y, z;
};
V3 sub(V3 a, V3 b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
V3 crs(V3 a, V3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double dt(V3 a, V3 b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}

int find(std::vector<int>& p, int a) {
  while (p[a] != a) a = p[a] = p[p[a]];
  return a;
}

}  // namespace

void ShapeTable::clear() {
  shapes_.clear();
  bound_.clear();
  a_ = Arrays{};
}

std::int32_t ShapeTable::add(const PolyhedronShape& s) {
  const std::string& nm = s.name;
  if (s.vertices.empty() || s.vertices.size() % 3 != 0)
    bad(nm, "vertices has " + std::to_string(s.vertices.size()) +
                " entries, need a positive multiple of 3");
  for (double x : s.vertices)
    if (!std::isfinite(x)) bad(nm, "vertices: non-finite coordinate");
  const int nv = static_cast<int>(s.vertices.size() / 3);
  auto vtx = [&](int k) {
    return V3{s.vertices[3 * k], s.vertices[3 * k + 1], s.vertices[3 * k + 2]};
  };
  double size = 0.0;
  for (int k = 0; k < nv; ++k) size = std::max(size, std::sqrt(dt(vtx(k), vtx(k))));
  if (!(s.dilation > 0.0) || !std::isfinite(s.dilation))
    bad(nm, "dilation = " + std::to_string(s.dilation) + " must be > 0 m");
  if (!(s.volume > 0.0) || !std::isfinite(s.volume))
    bad(nm, "volume = " + std::to_string(s.volume) + " must be > 0 m^3");
  const auto& I = s.inertia;
  for (int k = 0; k < 3; ++k)
    if (!(I[k] > 0.0) || !std::isfinite(I[k]))
      bad(nm, "inertia[" + std::to_string(k) + "] = " + std::to_string(I[k]) + " must be > 0 m^5");
  for (int k = 0; k < 3; ++k)
    if (I[k] > (1 + 1e-9) * (I[(k + 1) % 3] + I[(k + 2) % 3]))
      bad(nm, "inertia: principal moments violate I_a <= I_b + I_c (not a body's)");
  const std::size_t nt = s.triangles.size() / 3;
  if (s.triangles.size() % 3 != 0) bad(nm, "triangles size is not a multiple of 3");
  for (auto t : s.triangles)
    if (t < 0 || t >= nv)
      bad(nm, "triangle vertex index " + std::to_string(t) + " outside [0, " + std::to_string(nv) +
                  ")");
  if (nv <= 3 && nt > 0)
    bad(nm, "a core of " + std::to_string(nv) + " vertices has no volume: give no triangles");
  if (nv >= 4 && nt < 4)
    bad(nm, "a core of " + std::to_string(nv) +
                " vertices needs its hull triangles (at least 4), got " + std::to_string(nt));

  std::vector<V3> tn(nt);
  std::vector<double> toff(nt);
  if (nv >= 4) {
    // closed: every directed edge once, its reverse once
    std::map<std::pair<int, int>, int> dir;
    for (std::size_t t = 0; t < nt; ++t)
      for (int e = 0; e < 3; ++e) {
        const int a = s.triangles[3 * t + e], b = s.triangles[3 * t + (e + 1) % 3];
        if (a == b) bad(nm, "triangle " + std::to_string(t) + " repeats a vertex");
        if (++dir[{a, b}] > 1)
          bad(nm, "edge " + std::to_string(a) + "-" + std::to_string(b) +
                      " used twice in one direction: triangles not a closed, consistently oriented "
                      "surface");
      }
    for (const auto& [e, c] : dir)
      if (!dir.count({e.second, e.first}))
        bad(nm, "edge " + std::to_string(e.first) + "-" + std::to_string(e.second) +
                    " has no opposite: the triangles are not a closed surface");
    // convex with outward normals: every vertex on or below every triangle's plane
    for (std::size_t t = 0; t < nt; ++t) {
      const V3 a = vtx(s.triangles[3 * t]), b = vtx(s.triangles[3 * t + 1]),
               c = vtx(s.triangles[3 * t + 2]);
      V3 n = crs(sub(b, a), sub(c, a));
      const double l = std::sqrt(dt(n, n));
      if (!(l > 1e-12 * size * size))
        bad(nm, "triangle " + std::to_string(t) + " has zero area (degenerate core)");
      n = {n.x / l, n.y / l, n.z / l};
      tn[t] = n;
      toff[t] = dt(n, a);
      for (int k = 0; k < nv; ++k)
        if (dt(n, vtx(k)) - toff[t] > 1e-9 * size)
          bad(nm, "vertex " + std::to_string(k) + " lies outside the plane of triangle " +
                      std::to_string(t) +
                      ": the core is not convex or the triangles are not oriented outwards");
    }
  }

  // faces: triangles sharing an edge with the same plane, merged (union-find)
  std::vector<int> parent(nt);
  for (std::size_t t = 0; t < nt; ++t) parent[t] = static_cast<int>(t);
  {
    std::map<std::pair<int, int>, int> owner;  // directed edge -> triangle
    for (std::size_t t = 0; t < nt; ++t)
      for (int e = 0; e < 3; ++e)
        owner[{s.triangles[3 * t + e], s.triangles[3 * t + (e + 1) % 3]}] = static_cast<int>(t);
    for (std::size_t t = 0; t < nt; ++t)
      for (int e = 0; e < 3; ++e) {
        const int a = s.triangles[3 * t + e], b = s.triangles[3 * t + (e + 1) % 3];
        const int u = owner[{b, a}];
        if (dt(tn[t], tn[u]) >= 1.0 - 1e-12 && std::abs(toff[t] - toff[u]) <= 1e-12 * size) {
          const int ra = find(parent, static_cast<int>(t)), rb = find(parent, u);
          if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
        }
      }
  }
  const std::int32_t id = static_cast<std::int32_t>(shapes_.size());
  a_.vbase.push_back(static_cast<std::int32_t>(a_.vert.size() / 3));
  a_.nv.push_back(nv);
  a_.vert.insert(a_.vert.end(), s.vertices.begin(), s.vertices.end());
  a_.fbase.push_back(static_cast<std::int32_t>(a_.flen.size()));
  a_.ebase.push_back(static_cast<std::int32_t>(a_.edge.size() / 2));
  int nfaces = 0, nedges = 0;
  std::vector<std::pair<int, int>> edges;
  for (std::size_t root = 0; root < nt; ++root) {
    if (find(parent, static_cast<int>(root)) != static_cast<int>(root)) continue;
    // boundary of the group: directed edges whose reverse is not in the group
    std::map<int, int> next;
    V3 n{0, 0, 0};
    std::map<std::pair<int, int>, int> in;
    for (std::size_t t = 0; t < nt; ++t)
      if (find(parent, static_cast<int>(t)) == static_cast<int>(root))
        for (int e = 0; e < 3; ++e)
          in[{s.triangles[3 * t + e], s.triangles[3 * t + (e + 1) % 3]}] = 1;
    for (std::size_t t = 0; t < nt; ++t) {
      if (find(parent, static_cast<int>(t)) != static_cast<int>(root)) continue;
      const V3 a = vtx(s.triangles[3 * t]), b = vtx(s.triangles[3 * t + 1]),
               c = vtx(s.triangles[3 * t + 2]);
      const V3 an = crs(sub(b, a), sub(c, a));
      n = {n.x + an.x, n.y + an.y, n.z + an.z};
      for (int e = 0; e < 3; ++e) {
        const int u = s.triangles[3 * t + e], w = s.triangles[3 * t + (e + 1) % 3];
        if (!in.count({w, u})) next[u] = w;
      }
    }
    const double l = std::sqrt(dt(n, n));
    n = {n.x / l, n.y / l, n.z / l};
    std::vector<int> loop;
    const int start = next.begin()->first;
    int cur = start;
    do {
      loop.push_back(cur);
      auto it = next.find(cur);
      if (it == next.end() || loop.size() > next.size())
        bad(nm, "a face of coplanar triangles has no single boundary loop");
      cur = it->second;
    } while (cur != start);
    if (loop.size() != next.size()) bad(nm, "a face of coplanar triangles has holes");
    a_.fnormal.insert(a_.fnormal.end(), {n.x, n.y, n.z});
    a_.floop.push_back(static_cast<std::int32_t>(a_.fvert.size()));
    a_.flen.push_back(static_cast<std::int32_t>(loop.size()));
    for (std::size_t k = 0; k < loop.size(); ++k) {
      a_.fvert.push_back(loop[k]);
      const int u = loop[k], w = loop[(k + 1) % loop.size()];
      if (u < w) edges.push_back({u, w});
    }
    ++nfaces;
  }
  if (nv == 2) edges.push_back({0, 1});
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  for (const auto& [u, w] : edges) {
    a_.edge.push_back(u);
    a_.edge.push_back(w);
    ++nedges;
  }
  a_.nf.push_back(nfaces);
  a_.ne.push_back(nedges);
  // the columns of the vertices and face normals, zero-padded
  auto columns = [](const double* rows, int n, std::vector<double>& soa,
                    std::vector<std::int32_t>& base) {
    const int np = phys::soa_padded(n);
    base.push_back(static_cast<std::int32_t>(soa.size()));
    soa.resize(soa.size() + 3 * static_cast<std::size_t>(np), 0.0);
    double* col = soa.data() + base.back();
    for (int k = 0; k < n; ++k)
      for (int c = 0; c < 3; ++c) col[c * np + k] = rows[3 * k + c];
  };
  columns(a_.vert.data() + 3 * static_cast<std::size_t>(a_.vbase.back()), nv, a_.vsoa,
          a_.vsoa_base);
  columns(a_.fnormal.data() + 3 * static_cast<std::size_t>(a_.fbase.back()), nfaces, a_.fsoa,
          a_.fsoa_base);
  a_.dilation.push_back(s.dilation);
  a_.bound.push_back(size + s.dilation);
  bound_.push_back(size + s.dilation);
  shapes_.push_back(s);
  return id;
}

phys::ShapeTableView ShapeTable::view() const {
  return phys::ShapeTableView{
      a_.vbase.data(),     a_.nv.data(),    a_.vert.data(),     a_.fbase.data(), a_.nf.data(),
      a_.fnormal.data(),   a_.floop.data(), a_.flen.data(),     a_.fvert.data(), a_.ebase.data(),
      a_.ne.data(),        a_.edge.data(),  a_.dilation.data(), a_.bound.data(), a_.vsoa.data(),
      a_.vsoa_base.data(), a_.fsoa.data(),  a_.fsoa_base.data()};
}

}  // namespace demfem::dem::detail
