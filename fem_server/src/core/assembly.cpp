// Assembly of the FEM system (see assembly.hpp).
#include "demfem/fem/assembly.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <stdexcept>

#include "demfem/fem/element_topology.hpp"
#include "demfem/io/h5_file.hpp"
#include "elements.hpp"

namespace demfem::fem {
namespace {

using detail::Vec3;

Vec3 node_pos(const Mesh& m, std::int32_t n) {
  const auto& p = m.nodes[static_cast<std::size_t>(n)];
  return {p[0], p[1], p[2]};
}

[[noreturn]] void bad(const std::string& what) {
  throw std::invalid_argument("FEM problem: " + what);
}

/// An element whose smallest measure (Gauss-point Jacobian, corner area, volume) is below
/// this fraction of its size is collapsed: its stiffness is singular in some direction and
/// would leave a mechanism. Legitimately distorted elements are orders of magnitude above.
constexpr double kCollapsedRatio = 1e-6;

const Material& element_material(const FemProblem& p, const Element& el) {
  return p.materials[static_cast<std::size_t>(
      p.sections[static_cast<std::size_t>(el.section)].material)];
}

/// Director used by a shell element at its local node a: the averaged nodal director where
/// the surface is smooth there (within 20 degrees), the element's own normal at a kink.
detail::ShellGeometry shell_geometry(const FemProblem& p, const Element& el,
                                     const std::vector<Vec3>& directors) {
  detail::ShellGeometry g;
  for (int a = 0; a < 4; ++a) g.x[a] = node_pos(p.mesh, el.nodes[a]);
  for (int a = 0; a < 4; ++a) {
    const Vec3 own = detail::quad_corner_normal(g.x, a).normalized();
    const Vec3& avg = directors[static_cast<std::size_t>(el.nodes[a])];
    g.director[a] = own.dot(avg) > std::cos(20.0 * M_PI / 180.0) ? avg : own;
  }
  g.thickness = p.sections[static_cast<std::size_t>(el.section)].thickness;
  return g;
}

/// Global DOFs of an element (3 per node for solids, 6 for shells).
int element_dofs(const Element& el, const DofMap& dofs, std::array<std::int32_t, 24>& out) {
  const int per = el.type == ElementType::quad4 ? 6 : 3;
  const int nn = nodes_per_element(el.type);
  for (int a = 0; a < nn; ++a)
    for (int c = 0; c < per; ++c)
      out[static_cast<std::size_t>(per * a + c)] =
          dofs.node_offset[static_cast<std::size_t>(el.nodes[a])] + c;
  return per * nn;
}

enum class MatrixKind { stiffness, mass };

void element_matrix(const FemProblem& p, const std::vector<Vec3>& directors, std::size_t e,
                    MatrixKind kind, Eigen::MatrixXd& out) {
  const Element& el = p.mesh.elements[e];
  const Material& mat = element_material(p, el);
  const bool lumped = p.mass == MassLumping::lumped;
  switch (el.type) {
    case ElementType::hex8: {
      std::array<Vec3, 8> x;
      for (int a = 0; a < 8; ++a) x[a] = node_pos(p.mesh, el.nodes[a]);
      const auto d = detail::elasticity_matrix(mat.youngs_modulus, mat.poisson_ratio);
      if (kind == MatrixKind::stiffness && el.formulation == SolidFormulation::selective_reduced)
        detail::hex8_bbar_stiffness(x, d, out);
      else if (kind == MatrixKind::stiffness)
        detail::hex8_stiffness(x, d, out);
      else
        detail::hex8_mass(x, mat.density, lumped, out);
      break;
    }
    case ElementType::tet4: {
      std::array<Vec3, 4> x;
      for (int a = 0; a < 4; ++a) x[a] = node_pos(p.mesh, el.nodes[a]);
      if (kind == MatrixKind::stiffness)
        detail::tet4_stiffness(x, detail::elasticity_matrix(mat.youngs_modulus, mat.poisson_ratio),
                               out);
      else
        detail::tet4_mass(x, mat.density, lumped, out);
      break;
    }
    case ElementType::quad4: {
      const auto g = shell_geometry(p, el, directors);
      if (kind == MatrixKind::stiffness)
        detail::mitc4_stiffness(g, mat.youngs_modulus, mat.poisson_ratio, out);
      else
        detail::mitc4_mass(g, mat.density, lumped, out);
      break;
    }
  }
}

SparseMatrix assemble(const FemProblem& p, const DofMap& dofs, MatrixKind kind) {
  std::vector<Vec3> directors;
  std::vector<double> thick;
  shell_nodal_directors(p, directors, thick);
  const std::size_t ne = p.mesh.elements.size();
  std::size_t count = 0;
  for (const auto& el : p.mesh.elements) {
    const std::size_t n = static_cast<std::size_t>(nodes_per_element(el.type)) *
                          (el.type == ElementType::quad4 ? 6u : 3u);
    count += n * n;
  }
  std::vector<Eigen::Triplet<double, int>> trip;
  trip.reserve(count);
  // Element matrices in parallel, chunk by chunk; triplets appended in element order so
  // the summation order (and the result) does not depend on the thread count.
  constexpr std::size_t chunk = 1024;
  std::vector<Eigen::MatrixXd> ke(chunk);
  for (std::size_t start = 0; start < ne; start += chunk) {
    const std::size_t end = std::min(ne, start + chunk);
    const auto n = static_cast<std::ptrdiff_t>(end - start);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < n; ++i)
      element_matrix(p, directors, start + static_cast<std::size_t>(i), kind,
                     ke[static_cast<std::size_t>(i)]);
    for (std::size_t e = start; e < end; ++e) {
      std::array<std::int32_t, 24> ed{};
      const int nd = element_dofs(p.mesh.elements[e], dofs, ed);
      const auto& m = ke[e - start];
      for (int b = 0; b < nd; ++b)
        for (int a = 0; a < nd; ++a)
          if (m(a, b) != 0.0) trip.emplace_back(ed[a], ed[b], m(a, b));
    }
  }
  SparseMatrix k(dofs.total, dofs.total);
  k.setFromTriplets(trip.begin(), trip.end());
  k.makeCompressed();
  return k;
}

}  // namespace

