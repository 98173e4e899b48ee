// The .inp reader's entry points and keyword dispatch: which keywords are model data, history
// data, harmless (accepted, some with a note) or refused. See inp_parser.hpp.
#include "demfem/fem/inp_reader.hpp"

#include <algorithm>
#include <cstring>

#include "demfem/io/input_file.hpp"
#include "inp_parser.hpp"

namespace demfem::fem {

namespace inp {

namespace {

/// Accepted without effect, silently: they carry nothing that changes a linear solve.
const std::set<std::string> kSilent = {"HEADING", "PREPRINT", "PHYSICAL CONSTANTS"};

/// Output requests and solution controls: accepted, listed in one note (demfem's output is
/// [fem.output]; a linear solve has no increments or iterations to control).
const std::set<std::string> kOutputRequests = {"OUTPUT",
                                               "NODE OUTPUT",
                                               "ELEMENT OUTPUT",
                                               "CONTACT OUTPUT",
                                               "ENERGY OUTPUT",
                                               "NODE PRINT",
                                               "EL PRINT",
                                               "ENERGY PRINT",
                                               "NODE FILE",
                                               "EL FILE",
                                               "ENERGY FILE",
                                               "MONITOR",
                                               "RESTART",
                                               "FILE FORMAT",
                                               "FILE OUTPUT",
                                               "CONTROLS",
                                               "SOLVER CONTROLS",
                                               "DIAGNOSTICS",
                                               "PRINT",
                                               "MODAL OUTPUT",
                                               "INTEGRATED OUTPUT",
                                               "INCREMENTATION OUTPUT",
                                               "SECTION PRINT",
                                               "SECTION FILE"};

/// Keywords refused with a specific reason (every other unknown keyword is refused too).
const char* refusal_reason(const std::string& k) {
  static const std::pair<const char*, const char*> reasons[] = {
      {"DAMPING", "material damping: put Rayleigh damping into [fem.damping] of the scene"},
      {"PLASTIC", "demfem's FEM is linear elastic"},
      {"HYPERELASTIC", "demfem's FEM is linear elastic"},
      {"HYPERFOAM", "demfem's FEM is linear elastic"},
      {"VISCOELASTIC", "demfem's FEM is linear elastic"},
      {"CREEP", "demfem's FEM is linear elastic"},
      {"DAMAGE INITIATION", "demfem's FEM is linear elastic"},
      {"CONCRETE DAMAGED PLASTICITY", "demfem's FEM is linear elastic"},
      {"USER MATERIAL", "demfem's FEM is linear elastic"},
      {"TRANSFORM", "it changes the directions of the nodes' DOFs"},
      {"SYSTEM", "it changes the coordinate system of the nodes"},
      {"EQUATION", "multi-point constraints are not supported"},
      {"MPC", "multi-point constraints are not supported"},
      {"KINEMATIC COUPLING", "coupling constraints are not supported"},
      {"COUPLING", "coupling constraints are not supported"},
      {"DISTRIBUTING COUPLING", "coupling constraints are not supported"},
      {"TIE", "tie constraints are not supported"},
      {"RIGID BODY", "rigid bodies are not supported"},
      {"CONTACT PAIR", "contact inside the FEM is not supported (contact is the DEM's)"},
      {"CONTACT", "contact inside the FEM is not supported (contact is the DEM's)"},
      {"SURFACE INTERACTION", "contact inside the FEM is not supported"},
      {"INITIAL CONDITIONS", "initial states are not supported (the FEM starts at rest)"},
      {"MASS", "point masses are not supported"},
      {"ROTARY INERTIA", "point inertias are not supported"},
      {"SPRING", "spring elements are not supported"},
      {"DASHPOT", "dashpot elements are not supported"},
      {"TEMPERATURE", "temperature loads are not supported"},
      {"FIELD", "field variables are not supported"},
      {"NCOPY", "mesh generation: generate the mesh in the preprocessor"},
      {"NGEN", "mesh generation: generate the mesh in the preprocessor"},
      {"NFILL", "mesh generation: generate the mesh in the preprocessor"},
      {"ELGEN", "mesh generation: generate the mesh in the preprocessor"},
      {"ELCOPY", "mesh generation: generate the mesh in the preprocessor"},
      {"MODAL DAMPING", "modal procedures are not supported"},
      {"BEAM SECTION", "beam elements are not supported"},
      {"MEMBRANE SECTION", "membrane elements are not supported"},
      {"COHESIVE SECTION", "cohesive elements are not supported"},
      {"SHELL GENERAL SECTION", "general shell sections are not supported (use *SHELL SECTION)"},
      {"TRANSVERSE SHEAR STIFFNESS", "it changes the shell's transverse shear stiffness"},
      {"HOURGLASS STIFFNESS", "demfem has no hourglass-controlled element"},
      {"SECTION CONTROLS", "demfem has no hourglass-controlled element"},
      {"NODAL THICKNESS", "nodal shell thickness is not supported (one thickness per section)"},
      {"INITIAL STATE", "initial states are not supported"},
      {"SUBMODEL", "submodelling is not supported"},
      {"IMPORT", "importing a previous analysis is not supported"},
      {"PARAMETER", "parametrised decks are not supported: write the values out"},
  };
  for (const auto& [name, why] : reasons)
    if (k == name) return why;
  return nullptr;
}

}  // namespace

void Parser::note(Loc loc, const std::string& text) {
  model_.notes.push_back(deck_.where(loc) + ": " + text);
}

void Parser::check_params(const Keyword& kw, std::initializer_list<const char*> accepted) const {
  for (const auto& param : kw.params) {
    const std::string& key = param.first;
    const bool ok =
        std::any_of(accepted.begin(), accepted.end(), [&](const char* a) { return key == a; });
    if (!ok) {
      std::string list;
      for (const char* a : accepted) list += (list.empty() ? "" : ", ") + std::string(a);
      deck_.fail(kw.loc, "parameter " + key + " of *" + kw.name + " is not supported (accepted: " +
                             (list.empty() ? "none" : list) + "); demfem would not honour it");
    }
  }
}

std::string Parser::required_name(const Keyword& kw, std::string_view key) const {
  auto v = kw.param(key);
  if (!v || v->empty()) {
    deck_.fail(kw.loc, "*" + kw.name + " needs " + std::string(key) + "=<name>");
  }
  return upper(*v);
}

std::vector<std::string> Parser::single_data_line(const Keyword& kw, std::size_t begin,
                                                  std::size_t end) const {
  const auto& lines = deck_.lines();
  if (begin == end) deck_.fail(kw.loc, "*" + kw.name + " needs a data line");
  if (end - begin > 1) deck_.fail(lines[begin + 1].loc, "*" + kw.name + " takes one data line");
  return split_commas(lines[begin].text);
}

[[noreturn]] void Parser::refuse(const Keyword& kw) {
  const char* why = refusal_reason(kw.name);
  deck_.fail(kw.loc, "*" + kw.name + " is not supported by demfem's .inp reader" +
                         (why ? std::string(" (") + why + ")" : std::string()) +
                         "; ignoring it would change the model. Remove it, or express it in "
                         "the scene instead (docs/scene_fem.md lists both)");
}

bool Parser::handle_ignored(const Keyword& kw) {
  if (kSilent.count(kw.name)) return true;
  if (kOutputRequests.count(kw.name)) {
    ignored_[kw.name].push_back(kw.loc);
    return true;
  }
  return false;
}

bool Parser::handle_structure(const Keyword& kw, std::size_t begin, std::size_t end) {
  const std::string& k = kw.name;
  const auto& lines = deck_.lines();
  auto no_data = [&] {
    if (begin != end) deck_.fail(lines[begin].loc, "*" + k + " takes no data lines");
  };
  auto outside_step = [&] {
    if (in_step_) deck_.fail(kw.loc, "*" + k + " inside a *STEP (model data comes before it)");
  };
  if (k == "PART") {
    outside_step();
    check_params(kw, {"NAME"});
    if (block_ != Block::model) deck_.fail(kw.loc, "*PART inside another *PART or *ASSEMBLY");
    current_part_ = required_name(kw, "NAME");
    if (parts_.count(current_part_))
      deck_.fail(kw.loc, "part " + current_part_ + " is defined twice");
    parts_[current_part_];
    block_ = Block::part;
    block_loc_ = kw.loc;
    no_data();
  } else if (k == "END PART") {
    if (block_ != Block::part) deck_.fail(kw.loc, "*END PART without *PART");
    block_ = Block::model;
    no_data();
  } else if (k == "ASSEMBLY") {
    outside_step();
    check_params(kw, {"NAME"});
    if (block_ != Block::model) deck_.fail(kw.loc, "*ASSEMBLY inside a *PART or *ASSEMBLY");
    block_ = Block::assembly;
    block_loc_ = kw.loc;
    no_data();
  } else if (k == "END ASSEMBLY") {
    if (block_ != Block::assembly) deck_.fail(kw.loc, "*END ASSEMBLY without *ASSEMBLY");
    block_ = Block::model;
    no_data();
  } else if (k == "INSTANCE") {
    check_params(kw, {"NAME", "PART"});
    if (block_ != Block::assembly) deck_.fail(kw.loc, "*INSTANCE outside *ASSEMBLY");
    RawInstance inst;
    inst.name = required_name(kw, "NAME");
    inst.part = required_name(kw, "PART");
    inst.loc = kw.loc;
    for (const auto& other : instances_)
      if (other.name == inst.name)
        deck_.fail(kw.loc, "instance " + inst.name + " is defined twice");
    // Data lines: the translation, then the rotation (axis point a, point b, angle in
    // degrees); Abaqus applies the translation first.
    if (end - begin > 2) deck_.fail(lines[begin + 2].loc, "*INSTANCE takes at most two data lines");
    if (begin < end) {
      const auto t = split_commas(lines[begin].text);
      if (t.size() > 3) deck_.fail(lines[begin].loc, "*INSTANCE translation: at most 3 values");
      for (std::size_t c = 0; c < t.size(); ++c)
        inst.translation[c] = t[c].empty() ? 0.0
                                           : deck_.number(t[c], lines[begin].loc,
                                                          std::string("translation ") + "xyz"[c]);
    }
    if (begin + 1 < end) {
      const Loc l = lines[begin + 1].loc;
      const auto r = split_commas(lines[begin + 1].text);
      if (r.size() != 7)
        deck_.fail(l,
                   "*INSTANCE rotation needs 7 values: point a (3), point b (3), angle (degrees)");
      for (int c = 0; c < 3; ++c) {
        inst.axis_a[c] = deck_.number(r[c], l, "rotation axis point a");
        inst.axis_b[c] = deck_.number(r[c + 3], l, "rotation axis point b");
      }
      inst.angle_deg = deck_.number(r[6], l, "rotation angle");
      const double dx = inst.axis_b[0] - inst.axis_a[0], dy = inst.axis_b[1] - inst.axis_a[1],
                   dz = inst.axis_b[2] - inst.axis_a[2];
      if (!(dx * dx + dy * dy + dz * dz > 0.0))
        deck_.fail(l, "*INSTANCE rotation: points a and b of the axis coincide");
      inst.rotate = true;
    }
    instances_.push_back(std::move(inst));
    block_ = Block::instance;
  } else if (k == "END INSTANCE") {
    if (block_ != Block::instance) deck_.fail(kw.loc, "*END INSTANCE without *INSTANCE");
    block_ = Block::assembly;
    no_data();
  } else if (k == "STEP") {
    check_params(kw, {"NAME", "NLGEOM", "PERTURBATION", "INC", "AMPLITUDE", "UNSYMM",
                      "EXTRAPOLATION", "CONVERT SDI", "SOLVER"});
    if (in_step_) deck_.fail(kw.loc, "*STEP inside a *STEP (missing *END STEP)");
    if (block_ != Block::model) deck_.fail(kw.loc, "*STEP inside a *PART or *ASSEMBLY");
    if (++steps_ > 1) {
      deck_.fail(kw.loc, "a second *STEP (the first is at " + model_.step.where +
                             "): demfem runs one analysis; keep one step in the deck, or put "
                             "the loads into the scene ([[fem.clamps]], [[fem.pressures]], "
                             "[[fem.nodal_loads]]) and drop the steps");
    }
    if (auto nl = kw.param("NLGEOM"); nl && upper(*nl) != "NO") {
      deck_.fail(kw.loc, "*STEP, NLGEOM=" + upper(*nl) +
                             " asks for geometric nonlinearity; demfem's FEM is linear (use "
                             "NLGEOM=NO or remove the parameter)");
    }
    if (auto amp = kw.param("AMPLITUDE")) {
      const std::string a = upper(*amp);
      if (a != "RAMP" && a != "STEP") deck_.fail(kw.loc, "*STEP, AMPLITUDE= must be RAMP or STEP");
      model_.step.ramp = a == "RAMP";
      explicit_step_amplitude_ = true;
    }
    in_step_ = true;
    step_loc_ = kw.loc;
    model_.step.present = true;
    model_.step.where = deck_.where(kw.loc);
    // Data lines of *STEP are its subheading (text).
  } else if (k == "END STEP") {
    if (!in_step_) deck_.fail(kw.loc, "*END STEP without *STEP");
    if (!procedure_)
      deck_.fail(kw.loc, "the *STEP has no procedure (*STATIC, *DYNAMIC or *FREQUENCY)");
    in_step_ = false;
    no_data();
  } else {
    return false;
  }
  return true;
}

void Parser::handle(const Keyword& kw, std::size_t begin, std::size_t end) {
  const bool material_option = handle_material(kw, begin, end);
  if (!material_option) material_open_ = false;
  if (material_option) return;
  if (handle_structure(kw, begin, end)) return;
  if (handle_history(kw, begin, end)) return;
  if (handle_mesh(kw, begin, end)) return;
  if (handle_ignored(kw)) return;
  refuse(kw);
}

InpModel Parser::run() {
  const auto& lines = deck_.lines();
  std::size_t i = 0;
  while (i < lines.size()) {
    const Line& l = lines[i];
    if (!is_keyword(l.text))
      deck_.fail(l.loc, "data line outside of any keyword: '" + l.text + "'");
    std::size_t next = i + 1;
    Keyword kw = deck_.keyword(i, next);
    std::size_t end = next;
    while (end < lines.size() && !is_keyword(lines[end].text)) ++end;
    handle(kw, next, end);
    i = end;
  }
  if (block_ == Block::part) deck_.fail(block_loc_, "*PART without *END PART");
  if (block_ == Block::assembly) deck_.fail(block_loc_, "*ASSEMBLY without *END ASSEMBLY");
  if (block_ == Block::instance)
    deck_.fail(instances_.back().loc, "*INSTANCE without *END INSTANCE");
  if (in_step_) deck_.fail(step_loc_, "*STEP without *END STEP");
  build();
  resolve_history();
  if (!ignored_.empty()) {
    std::string list;
    for (const auto& [name, locs] : ignored_)
      list += (list.empty() ? "*" : ", *") + name + " (line " + std::to_string(locs[0].line) +
              (locs.size() > 1 ? " and " + std::to_string(locs.size() - 1) + " more)" : ")");
    model_.notes.push_back(deck_.files()[0] +
                           ": output requests and solution controls ignored (demfem writes "
                           "what [fem.output] asks; a linear solve has no increments to "
                           "control): " +
                           list);
  }
  return std::move(model_);
}

}  // namespace inp

InpModel parse_inp(const std::string& text, const std::string& name, const InpOptions& options) {
  const inp::Deck deck(text, name, options.allow_include);
  return inp::Parser(deck, options).run();
}

InpModel read_inp_model(const std::filesystem::path& file, const InpOptions& options) {
  std::string text;
  try {
    text = io::read_regular_file(file, io::kMeshFileLimit, "an Abaqus input file (.inp)");
  } catch (const io::InputFileError& e) {
    throw InpError(e.what());
  }
  return parse_inp(text, file.string(), options);
}

Mesh read_inp(const std::filesystem::path& file, const InpOptions& options) {
  Mesh mesh = read_inp_model(file, options).mesh;
  for (auto& e : mesh.elements) e.section = 0;
  return mesh;
}

}  // namespace demfem::fem
