#include "demfem/fem/inp_reader.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <sstream>
#include <unordered_map>

#include "demfem/io/input_file.hpp"

namespace demfem::fem {

namespace {

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

std::string trim(std::string_view s) {
  std::size_t b = 0;
  std::size_t e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1]))) --e;
  return std::string(s.substr(b, e - b));
}

/// Splits a line at commas; a trailing comma gives no empty last entry (it marks a
/// continuation), and entries are trimmed.
std::vector<std::string> split_commas(std::string_view line) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= line.size()) {
    const std::size_t comma = line.find(',', start);
    const std::size_t end = comma == std::string_view::npos ? line.size() : comma;
    out.push_back(trim(line.substr(start, end - start)));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  if (!out.empty() && out.back().empty()) out.pop_back();
  return out;
}

bool ends_with_comma(std::string_view line) {
  const std::string t = trim(line);
  return !t.empty() && t.back() == ',';
}

struct Line {
  std::string text;
  int number = 0;  // 1-based line in the file
};

struct Keyword {
  std::string name;                                         // upper case, single spaces
  std::vector<std::pair<std::string, std::string>> params;  // upper-case key, raw value
  int line = 0;

  std::optional<std::string> param(std::string_view key) const {
    for (const auto& [k, v] : params) {
      if (k == key) return v;
    }
    return std::nullopt;
  }
  bool flag(std::string_view key) const { return param(key).has_value(); }
};

struct ElementType3 {
  ElementType type;
  int nodes;
};

std::optional<ElementType3> element_type_of(const std::string& abaqus) {
  // C3D8R (reduced integration) is read as the locking-free hex8 too: the engine has one
  // hexahedron formulation.
  if (abaqus == "C3D8" || abaqus == "C3D8I" || abaqus == "C3D8R") {
    return ElementType3{ElementType::hex8, 8};
  }
  if (abaqus == "C3D4") return ElementType3{ElementType::tet4, 4};
  if (abaqus == "S4" || abaqus == "S4R") return ElementType3{ElementType::quad4, 4};
  return std::nullopt;
}

struct RawNode {
  std::int64_t label;
  std::array<double, 3> x;
  int line;
};

struct RawElement {
  std::int64_t label;
  ElementType type;
  std::vector<std::int64_t> nodes;
  int line;
};

/// One data entry of a set or surface definition, kept until all nodes and elements are
/// known (a file may define them in any order).
struct SetEntry {
  std::string token;
  std::string face;  // surfaces only
  int line;
};

enum class SetKind { node, element, surface, node_from_elset };

struct SetOp {
  SetKind kind;
  std::string name;
  bool generate = false;
  int line = 0;
  std::vector<SetEntry> entries;
  std::vector<std::int64_t> direct_labels;  // labels added by *NODE,NSET= / *ELEMENT,ELSET=
  std::vector<int> direct_lines;
};

class Parser {
 public:
  Parser(const std::string& text, std::string name) : name_(std::move(name)) { split(text); }

  InpModel run() {
    std::size_t i = 0;
    while (i < lines_.size()) {
      const Line& l = lines_[i];
      if (!is_keyword(l.text)) fail(l.number, "data line outside of any keyword: '" + l.text + "'");
      std::size_t next = i + 1;
      Keyword kw = parse_keyword(i, next);
      std::size_t end = next;
      while (end < lines_.size() && !is_keyword(lines_[end].text)) ++end;
      handle(kw, next, end);
      i = end;
    }
    return finish();
  }

 private:
  [[noreturn]] void fail(int line, const std::string& message) const {
    throw InpError(name_ + ":" + std::to_string(line) + ": " + message);
  }

  void split(const std::string& text) {
    std::istringstream in(text);
    std::string s;
    int n = 0;
    while (std::getline(in, s)) {
      ++n;
      if (!s.empty() && s.back() == '\r') s.pop_back();
      const std::string t = trim(s);
      if (t.empty() || t.rfind("**", 0) == 0) continue;  // blank or comment
      lines_.push_back({t, n});
    }
  }

