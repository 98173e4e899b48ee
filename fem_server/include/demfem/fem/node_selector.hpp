#pragma once
// Choosing nodes and faces of a mesh by name or by position, for clamps, loads and the
// coupled surface.
//
// Node selector: one of
//   * a node set name (exact, or case-insensitive: .inp names are upper case),
//   * "all",
//   * an expression: comparisons of x, y or z with a number, joined by "and":
//       "x <= 0", "z >= 0.1", "x <= 1e-9 and y > 0", "0.5 <= x", "z == 0.18"
//     Operators: <, <=, >, >=, ==. Comparisons are made with a tolerance
//     tol = 1e-6 * (diagonal of the mesh's bounding box): "x <= c" holds for x <= c + tol,
//     "x >= c" for x >= c - tol, "x == c" for |x - c| <= tol, while the strict "x < c" needs
//     x < c - tol and "x > c" needs x > c + tol (strictly inside, beyond round-off).
// Face selector: a surface name (exact or case-insensitive), or a node selector, meaning the
// exterior faces whose nodes all satisfy it ("exterior" = all exterior faces). Exterior faces
// of volume elements are those not shared with another element; for shell (quad4) elements
// the selector takes the SPOS face (face 1, the side the element normal points to).

#include <array>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "demfem/fem/fem_problem.hpp"

namespace demfem::fem {

/// @brief A selector that names no set and does not parse; what() says why.
class SelectorError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// @brief A parsed geometric expression; true for points that satisfy all comparisons.
class NodePredicate {
 public:
  /// Parses `expression` (grammar above); throws SelectorError naming the bad token.
  static NodePredicate parse(std::string_view expression, double tolerance);
  bool operator()(const std::array<double, 3>& x) const;

 private:
  struct Comparison {
    int axis;  // 0, 1, 2
    int op;    // 0 <, 1 <=, 2 >, 3 >=, 4 ==
    double value;
  };
  std::vector<Comparison> terms_;
  double tolerance_ = 0.0;
};

/// @brief Selector tolerance of a mesh: 1e-6 times its bounding-box diagonal.
double selector_tolerance(const Mesh& mesh);

/// @brief Nodes (sorted, 0-based) chosen by `selector`; throws SelectorError if the selector
/// is neither a node set, "all", nor a valid expression, or if it selects no node.
std::vector<std::int32_t> select_nodes(const Mesh& mesh, std::string_view selector);

/// @brief Faces chosen by `selector` (see above); throws SelectorError when nothing matches.
std::vector<Face> select_faces(const Mesh& mesh, std::string_view selector);

/// @brief Node indices of a face, ordered so that the right-hand rule gives the outward
/// normal (element_topology.hpp; shells: SNEG reversed, SPOS element order). Hex faces have 4
/// nodes, tet faces 3. Abaqus numbering: C3D8 S1 = nodes 1-2-3-4, S2 = 5-8-7-6,
/// S3 = 1-5-6-2, S4 = 2-6-7-3, S5 = 3-7-8-4, S6 = 4-8-5-1; C3D4 S1 = 1-2-3, S2 = 1-4-2,
/// S3 = 2-4-3, S4 = 3-4-1 (Abaqus lists them with inward normals; returned reversed).
std::vector<std::int32_t> face_nodes(const Mesh& mesh, const Face& face);

/// @brief All exterior faces of the volume elements plus the SPOS face of every shell.
std::vector<Face> exterior_faces(const Mesh& mesh);

/// @brief Area of a face in the reference configuration, m^2 (planar split into triangles).
double face_area(const Mesh& mesh, const Face& face);

}  // namespace demfem::fem
