#pragma once
// Reader for the subset of the Abaqus input (.inp) format that meshes exported from
// Abaqus/CAE, Gmsh or Salome use: nodes, C3D8/C3D8I, C3D4, S4/S4R elements, node and element
// sets, element-based surfaces, materials and solid/shell sections. Keywords a mesh does not
// need (*HEADING, *STEP, *BOUNDARY, ...) are skipped with their data lines.
//
// Labels become 0-based indices in file order; the labels are kept in Mesh::node_labels /
// Mesh::element_labels. Every error names the file and the line: "beam.inp:17: ...".

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "demfem/fem/fem_problem.hpp"

namespace demfem::fem {

/// @brief Malformed or unsupported .inp input; what() is "file:line: message".
class InpError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// @brief A *SOLID SECTION or *SHELL SECTION as written in the file (names, not indices).
struct InpSection {
  std::string element_set;  ///< ELSET= (upper case, as all names from the file)
  std::string material;     ///< MATERIAL= (upper case)
  bool shell = false;       ///< *SHELL SECTION
  double thickness = 0.0;   ///< m, shells (first data line); 0 for solids
};

/// @brief Everything read from a .inp file.
struct InpModel {
  Mesh mesh;
  std::vector<Material> materials;  ///< names upper case; unset properties stay 0
  std::vector<InpSection> sections;
};

/// @brief Reads mesh, materials and sections. Set, surface and material names are
/// case-insensitive in Abaqus and are stored upper case.
InpModel read_inp_model(const std::filesystem::path& file);

/// @brief Reads only the mesh (all elements get section 0).
Mesh read_inp(const std::filesystem::path& file);

/// @brief Parses .inp text; `name` is used in messages and to report the file.
InpModel parse_inp(const std::string& text, const std::string& name);

}  // namespace demfem::fem