  static bool is_keyword(const std::string& t) { return !t.empty() && t[0] == '*'; }

  /// Parses the keyword line at `i`, joining continuation lines (a trailing comma); `next`
  /// becomes the first line after it.
  Keyword parse_keyword(std::size_t i, std::size_t& next) const {
    std::string text = lines_[i].text;
    next = i + 1;
    while (ends_with_comma(text) && next < lines_.size() && !is_keyword(lines_[next].text)) {
      text += lines_[next].text;
      ++next;
    }
    Keyword kw;
    kw.line = lines_[i].number;
    auto parts = split_commas(std::string_view(text).substr(1));
    if (parts.empty() || parts[0].empty()) fail(kw.line, "empty keyword");
    {
      std::string name;
      std::istringstream words(upper(parts[0]));
      std::string w;
      while (words >> w) name += (name.empty() ? "" : " ") + w;
      kw.name = name;
    }
    for (std::size_t p = 1; p < parts.size(); ++p) {
      if (parts[p].empty()) continue;
      const auto eq = parts[p].find('=');
      std::string key = upper(trim(parts[p].substr(0, eq)));
      std::string value = eq == std::string::npos ? "" : trim(parts[p].substr(eq + 1));
      if (value.size() >= 2 && value.front() == '"' && value.back() == '"') {
        value = value.substr(1, value.size() - 2);
      }
      kw.params.emplace_back(std::move(key), std::move(value));
    }
    return kw;
  }

  std::string required_name(const Keyword& kw, std::string_view key) const {
    auto v = kw.param(key);
    if (!v || v->empty()) {
      fail(kw.line, "*" + kw.name + " needs " + std::string(key) + "=<name>");
    }
    return upper(*v);
  }

  double number(const std::string& token, int line, const std::string& what) const {
    if (token.empty()) fail(line, what + " is missing");
    const char* begin = token.c_str();
    char* end = nullptr;
    const double v = std::strtod(begin, &end);
    if (end == begin || *end != '\0') fail(line, what + " '" + token + "' is not a number");
    if (!std::isfinite(v)) fail(line, what + " is " + token + ", not a finite number");
    return v;
  }

  std::int64_t label(const std::string& token, int line, const std::string& what) const {
    std::int64_t v = 0;
    const auto* b = token.data();
    const auto* e = token.data() + token.size();
    auto [ptr, ec] = std::from_chars(b, e, v);
    if (token.empty() || ec != std::errc() || ptr != e) {
      fail(line, what + " '" + token + "' is not an integer label");
    }
    if (v <= 0) fail(line, what + " " + token + " must be a positive label");
    return v;
  }

  static bool looks_numeric(const std::string& token) {
    return !token.empty() && (std::isdigit(static_cast<unsigned char>(token[0])) ||
                              token[0] == '-' || token[0] == '+');
  }

