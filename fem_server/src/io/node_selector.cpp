#include "demfem/fem/node_selector.hpp"

#include "demfem/fem/element_topology.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <map>
#include <tuple>

namespace demfem::fem {

namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

template <class Map>
auto find_named(const Map& map, std::string_view name) -> decltype(map.end()) {
  auto it = map.find(std::string(name));
  if (it != map.end()) return it;
  const std::string want = lower(name);
  for (auto i = map.begin(); i != map.end(); ++i) {
    if (lower(i->first) == want) return i;
  }
  return map.end();
}

struct Tokenizer {
  std::string_view s;
  std::size_t pos = 0;

  void skip_space() {
    while (pos < s.size() && std::isspace(static_cast<unsigned char>(s[pos]))) ++pos;
  }
  bool done() {
    skip_space();
    return pos >= s.size();
  }
  std::string next() {
    skip_space();
    if (pos >= s.size()) return "";
    const std::size_t start = pos;
    const char c = s[pos];
    if (c == '<' || c == '>' || c == '=' || c == '!') {
      ++pos;
      if (pos < s.size() && s[pos] == '=') ++pos;
      return std::string(s.substr(start, pos - start));
    }
    while (pos < s.size() && !std::isspace(static_cast<unsigned char>(s[pos])) && s[pos] != '<' &&
           s[pos] != '>' && s[pos] != '=' && s[pos] != '!') {
      // keep the sign of an exponent ("1e-9") inside the number
      ++pos;
    }
    return std::string(s.substr(start, pos - start));
  }
};

int axis_of(const std::string& t) {
  if (t == "x" || t == "X") return 0;
  if (t == "y" || t == "Y") return 1;
  if (t == "z" || t == "Z") return 2;
  return -1;
}

int op_of(const std::string& t) {
  if (t == "<") return 0;
  if (t == "<=") return 1;
  if (t == ">") return 2;
  if (t == ">=") return 3;
  if (t == "==") return 4;
  return -1;
}

bool parse_number(const std::string& t, double& v) {
  if (t.empty()) return false;
  char* end = nullptr;
  v = std::strtod(t.c_str(), &end);
  return end == t.c_str() + t.size() && std::isfinite(v);
}

}  // namespace

NodePredicate NodePredicate::parse(std::string_view expression, double tolerance) {
  NodePredicate p;
  p.tolerance_ = tolerance;
  Tokenizer tk{expression};
  // Built with append: GCC 12 warns falsely (-Wrestrict) on "literal" + std::string here.
  std::string quoted(1, '\'');
  quoted.append(expression).push_back('\'');
  while (true) {
    const std::string a = tk.next();
    const std::string op = tk.next();
    const std::string b = tk.next();
    int axis = axis_of(a);
    int o = op_of(op);
    double value = 0.0;
    if (o < 0) {
      throw SelectorError(quoted + ": expected a comparison operator (<, <=, >, >=, ==) after '" +
                          a + "', found '" + op + "'");
    }
    if (axis >= 0) {
      if (!parse_number(b, value)) {
        throw SelectorError(quoted + ": '" + b + "' is not a finite number");
      }
    } else {
      // "number op coordinate": mirror it to "coordinate op' number".
      axis = axis_of(b);
      if (axis < 0 || !parse_number(a, value)) {
        throw SelectorError(quoted +
                            ": a comparison needs x, y or z on one side and a number on "
                            "the other, found '" +
                            a + " " + op + " " + b + "'");
      }
      static constexpr int mirror[5] = {2, 3, 0, 1, 4};
      o = mirror[o];
    }
    p.terms_.push_back({axis, o, value});
    if (tk.done()) break;
    const std::string conj = tk.next();
    if (lower(conj) != "and") {
      throw SelectorError(quoted + ": expected 'and' between comparisons, found '" + conj + "'");
    }
  }
  return p;
}