void validate_problem(const FemProblem& p) {
  const Mesh& m = p.mesh;
  const auto nn = static_cast<std::int64_t>(m.nodes.size());
  if (m.nodes.empty() || m.elements.empty()) bad("the mesh has no nodes or no elements");
  for (std::size_t i = 0; i < m.nodes.size(); ++i)
    for (double c : m.nodes[i])
      if (!std::isfinite(c)) bad("node " + std::to_string(i) + " has a non-finite coordinate");
  for (std::size_t i = 0; i < p.materials.size(); ++i) {
    const auto& mat = p.materials[i];
    const std::string name = "material " + std::to_string(i) + " '" + mat.name + "'";
    if (!(mat.youngs_modulus > 0) || !std::isfinite(mat.youngs_modulus))
      bad(name + ": youngs_modulus must be finite and > 0");
    if (!(mat.poisson_ratio > -1.0 && mat.poisson_ratio < 0.5))
      bad(name + ": poisson_ratio must be in (-1, 0.5)");
    if (!(mat.density >= 0) || !std::isfinite(mat.density))
      bad(name + ": density must be finite and >= 0");
  }
  for (std::size_t i = 0; i < p.sections.size(); ++i)
    if (p.sections[i].material < 0 ||
        static_cast<std::size_t>(p.sections[i].material) >= p.materials.size())
      bad("section " + std::to_string(i) + ": material index " +
          std::to_string(p.sections[i].material) + " out of range [0, " +
          std::to_string(p.materials.size()) + ")");
  for (std::size_t e = 0; e < m.elements.size(); ++e) {
    const Element& el = m.elements[e];
    if (el.section < 0 || static_cast<std::size_t>(el.section) >= p.sections.size())
      bad(element_name(m, e) + ": section index " + std::to_string(el.section) +
          " out of range [0, " + std::to_string(p.sections.size()) + ")");
    for (int a = 0; a < nodes_per_element(el.type); ++a)
      if (el.nodes[a] < 0 || el.nodes[a] >= nn)
        bad(element_name(m, e) + ": node index " + std::to_string(el.nodes[a]) +
            " out of range [0, " + std::to_string(nn) + ")");
    if (el.type == ElementType::quad4) {
      const double t = p.sections[static_cast<std::size_t>(el.section)].thickness;
      if (!(t > 0) || !std::isfinite(t))
        bad(element_name(m, e) + ": shell thickness must be finite and > 0");
      std::array<Vec3, 4> x;
      for (int a = 0; a < 4; ++a) x[a] = node_pos(m, el.nodes[a]);
      double longest = 0.0;
      for (int a = 0; a < 4; ++a) longest = std::max(longest, (x[(a + 1) % 4] - x[a]).norm());
      for (int a = 0; a < 4; ++a) {
        // Each corner's area must be a fair part of the largest possible (a collapsed edge
        // or a folded quad gives ~0 or a flipped normal).
        const Vec3 na = detail::quad_corner_normal(x, a);
        if (!(na.dot(detail::quad_corner_normal(x, 0)) > 0) ||
            !(na.norm() > kCollapsedRatio * longest * longest))
          bad(element_name(m, e) + ": degenerate or non-convex shell quadrilateral (corner " +
              std::to_string(a + 1) + " has no area: coincident nodes or a folded quad)");
      }
      // Thickness relative to the element: below 1e-5 of the longest edge the bending
      // stiffness ((t/h)^2 of the membrane one, < 1e-10) is lost to round-off.
      if (t < 1e-5 * longest) {
        char buf[160];
        std::snprintf(buf, sizeof buf,
                      ": shell thickness %g m is below 1e-5 of its longest edge (%g m): the "
                      "bending stiffness would be lost to round-off",
                      t, longest);
        bad(element_name(m, e) + buf);
      }
    } else if (el.type == ElementType::hex8) {
      std::array<Vec3, 8> x;
      for (int a = 0; a < 8; ++a) x[a] = node_pos(m, el.nodes[a]);
      const auto det = detail::hex8_gauss_jacobians(x);
      const double dmax = *std::max_element(det.begin(), det.end());
      const auto worst = std::min_element(det.begin(), det.end()) - det.begin();
      if (!(det[static_cast<std::size_t>(worst)] > 0))
        bad(element_name(m, e) + ": non-positive Jacobian at Gauss point " +
            std::to_string(worst + 1) +
            " (node order inverted, or the element folded over itself)");
      // Against the largest Jacobian (a corner folded in) and against a cube of the longest
      // edge (an element squashed flat: det J of a cube of edge L is L^3 / 8).
      double longest = 0.0;
      for (int a = 0; a < 8; ++a)
        for (int b = a + 1; b < 8; ++b) longest = std::max(longest, (x[b] - x[a]).norm());
      const double dmin = det[static_cast<std::size_t>(worst)];
      if (!(dmin > kCollapsedRatio * std::max(dmax, longest * longest * longest / 8.0))) {
        char buf[200];
        std::snprintf(buf, sizeof buf,
                      ": collapsed: its Jacobian at Gauss point %d is %.3g of the largest and "
                      "%.3g of a cube of its longest edge (nodes that coincide or lie in one "
                      "plane)",
                      static_cast<int>(worst + 1), dmin / dmax,
                      dmin / (longest * longest * longest / 8.0));
        bad(element_name(m, e) + buf);
      }
    } else {
      std::array<Vec3, 4> x;
      for (int a = 0; a < 4; ++a) x[a] = node_pos(m, el.nodes[a]);
      double longest = 0.0;
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) longest = std::max(longest, (x[b] - x[a]).norm());
      const double v = detail::tet4_volume(x);
      if (!(v > 0)) bad(element_name(m, e) + ": non-positive volume (node order inverted?)");
      // A regular tetrahedron of edge L has L^3 / (6 sqrt 2).
      if (!(v > kCollapsedRatio * longest * longest * longest / (6.0 * std::sqrt(2.0))))
        bad(element_name(m, e) + ": collapsed: its volume is below " +
            std::to_string(kCollapsedRatio) +
            " of a regular tetrahedron of its longest edge "
            "(nodes that coincide or lie in one plane)");
    }
  }
  auto check_nodes = [&](const std::vector<std::int32_t>& nodes, const std::string& what) {
    for (auto n : nodes)
      if (n < 0 || n >= nn)
        bad(what + ": node index " + std::to_string(n) + " out of range [0, " + std::to_string(nn) +
            ")");
  };
  for (std::size_t i = 0; i < p.constraints.size(); ++i)
    check_nodes(p.constraints[i].nodes, "constraint " + std::to_string(i));
  auto check_faces = [&](const std::vector<Face>& faces, const std::string& what) {
    for (const auto& f : faces) {
      if (f.element < 0 || static_cast<std::size_t>(f.element) >= m.elements.size())
        bad(what + ": element index " + std::to_string(f.element) + " out of range");
      const auto t = m.elements[static_cast<std::size_t>(f.element)].type;
      if (f.face < 0 || f.face >= face_count(t))
        bad(what + ": face " + std::to_string(f.face) + " out of range [0, " +
            std::to_string(face_count(t)) + ") for " +
            element_name(m, static_cast<std::size_t>(f.element)));
    }
  };
  for (std::size_t i = 0; i < p.pressures.size(); ++i) {
    check_faces(p.pressures[i].faces, "pressure load " + std::to_string(i));
    if (!std::isfinite(p.pressures[i].magnitude))
      bad("pressure load " + std::to_string(i) + ": magnitude is not finite");
  }
  for (std::size_t i = 0; i < p.nodal_loads.size(); ++i) {
    check_nodes(p.nodal_loads[i].nodes, "nodal load " + std::to_string(i));
    for (double f : p.nodal_loads[i].force)
      if (!std::isfinite(f)) bad("nodal load " + std::to_string(i) + ": force is not finite");
  }
  for (double g : p.gravity)
    if (!std::isfinite(g)) bad("gravity is not finite");
  if (p.gravity != std::array<double, 3>{0.0, 0.0, 0.0})
    for (std::size_t e = 0; e < m.elements.size(); ++e)
      if (!(element_material(p, m.elements[e]).density > 0))
        bad("gravity is given but " + element_name(m, e) + " has material '" +
            element_material(p, m.elements[e]).name +
            "' of density 0: its weight would be missing (give the density)");
  // A load on a node that no element carries would vanish from the system.
  {
    std::vector<char> used(m.nodes.size(), 1);
    for (auto n : orphan_nodes(m)) used[static_cast<std::size_t>(n)] = 0;
    for (std::size_t i = 0; i < p.nodal_loads.size(); ++i)
      for (auto n : p.nodal_loads[i].nodes)
        if (n >= 0 && n < nn && !used[static_cast<std::size_t>(n)])
          bad("nodal load " + std::to_string(i) + " acts on " +
              node_name(m, static_cast<std::size_t>(n)) +
              ", which belongs to no element: its force would be lost");
  }
  const auto& b = p.bossak;
  if (!std::isfinite(b.alpha) || !(b.alpha <= 0.0 && b.alpha >= -1.0 / 3.0))
    bad("bossak.alpha must be in [-1/3, 0]");
  if (!(b.beta > 0) || !std::isfinite(b.beta)) bad("bossak.beta must be finite and > 0");
  if (!(b.gamma >= 0.5) || !std::isfinite(b.gamma)) bad("bossak.gamma must be finite and >= 0.5");
  if (!(p.damping.mass_factor >= 0) || !std::isfinite(p.damping.mass_factor) ||
      !(p.damping.stiffness_factor >= 0) || !std::isfinite(p.damping.stiffness_factor))
    bad("Rayleigh damping factors must be finite and >= 0");
  if (!p.interface_surface.empty()) {
    auto it = m.surfaces.find(p.interface_surface);
    if (it == m.surfaces.end())
      bad("interface_surface '" + p.interface_surface + "' is not a surface of the mesh");
    check_faces(it->second, "surface '" + p.interface_surface + "'");
  }
}

