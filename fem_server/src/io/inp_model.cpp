// Model data of the .inp reader: nodes, elements, sets, surfaces, materials, sections, and
// building the flat mesh from parts and instances (see inp_parser.hpp).
#include <algorithm>
#include <cmath>

#include "inp_parser.hpp"

namespace demfem::fem::inp {

namespace {

struct TypeInfo {
  ElementType type;
  SolidFormulation formulation;
  int nodes;
  std::uint8_t abaqus;
};

const char* kSupportedTypes = "C3D8, C3D8I, C3D8R (on request), C3D4, S4, S4R";

std::string formulation_note(const std::string& abaqus, SolidFormulation f) {
  if (abaqus == "C3D8")
    return "hex8, full 2x2x2 integration with the mean-dilatation B-bar (Abaqus C3D8's "
           "selectively reduced integration)";
  if (abaqus == "C3D8I") return "hex8 with incompatible modes (Wilson-Taylor, as Abaqus C3D8I)";
  if (abaqus == "C3D8R")
    return std::string("hex8 with ") +
           (f == SolidFormulation::incompatible_modes ? "incompatible modes (C3D8I)"
                                                      : "the B-bar of C3D8") +
           ", as fem.mesh.c3d8r_as asks (Abaqus C3D8R integrates once with hourglass "
           "control: results differ, most on coarse meshes in bending)";
  if (abaqus == "C3D4") return "tet4, the linear tetrahedron (as Abaqus C3D4)";
  if (abaqus == "S4")
    return "quad4 MITC4 shell (Dvorkin-Bathe transverse shear, full 2x2 integration; Abaqus "
           "S4 also enhances the membrane for in-plane bending, MITC4 does not)";
  return "quad4 MITC4 shell with full 2x2 integration (Abaqus S4R integrates once with "
         "hourglass control; results differ slightly on coarse meshes)";
}

void merge_into(std::vector<std::int32_t>& set, std::vector<std::int32_t> add) {
  set.insert(set.end(), add.begin(), add.end());
  std::sort(set.begin(), set.end());
  set.erase(std::unique(set.begin(), set.end()), set.end());
}

}  // namespace

Scope& Parser::scope() {
  switch (block_) {
    case Block::part:
      return parts_.at(current_part_);
    case Block::instance:
      return instances_.back().own;
    default:
      return global_;
  }
}

Material& Parser::current_material(const Keyword& kw) {
  if (!material_open_ || model_.materials.empty())
    deck_.fail(kw.loc, "*" + kw.name + " outside of a *MATERIAL (it must follow *MATERIAL)");
  return model_.materials.back();
}

bool Parser::handle_material(const Keyword& kw, std::size_t begin, std::size_t end) {
  const std::string& k = kw.name;
  const auto& lines = deck_.lines();
  if (k == "MATERIAL") {
    check_params(kw, {"NAME"});
    if (in_step_) deck_.fail(kw.loc, "*MATERIAL inside a *STEP");
    Material m;
    m.name = required_name(kw, "NAME");
    for (const auto& other : model_.materials) {
      if (other.name == m.name) deck_.fail(kw.loc, "material " + m.name + " is defined twice");
    }
    model_.materials.push_back(m);
    model_.material_where.push_back(deck_.where(kw.loc));
    material_open_ = true;
    if (begin != end) deck_.fail(lines[begin].loc, "*MATERIAL takes no data lines");
    return true;
  }
  if (k == "ELASTIC") {
    check_params(kw, {"TYPE"});
    Material& m = current_material(kw);
    const std::string type = upper(kw.param("TYPE").value_or("ISOTROPIC"));
    if (type != "ISOTROPIC")
      deck_.fail(kw.loc, "*ELASTIC TYPE=" + type + " is not supported (isotropic only)");
    auto parts = single_data_line(kw, begin, end);
    const Loc l = lines[begin].loc;
    if (parts.size() < 2) deck_.fail(l, "*ELASTIC needs E, nu");
    if (parts.size() > 2) deck_.fail(l, "*ELASTIC: temperature-dependent data is not supported");
    m.youngs_modulus = deck_.number(parts[0], l, "Young's modulus");
    m.poisson_ratio = deck_.number(parts[1], l, "Poisson's ratio");
    if (m.youngs_modulus <= 0.0) deck_.fail(l, "Young's modulus must be > 0");
    if (m.poisson_ratio <= -1.0 || m.poisson_ratio >= 0.5) {
      deck_.fail(l, "Poisson's ratio must be in (-1, 0.5)");
    }
    return true;
  }
  if (k == "DENSITY") {
    check_params(kw, {});
    Material& m = current_material(kw);
    auto parts = single_data_line(kw, begin, end);
    const Loc l = lines[begin].loc;
    if (parts.size() != 1)
      deck_.fail(l, "*DENSITY needs one value (temperature-dependent data is not supported)");
    m.density = deck_.number(parts[0], l, "density");
    if (m.density < 0.0) deck_.fail(l, "density must be >= 0");
    return true;
  }
  if (k == "EXPANSION" || k == "CONDUCTIVITY" || k == "SPECIFIC HEAT" || k == "LATENT HEAT") {
    // Thermal properties: without temperature loads (refused) they do not act.
    current_material(kw);
    note(kw.loc, "*" + k + " of material " + model_.materials.back().name +
                     " has no effect (no temperature loads in a demfem analysis)");
    return true;
  }
  return false;
}

bool Parser::handle_mesh(const Keyword& kw, std::size_t begin, std::size_t end) {
  const std::string& k = kw.name;
  const auto& lines = deck_.lines();
  const bool mesh_keyword = k == "NODE" || k == "ELEMENT" || k == "NSET" || k == "ELSET" ||
                            k == "SURFACE" || k == "SOLID SECTION" || k == "SHELL SECTION" ||
                            k == "ORIENTATION";
  if (!mesh_keyword) return false;
  if (in_step_) deck_.fail(kw.loc, "*" + k + " inside a *STEP (model data comes before it)");
  Scope& sc = scope();
  if (k == "NODE") {
    check_params(kw, {"NSET"});
    read_nodes(kw, begin, end);
  } else if (k == "ELEMENT") {
    check_params(kw, {"TYPE", "ELSET"});
    read_elements(kw, begin, end);
  } else if (k == "NSET") {
    check_params(kw, {"NSET", "ELSET", "GENERATE", "INTERNAL", "UNSORTED", "INSTANCE"});
    SetOp op{kw.flag("ELSET") ? SetKind::node_from_elset : SetKind::node,
             required_name(kw, "NSET"),
             kw.flag("GENERATE"),
             kw.loc,
             {},
             {},
             {},
             upper(kw.param("INSTANCE").value_or(""))};
    if (!op.instance.empty() && block_ != Block::assembly && block_ != Block::model)
      deck_.fail(kw.loc, "INSTANCE= is only allowed at the assembly level");
    if (op.kind == SetKind::node_from_elset) {
      op.entries.push_back({upper(*kw.param("ELSET")), "", kw.loc});
      if (begin != end) deck_.fail(lines[begin].loc, "*NSET with ELSET= takes no data lines");
    } else {
      read_set_entries(op, begin, end);
    }
    sc.ops.push_back(std::move(op));
  } else if (k == "ELSET") {
    check_params(kw, {"ELSET", "GENERATE", "INTERNAL", "UNSORTED", "INSTANCE"});
    SetOp op{SetKind::element,
             required_name(kw, "ELSET"),
             kw.flag("GENERATE"),
             kw.loc,
             {},
             {},
             {},
             upper(kw.param("INSTANCE").value_or(""))};
    if (!op.instance.empty() && block_ != Block::assembly && block_ != Block::model)
      deck_.fail(kw.loc, "INSTANCE= is only allowed at the assembly level");
    read_set_entries(op, begin, end);
    sc.ops.push_back(std::move(op));
  } else if (k == "SURFACE") {
    check_params(kw, {"NAME", "TYPE", "INTERNAL"});
    const std::string type = upper(kw.param("TYPE").value_or("ELEMENT"));
    if (type != "ELEMENT") {
      deck_.fail(kw.loc, "*SURFACE TYPE=" + type + " is not supported (only TYPE=ELEMENT)");
    }
    SetOp op{SetKind::surface, required_name(kw, "NAME"), false, kw.loc, {}, {}, {}, ""};
    for (std::size_t i = begin; i < end; ++i) {
      auto parts = split_commas(lines[i].text);
      if (parts.size() != 2 || parts[1].empty()) {
        deck_.fail(
            lines[i].loc,
            "surface " + op.name + ": expected '<element set or label>, <face S1..S6|SPOS|SNEG>'");
      }
      op.entries.push_back({parts[0], upper(parts[1]), lines[i].loc});
    }
    sc.ops.push_back(std::move(op));
  } else if (k == "SOLID SECTION" || k == "SHELL SECTION") {
    const bool shell = k == "SHELL SECTION";
    if (shell)
      check_params(kw, {"ELSET", "MATERIAL", "OFFSET", "ORIENTATION", "SECTION INTEGRATION",
                        "CONTROLS", "TEMPERATURE", "POISSON", "DENSITY"});
    else
      check_params(kw, {"ELSET", "MATERIAL", "ORIENTATION", "CONTROLS"});
    RawSection rs;
    InpSection& s = rs.section;
    s.element_set = required_name(kw, "ELSET");
    s.material = required_name(kw, "MATERIAL");
    s.shell = shell;
    s.where = deck_.where(kw.loc);
    rs.loc = kw.loc;
    if (auto o = kw.param("ORIENTATION"))
      note(kw.loc, "ORIENTATION=" + upper(*o) +
                       " changes only the frame Abaqus reports results in for isotropic "
                       "materials (the only kind demfem reads); demfem writes global components");
    if (kw.param("CONTROLS"))
      note(kw.loc,
           "CONTROLS= (hourglass or element controls) does not apply to demfem's "
           "elements");
    if (shell) {
      if (auto off = kw.param("OFFSET")) {
        const std::string o = upper(*off);
        bool zero = o == "MIDSURFACE";
        if (!zero && looks_numeric(o)) zero = deck_.number(o, kw.loc, "shell offset") == 0.0;
        if (!zero) {
          deck_.fail(kw.loc, "*SHELL SECTION, OFFSET=" + o +
                                 " moves the reference surface off the mid-surface; demfem's "
                                 "shells are at their mid-surface (OFFSET=0). Move the nodes to "
                                 "the mid-surface in the preprocessor");
        }
      }
      if (kw.param("TEMPERATURE") || kw.param("POISSON") || kw.param("DENSITY"))
        deck_.fail(kw.loc,
                   "*SHELL SECTION: TEMPERATURE=, POISSON= and DENSITY= are not "
                   "supported (they change the section's behaviour)");
      if (auto si = kw.param("SECTION INTEGRATION"))
        note(kw.loc, "SECTION INTEGRATION=" + upper(*si) +
                         ": a linear elastic homogeneous section is integrated exactly either way");
      auto parts = single_data_line(kw, begin, end);
      if (parts.empty()) deck_.fail(lines[begin].loc, "*SHELL SECTION needs a thickness");
      s.thickness = deck_.number(parts[0], lines[begin].loc, "shell thickness");
      if (s.thickness <= 0.0) deck_.fail(lines[begin].loc, "shell thickness must be > 0");
    } else if (begin != end) {
      // The optional data line holds a thickness for plane elements; CAE writes ",".
      if (end - begin > 1) deck_.fail(lines[begin + 1].loc, "*SOLID SECTION takes one data line");
      for (const auto& t : split_commas(lines[begin].text))
        if (!t.empty())
          deck_.fail(lines[begin].loc, "*SOLID SECTION: a data value (" + t +
                                           ") applies to plane or beam elements, which demfem "
                                           "does not have");
    }
    sc.sections.push_back(std::move(rs));
  } else {  // ORIENTATION
    note(kw.loc,
         "*ORIENTATION accepted: for isotropic materials (the only kind demfem reads) "
         "it changes only the frame Abaqus reports results in; demfem writes global "
         "components");
  }
  return true;
}

void Parser::read_nodes(const Keyword& kw, std::size_t begin, std::size_t end) {
  const auto& lines = deck_.lines();
  std::optional<std::string> nset;
  if (auto v = kw.param("NSET")) nset = upper(*v);
  SetOp op{SetKind::node, nset.value_or(""), false, kw.loc, {}, {}, {}, ""};
  Scope& sc = scope();
  for (std::size_t i = begin; i < end; ++i) {
    const Loc ln = lines[i].loc;
    auto parts = split_commas(lines[i].text);
    if (parts.empty()) deck_.fail(ln, "empty node line");
    const std::int64_t lab = deck_.label(parts[0], ln, "node");
    if (parts.size() != 4) {
      deck_.fail(ln, "node " + std::to_string(lab) + " has " + std::to_string(parts.size() - 1) +
                         " coordinates, needs 3 (x, y, z)");
    }
    RawNode n{lab, {}, ln};
    for (int c = 0; c < 3; ++c) {
      n.x[c] =
          deck_.number(parts[c + 1], ln,
                       std::string("coordinate ") + "xyz"[c] + " of node " + std::to_string(lab));
    }
    sc.nodes.push_back(n);
    if (nset) {
      op.direct_labels.push_back(lab);
      op.direct_locs.push_back(ln);
    }
  }
  if (nset) sc.ops.push_back(std::move(op));
}

void Parser::read_elements(const Keyword& kw, std::size_t begin, std::size_t end) {
  const auto& lines = deck_.lines();
  auto type_param = kw.param("TYPE");
  if (!type_param) deck_.fail(kw.loc, "*ELEMENT needs TYPE=");
  const std::string abaqus = upper(*type_param);
  TypeInfo info{};
  if (abaqus == "C3D8") {
    info = {ElementType::hex8, SolidFormulation::selective_reduced, 8, 0};
  } else if (abaqus == "C3D8I") {
    info = {ElementType::hex8, SolidFormulation::incompatible_modes, 8, 1};
  } else if (abaqus == "C3D8R") {
    if (!options_.c3d8r_as) {
      deck_.fail(
          kw.loc,
          "element type C3D8R (one integration point with hourglass control) is not "
          "available: demfem has no hourglass-controlled hexahedron, and solving C3D8R as "
          "another formulation changes the results (on the 2x12 mesh of Abaqus' Getting "
          "Started cantilever C3D8R is 32 % too soft, C3D8 75 % too stiff, C3D8I "
          "within 0.1 %; docs/verification.md). Change the type in the deck to C3D8I (incompatible "
          "modes) or C3D8 (B-bar), or set fem.mesh.c3d8r_as = \"C3D8I\" or \"C3D8\" in "
          "the scene to accept that mapping");
    }
    info = {ElementType::hex8, *options_.c3d8r_as, 8, 2};
  } else if (abaqus == "C3D4") {
    info = {ElementType::tet4, SolidFormulation::incompatible_modes, 4, 3};
  } else if (abaqus == "S4" || abaqus == "S4R") {
    info = {ElementType::quad4, SolidFormulation::incompatible_modes, 4,
            static_cast<std::uint8_t>(abaqus == "S4" ? 4 : 5)};
  } else {
    deck_.fail(kw.loc,
               "element type " + abaqus + " is not supported (supported: " + kSupportedTypes + ")");
  }
  std::optional<std::string> elset;
  if (auto v = kw.param("ELSET")) elset = upper(*v);
  SetOp op{SetKind::element, elset.value_or(""), false, kw.loc, {}, {}, {}, ""};
  Scope& sc = scope();
  for (std::size_t i = begin; i < end; ++i) {
    const Loc ln = lines[i].loc;
    std::vector<std::string> parts = split_commas(lines[i].text);
    // A data line that ends with a comma continues on the next line (long elements).
    while (ends_with_comma(lines[i].text) && static_cast<int>(parts.size()) < info.nodes + 1 &&
           i + 1 < end) {
      ++i;
      auto more = split_commas(lines[i].text);
      parts.insert(parts.end(), more.begin(), more.end());
    }
    if (parts.empty()) deck_.fail(ln, "empty element line");
    const std::int64_t lab = deck_.label(parts[0], ln, "element");
    const int given = static_cast<int>(parts.size()) - 1;
    if (given != info.nodes) {
      deck_.fail(ln, "element " + std::to_string(lab) + " has " + std::to_string(given) +
                         " nodes, " + abaqus + " needs " + std::to_string(info.nodes));
    }
    RawElement e{lab, info.type, info.formulation, info.abaqus, {}, ln};
    for (int k = 0; k < given; ++k) {
      e.nodes.push_back(deck_.label(parts[k + 1], ln, "node of element " + std::to_string(lab)));
    }
    sc.elements.push_back(std::move(e));
    if (elset) {
      op.direct_labels.push_back(lab);
      op.direct_locs.push_back(ln);
    }
  }
  if (elset) sc.ops.push_back(std::move(op));
}

void Parser::read_set_entries(SetOp& op, std::size_t begin, std::size_t end) {
  const auto& lines = deck_.lines();
  for (std::size_t i = begin; i < end; ++i) {
    for (auto& t : split_commas(lines[i].text)) {
      if (t.empty()) deck_.fail(lines[i].loc, "empty entry in set " + op.name);
      op.entries.push_back({t, "", lines[i].loc});
    }
  }
}

// ---- building the flat mesh -------------------------------------------------------------

std::optional<std::int32_t> Parser::find_label(bool node, const std::string& token, int scope_id,
                                               Loc loc, std::int64_t* label_out) const {
  int sid = scope_id;
  std::string lab_text = token;
  if (const auto dot = token.rfind('.'); dot != std::string::npos && !looks_numeric(token)) {
    const std::string inst = upper(token.substr(0, dot));
    const auto it = instance_scope_.find(inst);
    if (it == instance_scope_.end()) deck_.fail(loc, "instance " + inst + " is not defined");
    sid = it->second;
    lab_text = token.substr(dot + 1);
  }
  const std::int64_t lab = deck_.label(lab_text, loc, node ? "node" : "element");
  if (label_out) *label_out = lab;
  const auto& index = node ? node_index_[static_cast<std::size_t>(sid)]
                           : element_index_[static_cast<std::size_t>(sid)];
  const auto it = index.find(lab);
  if (it == index.end()) return std::nullopt;
  return it->second;
}

const std::vector<std::int32_t>* Parser::find_set(
    const std::map<std::string, std::vector<std::int32_t>>& sets, const std::string& name,
    const std::string& prefix) const {
  const std::string key = prefix + upper(name);
  const auto it = sets.find(key);
  return it == sets.end() ? nullptr : &it->second;
}

int Parser::face_number(const std::string& face, ElementType type, Loc loc,
                        const std::string& surface) const {
  if (type == ElementType::quad4) {
    if (face == "SNEG") return 0;
    if (face == "SPOS") return 1;
    deck_.fail(loc, "surface " + surface + ": face " + face + " of a shell must be SNEG or SPOS");
  }
  const int faces = type == ElementType::hex8 ? 6 : 4;
  if (face.size() == 2 && face[0] == 'S' && face[1] >= '1' && face[1] < '1' + faces) {
    return face[1] - '1';
  }
  deck_.fail(loc, "surface " + surface + ": face " + face + " is not one of S1..S" +
                      std::to_string(faces) + " for a " +
                      (type == ElementType::hex8 ? "hexahedron" : "tetrahedron"));
}

void Parser::add_scope_mesh(const Scope& s, int scope_id, const RawInstance* inst) {
  Mesh& mesh = model_.mesh;
  auto& index = node_index_[static_cast<std::size_t>(scope_id)];
  // Abaqus: the translation first, then the rotation about the axis a-b (right-handed).
  std::array<double, 3> k{};
  double c = 1.0, sn = 0.0;
  if (inst && inst->rotate) {
    const double dx = inst->axis_b[0] - inst->axis_a[0], dy = inst->axis_b[1] - inst->axis_a[1],
                 dz = inst->axis_b[2] - inst->axis_a[2];
    const double len = std::sqrt(dx * dx + dy * dy + dz * dz);
    k = {dx / len, dy / len, dz / len};
    const double th = inst->angle_deg * M_PI / 180.0;
    c = std::cos(th);
    sn = std::sin(th);
  }
  for (const auto& n : s.nodes) {
    auto [it, fresh] = index.emplace(n.label, static_cast<std::int32_t>(mesh.nodes.size()));
    if (!fresh) {
      deck_.fail(n.loc, "node " + std::to_string(n.label) + " is defined twice (first on line " +
                            std::to_string(node_locs_[static_cast<std::size_t>(it->second)].line) +
                            ")");
    }
    std::array<double, 3> x = n.x;
    if (inst) {
      for (int d = 0; d < 3; ++d) x[d] += inst->translation[d];
      if (inst->rotate) {
        const std::array<double, 3> v{x[0] - inst->axis_a[0], x[1] - inst->axis_a[1],
                                      x[2] - inst->axis_a[2]};
        const std::array<double, 3> kxv{k[1] * v[2] - k[2] * v[1], k[2] * v[0] - k[0] * v[2],
                                        k[0] * v[1] - k[1] * v[0]};
        const double kv = k[0] * v[0] + k[1] * v[1] + k[2] * v[2];
        for (int d = 0; d < 3; ++d)
          x[d] = inst->axis_a[d] + v[d] * c + kxv[d] * sn + k[d] * kv * (1.0 - c);
      }
    }
    mesh.nodes.push_back(x);
    mesh.node_labels.push_back(n.label);
    mesh.node_sources.push_back({n.loc.file, n.loc.line, scope_id - 1});
    node_locs_.push_back(n.loc);
  }
}

void Parser::build() {
  Mesh& mesh = model_.mesh;
  mesh.source_files = deck_.files();
  const std::size_t scopes = 1 + instances_.size();
  node_index_.assign(scopes, {});
  element_index_.assign(scopes, {});
  for (std::size_t k = 0; k < instances_.size(); ++k) {
    const auto& inst = instances_[k];
    if (!parts_.count(inst.part))
      deck_.fail(inst.loc, "instance " + inst.name + " refers to part " + inst.part +
                               ", which is not defined (before this line or anywhere)");
    instance_scope_[inst.name] = static_cast<int>(k + 1);
    mesh.instance_names.push_back(inst.name);
  }
  // Nodes of every scope first (elements may refer to nodes defined after them).
  add_scope_mesh(global_, 0, nullptr);
  for (std::size_t k = 0; k < instances_.size(); ++k) {
    add_scope_mesh(parts_.at(instances_[k].part), static_cast<int>(k + 1), &instances_[k]);
    add_scope_mesh(instances_[k].own, static_cast<int>(k + 1), &instances_[k]);
  }
  if (!parts_.empty() && instances_.empty())
    deck_.fail({0, deck_.lines().empty() ? 0 : deck_.lines().front().loc.line},
               "the deck defines parts but no *INSTANCE of them: nothing to analyse");
  // Elements.
  std::array<std::int64_t, std::size(kAbaqusTypes)> type_counts{};
  auto add_elements = [&](const Scope& s, int sid) {
    auto& index = element_index_[static_cast<std::size_t>(sid)];
    for (const auto& e : s.elements) {
      Element el;
      el.type = e.type;
      el.formulation = e.formulation;
      for (std::size_t a = 0; a < e.nodes.size(); ++a) {
        const auto& nodes = node_index_[static_cast<std::size_t>(sid)];
        auto it = nodes.find(e.nodes[a]);
        if (it == nodes.end()) {
          deck_.fail(e.loc, "element " + std::to_string(e.label) + " references node " +
                                std::to_string(e.nodes[a]) + ", which is not defined");
        }
        el.nodes[a] = it->second;
        for (std::size_t b = 0; b < a; ++b)
          if (e.nodes[a] == e.nodes[b])
            deck_.fail(e.loc, "element " + std::to_string(e.label) + " uses node " +
                                  std::to_string(e.nodes[a]) + " twice");
      }
      auto [it, fresh] = index.emplace(e.label, static_cast<std::int32_t>(mesh.elements.size()));
      if (!fresh) {
        deck_.fail(e.loc,
                   "element " + std::to_string(e.label) + " is defined twice (first on line " +
                       std::to_string(element_locs_[static_cast<std::size_t>(it->second)].line) +
                       ")");
      }
      mesh.elements.push_back(el);
      ++type_counts[e.abaqus];
      mesh.element_labels.push_back(e.label);
      mesh.element_sources.push_back({e.loc.file, e.loc.line, sid - 1});
      element_locs_.push_back(e.loc);
    }
  };
  add_elements(global_, 0);
  for (std::size_t k = 0; k < instances_.size(); ++k) {
    add_elements(parts_.at(instances_[k].part), static_cast<int>(k + 1));
    add_elements(instances_[k].own, static_cast<int>(k + 1));
  }
  // Sets and surfaces: each instance's (named "INSTANCE.SET"), then the model's / assembly's,
  // which may refer to them.
  for (std::size_t k = 0; k < instances_.size(); ++k) {
    const std::string prefix = instances_[k].name + ".";
    resolve_ops(parts_.at(instances_[k].part).ops, static_cast<int>(k + 1), prefix);
    resolve_ops(instances_[k].own.ops, static_cast<int>(k + 1), prefix);
  }
  resolve_ops(global_.ops, 0, "");
  add_aliases();
  finish_sections();
  for (std::size_t t = 0; t < type_counts.size(); ++t) {
    if (type_counts[t] == 0) continue;
    const std::string type = kAbaqusTypes[t];
    SolidFormulation f = SolidFormulation::incompatible_modes;
    if (type == "C3D8R" && options_.c3d8r_as) f = *options_.c3d8r_as;
    model_.notes.push_back(deck_.files()[0] + ": " + std::to_string(type_counts[t]) + " " + type +
                           " element(s) -> " + formulation_note(type, f));
  }
}

std::vector<std::int32_t> Parser::resolve_set(const SetOp& op, int scope_id,
                                              const std::string& prefix) {
  const bool nodes = op.kind == SetKind::node;
  const char* what = nodes ? "node" : "element";
  const auto& sets = nodes ? model_.mesh.node_sets : model_.mesh.element_sets;
  // An assembly-level set with INSTANCE= takes labels (and set names) of that instance.
  int sid = scope_id;
  std::string name_prefix = prefix;
  if (!op.instance.empty()) {
    const auto it = instance_scope_.find(op.instance);
    if (it == instance_scope_.end())
      deck_.fail(op.loc, "instance " + op.instance + " is not defined");
    sid = it->second;
    name_prefix = op.instance + ".";
  }
  std::vector<std::int32_t> out;
  auto add_label = [&](const std::string& token, Loc loc) {
    std::int64_t lab = 0;
    const auto idx = find_label(nodes, token, sid, loc, &lab);
    if (!idx) {
      deck_.fail(loc, std::string(nodes ? "node set " : "element set ") + op.name + " references " +
                          what + " " + token + ", which is not defined");
    }
    out.push_back(*idx);
  };
  for (std::size_t k = 0; k < op.direct_labels.size(); ++k) {
    add_label(std::to_string(op.direct_labels[k]), op.direct_locs[k]);
  }
  if (op.generate) {
    // Entries come in groups per line: first, last[, increment].
    std::size_t k = 0;
    while (k < op.entries.size()) {
      const Loc loc = op.entries[k].loc;
      std::vector<std::int64_t> v;
      while (k < op.entries.size() && op.entries[k].loc.line == loc.line &&
             op.entries[k].loc.file == loc.file) {
        v.push_back(deck_.label(op.entries[k].token, loc, "GENERATE value"));
        ++k;
      }
      if (v.size() < 2 || v.size() > 3)
        deck_.fail(loc, "GENERATE needs 'first, last[, increment]'");
      const std::int64_t inc = v.size() == 3 ? v[2] : 1;
      if (v[1] < v[0]) deck_.fail(loc, "GENERATE: last must not be smaller than first");
      if ((v[1] - v[0]) / inc > 100000000)
        deck_.fail(loc, "GENERATE: more than 1e8 labels in one range");
      for (std::int64_t lab = v[0]; lab <= v[1]; lab += inc) add_label(std::to_string(lab), loc);
    }
  } else {
    for (const auto& e : op.entries) {
      if (is_label_token(e.token)) {
        add_label(e.token, e.loc);
        continue;
      }
      const auto* set = find_set(sets, e.token, name_prefix);
      if (!set && name_prefix != prefix) set = find_set(sets, e.token, prefix);
      if (!set) {
        deck_.fail(e.loc, std::string(what) + " set " + upper(e.token) +
                              " is not defined (before this line)");
      }
      out.insert(out.end(), set->begin(), set->end());
    }
  }
  return out;
}

std::vector<Face> Parser::resolve_surface(const SetOp& op, int scope_id,
                                          const std::string& prefix) {
  const Mesh& mesh = model_.mesh;
  std::vector<Face> faces;
  for (const auto& e : op.entries) {
    std::vector<std::int32_t> elems;
    if (is_label_token(e.token)) {
      const auto idx = find_label(false, e.token, scope_id, e.loc);
      if (!idx) {
        deck_.fail(e.loc, "surface " + op.name + " references element " + e.token +
                              ", which is not defined");
      }
      elems.push_back(*idx);
    } else {
      const auto* set = find_set(mesh.element_sets, e.token, prefix);
      if (!set) {
        deck_.fail(e.loc, "surface " + op.name + ": element set " + upper(e.token) +
                              " is not defined (before this line)");
      }
      elems = *set;
    }
    for (auto el : elems) {
      const int f =
          face_number(e.face, mesh.elements[static_cast<std::size_t>(el)].type, e.loc, op.name);
      faces.push_back({el, f});
    }
  }
  return faces;
}

void Parser::resolve_ops(const std::vector<SetOp>& ops, int scope_id, const std::string& prefix) {
  Mesh& mesh = model_.mesh;
  for (const auto& op : ops) {
    const std::string name = prefix + op.name;
    switch (op.kind) {
      case SetKind::node:
        merge_into(mesh.node_sets[name], resolve_set(op, scope_id, prefix));
        break;
      case SetKind::element:
        merge_into(mesh.element_sets[name], resolve_set(op, scope_id, prefix));
        break;
      case SetKind::node_from_elset: {
        const auto* set = find_set(mesh.element_sets, op.entries[0].token, prefix);
        if (!set) {
          deck_.fail(op.loc,
                     "element set " + op.entries[0].token + " is not defined (before this line)");
        }
        std::vector<std::int32_t> nodes;
        for (auto e : *set) {
          const Element& el = mesh.elements[static_cast<std::size_t>(e)];
          for (int k = 0; k < nodes_per_element(el.type); ++k) nodes.push_back(el.nodes[k]);
        }
        merge_into(mesh.node_sets[name], std::move(nodes));
        break;
      }
      case SetKind::surface: {
        auto faces = resolve_surface(op, scope_id, prefix);
        auto& target = mesh.surfaces[name];
        target.insert(target.end(), faces.begin(), faces.end());
        break;
      }
    }
  }
}

void Parser::add_aliases() {
  if (instances_.empty()) return;
  // A set "INSTANCE.NAME" is also reachable as "NAME" when no other instance and no
  // assembly-level set uses that name (the usual single-part deck).
  auto alias = [&](auto& sets) {
    std::map<std::string, std::vector<std::string>> by_name;
    for (const auto& [key, value] : sets) {
      const auto dot = key.find('.');
      if (dot != std::string::npos && instance_scope_.count(key.substr(0, dot)))
        by_name[key.substr(dot + 1)].push_back(key);
    }
    for (const auto& [name, keys] : by_name)
      if (keys.size() == 1 && !sets.count(name)) sets[name] = sets[keys[0]];
  };
  alias(model_.mesh.node_sets);
  alias(model_.mesh.element_sets);
  alias(model_.mesh.surfaces);
  model_.notes.push_back(deck_.files()[0] + ": " + std::to_string(instances_.size()) +
                         " part instance(s) flattened; their sets and surfaces are named "
                         "INSTANCE.NAME (e.g. " +
                         instances_[0].name +
                         ".<set>), and NAME alone where only one instance has it");
}

void Parser::finish_sections() {
  auto add = [&](const RawSection& rs, const std::string& prefix) {
    InpSection s = rs.section;
    s.element_set = prefix + s.element_set;
    if (!model_.mesh.element_sets.contains(s.element_set)) {
      deck_.fail(rs.loc,
                 "section refers to element set " + s.element_set + ", which is not defined");
    }
    const bool known = std::any_of(model_.materials.begin(), model_.materials.end(),
                                   [&](const Material& m) { return m.name == s.material; });
    if (!known) {
      deck_.fail(rs.loc, "section refers to material " + s.material + ", which is not defined");
    }
    model_.sections.push_back(s);
  };
  for (const auto& rs : global_.sections) add(rs, "");
  for (const auto& inst : instances_) {
    for (const auto& rs : parts_.at(inst.part).sections) add(rs, inst.name + ".");
    for (const auto& rs : inst.own.sections) add(rs, inst.name + ".");
  }
}

}  // namespace demfem::fem::inp
