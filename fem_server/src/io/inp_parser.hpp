#pragma once
// The .inp parser (internal): one pass over the deck's keyword blocks collects model data per
// scope (the flat model / assembly, each part, each instance block) and history data; build()
// then flattens parts into instances and resolves every name. Model data is in
// inp_model.cpp, history data (steps, boundary conditions, loads, amplitudes) in inp_step.cpp.

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include "demfem/fem/inp_reader.hpp"
#include "inp_deck.hpp"

namespace demfem::fem::inp {

struct RawNode {
  std::int64_t label;
  std::array<double, 3> x;
  Loc loc;
};

/// Abaqus element types the reader knows, indexed by RawElement::abaqus.
inline constexpr const char* kAbaqusTypes[] = {"C3D8", "C3D8I", "C3D8R", "C3D4", "S4", "S4R"};

struct RawElement {
  std::int64_t label;
  ElementType type;
  SolidFormulation formulation;
  std::uint8_t abaqus;  ///< index into kAbaqusTypes
  std::vector<std::int64_t> nodes;
  Loc loc;
};

/// One data entry of a set or surface definition.
struct SetEntry {
  std::string token;
  std::string face;  // surfaces only
  Loc loc;
};

enum class SetKind { node, element, surface, node_from_elset };

struct SetOp {
  SetKind kind;
  std::string name;  ///< unqualified, upper case
  bool generate = false;
  Loc loc;
  std::vector<SetEntry> entries;
  std::vector<std::int64_t> direct_labels;  ///< labels added by *NODE,NSET= / *ELEMENT,ELSET=
  std::vector<Loc> direct_locs;
  std::string instance;  ///< INSTANCE= of an assembly-level set (upper case), "" = none
};

struct RawSection {
  InpSection section;  ///< element_set unqualified
  Loc loc;
};

/// Mesh data of one scope: the flat model (or assembly level), a part, or the extra content
/// of an *INSTANCE block.
struct Scope {
  std::vector<RawNode> nodes;
  std::vector<RawElement> elements;
  std::vector<SetOp> ops;
  std::vector<RawSection> sections;
};

struct RawInstance {
  std::string name;  ///< upper case
  std::string part;  ///< upper case
  Loc loc;
  std::array<double, 3> translation{};
  bool rotate = false;
  std::array<double, 3> axis_a{}, axis_b{};
  double angle_deg = 0.0;
  Scope own;  ///< mesh data inside the *INSTANCE block
};

// History data, resolved against the flattened mesh at the end.
struct RawBoundary {
  std::string token;  ///< node label, "INSTANCE.label" or node set
  std::array<bool, 6> fixed{};
  std::array<double, 6> value{};
  std::string amplitude;
  Loc loc;
};
struct RawCload {
  std::string token;
  int dof = 0;
  double magnitude = 0.0;
  std::string amplitude;
  Loc loc;
};
struct RawDload {
  std::string token;  ///< element label, "INSTANCE.label", element set, or "" (whole model)
  std::string type;   ///< P, P1..P6, GRAV
  double magnitude = 0.0;
  std::array<double, 3> direction{};
  std::string amplitude;
  Loc loc;
};
struct RawDsload {
  std::string surface;
  double magnitude = 0.0;
  std::string amplitude;
  Loc loc;
};

class Parser {
 public:
  Parser(const Deck& deck, const InpOptions& options) : deck_(deck), options_(options) {}
  InpModel run();

 private:
  enum class Block { model, part, assembly, instance };

