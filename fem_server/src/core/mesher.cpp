// Structured meshers (see mesher.hpp).
#include "demfem/fem/mesher.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "demfem/fem/element_topology.hpp"

namespace demfem::fem {
namespace {

void check_box(std::array<double, 3> lo, std::array<double, 3> hi, std::array<int, 3> counts,
               const char* who) {
  for (int d = 0; d < 3; ++d) {
    if (counts[d] < 1)
      throw std::invalid_argument(std::string(who) + ": counts[" + std::to_string(d) +
                                  "] = " + std::to_string(counts[d]) + ", must be >= 1");
    if (!(hi[d] > lo[d]) || !std::isfinite(hi[d]) || !std::isfinite(lo[d]))
      throw std::invalid_argument(std::string(who) + ": hi[" + std::to_string(d) +
                                  "] must be finite and greater than lo[" + std::to_string(d) +
                                  "]");
  }
}

/// Nodes of the structured grid, index (i, j, k) -> i + (nx+1) * (j + (ny+1) * k).
void grid_nodes(Mesh& mesh, std::array<double, 3> lo, std::array<double, 3> hi,
                std::array<int, 3> n) {
  for (int k = 0; k <= n[2]; ++k)
    for (int j = 0; j <= n[1]; ++j)
      for (int i = 0; i <= n[0]; ++i) {
        const std::array<int, 3> idx{i, j, k};
        std::array<double, 3> x{};
        for (int d = 0; d < 3; ++d)
          x[d] = idx[d] == n[d] ? hi[d] : lo[d] + (hi[d] - lo[d]) * idx[d] / n[d];
        mesh.nodes.push_back(x);
        const std::array<bool, 6> on{i == 0, i == n[0], j == 0, j == n[1], k == 0, k == n[2]};
        static const char* names[6] = {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"};
        const auto id = static_cast<std::int32_t>(mesh.nodes.size() - 1);
        for (int f = 0; f < 6; ++f)
          if (on[f]) mesh.node_sets[names[f]].push_back(id);
        mesh.node_sets["all"].push_back(id);
      }
}

/// Adds every element face whose nodes all lie in a named face node set to that surface.
void add_box_surfaces(Mesh& mesh) {
  static const char* names[6] = {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"};
  std::vector<std::array<bool, 6>> on(mesh.nodes.size(), std::array<bool, 6>{});
  for (int f = 0; f < 6; ++f)
    for (auto n : mesh.node_sets[names[f]]) on[static_cast<std::size_t>(n)][f] = true;
  for (std::size_t e = 0; e < mesh.elements.size(); ++e) {
    const auto& el = mesh.elements[e];
    for (int face = 0; face < face_count(el.type); ++face) {
      const auto local = face_local_nodes(el.type, face);
      for (int f = 0; f < 6; ++f) {
        bool all = true;
        for (int a = 0; a < face_node_count(el.type); ++a)
          all = all && on[static_cast<std::size_t>(el.nodes[local[a]])][f];
        if (all) mesh.surfaces[names[f]].push_back(Face{static_cast<std::int32_t>(e), face});
      }
    }
  }
}

void finish(Mesh& mesh) {
  mesh.node_labels.resize(mesh.nodes.size());
  for (std::size_t i = 0; i < mesh.nodes.size(); ++i)
    mesh.node_labels[i] = static_cast<std::int64_t>(i + 1);
  mesh.element_labels.resize(mesh.elements.size());
  auto& all = mesh.element_sets["all"];
  for (std::size_t i = 0; i < mesh.elements.size(); ++i) {
    mesh.element_labels[i] = static_cast<std::int64_t>(i + 1);
    all.push_back(static_cast<std::int32_t>(i));
  }
}

}  // namespace

Mesh box_mesh_hex(std::array<double, 3> lo, std::array<double, 3> hi, std::array<int, 3> n) {
  check_box(lo, hi, n, "box_mesh_hex");
  Mesh mesh;
  grid_nodes(mesh, lo, hi, n);
  auto id = [&](int i, int j, int k) { return i + (n[0] + 1) * (j + (n[1] + 1) * k); };
  for (int k = 0; k < n[2]; ++k)
    for (int j = 0; j < n[1]; ++j)
      for (int i = 0; i < n[0]; ++i) {
        Element e;
        e.type = ElementType::hex8;
        e.nodes = {
            id(i, j, k),     id(i + 1, j, k),     id(i + 1, j + 1, k),     id(i, j + 1, k),
            id(i, j, k + 1), id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)};
        mesh.elements.push_back(e);
      }
  add_box_surfaces(mesh);
  finish(mesh);
  return mesh;
}

Mesh box_mesh_tet(std::array<double, 3> lo, std::array<double, 3> hi, std::array<int, 3> n) {
  check_box(lo, hi, n, "box_mesh_tet");
  Mesh mesh;
  grid_nodes(mesh, lo, hi, n);
  auto id = [&](int i, int j, int k) { return i + (n[0] + 1) * (j + (n[1] + 1) * k); };
  // Kuhn split: the six paths from corner (0,0,0) to (1,1,1) along the cube edges, one per
  // permutation of the axes; every cell is split the same way, so faces match.
  static const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < n[2]; ++k)
    for (int j = 0; j < n[1]; ++j)
      for (int i = 0; i < n[0]; ++i)
        for (const auto& p : perms) {
          std::array<int, 3> c{0, 0, 0};
          std::array<std::int32_t, 4> t{};
          t[0] = id(i, j, k);
          for (int s = 0; s < 3; ++s) {
            c[p[s]] = 1;
            t[s + 1] = id(i + c[0], j + c[1], k + c[2]);
          }
          // Orient for a positive volume.
          const auto& x0 = mesh.nodes[t[0]];
          std::array<std::array<double, 3>, 3> d{};
          for (int s = 0; s < 3; ++s)
            for (int q = 0; q < 3; ++q) d[s][q] = mesh.nodes[t[s + 1]][q] - x0[q];
          const double vol = d[0][0] * (d[1][1] * d[2][2] - d[1][2] * d[2][1]) -
                             d[0][1] * (d[1][0] * d[2][2] - d[1][2] * d[2][0]) +
                             d[0][2] * (d[1][0] * d[2][1] - d[1][1] * d[2][0]);
          if (vol < 0) std::swap(t[1], t[2]);
          Element e;
          e.type = ElementType::tet4;
          std::copy(t.begin(), t.end(), e.nodes.begin());
          mesh.elements.push_back(e);
        }
  add_box_surfaces(mesh);
  finish(mesh);
  return mesh;
}

Mesh plate_mesh_quad(std::array<double, 3> origin, double size_x, double size_y,
                     std::array<int, 2> counts) {
  if (counts[0] < 1 || counts[1] < 1)
    throw std::invalid_argument("plate_mesh_quad: counts must be >= 1");
  if (!(size_x > 0) || !(size_y > 0) || !std::isfinite(size_x) || !std::isfinite(size_y))
    throw std::invalid_argument("plate_mesh_quad: size_x and size_y must be finite and > 0");
  Mesh mesh;
  const int nx = counts[0], ny = counts[1];
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) {
      mesh.nodes.push_back({origin[0] + (i == nx ? size_x : size_x * i / nx),
                            origin[1] + (j == ny ? size_y : size_y * j / ny), origin[2]});
      const auto nid = static_cast<std::int32_t>(mesh.nodes.size() - 1);
      if (i == 0) mesh.node_sets["xmin"].push_back(nid);
      if (i == nx) mesh.node_sets["xmax"].push_back(nid);
      if (j == 0) mesh.node_sets["ymin"].push_back(nid);
      if (j == ny) mesh.node_sets["ymax"].push_back(nid);
      mesh.node_sets["all"].push_back(nid);
    }
  auto id = [&](int i, int j) { return i + (nx + 1) * j; };
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      Element e;
      e.type = ElementType::quad4;
      e.nodes = {id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1), 0, 0, 0, 0};
      const auto eid = static_cast<std::int32_t>(mesh.elements.size());
      mesh.elements.push_back(e);
      mesh.surfaces["bottom"].push_back(Face{eid, 0});
      mesh.surfaces["top"].push_back(Face{eid, 1});
    }
  finish(mesh);
  return mesh;
}

}  // namespace demfem::fem