  void handle(const Keyword& kw, std::size_t begin, std::size_t end) {
    const std::string& k = kw.name;
    if (k == "NODE") {
      read_nodes(kw, begin, end);
    } else if (k == "ELEMENT") {
      read_elements(kw, begin, end);
    } else if (k == "NSET") {
      SetOp op{kw.flag("ELSET") ? SetKind::node_from_elset : SetKind::node,
               required_name(kw, "NSET"),
               kw.flag("GENERATE"),
               kw.line,
               {},
               {},
               {}};
      if (op.kind == SetKind::node_from_elset) {
        op.entries.push_back({upper(*kw.param("ELSET")), "", kw.line});
        if (begin != end) fail(lines_[begin].number, "*NSET with ELSET= takes no data lines");
      } else {
        read_set_entries(op, begin, end);
      }
      ops_.push_back(std::move(op));
    } else if (k == "ELSET") {
      SetOp op{
          SetKind::element, required_name(kw, "ELSET"), kw.flag("GENERATE"), kw.line, {}, {}, {}};
      read_set_entries(op, begin, end);
      ops_.push_back(std::move(op));
    } else if (k == "SURFACE") {
      const std::string type = upper(kw.param("TYPE").value_or("ELEMENT"));
      if (type != "ELEMENT") {
        fail(kw.line, "*SURFACE TYPE=" + type + " is not supported (only TYPE=ELEMENT)");
      }
      SetOp op{SetKind::surface, required_name(kw, "NAME"), false, kw.line, {}, {}, {}};
      for (std::size_t i = begin; i < end; ++i) {
        auto parts = split_commas(lines_[i].text);
        if (parts.size() != 2 || parts[1].empty()) {
          fail(lines_[i].number,
               "surface " + op.name +
                   ": expected '<element set or label>, <face S1..S6|SPOS|SNEG>'");
        }
        op.entries.push_back({parts[0], upper(parts[1]), lines_[i].number});
      }
      ops_.push_back(std::move(op));
    } else if (k == "MATERIAL") {
      Material m;
      m.name = required_name(kw, "NAME");
      for (const auto& other : model_.materials) {
        if (other.name == m.name) fail(kw.line, "material " + m.name + " is defined twice");
      }
      model_.materials.push_back(m);
      material_lines_.push_back(kw.line);
    } else if (k == "ELASTIC") {
      Material& m = current_material(kw);
      const std::string type = upper(kw.param("TYPE").value_or("ISOTROPIC"));
      if (type != "ISOTROPIC") fail(kw.line, "*ELASTIC TYPE=" + type + " is not supported");
      auto parts = single_data_line(kw, begin, end);
      if (parts.size() < 2) fail(lines_[begin].number, "*ELASTIC needs E, nu");
      if (parts.size() > 2) {
        fail(lines_[begin].number, "*ELASTIC: temperature-dependent data is not supported");
      }
      m.youngs_modulus = number(parts[0], lines_[begin].number, "Young's modulus");
      m.poisson_ratio = number(parts[1], lines_[begin].number, "Poisson's ratio");
      if (m.youngs_modulus <= 0.0) fail(lines_[begin].number, "Young's modulus must be > 0");
      if (m.poisson_ratio <= -1.0 || m.poisson_ratio >= 0.5) {
        fail(lines_[begin].number, "Poisson's ratio must be in (-1, 0.5)");
      }
    } else if (k == "DENSITY") {
      Material& m = current_material(kw);
      auto parts = single_data_line(kw, begin, end);
      if (parts.size() != 1) fail(lines_[begin].number, "*DENSITY needs one value");
      m.density = number(parts[0], lines_[begin].number, "density");
      if (m.density < 0.0) fail(lines_[begin].number, "density must be >= 0");
    } else if (k == "SOLID SECTION" || k == "SHELL SECTION") {
      InpSection s;
      s.element_set = required_name(kw, "ELSET");
      s.material = required_name(kw, "MATERIAL");
      s.shell = k == "SHELL SECTION";
      if (s.shell) {
        auto parts = single_data_line(kw, begin, end);
        if (parts.empty()) fail(lines_[begin].number, "*SHELL SECTION needs a thickness");
        s.thickness = number(parts[0], lines_[begin].number, "shell thickness");
        if (s.thickness <= 0.0) fail(lines_[begin].number, "shell thickness must be > 0");
      }
      model_.sections.push_back(s);
      section_lines_.push_back(kw.line);
    }
    // Any other keyword (*HEADING, *PART, *STEP, *BOUNDARY, ...) is not part of the mesh:
    // skipped together with its data lines.
  }

  Material& current_material(const Keyword& kw) {
    if (model_.materials.empty()) fail(kw.line, "*" + kw.name + " outside of a *MATERIAL");
    return model_.materials.back();
  }

  std::vector<std::string> single_data_line(const Keyword& kw, std::size_t begin,
                                            std::size_t end) const {
    if (begin == end) fail(kw.line, "*" + kw.name + " needs a data line");
    if (end - begin > 1) fail(lines_[begin + 1].number, "*" + kw.name + " takes one data line");
    return split_commas(lines_[begin].text);
  }