  // ---- dispatch (inp_model.cpp) ----
  void handle(const Keyword& kw, std::size_t begin, std::size_t end);
  bool handle_structure(const Keyword& kw, std::size_t begin, std::size_t end);
  bool handle_mesh(const Keyword& kw, std::size_t begin, std::size_t end);
  bool handle_material(const Keyword& kw, std::size_t begin, std::size_t end);
  bool handle_ignored(const Keyword& kw);
  [[noreturn]] void refuse(const Keyword& kw);
  void check_params(const Keyword& kw, std::initializer_list<const char*> accepted) const;
  std::string required_name(const Keyword& kw, std::string_view key) const;
  std::vector<std::string> single_data_line(const Keyword& kw, std::size_t begin,
                                            std::size_t end) const;
  Scope& scope();
  void read_nodes(const Keyword& kw, std::size_t begin, std::size_t end);
  void read_elements(const Keyword& kw, std::size_t begin, std::size_t end);
  void read_set_entries(SetOp& op, std::size_t begin, std::size_t end);
  Material& current_material(const Keyword& kw);
  void note(Loc loc, const std::string& text);

  // ---- history (inp_step.cpp) ----
  bool handle_history(const Keyword& kw, std::size_t begin, std::size_t end);
  void read_boundary(const Keyword& kw, std::size_t begin, std::size_t end);
  void read_cload(const Keyword& kw, std::size_t begin, std::size_t end);
  void read_dload(const Keyword& kw, std::size_t begin, std::size_t end);
  void read_dsload(const Keyword& kw, std::size_t begin, std::size_t end);
  void read_amplitude(const Keyword& kw, std::size_t begin, std::size_t end);
  void read_procedure(const Keyword& kw, std::size_t begin, std::size_t end, bool dynamic);
  void read_frequency(const Keyword& kw, std::size_t begin, std::size_t end);
  void resolve_history();
  std::vector<std::int32_t> history_nodes(const std::string& token, Loc loc) const;
  std::vector<std::int32_t> history_elements(const std::string& token, Loc loc) const;

  // ---- building the mesh (inp_model.cpp) ----
  void build();
  void add_scope_mesh(const Scope& s, int scope_id, const RawInstance* inst);
  void resolve_ops(const std::vector<SetOp>& ops, int scope_id, const std::string& prefix);
  std::vector<std::int32_t> resolve_set(const SetOp& op, int scope_id, const std::string& prefix);
  std::vector<Face> resolve_surface(const SetOp& op, int scope_id, const std::string& prefix);
  /// A set of the mesh for a name used in scope `scope_id` (qualified by the instance's
  /// prefix inside an instance; "INSTANCE.SET" or a unique alias at the assembly level).
  const std::vector<std::int32_t>* find_set(
      const std::map<std::string, std::vector<std::int32_t>>& sets, const std::string& name,
      const std::string& prefix) const;
  /// Index of a label in a scope; "INSTANCE.label" tokens select the instance's scope.
  std::optional<std::int32_t> find_label(bool node, const std::string& token, int scope_id, Loc loc,
                                         std::int64_t* label_out = nullptr) const;
  int face_number(const std::string& face, ElementType type, Loc loc,
                  const std::string& surface) const;
  void add_aliases();
  void finish_sections();

  const Deck& deck_;
  const InpOptions& options_;
  InpModel model_;

  Block block_ = Block::model;
  Loc block_loc_;
  Scope global_;
  std::map<std::string, Scope> parts_;
  std::string current_part_;
  std::vector<RawInstance> instances_;
  std::vector<Loc> material_locs_;
  std::map<std::string, std::vector<Loc>> ignored_;  ///< harmless keywords seen

  // Label maps per scope: 0 = flat model / assembly, 1 + k = instance k.
  std::vector<std::unordered_map<std::int64_t, std::int32_t>> node_index_, element_index_;
  std::vector<Loc> node_locs_, element_locs_;
  std::map<std::string, int> instance_scope_;  ///< instance name -> scope id

  bool material_open_ = false;  ///< material options may follow (*MATERIAL seen just before)

  // History.
  int steps_ = 0;
  bool in_step_ = false;
  bool procedure_ = false;
  bool explicit_step_amplitude_ = false;  ///< *STEP, AMPLITUDE= given
  Loc step_loc_;
  std::vector<RawBoundary> boundaries_;
  std::vector<RawCload> cloads_;
  std::vector<RawDload> dloads_;
  std::vector<RawDsload> dsloads_;
};

}  // namespace demfem::fem::inp