DofMap make_dof_map(const FemProblem& p) {
  DofMap d;
  const std::size_t nn = p.mesh.nodes.size();
  d.node_dofs.assign(nn, 3);
  for (const auto& el : p.mesh.elements)
    if (el.type == ElementType::quad4)
      for (int a = 0; a < 4; ++a) d.node_dofs[static_cast<std::size_t>(el.nodes[a])] = 6;
  d.node_offset.resize(nn);
  std::int32_t off = 0;
  for (std::size_t i = 0; i < nn; ++i) {
    d.node_offset[i] = off;
    off += d.node_dofs[i];
  }
  d.total = off;
  std::vector<std::uint8_t> fixed(static_cast<std::size_t>(off), 0);
  // Nodes of no element have no stiffness and no mass: their DOFs stay out of the system
  // (zero), as Abaqus does with unused nodes.
  for (auto n : orphan_nodes(p.mesh))
    for (int k = 0; k < d.node_dofs[static_cast<std::size_t>(n)]; ++k)
      fixed[static_cast<std::size_t>(d.node_offset[static_cast<std::size_t>(n)] + k)] = 1;
  for (const auto& c : p.constraints)
    for (auto n : c.nodes)
      for (int k = 0; k < d.node_dofs[static_cast<std::size_t>(n)]; ++k)
        if (c.fixed[static_cast<std::size_t>(k)])
          fixed[static_cast<std::size_t>(d.node_offset[static_cast<std::size_t>(n)] + k)] = 1;
  d.reduced.assign(static_cast<std::size_t>(off), -1);
  for (std::int32_t i = 0; i < off; ++i)
    if (!fixed[static_cast<std::size_t>(i)]) {
      d.reduced[static_cast<std::size_t>(i)] = static_cast<std::int32_t>(d.free.size());
      d.free.push_back(i);
    }
  return d;
}