  void read_nodes(const Keyword& kw, std::size_t begin, std::size_t end) {
    std::optional<std::string> nset;
    if (auto v = kw.param("NSET")) nset = upper(*v);
    SetOp op{SetKind::node, nset.value_or(""), false, kw.line, {}, {}, {}};
    for (std::size_t i = begin; i < end; ++i) {
      const int ln = lines_[i].number;
      auto parts = split_commas(lines_[i].text);
      const std::int64_t lab = label(parts[0], ln, "node");
      if (parts.size() != 4) {
        fail(ln, "node " + std::to_string(lab) + " has " + std::to_string(parts.size() - 1) +
                     " coordinates, needs 3 (x, y, z)");
      }
      RawNode n{lab, {}, ln};
      for (int c = 0; c < 3; ++c) {
        n.x[c] = number(parts[c + 1], ln,
                        std::string("coordinate ") + "xyz"[c] + " of node " + std::to_string(lab));
      }
      auto [it, fresh] = node_index_.emplace(lab, static_cast<std::int32_t>(nodes_.size()));
      if (!fresh) {
        fail(ln, "node " + std::to_string(lab) + " is defined twice (first on line " +
                     std::to_string(nodes_[it->second].line) + ")");
      }
      nodes_.push_back(n);
      if (nset) {
        op.direct_labels.push_back(lab);
        op.direct_lines.push_back(ln);
      }
    }
    if (nset) ops_.push_back(std::move(op));
  }

  void read_elements(const Keyword& kw, std::size_t begin, std::size_t end) {
    auto type_name = kw.param("TYPE");
    if (!type_name) fail(kw.line, "*ELEMENT needs TYPE=");
    auto type = element_type_of(upper(*type_name));
    if (!type) {
      fail(kw.line, "element type " + upper(*type_name) +
                        " is not supported (supported: C3D8, C3D8I, C3D8R, C3D4, S4, S4R)");
    }
    std::optional<std::string> elset;
    if (auto v = kw.param("ELSET")) elset = upper(*v);
    SetOp op{SetKind::element, elset.value_or(""), false, kw.line, {}, {}, {}};
    for (std::size_t i = begin; i < end; ++i) {
      const int ln = lines_[i].number;
      std::vector<std::string> parts = split_commas(lines_[i].text);
      // A data line that ends with a comma continues on the next line (long elements).
      while (ends_with_comma(lines_[i].text) && static_cast<int>(parts.size()) < type->nodes + 1 &&
             i + 1 < end) {
        ++i;
        auto more = split_commas(lines_[i].text);
        parts.insert(parts.end(), more.begin(), more.end());
      }
      const std::int64_t lab = label(parts[0], ln, "element");
      const int given = static_cast<int>(parts.size()) - 1;
      if (given != type->nodes) {
        fail(ln, "element " + std::to_string(lab) + " has " + std::to_string(given) + " nodes, " +
                     upper(*type_name) + " needs " + std::to_string(type->nodes));
      }
      RawElement e{lab, type->type, {}, ln};
      for (int k = 0; k < given; ++k) {
        e.nodes.push_back(label(parts[k + 1], ln, "node of element " + std::to_string(lab)));
      }
      auto [it, fresh] = element_index_.emplace(lab, static_cast<std::int32_t>(elements_.size()));
      if (!fresh) {
        fail(ln, "element " + std::to_string(lab) + " is defined twice (first on line " +
                     std::to_string(elements_[it->second].line) + ")");
      }
      elements_.push_back(std::move(e));
      if (elset) {
        op.direct_labels.push_back(lab);
        op.direct_lines.push_back(ln);
      }
    }
    if (elset) ops_.push_back(std::move(op));
  }

