#pragma once
// The structure as the FEM engine takes it: mesh, materials, sections, constraints, loads
// and analysis settings. Built by the readers (Abaqus .inp, structured mesher, scene) and
// consumed by FemSolver. Units: SI.

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace demfem::fem {

enum class ElementType : std::uint8_t {
  hex8,   ///< 8-node hexahedron; its formulation is Element::formulation
  tet4,   ///< 4-node linear tetrahedron
  quad4,  ///< 4-node shell (MITC4), 6 DOF per node, thickness from its section
};

/// @brief How a hex8 is integrated. Both pass the patch test; they differ in bending on
/// coarse meshes (docs/verification.md).
enum class SolidFormulation : std::uint8_t {
  /// Wilson-Taylor incompatible modes (QM6 with Taylor's correction): locking-free in bending
  /// and near incompressibility. Abaqus C3D8I; the default of generated box meshes.
  incompatible_modes,
  /// Full 2x2x2 integration with the volumetric strain replaced by its element mean (B-bar,
  /// selectively reduced integration, Hughes 1980): Abaqus C3D8. Free of volumetric locking,
  /// shear-locks in bending like every fully integrated trilinear brick.
  selective_reduced,
};

/// @brief Short name of a formulation for messages ("incompatible modes", "B-bar").
const char* formulation_name(SolidFormulation f);

/// Node count of each element type.
constexpr int nodes_per_element(ElementType t) {
  return t == ElementType::hex8 ? 8 : 4;
}

/// @brief One element: type, node indices (0-based, Abaqus ordering), and its section.
struct Element {
  ElementType type = ElementType::hex8;
  SolidFormulation formulation = SolidFormulation::incompatible_modes;  ///< hex8 only
  std::array<std::int32_t, 8> nodes{};  ///< first nodes_per_element(type) are used
  std::int32_t section = 0;             ///< index into FemProblem::sections
};

/// @brief Isotropic linear-elastic material.
struct Material {
  std::string name;
  double youngs_modulus = 0.0;  ///< Pa
  double poisson_ratio = 0.0;   ///< -
  double density = 0.0;         ///< kg/m^3
};

/// @brief Material (and thickness for shells) of a set of elements.
struct Section {
  std::int32_t material = 0;  ///< index into FemProblem::materials
  double thickness = 0.0;     ///< m, shells only
};

/// @brief A mesh face: element index and local face number (Abaqus S1..S6 -> 0..5; shells:
/// 0 = bottom (SNEG), 1 = top (SPOS)).
struct Face {
  std::int32_t element = 0;
  std::int32_t face = 0;
};

/// @brief Where a node or element was defined: Mesh::source_files[file], 1-based line, and
/// the part instance it belongs to (Mesh::instance_names[instance], -1 = none).
struct SourceLine {
  std::int32_t file = -1;
  std::int32_t line = 0;
  std::int32_t instance = -1;
};

/// @brief Mesh with named node sets, element sets and surfaces.
struct Mesh {
  std::vector<std::array<double, 3>> nodes;  ///< m
  std::vector<Element> elements;
  std::vector<std::int64_t> node_labels;     ///< label in the source file, per node
  std::vector<std::int64_t> element_labels;  ///< label in the source file, per element
  /// Source of each node / element (empty for generated meshes), so that a solver-level
  /// message can name the file and line.
  std::vector<SourceLine> node_sources, element_sources;
  std::vector<std::string> source_files;
  std::vector<std::string> instance_names;  ///< Abaqus part instances (labels repeat per instance)
  std::map<std::string, std::vector<std::int32_t>> node_sets;
  std::map<std::string, std::vector<std::int32_t>> element_sets;
  std::map<std::string, std::vector<Face>> surfaces;
};

/// @brief "node 17 (beam.inp:23)", "node PART-1-1.17 (beam.inp:23)" or "node 5" (label, or
/// index + 1 when the mesh has no labels) for messages.
std::string node_name(const Mesh& mesh, std::size_t node);
/// @brief Same for elements: "element 7 (beam.inp:40)".
std::string element_name(const Mesh& mesh, std::size_t element);
/// @brief Nodes that no element uses (Gmsh and CAE exports often keep such points). The
/// solver leaves their DOFs out of the system (they stay at zero).
std::vector<std::int32_t> orphan_nodes(const Mesh& mesh);

/// @brief Scalar function of time (load amplitude); dimensionless factor.
using TimeFunction = std::function<double(double)>;

/// @brief Fixed DOFs of a node set (DOF 0..2 translations, 3..5 rotations for shells), held
/// at `value` (m, rad; non-zero values are supported by the static solve only).
struct Constraint {
  std::vector<std::int32_t> nodes;
  std::array<bool, 6> fixed{true, true, true, true, true, true};
  std::array<double, 6> value{};
};

/// @brief Uniform pressure p(t) = magnitude * amplitude(t) on faces, acting against the
/// outward face normal (positive pressure pushes into the body), Pa.
struct PressureLoad {
  std::vector<Face> faces;
  double magnitude = 0.0;
  TimeFunction amplitude;  ///< empty = constant 1
};

/// @brief Point force on nodes, N, times an amplitude.
struct NodalLoad {
  std::vector<std::int32_t> nodes;
  std::array<double, 3> force{};
  TimeFunction amplitude;
};

enum class MassLumping : std::uint8_t { consistent, lumped };

/// @brief Bossak-Newmark parameters in the standard sign convention (alpha <= 0 damps).
/// Default: alpha = -0.1, gamma = 1/2 - alpha, beta = (1 - alpha)^2 / 4 (thesis' choice).
struct BossakParameters {
  double alpha = -0.1;
  double beta = 0.3025;
  double gamma = 0.6;
};

/// @brief Rayleigh damping C = mass_factor M + stiffness_factor K.
struct RayleighDamping {
  double mass_factor = 0.0;       ///< 1/s
  double stiffness_factor = 0.0;  ///< s
};

/// @brief Everything the FEM engine needs to build and solve a structure.
struct FemProblem {
  Mesh mesh;
  std::vector<Material> materials;
  std::vector<Section> sections;
  std::vector<Constraint> constraints;
  std::vector<PressureLoad> pressures;
  std::vector<NodalLoad> nodal_loads;
  std::array<double, 3> gravity{0.0, 0.0, 0.0};  ///< m/s^2; zero = no self weight
  MassLumping mass = MassLumping::consistent;
  BossakParameters bossak;
  RayleighDamping damping;
  /// Surface that is coupled to the DEM: a surface name, or "" for the whole exterior
  /// surface of the volume mesh (shells: both offset surfaces of all shell elements).
  std::string interface_surface;
};

}  // namespace demfem::fem
