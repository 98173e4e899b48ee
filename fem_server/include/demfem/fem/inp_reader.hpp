#pragma once
// Reader for Abaqus input (.inp) decks as Abaqus/CAE, Gmsh, Salome and hand-written decks
// hold them: nodes, elements, sets, element surfaces, materials, solid and shell sections,
// *INCLUDE, parts and instances (flattened, with translation and rotation), *BOUNDARY, *CLOAD,
// *DLOAD, *DSLOAD, *AMPLITUDE and one *STEP with *STATIC, *DYNAMIC or *FREQUENCY. Every other
// keyword is refused naming the keyword and line, except a documented list of harmless ones
// (*HEADING, output requests, ...), some of them with a note. docs/scene_fem.md has the table.
//
// Labels become 0-based indices in file order; the labels are kept in Mesh::node_labels /
// Mesh::element_labels and the source of each node and element in Mesh::*_sources. Every
// error names the file and the line: "beam.inp:17: ...".

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "demfem/fem/fem_problem.hpp"

namespace demfem::fem {

/// @brief Malformed or unsupported .inp input; what() is "file:line: message".
class InpError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// @brief Choices the deck cannot make itself (scene keys of fem.mesh).
struct InpOptions {
  /// C3D8R (reduced integration with hourglass control) has no faithful counterpart here;
  /// without this it is refused. Set, its elements get this formulation.
  std::optional<SolidFormulation> c3d8r_as;
  /// *INCLUDE reads other files (off for the fuzzer, which must not touch the file system).
  bool allow_include = true;
};

/// @brief A *SOLID SECTION or *SHELL SECTION as written in the file (names, not indices).
struct InpSection {
  std::string element_set;  ///< ELSET= (upper case, qualified "INSTANCE.SET" inside parts)
  std::string material;     ///< MATERIAL= (upper case)
  bool shell = false;       ///< *SHELL SECTION
  double thickness = 0.0;   ///< m, shells (first data line); 0 for solids
  std::string where;        ///< "file:line" of the keyword
};

/// @brief *BOUNDARY: fixed DOFs (0..5) of nodes, with their prescribed values.
struct InpBoundary {
  std::vector<std::int32_t> nodes;
  std::array<bool, 6> fixed{};
  std::array<double, 6> value{};
  std::string amplitude;  ///< AMPLITUDE= (upper case), "" = the step's default
  std::string where;
};

/// @brief *CLOAD: force on each listed node in direction `dof` (0..2), N.
struct InpConcentratedLoad {
  std::vector<std::int32_t> nodes;
  int dof = 0;
  double magnitude = 0.0;
  std::string amplitude;
  std::string where;
};

/// @brief *DLOAD Pn / P or *DSLOAD P: pressure on faces, Pa (positive into the body).
struct InpPressure {
  std::vector<Face> faces;
  double magnitude = 0.0;
  std::string amplitude;
  std::string where;
};

/// @brief *DLOAD GRAV: acceleration `magnitude` along the unit `direction`, m/s^2.
struct InpGravity {
  double magnitude = 0.0;
  std::array<double, 3> direction{};
  std::vector<std::int32_t> elements;  ///< the elements it acts on
  std::string amplitude;
  std::string where;
};

/// @brief *AMPLITUDE, DEFINITION=TABULAR or EQUALLY SPACED: (time, factor) points.
struct InpAmplitude {
  std::vector<std::pair<double, double>> points;
  std::string where;
};

/// @brief The deck's analysis step (*STEP with *STATIC, *DYNAMIC or *FREQUENCY).
struct InpStep {
  bool present = false;
  bool dynamic = false;    ///< *DYNAMIC (else *STATIC or *FREQUENCY)
  bool frequency = false;  ///< *FREQUENCY: natural frequencies (fem.analysis = "modal")
  int modes = 0;           ///< *FREQUENCY: number of eigenvalues asked for (0 = not given)
  /// "*STATIC", "*DYNAMIC" or "*FREQUENCY"
  const char* procedure() const {
    return frequency ? "*FREQUENCY" : dynamic ? "*DYNAMIC" : "*STATIC";
  }
  double period = 1.0;     ///< time period of the step (data line of the procedure), s
  double increment = 0.0;  ///< initial time increment given, s (0 = not given)
  bool ramp = false;       ///< loads without AMPLITUDE= ramp over the step (else step)
  std::string where;       ///< "file:line" of *STEP
  std::string procedure_where;
};

/// @brief Everything read from a .inp deck.
struct InpModel {
  Mesh mesh;
  std::vector<Material> materials;          ///< names upper case; unset properties stay 0
  std::vector<std::string> material_where;  ///< "file:line" of each *MATERIAL
  std::vector<InpSection> sections;
  // History (and model-level *BOUNDARY): what the deck applies.
  std::vector<InpBoundary> boundaries;
  std::vector<InpConcentratedLoad> concentrated_loads;
  std::vector<InpPressure> pressures;
  std::vector<InpGravity> gravity;
  std::map<std::string, InpAmplitude> amplitudes;
  InpStep step;
  /// Run-time information: which formulation each element type maps to, keywords accepted
  /// with a caveat, set names qualified by instance. Each starts with "file[:line]: ".
  std::vector<std::string> notes;
};

/// @brief Reads a deck (following *INCLUDE). Set, surface and material names are
/// case-insensitive in Abaqus and are stored upper case.
InpModel read_inp_model(const std::filesystem::path& file, const InpOptions& options = {});

/// @brief Reads only the mesh (all elements get section 0).
Mesh read_inp(const std::filesystem::path& file, const InpOptions& options = {});

/// @brief Parses .inp text; `name` is used in messages and, for *INCLUDE, as the path the
/// included files are relative to.
InpModel parse_inp(const std::string& text, const std::string& name,
                   const InpOptions& options = {});

/// @brief Limits of *INCLUDE: nesting depth, and all files of one deck together (bytes).
inline constexpr int kInpIncludeDepth = 10;

}  // namespace demfem::fem