SparseMatrix assemble_stiffness(const FemProblem& p, const DofMap& d) {
  return assemble(p, d, MatrixKind::stiffness);
}

SparseMatrix assemble_mass(const FemProblem& p, const DofMap& d) {
  return assemble(p, d, MatrixKind::mass);
}

SparseMatrix reduce_matrix(const SparseMatrix& full, const DofMap& d) {
  const auto nf = static_cast<int>(d.free.size());
  SparseMatrix r(nf, nf);
  std::vector<int> nnz(static_cast<std::size_t>(nf), 0);
  for (int c = 0; c < nf; ++c)
    for (SparseMatrix::InnerIterator it(full, d.free[static_cast<std::size_t>(c)]); it; ++it)
      if (d.reduced[static_cast<std::size_t>(it.row())] >= 0) ++nnz[static_cast<std::size_t>(c)];
  r.reserve(nnz);
  for (int c = 0; c < nf; ++c)
    for (SparseMatrix::InnerIterator it(full, d.free[static_cast<std::size_t>(c)]); it; ++it) {
      const int row = d.reduced[static_cast<std::size_t>(it.row())];
      if (row >= 0) r.insert(row, c) = it.value();
    }
  r.makeCompressed();
  return r;
}

void shell_nodal_directors(const FemProblem& p, std::vector<Vec3>& directors,
                           std::vector<double>& thickness) {
  const std::size_t nn = p.mesh.nodes.size();
  directors.assign(nn, Vec3::Zero());
  thickness.assign(nn, 0.0);
  std::vector<int> count(nn, 0);
  for (const auto& el : p.mesh.elements) {
    if (el.type != ElementType::quad4) continue;
    std::array<Vec3, 4> x;
    for (int a = 0; a < 4; ++a) x[a] = node_pos(p.mesh, el.nodes[a]);
    for (int a = 0; a < 4; ++a) {
      const auto n = static_cast<std::size_t>(el.nodes[a]);
      directors[n] += detail::quad_corner_normal(x, a).normalized();
      thickness[n] += p.sections[static_cast<std::size_t>(el.section)].thickness;
      ++count[n];
    }
  }
  for (std::size_t n = 0; n < nn; ++n)
    if (count[n] > 0) {
      directors[n].normalize();
      thickness[n] /= count[n];
    }
}

