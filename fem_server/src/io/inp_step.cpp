// History data of the .inp reader: *STEP with *STATIC or *DYNAMIC, *BOUNDARY, *CLOAD, *DLOAD,
// *DSLOAD and *AMPLITUDE (see inp_parser.hpp). Each is kept with its line and resolved
// against the flattened mesh at the end; fem_scene.cpp maps the result onto the FEM's load
// model.
#include <algorithm>
#include <cmath>
#include <set>

#include "inp_parser.hpp"

namespace demfem::fem::inp {

namespace {

/// Procedures of Abaqus that demfem does not run.
const std::set<std::string> kOtherProcedures = {"BUCKLE",
                                                "HEAT TRANSFER",
                                                "COUPLED TEMPERATURE-DISPLACEMENT",
                                                "COUPLED THERMAL-ELECTRICAL",
                                                "VISCO",
                                                "MODAL DYNAMIC",
                                                "STEADY STATE DYNAMICS",
                                                "GEOSTATIC",
                                                "SOILS",
                                                "DYNAMIC TEMPERATURE-DISPLACEMENT",
                                                "COMPLEX FREQUENCY",
                                                "RANDOM RESPONSE",
                                                "RESPONSE SPECTRUM",
                                                "SUBSTRUCTURE GENERATE",
                                                "MASS DIFFUSION",
                                                "ANNEAL",
                                                "DIRECT CYCLIC",
                                                "MATRIX GENERATE",
                                                "SUBSPACE DYNAMIC",
                                                "DYNAMIC EXPLICIT"};

/// DOFs (1-based) fixed by the symbolic *BOUNDARY types.
bool symbolic_dofs(const std::string& type, std::array<bool, 6>& fixed) {
  static const std::pair<const char*, std::array<int, 6>> kTypes[] = {
      {"ENCASTRE", {1, 1, 1, 1, 1, 1}}, {"PINNED", {1, 1, 1, 0, 0, 0}},
      {"XSYMM", {1, 0, 0, 0, 1, 1}},    {"YSYMM", {0, 1, 0, 1, 0, 1}},
      {"ZSYMM", {0, 0, 1, 1, 1, 0}},    {"XASYMM", {0, 1, 1, 1, 0, 0}},
      {"YASYMM", {1, 0, 1, 0, 1, 0}},   {"ZASYMM", {1, 1, 0, 0, 0, 1}}};
  for (const auto& [name, dofs] : kTypes)
    if (type == name) {
      for (int d = 0; d < 6; ++d) fixed[d] = dofs[d] != 0;
      return true;
    }
  return false;
}

}  // namespace

bool Parser::handle_history(const Keyword& kw, std::size_t begin, std::size_t end) {
  const std::string& k = kw.name;
  auto need_step = [&] {
    if (!in_step_) deck_.fail(kw.loc, "*" + k + " outside a *STEP (loads belong to a step)");
  };
  if (k == "BOUNDARY") {
    if (block_ == Block::part || block_ == Block::instance)
      deck_.fail(kw.loc,
                 "*BOUNDARY inside a *PART or *INSTANCE (give it at the assembly or model level)");
    read_boundary(kw, begin, end);
  } else if (k == "CLOAD") {
    need_step();
    read_cload(kw, begin, end);
  } else if (k == "DLOAD") {
    need_step();
    read_dload(kw, begin, end);
  } else if (k == "DSLOAD") {
    need_step();
    read_dsload(kw, begin, end);
  } else if (k == "AMPLITUDE") {
    read_amplitude(kw, begin, end);
  } else if (k == "STATIC" || k == "DYNAMIC") {
    read_procedure(kw, begin, end, k == "DYNAMIC");
  } else if (k == "FREQUENCY") {
    read_frequency(kw, begin, end);
  } else if (kOtherProcedures.count(k)) {
    deck_.fail(kw.loc, "procedure *" + k +
                           " is not supported: demfem runs a linear static analysis (*STATIC), "
                           "a Bossak-Newmark dynamic one (*DYNAMIC) or a modal analysis "
                           "(*FREQUENCY, with fem.analysis = \"modal\")");
  } else {
    return false;
  }
  return true;
}

void Parser::read_procedure(const Keyword& kw, std::size_t begin, std::size_t end, bool dynamic) {
  const auto& lines = deck_.lines();
  if (!in_step_) deck_.fail(kw.loc, "*" + kw.name + " outside a *STEP");
  if (procedure_) deck_.fail(kw.loc, "a second procedure in one *STEP");
  procedure_ = true;
  if (dynamic) {
    check_params(kw, {"ALPHA", "APPLICATION", "DIRECT", "HAFTOL", "HALFINC SCALE FACTOR", "NOHAF",
                      "INITIAL"});
    std::string given;
    for (const char* p : {"ALPHA", "APPLICATION", "INITIAL"})
      if (auto v = kw.param(p)) given += std::string(given.empty() ? "" : ", ") + p + "=" + *v;
    note(kw.loc,
         "*DYNAMIC: demfem integrates with Bossak-Newmark (fem.bossak of the scene) at "
         "the fixed step fem.dt up to run.end_time, not with Abaqus' HHT and automatic "
         "increments" +
             (given.empty() ? std::string() : "; ignored: " + given));
  } else {
    check_params(kw, {"DIRECT"});
  }
  InpStep& st = model_.step;
  st.dynamic = dynamic;
  st.procedure_where = deck_.where(kw.loc);
  if (end - begin > 1) deck_.fail(lines[begin + 1].loc, "*" + kw.name + " takes one data line");
  if (begin < end) {
    const Loc l = lines[begin].loc;
    const auto v = split_commas(lines[begin].text);
    if (v.size() > 4 && !dynamic)
      deck_.fail(l, "*STATIC data: initial increment, period, minimum, maximum");
    if (!v.empty() && !v[0].empty()) {
      st.increment = deck_.number(v[0], l, "initial time increment");
      if (!(st.increment > 0)) deck_.fail(l, "initial time increment must be > 0");
    }
    if (v.size() > 1 && !v[1].empty()) {
      st.period = deck_.number(v[1], l, "time period");
      if (!(st.period > 0)) deck_.fail(l, "time period must be > 0");
    }
  }
  // Abaqus' default variation of loads without AMPLITUDE=: ramp over a static step, step
  // (applied at once) in a dynamic one.
  if (!explicit_step_amplitude_) st.ramp = !dynamic;
}

void Parser::read_frequency(const Keyword& kw, std::size_t begin, std::size_t end) {
  const auto& lines = deck_.lines();
  if (!in_step_) deck_.fail(kw.loc, "*FREQUENCY outside a *STEP");
  if (procedure_) deck_.fail(kw.loc, "a second procedure in one *STEP");
  procedure_ = true;
  // Abaqus' and CalculiX' choices of eigensolver and normalisation: demfem has its own
  // (shift-invert Lanczos, mass-normalised modes).
  check_params(kw, {"EIGENSOLVER", "NORMALIZATION", "SOLVER", "STORAGE", "GLOBAL", "CYCMPC",
                    "ALPHA", "SIM", "ACOUSTIC COUPLING", "PROPERTY EVALUATION"});
  InpStep& st = model_.step;
  st.frequency = true;
  st.procedure_where = deck_.where(kw.loc);
  if (end - begin > 1) deck_.fail(lines[begin + 1].loc, "*FREQUENCY takes one data line");
  std::string ignored;
  if (begin < end) {
    const Loc l = lines[begin].loc;
    const auto v = split_commas(lines[begin].text);
    if (!v.empty() && !v[0].empty()) {
      const double n = deck_.number(v[0], l, "number of eigenvalues");
      if (!(n >= 1 && n <= 100000 && n == std::floor(n)))
        deck_.fail(l, "number of eigenvalues " + v[0] + " is outside [1, 100000] (a whole number)");
      st.modes = static_cast<int>(n);
    }
    for (std::size_t i = 1; i < v.size(); ++i)
      if (!v[i].empty())
        ignored =
            "; the data line's other fields (frequency range, shift) are "
            "ignored: give fem.modal.shift in the scene";
  }
  note(kw.loc,
       "*FREQUENCY: demfem computes the modes nearest fem.modal.shift by shift-invert "
       "Lanczos (mass-normalised), not with the deck's eigensolver" +
           ignored);
}

void Parser::read_boundary(const Keyword& kw, std::size_t begin, std::size_t end) {
  const auto& lines = deck_.lines();
  check_params(kw, {"OP", "TYPE", "AMPLITUDE"});
  const std::string type = upper(kw.param("TYPE").value_or("DISPLACEMENT"));
  if (type != "DISPLACEMENT") {
    deck_.fail(kw.loc, "*BOUNDARY, TYPE=" + type +
                           " is not supported (only prescribed displacements and rotations)");
  }
  const std::string op = upper(kw.param("OP").value_or("MOD"));
  if (op != "MOD" && op != "NEW") deck_.fail(kw.loc, "*BOUNDARY, OP= must be MOD or NEW");
  if (op == "NEW") boundaries_.clear();  // removes every boundary condition given before
  const std::string amplitude = upper(kw.param("AMPLITUDE").value_or(""));
  for (std::size_t i = begin; i < end; ++i) {
    const Loc l = lines[i].loc;
    const auto p = split_commas(lines[i].text);
    if (p.size() < 2 || p[0].empty()) {
      deck_.fail(l,
                 "*BOUNDARY data: '<node or node set>, <first DOF>[, <last DOF>[, <value>]]' "
                 "or '<node or node set>, ENCASTRE|PINNED|XSYMM|...'");
    }
    RawBoundary b;
    b.token = p[0];
    b.amplitude = amplitude;
    b.loc = l;
    if (!looks_numeric(p[1])) {
      if (p.size() != 2 || !symbolic_dofs(upper(p[1]), b.fixed)) {
        deck_.fail(l, "*BOUNDARY: '" + p[1] +
                          "' is not a DOF number nor one of ENCASTRE, PINNED, XSYMM, YSYMM, "
                          "ZSYMM, XASYMM, YASYMM, ZASYMM");
      }
    } else {
      if (p.size() > 4) deck_.fail(l, "*BOUNDARY: at most 4 values per line");
      const auto first = deck_.label(p[1], l, "first DOF");
      const auto last = p.size() > 2 && !p[2].empty() ? deck_.label(p[2], l, "last DOF") : first;
      const double value = p.size() > 3 ? deck_.number(p[3], l, "prescribed value") : 0.0;
      if (first > 6 || last > 6)
        deck_.fail(l, "*BOUNDARY: DOF " + std::to_string(std::max(first, last)) +
                          " is not a displacement (1-3) or rotation (4-6); other fields are not "
                          "supported");
      if (last < first) deck_.fail(l, "*BOUNDARY: last DOF is smaller than the first");
      for (auto d = first; d <= last; ++d) {
        b.fixed[static_cast<std::size_t>(d - 1)] = true;
        b.value[static_cast<std::size_t>(d - 1)] = value;
      }
    }
    boundaries_.push_back(std::move(b));
  }
}

void Parser::read_cload(const Keyword& kw, std::size_t begin, std::size_t end) {
  const auto& lines = deck_.lines();
  check_params(kw, {"OP", "AMPLITUDE"});
  const std::string op = upper(kw.param("OP").value_or("MOD"));
  if (op != "MOD" && op != "NEW") deck_.fail(kw.loc, "*CLOAD, OP= must be MOD or NEW");
  if (op == "NEW") cloads_.clear();
  for (std::size_t i = begin; i < end; ++i) {
    const Loc l = lines[i].loc;
    const auto p = split_commas(lines[i].text);
    if (p.size() != 3) deck_.fail(l, "*CLOAD data: '<node or node set>, <DOF>, <magnitude>'");
    const auto dof = deck_.label(p[1], l, "DOF");
    if (dof > 3) {
      deck_.fail(l, "*CLOAD on DOF " + std::to_string(dof) +
                        ": only forces (DOF 1-3) are supported, not moments or other fields; "
                        "apply moments as force couples or put loads into the scene");
    }
    cloads_.push_back({p[0], static_cast<int>(dof - 1), deck_.number(p[2], l, "load magnitude"),
                       upper(kw.param("AMPLITUDE").value_or("")), l});
  }
}

void Parser::read_dload(const Keyword& kw, std::size_t begin, std::size_t end) {
  const auto& lines = deck_.lines();
  check_params(kw, {"OP", "AMPLITUDE"});
  const std::string op = upper(kw.param("OP").value_or("MOD"));
  if (op != "MOD" && op != "NEW") deck_.fail(kw.loc, "*DLOAD, OP= must be MOD or NEW");
  if (op == "NEW") dloads_.clear();
  for (std::size_t i = begin; i < end; ++i) {
    const Loc l = lines[i].loc;
    auto p = split_commas(lines[i].text);
    if (p.size() < 3)
      deck_.fail(l, "*DLOAD data: '<element or element set>, <load type>, <magnitude>[, ...]'");
    RawDload d;
    d.token = p[0];
    d.type = upper(p[1]);
    d.magnitude = deck_.number(p[2], l, "load magnitude");
    d.amplitude = upper(kw.param("AMPLITUDE").value_or(""));
    d.loc = l;
    const bool face = d.type == "P" || (d.type.size() == 2 && d.type[0] == 'P' &&
                                        d.type[1] >= '1' && d.type[1] <= '6');
    if (d.type == "GRAV") {
      if (p.size() != 6) deck_.fail(l, "*DLOAD GRAV needs '<elements>, GRAV, <g>, <x>, <y>, <z>'");
      double n2 = 0;
      for (int c = 0; c < 3; ++c) {
        d.direction[c] = deck_.number(p[3 + c], l, "gravity direction");
        n2 += d.direction[c] * d.direction[c];
      }
      if (!(n2 > 0)) deck_.fail(l, "*DLOAD GRAV: the direction is zero");
      for (auto& c : d.direction) c /= std::sqrt(n2);  // Abaqus normalises it
    } else if (face) {
      if (p.size() != 3)
        deck_.fail(l, "*DLOAD " + d.type + " takes '<elements>, " + d.type + ", <magnitude>'");
    } else {
      deck_.fail(l, "*DLOAD load type " + d.type +
                        " is not supported (supported: P1..P6 face pressures of solids, P of "
                        "shells, GRAV); put body forces as gravity into the scene "
                        "(fem.gravity)");
    }
    dloads_.push_back(std::move(d));
  }
}

void Parser::read_dsload(const Keyword& kw, std::size_t begin, std::size_t end) {
  const auto& lines = deck_.lines();
  check_params(kw, {"OP", "AMPLITUDE"});
  const std::string op = upper(kw.param("OP").value_or("MOD"));
  if (op != "MOD" && op != "NEW") deck_.fail(kw.loc, "*DSLOAD, OP= must be MOD or NEW");
  if (op == "NEW") dsloads_.clear();
  for (std::size_t i = begin; i < end; ++i) {
    const Loc l = lines[i].loc;
    const auto p = split_commas(lines[i].text);
    if (p.size() >= 2 && upper(p[1]) != "P") {
      deck_.fail(l, "*DSLOAD load type " + upper(p[1]) +
                        " is not supported (only P, a pressure); put tractions into the scene");
    }
    if (p.size() != 3) deck_.fail(l, "*DSLOAD data: '<surface>, P, <magnitude>'");
    dsloads_.push_back(
        {p[0], deck_.number(p[2], l, "pressure"), upper(kw.param("AMPLITUDE").value_or("")), l});
  }
}

void Parser::read_amplitude(const Keyword& kw, std::size_t begin, std::size_t end) {
  const auto& lines = deck_.lines();
  check_params(kw, {"NAME", "DEFINITION", "TIME", "VALUE", "SMOOTH", "SCALEX", "SCALEY", "SHIFTX",
                    "SHIFTY", "FIXED INTERVAL", "BEGIN"});
  const std::string name = required_name(kw, "NAME");
  if (model_.amplitudes.count(name)) deck_.fail(kw.loc, "amplitude " + name + " is defined twice");
  const std::string def = upper(kw.param("DEFINITION").value_or("TABULAR"));
  if (def != "TABULAR" && def != "EQUALLY SPACED") {
    deck_.fail(kw.loc, "*AMPLITUDE, DEFINITION=" + def +
                           " is not supported (TABULAR and EQUALLY SPACED are); write it as a "
                           "table, or use a time function of the scene (docs/scene_fem.md)");
  }
  const std::string time = upper(kw.param("TIME").value_or("STEP TIME"));
  if (time != "STEP TIME" && time != "TOTAL TIME")
    deck_.fail(kw.loc, "*AMPLITUDE, TIME= must be STEP TIME or TOTAL TIME");
  if (upper(kw.param("VALUE").value_or("RELATIVE")) != "RELATIVE") {
    deck_.fail(kw.loc,
               "*AMPLITUDE, VALUE=ABSOLUTE is not supported (the amplitude must scale "
               "the load's magnitude)");
  }
  auto param_number = [&](const char* key, double fallback) {
    auto v = kw.param(key);
    return v ? deck_.number(*v, kw.loc, std::string(key) + "=") : fallback;
  };
  const double sx = param_number("SCALEX", 1.0), sy = param_number("SCALEY", 1.0),
               dx = param_number("SHIFTX", 0.0), dy = param_number("SHIFTY", 0.0);
  std::vector<double> v;
  for (std::size_t i = begin; i < end; ++i)
    for (const auto& t : split_commas(lines[i].text))
      v.push_back(deck_.number(t, lines[i].loc, "amplitude value"));
  if (v.empty()) deck_.fail(kw.loc, "*AMPLITUDE " + name + " has no data");
  InpAmplitude a;
  a.where = deck_.where(kw.loc);
  if (def == "TABULAR") {
    if (v.size() % 2 != 0)
      deck_.fail(lines[end - 1].loc, "*AMPLITUDE " + name + ": (time, value) pairs expected");
    for (std::size_t i = 0; i < v.size(); i += 2) a.points.emplace_back(v[i], v[i + 1]);
  } else {
    const double dt = param_number("FIXED INTERVAL", 0.0);
    if (!(dt > 0))
      deck_.fail(kw.loc, "*AMPLITUDE, DEFINITION=EQUALLY SPACED needs FIXED INTERVAL > 0");
    const double t0 = param_number("BEGIN", 0.0);
    for (std::size_t i = 0; i < v.size(); ++i)
      a.points.emplace_back(t0 + dt * static_cast<double>(i), v[i]);
  }
  if (!(sx > 0)) deck_.fail(kw.loc, "*AMPLITUDE, SCALEX= must be > 0");
  for (auto& [t, f] : a.points) {
    t = t * sx + dx;
    f = f * sy + dy;
  }
  for (std::size_t i = 1; i < a.points.size(); ++i)
    if (!(a.points[i].first > a.points[i - 1].first))
      deck_.fail(kw.loc, "*AMPLITUDE " + name + ": times must increase strictly (entry " +
                             std::to_string(i + 1) + ")");
  model_.amplitudes[name] = std::move(a);
}

// ---- resolution ---------------------------------------------------------------------------

std::vector<std::int32_t> Parser::history_nodes(const std::string& token, Loc loc) const {
  if (is_label_token(token)) {
    const auto idx = find_label(true, token, 0, loc);
    if (!idx) deck_.fail(loc, "node " + token + " is not defined");
    return {*idx};
  }
  const auto* set = find_set(model_.mesh.node_sets, token, "");
  if (!set) deck_.fail(loc, "node set " + upper(token) + " is not defined");
  return *set;
}

std::vector<std::int32_t> Parser::history_elements(const std::string& token, Loc loc) const {
  if (token.empty()) {  // the whole model
    std::vector<std::int32_t> all(model_.mesh.elements.size());
    for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<std::int32_t>(i);
    return all;
  }
  if (is_label_token(token)) {
    const auto idx = find_label(false, token, 0, loc);
    if (!idx) deck_.fail(loc, "element " + token + " is not defined");
    return {*idx};
  }
  const auto* set = find_set(model_.mesh.element_sets, token, "");
  if (!set) deck_.fail(loc, "element set " + upper(token) + " is not defined");
  return *set;
}

void Parser::resolve_history() {
  const Mesh& mesh = model_.mesh;
  auto check_amplitude = [&](const std::string& name, Loc loc) {
    if (!name.empty() && !model_.amplitudes.count(name))
      deck_.fail(loc, "amplitude " + name + " is not defined");
  };
  for (const auto& b : boundaries_) {
    check_amplitude(b.amplitude, b.loc);
    model_.boundaries.push_back(
        {history_nodes(b.token, b.loc), b.fixed, b.value, b.amplitude, deck_.where(b.loc)});
  }
  for (const auto& c : cloads_) {
    check_amplitude(c.amplitude, c.loc);
    model_.concentrated_loads.push_back(
        {history_nodes(c.token, c.loc), c.dof, c.magnitude, c.amplitude, deck_.where(c.loc)});
  }
  for (const auto& d : dloads_) {
    check_amplitude(d.amplitude, d.loc);
    const auto elems = history_elements(d.token, d.loc);
    if (d.type == "GRAV") {
      model_.gravity.push_back({d.magnitude, d.direction, elems, d.amplitude, deck_.where(d.loc)});
      continue;
    }
    InpPressure p{{}, d.magnitude, d.amplitude, deck_.where(d.loc)};
    for (auto e : elems) {
      const ElementType t = mesh.elements[static_cast<std::size_t>(e)].type;
      int face = -1;
      if (t == ElementType::quad4 && d.type == "P") face = 1;  // pushes on the SPOS side
      if (t != ElementType::quad4 && d.type.size() == 2) {
        const int n = d.type[1] - '1';
        if (n < (t == ElementType::hex8 ? 6 : 4)) face = n;
      }
      if (face < 0) {
        deck_.fail(d.loc, "*DLOAD " + d.type + " does not fit element " +
                              std::to_string(mesh.element_labels[static_cast<std::size_t>(e)]) +
                              " (" +
                              (t == ElementType::quad4  ? "shells take P"
                               : t == ElementType::hex8 ? "C3D8 faces are P1..P6"
                                                        : "C3D4 faces are P1..P4") +
                              ")");
      }
      p.faces.push_back({e, face});
    }
    model_.pressures.push_back(std::move(p));
  }
  for (const auto& d : dsloads_) {
    check_amplitude(d.amplitude, d.loc);
    const auto it = mesh.surfaces.find(upper(d.surface));
    if (it == mesh.surfaces.end())
      deck_.fail(d.loc, "surface " + upper(d.surface) + " is not defined");
    model_.pressures.push_back({it->second, d.magnitude, d.amplitude, deck_.where(d.loc)});
  }
}

}  // namespace demfem::fem::inp