bool NodePredicate::operator()(const std::array<double, 3>& x) const {
  for (const auto& t : terms_) {
    const double v = x[static_cast<std::size_t>(t.axis)];
    bool ok = false;
    switch (t.op) {
      case 0:
        ok = v < t.value - tolerance_;
        break;
      case 1:
        ok = v <= t.value + tolerance_;
        break;
      case 2:
        ok = v > t.value + tolerance_;
        break;
      case 3:
        ok = v >= t.value - tolerance_;
        break;
      case 4:
        ok = std::abs(v - t.value) <= tolerance_;
        break;
    }
    if (!ok) return false;
  }
  return true;
}

double selector_tolerance(const Mesh& mesh) {
  if (mesh.nodes.empty()) return 0.0;
  std::array<double, 3> lo = mesh.nodes[0];
  std::array<double, 3> hi = mesh.nodes[0];
  for (const auto& n : mesh.nodes) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], n[k]);
      hi[k] = std::max(hi[k], n[k]);
    }
  }
  const double dx = hi[0] - lo[0], dy = hi[1] - lo[1], dz = hi[2] - lo[2];
  return 1e-6 * std::sqrt(dx * dx + dy * dy + dz * dz);
}

std::vector<std::int32_t> select_nodes(const Mesh& mesh, std::string_view selector) {
  if (auto it = find_named(mesh.node_sets, selector); it != mesh.node_sets.end()) {
    if (it->second.empty()) throw SelectorError("node set '" + it->first + "' is empty");
    return it->second;
  }
  std::vector<std::int32_t> out;
  if (lower(selector) == "all") {
    out.resize(mesh.nodes.size());
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = static_cast<std::int32_t>(i);
  } else {
    NodePredicate pred;
    try {
      pred = NodePredicate::parse(selector, selector_tolerance(mesh));
    } catch (const SelectorError& e) {
      std::string sets;
      for (const auto& [name, nodes] : mesh.node_sets) sets += (sets.empty() ? "" : ", ") + name;
      throw SelectorError(std::string("'") + std::string(selector) +
                          "' is not a node set of the mesh (sets: " +
                          (sets.empty() ? "none" : sets) + ") nor an expression: " + e.what());
    }
    for (std::size_t i = 0; i < mesh.nodes.size(); ++i) {
      if (pred(mesh.nodes[i])) out.push_back(static_cast<std::int32_t>(i));
    }
  }
  if (out.empty()) {
    throw SelectorError("'" + std::string(selector) + "' selects no node of the mesh");
  }
  return out;
}

std::vector<std::int32_t> face_nodes(const Mesh& mesh, const Face& face) {
  const Element& e = mesh.elements.at(static_cast<std::size_t>(face.element));
  if (face.face < 0 || face.face >= face_count(e.type)) {
    throw SelectorError("face " + std::to_string(face.face) + " of element " +
                        std::to_string(face.element) + " does not exist");
  }
  const auto local = face_local_nodes(e.type, face.face);
  std::vector<std::int32_t> out;
  for (int k = 0; k < face_node_count(e.type); ++k) {
    out.push_back(e.nodes[static_cast<std::size_t>(local[static_cast<std::size_t>(k)])]);
  }
  return out;
}