  void read_set_entries(SetOp& op, std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) {
      for (auto& t : split_commas(lines_[i].text)) {
        if (t.empty()) fail(lines_[i].number, "empty entry in set " + op.name);
        op.entries.push_back({t, "", lines_[i].number});
      }
    }
  }

  /// Expands set entries (labels, set names or GENERATE triples) to sorted unique indices.
  std::vector<std::int32_t> resolve(const SetOp& op, const InpModel& model) {
    const bool nodes = op.kind == SetKind::node;
    const auto& index = nodes ? node_index_ : element_index_;
    const char* what = nodes ? "node" : "element";
    const auto& sets = nodes ? model.mesh.node_sets : model.mesh.element_sets;
    std::vector<std::int32_t> out;
    auto add_label = [&](std::int64_t lab, int line) {
      auto it = index.find(lab);
      if (it == index.end()) {
        fail(line, std::string(nodes ? "node set " : "element set ") + op.name + " references " +
                       what + " " + std::to_string(lab) + ", which is not defined");
      }
      out.push_back(it->second);
    };
    for (std::size_t k = 0; k < op.direct_labels.size(); ++k) {
      add_label(op.direct_labels[k], op.direct_lines[k]);
    }
    if (op.generate) {
      // Entries come in groups per line: first, last[, increment].
      std::size_t k = 0;
      while (k < op.entries.size()) {
        const int line = op.entries[k].line;
        std::vector<std::int64_t> v;
        while (k < op.entries.size() && op.entries[k].line == line) {
          v.push_back(label(op.entries[k].token, line, "GENERATE value"));
          ++k;
        }
        if (v.size() < 2 || v.size() > 3) {
          fail(line, "GENERATE needs 'first, last[, increment]'");
        }
        const std::int64_t inc = v.size() == 3 ? v[2] : 1;
        if (v[1] < v[0]) fail(line, "GENERATE: last must not be smaller than first");
        for (std::int64_t lab = v[0]; lab <= v[1]; lab += inc) add_label(lab, line);
      }
    } else {
      for (const auto& e : op.entries) {
        if (looks_numeric(e.token)) {
          add_label(label(e.token, e.line, what), e.line);
        } else {
          auto it = sets.find(upper(e.token));
          if (it == sets.end()) {
            fail(e.line, std::string(what) + " set " + upper(e.token) +
                             " is not defined (before this line)");
          }
          out.insert(out.end(), it->second.begin(), it->second.end());
        }
      }
    }
    return out;
  }

  static void merge_into(std::vector<std::int32_t>& set, std::vector<std::int32_t> add) {
    set.insert(set.end(), add.begin(), add.end());
    std::sort(set.begin(), set.end());
    set.erase(std::unique(set.begin(), set.end()), set.end());
  }

  int face_number(const std::string& face, ElementType type, int line,
                  const std::string& surface) const {
    if (type == ElementType::quad4) {
      if (face == "SNEG") return 0;
      if (face == "SPOS") return 1;
      fail(line, "surface " + surface + ": face " + face + " of a shell must be SNEG or SPOS");
    }
    const int faces = type == ElementType::hex8 ? 6 : 4;
    if (face.size() == 2 && face[0] == 'S' && face[1] >= '1' && face[1] < '1' + faces) {
      return face[1] - '1';
    }
    fail(line, "surface " + surface + ": face " + face + " is not one of S1..S" +
                   std::to_string(faces) + " for a " +
                   (type == ElementType::hex8 ? "hexahedron" : "tetrahedron"));
  }

  InpModel finish() {
    Mesh& mesh = model_.mesh;
    mesh.nodes.reserve(nodes_.size());
    for (const auto& n : nodes_) {
      mesh.nodes.push_back(n.x);
      mesh.node_labels.push_back(n.label);
    }
    for (const auto& e : elements_) {
      Element el;
      el.type = e.type;
      for (std::size_t k = 0; k < e.nodes.size(); ++k) {
        auto it = node_index_.find(e.nodes[k]);
        if (it == node_index_.end()) {
          fail(e.line, "element " + std::to_string(e.label) + " references node " +
                           std::to_string(e.nodes[k]) + ", which is not defined");
        }
        el.nodes[k] = it->second;
      }
      for (std::size_t a = 0; a < e.nodes.size(); ++a) {
        for (std::size_t b = a + 1; b < e.nodes.size(); ++b) {
          if (e.nodes[a] == e.nodes[b]) {
            fail(e.line, "element " + std::to_string(e.label) + " uses node " +
                             std::to_string(e.nodes[a]) + " twice");
          }
        }
      }
      mesh.elements.push_back(el);
      mesh.element_labels.push_back(e.label);
    }
    for (const auto& op : ops_) {
      switch (op.kind) {
        case SetKind::node:
          merge_into(mesh.node_sets[op.name], resolve(op, model_));
          break;
        case SetKind::element:
          merge_into(mesh.element_sets[op.name], resolve(op, model_));
          break;
        case SetKind::node_from_elset: {
          auto it = mesh.element_sets.find(op.entries[0].token);
          if (it == mesh.element_sets.end()) {
            fail(op.line,
                 "element set " + op.entries[0].token + " is not defined (before this line)");
          }
          std::vector<std::int32_t> nodes;
          for (auto e : it->second) {
            const Element& el = mesh.elements[static_cast<std::size_t>(e)];
            for (int k = 0; k < nodes_per_element(el.type); ++k) nodes.push_back(el.nodes[k]);
          }
          merge_into(mesh.node_sets[op.name], std::move(nodes));
          break;
        }
        case SetKind::surface: {
          auto& faces = mesh.surfaces[op.name];
          for (const auto& e : op.entries) {
            std::vector<std::int32_t> elems;
            if (looks_numeric(e.token)) {
              const std::int64_t lab = label(e.token, e.line, "element");
              auto it = element_index_.find(lab);
              if (it == element_index_.end()) {
                fail(e.line, "surface " + op.name + " references element " + std::to_string(lab) +
                                 ", which is not defined");
              }
              elems.push_back(it->second);
            } else {
              auto it = mesh.element_sets.find(upper(e.token));
              if (it == mesh.element_sets.end()) {
                fail(e.line, "surface " + op.name + ": element set " + upper(e.token) +
                                 " is not defined (before this line)");
              }
              elems = it->second;
            }
            for (auto el : elems) {
              const int f = face_number(e.face, mesh.elements[static_cast<std::size_t>(el)].type,
                                        e.line, op.name);
              faces.push_back({el, f});
            }
          }
          break;
        }
      }
    }
    for (std::size_t s = 0; s < model_.sections.size(); ++s) {
      const auto& sec = model_.sections[s];
      if (!mesh.element_sets.contains(sec.element_set)) {
        fail(section_lines_[s],
             "section refers to element set " + sec.element_set + ", which is not defined");
      }
      const bool known = std::any_of(model_.materials.begin(), model_.materials.end(),
                                     [&](const Material& m) { return m.name == sec.material; });
      if (!known) {
        fail(section_lines_[s],
             "section refers to material " + sec.material + ", which is not defined");
      }
    }
    return std::move(model_);
  }

  std::string name_;
  std::vector<Line> lines_;
  std::vector<RawNode> nodes_;
  std::vector<RawElement> elements_;
  std::unordered_map<std::int64_t, std::int32_t> node_index_;
  std::unordered_map<std::int64_t, std::int32_t> element_index_;
  std::vector<SetOp> ops_;
  std::vector<int> material_lines_;
  std::vector<int> section_lines_;
  InpModel model_;
};

}  // namespace

InpModel parse_inp(const std::string& text, const std::string& name) {
  return Parser(text, name).run();
}

InpModel read_inp_model(const std::filesystem::path& file) {
  std::string text;
  try {
    text = io::read_regular_file(file, io::kMeshFileLimit, "an Abaqus input file (.inp)");
  } catch (const io::InputFileError& e) {
    throw InpError(e.what());
  }
  return parse_inp(text, file.string());
}

Mesh read_inp(const std::filesystem::path& file) {
  Mesh mesh = read_inp_model(file).mesh;
  for (auto& e : mesh.elements) e.section = 0;
  return mesh;
}

}  // namespace demfem::fem