Eigen::VectorXd pressure_load_vector(const FemProblem& p, const DofMap& d,
                                     const PressureLoad& load) {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(d.total);
  const double g = 0.57735026918962576451;
  for (const auto& face : load.faces) {
    const Element& el = p.mesh.elements[static_cast<std::size_t>(face.element)];
    const auto local = face_local_nodes(el.type, face.face);
    const int nf = face_node_count(el.type);
    std::array<Vec3, 4> x;
    std::array<std::int32_t, 4> node{};
    for (int a = 0; a < nf; ++a) {
      node[a] = el.nodes[local[a]];
      x[a] = node_pos(p.mesh, node[a]);
    }
    std::array<Vec3, 4> fa;
    if (nf == 3) {
      // Linear triangle: each node carries a third of the resultant.
      const Vec3 an = 0.5 * (x[1] - x[0]).cross(x[2] - x[0]);
      for (int a = 0; a < 3; ++a) fa[a] = -load.magnitude * an / 3.0;
    } else {
      // Bilinear face, 2x2 Gauss: f_a = -p sum N_a (x_s x x_t) (outward area element).
      for (auto& v : fa) v.setZero();
      static const double nat[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
      for (int q = 0; q < 4; ++q) {
        const double s = g * nat[q][0], t = g * nat[q][1];
        Vec3 xs = Vec3::Zero(), xt = Vec3::Zero();
        double n[4];
        for (int a = 0; a < 4; ++a) {
          n[a] = 0.25 * (1 + s * nat[a][0]) * (1 + t * nat[a][1]);
          xs += 0.25 * nat[a][0] * (1 + t * nat[a][1]) * x[a];
          xt += 0.25 * (1 + s * nat[a][0]) * nat[a][1] * x[a];
        }
        const Vec3 an = xs.cross(xt);
        for (int a = 0; a < 4; ++a) fa[a] -= load.magnitude * n[a] * an;
      }
    }
    for (int a = 0; a < nf; ++a) {
      const auto off = d.node_offset[static_cast<std::size_t>(node[a])];
      for (int c = 0; c < 3; ++c) f(off + c) += fa[a](c);
    }
  }
  return f;
}

Eigen::VectorXd nodal_load_vector(const FemProblem& p, const DofMap& d, const NodalLoad& load) {
  (void)p;
  Eigen::VectorXd f = Eigen::VectorXd::Zero(d.total);
  for (auto n : load.nodes)
    for (int c = 0; c < 3; ++c)
      f(d.node_offset[static_cast<std::size_t>(n)] + c) += load.force[static_cast<std::size_t>(c)];
  return f;
}

Eigen::VectorXd gravity_load_vector(const FemProblem& p, const DofMap& d,
                                    const SparseMatrix& mass) {
  Eigen::VectorXd g = Eigen::VectorXd::Zero(d.total);
  for (std::size_t n = 0; n < p.mesh.nodes.size(); ++n)
    for (int c = 0; c < 3; ++c) g(d.node_offset[n] + c) = p.gravity[static_cast<std::size_t>(c)];
  return mass * g;
}

InterfaceMap build_interface(const FemProblem& p) {
  const Mesh& m = p.mesh;
  std::vector<Vec3> directors;
  std::vector<double> thick;
  shell_nodal_directors(p, directors, thick);
  // Faces of the interface, each as (outward-ordered mesh nodes, side): side 0 = the node
  // itself (volume), +1 / -1 = top / bottom copy of a shell node.
  struct SurfFace {
    std::array<std::int32_t, 4> nodes;
    int count;
    int side;
  };
  std::vector<SurfFace> faces;
  auto add_face = [&](std::size_t e, int f) {
    const Element& el = m.elements[e];
    const auto local = face_local_nodes(el.type, f);
    SurfFace sf{{0, 0, 0, 0}, face_node_count(el.type), 0};
    for (int a = 0; a < sf.count; ++a) sf.nodes[a] = el.nodes[local[a]];
    if (el.type == ElementType::quad4) sf.side = f == 1 ? 1 : -1;
    faces.push_back(sf);
  };
  if (!p.interface_surface.empty()) {
    for (const auto& f : m.surfaces.at(p.interface_surface))
      add_face(static_cast<std::size_t>(f.element), f.face);
  } else {
    // Exterior faces of volume elements: used by exactly one element.
    std::map<std::array<std::int32_t, 4>, int> use;
    auto key = [&](std::size_t e, int f) {
      const Element& el = m.elements[e];
      const auto local = face_local_nodes(el.type, f);
      std::array<std::int32_t, 4> k{-1, -1, -1, -1};
      for (int a = 0; a < face_node_count(el.type); ++a) k[a] = el.nodes[local[a]];
      std::sort(k.begin(), k.end());  // triangles: -1 padding sorts first
      return k;
    };
    for (std::size_t e = 0; e < m.elements.size(); ++e)
      if (m.elements[e].type != ElementType::quad4)
        for (int f = 0; f < face_count(m.elements[e].type); ++f) ++use[key(e, f)];
    for (std::size_t e = 0; e < m.elements.size(); ++e) {
      const auto t = m.elements[e].type;
      for (int f = 0; f < face_count(t); ++f)
        if (t == ElementType::quad4 || use[key(e, f)] == 1) add_face(e, f);
    }
  }
  // Interface nodes: unique (mesh node, side), numbered in sorted order (deterministic).
  std::map<std::pair<std::int32_t, int>, std::int32_t> index;
  for (const auto& f : faces)
    for (int a = 0; a < f.count; ++a) index[{f.nodes[a], f.side}] = 0;
  InterfaceMap out;
  for (auto& [k, v] : index) {
    v = static_cast<std::int32_t>(out.mesh_node.size());
    out.mesh_node.push_back(k.first);
    const auto n = static_cast<std::size_t>(k.first);
    const Vec3 off = k.second == 0 ? Vec3::Zero() : Vec3(k.second * 0.5 * thick[n] * directors[n]);
    out.offset.push_back(off);
    const Vec3 x = node_pos(m, k.first) + off;
    for (int c = 0; c < 3; ++c) out.mesh.reference_positions.push_back(x(c));
  }
  for (const auto& f : faces) {
    std::array<std::int32_t, 4> v{};
    for (int a = 0; a < f.count; ++a) v[a] = index.at({f.nodes[a], f.side});
    if (f.count == 3) {
      out.mesh.triangles.insert(out.mesh.triangles.end(), {v[0], v[1], v[2]});
      continue;
    }
    // Split a quad along the diagonal through its lowest-numbered node (a fixed rule, so
    // the same face always gives the same triangles).
    const auto lowest = std::min_element(f.nodes.begin(), f.nodes.end()) - f.nodes.begin();
    const auto r = static_cast<std::size_t>(lowest % 2);
    out.mesh.triangles.insert(out.mesh.triangles.end(),
                              {v[r], v[r + 1], v[r + 2], v[r], v[r + 2], v[(r + 3) % 4]});
  }
  return out;
}

LoadVectors load_vectors(const FemProblem& p, const DofMap& dofs, const SparseMatrix& mass) {
  LoadVectors out;
  out.constant = gravity_load_vector(p, dofs, mass);
  auto add = [&](Eigen::VectorXd f, const TimeFunction& amp) {
    if (amp)
      out.timed.emplace_back(std::move(f), amp);
    else
      out.constant += f;
  };
  for (const auto& pl : p.pressures) add(pressure_load_vector(p, dofs, pl), pl.amplitude);
  for (const auto& nl : p.nodal_loads) add(nodal_load_vector(p, dofs, nl), nl.amplitude);
  return out;
}

SparseMatrix interface_load_matrix(const DofMap& dofs, const InterfaceMap& iface) {
  std::vector<Eigen::Triplet<double, int>> trip;
  for (std::size_t i = 0; i < iface.mesh_node.size(); ++i) {
    const auto n = static_cast<std::size_t>(iface.mesh_node[i]);
    const auto off = dofs.node_offset[n];
    const int col = 3 * static_cast<int>(i);
    auto add = [&](std::int32_t g, int c, double v) {
      const std::int32_t r = dofs.reduced[static_cast<std::size_t>(g)];
      if (r >= 0 && v != 0.0) trip.emplace_back(r, col + c, v);
    };
    for (int c = 0; c < 3; ++c) add(off + c, c, 1.0);
    if (dofs.node_dofs[n] == 6) {
      // moment = offset x f: column c (unit f_c) gives offset x e_c.
      const Vec3& r = iface.offset[i];
      for (int c = 0; c < 3; ++c) {
        const Vec3 m = r.cross(Vec3::Unit(c));
        for (int k = 0; k < 3; ++k) add(off + 3 + k, c, m(k));
      }
    }
  }
  SparseMatrix b(static_cast<Eigen::Index>(dofs.free.size()),
                 static_cast<Eigen::Index>(3 * iface.mesh_node.size()));
  b.setFromTriplets(trip.begin(), trip.end());
  return b;
}

void check_interface_forces(std::span<const double> forces, std::size_t expected, const char* who) {
  if (forces.size() != expected)
    throw std::invalid_argument(std::string(who) + "::set_interface_forces: got " +
                                std::to_string(forces.size()) + " values, expected " +
                                std::to_string(expected) + " (3 per interface node)");
  for (std::size_t i = 0; i < forces.size(); ++i)
    if (!std::isfinite(forces[i]))
      throw std::invalid_argument(std::string(who) +
                                  "::set_interface_forces: non-finite force at entry " +
                                  std::to_string(i));
}

void check_saved_dof_count(const io::H5File& file, const std::string& group, const DofMap& dofs,
                           const char* who) {
  const auto total = file.attribute_int64(group, "dof_count");
  const auto free = file.attribute_int64(group, "free_dof_count");
  if (total == dofs.total && free == static_cast<std::int64_t>(dofs.free.size())) return;
  throw std::runtime_error(
      std::string(who) + ": " + file.path().string() + ":" + group +
      " was saved from a model with a different DOF count (" + std::to_string(total) + ", " +
      std::to_string(free) + " free; this model has " + std::to_string(dofs.total) + ", " +
      std::to_string(dofs.free.size()) +
      " free): the mesh or the clamps changed; the state cannot be continued with this scene");
}

}  // namespace demfem::fem