std::vector<Face> exterior_faces(const Mesh& mesh) {
  // A volume face is exterior when no other element has a face with the same node set:
  // sort (sorted node list, face) pairs and keep the keys that occur once.
  struct Keyed {
    std::array<std::int32_t, 4> key;
    Face face;
  };
  std::vector<Keyed> keyed;
  for (std::size_t e = 0; e < mesh.elements.size(); ++e) {
    const Element& el = mesh.elements[e];
    if (el.type == ElementType::quad4) continue;
    for (int f = 0; f < face_count(el.type); ++f) {
      const auto local = face_local_nodes(el.type, f);
      std::array<std::int32_t, 4> k{-1, -1, -1, -1};
      const int count = face_node_count(el.type);
      for (int i = 0; i < count; ++i) {
        k[static_cast<std::size_t>(i)] =
            el.nodes[static_cast<std::size_t>(local[static_cast<std::size_t>(i)])];
      }
      // Insertion sort of 3-4 entries (std::sort here draws false -Warray-bounds from GCC 12).
      for (int i = 1; i < count; ++i) {
        for (int m = i;
             m > 0 && k[static_cast<std::size_t>(m - 1)] > k[static_cast<std::size_t>(m)]; --m) {
          std::swap(k[static_cast<std::size_t>(m - 1)], k[static_cast<std::size_t>(m)]);
        }
      }
      keyed.push_back({k, {static_cast<std::int32_t>(e), f}});
    }
  }
  std::sort(keyed.begin(), keyed.end(), [](const Keyed& a, const Keyed& b) {
    return a.key != b.key
               ? a.key < b.key
               : std::tie(a.face.element, a.face.face) < std::tie(b.face.element, b.face.face);
  });
  std::vector<char> exterior(mesh.elements.size() * 6, 0);
  for (std::size_t i = 0; i < keyed.size();) {
    std::size_t j = i + 1;
    while (j < keyed.size() && keyed[j].key == keyed[i].key) ++j;
    if (j == i + 1) {
      exterior[static_cast<std::size_t>(keyed[i].face.element) * 6 +
               static_cast<std::size_t>(keyed[i].face.face)] = 1;
    }
    i = j;
  }
  // In element and face order, so the result does not depend on the sort.
  std::vector<Face> out;
  for (std::size_t e = 0; e < mesh.elements.size(); ++e) {
    const ElementType t = mesh.elements[e].type;
    if (t == ElementType::quad4) {
      out.push_back({static_cast<std::int32_t>(e), 1});
      continue;
    }
    for (int f = 0; f < face_count(t); ++f) {
      if (exterior[e * 6 + static_cast<std::size_t>(f)])
        out.push_back({static_cast<std::int32_t>(e), f});
    }
  }
  return out;
}

std::vector<Face> select_faces(const Mesh& mesh, std::string_view selector) {
  if (auto it = find_named(mesh.surfaces, selector); it != mesh.surfaces.end()) {
    if (it->second.empty()) throw SelectorError("surface '" + it->first + "' is empty");
    return it->second;
  }
  const auto all = exterior_faces(mesh);
  if (lower(selector) == "exterior") return all;
  std::vector<std::int32_t> nodes;
  try {
    nodes = select_nodes(mesh, selector);
  } catch (const SelectorError& e) {
    throw SelectorError(
        "'" + std::string(selector) +
        "' is not a surface of the mesh, \"exterior\", nor a node selector: " + e.what());
  }
  std::vector<char> chosen(mesh.nodes.size(), 0);
  for (auto n : nodes) chosen[static_cast<std::size_t>(n)] = 1;
  std::vector<Face> out;
  for (const auto& f : all) {
    const auto fn = face_nodes(mesh, f);
    if (std::all_of(fn.begin(), fn.end(),
                    [&](std::int32_t n) { return chosen[static_cast<std::size_t>(n)]; })) {
      out.push_back(f);
    }
  }
  if (out.empty()) {
    throw SelectorError("'" + std::string(selector) + "' selects no exterior face of the mesh");
  }
  return out;
}

double face_area(const Mesh& mesh, const Face& face) {
  const auto fn = face_nodes(mesh, face);
  auto p = [&](std::size_t i) { return mesh.nodes[static_cast<std::size_t>(fn[i])]; };
  // Fan of triangles from the first node; the vector area sum is exact for planar faces and
  // the usual approximation for a warped quad.
  std::array<double, 3> s{0.0, 0.0, 0.0};
  for (std::size_t i = 1; i + 1 < fn.size(); ++i) {
    const auto a = p(0), b = p(i), c = p(i + 1);
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    s[0] += 0.5 * (u[1] * v[2] - u[2] * v[1]);
    s[1] += 0.5 * (u[2] * v[0] - u[0] * v[2]);
    s[2] += 0.5 * (u[0] * v[1] - u[1] * v[0]);
  }
  return std::sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
}

}  // namespace demfem::fem
