#include "demfem/fem/fem_scene.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <optional>
#include <stdexcept>

#include "demfem/fem/assembly.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/fem/inp_reader.hpp"
#include "demfem/fem/mesher.hpp"
#include "demfem/fem/node_selector.hpp"
#include "demfem/fem/time_function.hpp"
#include "inp_mapping.hpp"

namespace demfem::fem {

namespace {

using scene::Range;
using scene::Table;

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::array<int, 3> cell_counts(const Table& t, std::string_view key, std::size_t n) {
  const auto v = t.numbers(key, n, Range::closed(1.0, 1e6));
  std::array<int, 3> out{1, 1, 1};
  for (std::size_t i = 0; i < n; ++i) {
    if (v[i] != std::floor(v[i])) t.fail(key, "entries must be whole numbers of cells");
    out[i] = static_cast<int>(v[i]);
  }
  // A guard against a typo that would ask for more memory than a workstation has.
  const double total = static_cast<double>(out[0]) * out[1] * out[2];
  if (total > 2e7)
    t.fail(key, "asks for " + std::to_string(static_cast<long long>(total)) +
                    " cells; at most 2e7 are accepted");
  return out;
}

/// Cells of a structured mesh must be distinguishable in double precision at their
/// coordinates, and not so flat that their stiffness loses its digits (aspect ratio above
/// 1e4: the pivots of such a mesh fall to round-off, see docs/scene_fem.md).
void check_cells(const Table& t, std::string_view key, const std::vector<double>& size,
                 const std::vector<double>& at, const std::array<int, 3>& cells) {
  double hmin = INFINITY, hmax = 0.0;
  for (std::size_t k = 0; k < size.size(); ++k) {
    const double h = size[k] / cells[k];
    if (!(h > 1e-9 * std::abs(at[k]))) {
      t.fail(key, "gives cells of " + std::to_string(h) + " m at a coordinate of " +
                      std::to_string(at[k]) +
                      " m: their nodes cannot be told apart in double precision (cell size "
                      "must be > 1e-9 x the coordinate)");
    }
    hmin = std::min(hmin, h);
    hmax = std::max(hmax, h);
  }
  if (hmax > 1e4 * hmin) {
    t.fail(key, "gives cells of aspect ratio " + std::to_string(hmax / hmin) +
                    " (longest / shortest edge); at most 1e4 is accepted: flatter elements lose "
                    "their stiffness to round-off");
  }
}

/// fem.mesh.translate, m: the rigid shift of the whole model (zero when not given). A
/// [fem.mesh.seat] is demfem run's to resolve (it reads the prepared DEM state, which the
/// FEM cannot): the launcher passes its result on as translate, so a seat without one means
/// a solver started by hand.
std::array<double, 3> read_translation(const Table& mesh) {
  const std::array<double, 3> zero{0.0, 0.0, 0.0};
  if (mesh.has("seat")) {
    mesh.skip("seat");
    if (!mesh.has("translate"))
      mesh.fail("seat", "is resolved by `demfem run` from the prepared DEM state ([dem.load]) "
                        "into fem.mesh.translate; a solver started on its own needs "
                        "fem.mesh.translate = [dx, dy, dz] instead");
  }
  const auto t = mesh.vec3("translate", zero);
  for (double v : t)
    if (!(std::abs(v) <= 1e6)) mesh.fail("translate", "must lie within [-1e6, 1e6] m");
  return t;
}

/// The mesh, and the materials and sections of a .inp file when it has them.
InpModel read_mesh(const Table& fem, bool& deck_loads, std::array<double, 3>& translate) {
  const Table mesh = fem.required_table("mesh");
  translate = read_translation(mesh);
  const int kinds = int(mesh.has("file")) + int(mesh.has("box")) + int(mesh.has("plate"));
  if (kinds != 1) {
    fem.fail("mesh", "needs exactly one of file = \"...inp\", box = {...} or plate = {...}");
  }
  InpModel model;
  if (mesh.has("file")) {
    const auto path = mesh.path("file");
    InpOptions options;
    if (mesh.has("c3d8r_as")) {
      options.c3d8r_as = mesh.choice("c3d8r_as", {"C3D8I", "C3D8"}) == "C3D8I"
                             ? SolidFormulation::incompatible_modes
                             : SolidFormulation::selective_reduced;
    }
    deck_loads = mesh.boolean("deck_loads", true);
    try {
      model = read_inp_model(path, options);
    } catch (const InpError& e) {
      mesh.fail("file", e.what());
    }
  } else if (auto box = mesh.table("box")) {
    const auto lo = box->vec3("lo");
    const auto hi = box->vec3("hi");
    const auto cells = cell_counts(*box, "cells", 3);
    const auto element = box->choice("element", "hex8", {"hex8", "tet4"});
    for (int k = 0; k < 3; ++k) {
      if (!(hi[static_cast<std::size_t>(k)] > lo[static_cast<std::size_t>(k)])) {
        box->fail("hi", "must be greater than lo in every coordinate");
      }
    }
    check_cells(
        *box, "cells", {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]},
        {std::max(std::abs(lo[0]), std::abs(hi[0])), std::max(std::abs(lo[1]), std::abs(hi[1])),
         std::max(std::abs(lo[2]), std::abs(hi[2]))},
        cells);
    box->finish();
    model.mesh = element == "hex8" ? box_mesh_hex(lo, hi, cells) : box_mesh_tet(lo, hi, cells);
  } else if (auto plate = mesh.table("plate")) {
    const auto origin = plate->vec3("origin", std::array<double, 3>{0.0, 0.0, 0.0});
    const auto size = plate->numbers("size", 2, Range::positive());
    const auto cells = cell_counts(*plate, "cells", 2);
    check_cells(*plate, "cells", size,
                {std::max(std::abs(origin[0]), std::abs(origin[0] + size[0])),
                 std::max(std::abs(origin[1]), std::abs(origin[1] + size[1]))},
                cells);
    plate->finish();
    model.mesh = plate_mesh_quad(origin, size[0], size[1], {cells[0], cells[1]});
  }
  mesh.finish();
  if (model.mesh.elements.empty()) fem.fail("mesh", "has no elements");
  return model;
}

int find_material(const std::vector<Material>& materials, const std::string& name) {
  for (std::size_t i = 0; i < materials.size(); ++i) {
    if (lower(materials[i].name) == lower(name)) return static_cast<int>(i);
  }
  return -1;
}

std::vector<std::int32_t> element_set(const Mesh& mesh, const std::string& name) {
  if (lower(name) == "all") {
    std::vector<std::int32_t> all(mesh.elements.size());
    for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<std::int32_t>(i);
    return all;
  }
  for (const auto& [set, elems] : mesh.element_sets) {
    if (lower(set) == lower(name)) return elems;
  }
  throw SelectorError("'" + name + "' is not an element set of the mesh (nor \"all\")");
}

bool has_shell(const Mesh& mesh, const std::vector<std::int32_t>& elems) {
  return std::any_of(elems.begin(), elems.end(), [&](std::int32_t e) {
    return mesh.elements[static_cast<std::size_t>(e)].type == ElementType::quad4;
  });
}

/// Where a material was defined, for messages: the scene key of a [[fem.materials]] value,
/// or the mesh file's material.
struct MaterialOrigin {
  std::optional<Table> table;  ///< the [[fem.materials]] entry; empty for .inp materials
  std::string inp;             ///< "beam.inp:12: material STEEL" for .inp materials
};

void read_materials(const Table& fem, FemProblem& p, std::vector<MaterialOrigin>& origin) {
  for (const Table& m : fem.tables("materials")) {
    origin.push_back({m, ""});
    Material mat;
    mat.name = m.string("name");
    if (mat.name.empty()) m.fail("name", "must not be empty");
    if (find_material(p.materials, mat.name) >= 0) {
      m.fail("name", "material \"" + mat.name + "\" is defined twice (names are case-insensitive)");
    }
    mat.youngs_modulus =
        m.number("youngs_modulus", Range::closed(kMinYoungsModulus, kMaxYoungsModulus));
    mat.poisson_ratio = m.number("poisson_ratio", Range{-1.0, 0.5, true, true});
    mat.density = m.number("density", Range::closed(0.0, kMaxDensity));
    m.finish();
    p.materials.push_back(mat);
  }
}

void read_sections(const Table& fem, const InpModel& inp, FemProblem& p) {
  Mesh& mesh = p.mesh;
  std::vector<int> assigned(mesh.elements.size(), -1);
  const auto sections = fem.tables("sections");
  if (!sections.empty()) {
    for (const Table& s : sections) {
      const std::string elements = s.string("elements", "all");
      std::vector<std::int32_t> elems;
      try {
        elems = element_set(mesh, elements);
      } catch (const SelectorError& e) {
        s.fail("elements", e.what());
      }
      Section sec;
      const std::string material = s.string("material");
      sec.material = find_material(p.materials, material);
      if (sec.material < 0) {
        s.fail("material", "material \"" + material + "\" is not defined in [[fem.materials]] " +
                               "or the mesh file");
      }
      if (has_shell(mesh, elems)) {
        sec.thickness = s.number("thickness", Range::positive());
      } else if (s.has("thickness")) {
        s.fail("thickness", "applies to shell elements only; these elements are solids");
      }
      s.finish();
      for (auto e : elems)
        assigned[static_cast<std::size_t>(e)] = static_cast<int>(p.sections.size());
      p.sections.push_back(sec);
    }
  } else if (!inp.sections.empty()) {
    for (const auto& is : inp.sections) {
      Section sec;
      sec.material = find_material(p.materials, is.material);
      sec.thickness = is.thickness;
      const auto elems = element_set(mesh, is.element_set);
      if (has_shell(mesh, elems) && !is.shell) {
        fem.fail("mesh", "the mesh file gives shell elements of set " + is.element_set +
                             " a *SOLID SECTION; shells need a *SHELL SECTION");
      }
      for (auto e : elems)
        assigned[static_cast<std::size_t>(e)] = static_cast<int>(p.sections.size());
      p.sections.push_back(sec);
    }
  } else if (p.materials.size() == 1) {
    // One material and no sections: it applies to the whole mesh.
    if (has_shell(mesh, element_set(mesh, "all"))) {
      fem.fail("sections", "is required for a shell mesh: give [[fem.sections]] with a thickness");
    }
    p.sections.push_back({0, 0.0});
    std::fill(assigned.begin(), assigned.end(), 0);
  } else {
    fem.fail("sections", p.materials.empty()
                             ? "no material: give [[fem.materials]] (or *MATERIAL in the mesh file)"
                             : "several materials but no [[fem.sections]] saying which goes where");
  }
  for (std::size_t e = 0; e < assigned.size(); ++e) {
    if (assigned[e] < 0) {
      const std::string label = e < mesh.element_labels.size()
                                    ? std::to_string(mesh.element_labels[e])
                                    : std::to_string(e + 1);
      fem.fail("sections", "element " + label + " (and possibly others) has no section");
    }
    mesh.elements[e].section = assigned[e];
  }
}

TimeFunction optional_amplitude(const Table& t) {
  auto a = t.table("amplitude");
  if (!a) return {};
  return read_time_function(*a);
}

std::vector<Face> faces_of(const Table& t, std::string_view key, const Mesh& mesh) {
  const std::string sel = t.string(key);
  try {
    return select_faces(mesh, sel);
  } catch (const SelectorError& e) {
    t.fail(key, e.what());
  }
}

std::vector<std::int32_t> nodes_of(const Table& t, std::string_view key, const Mesh& mesh) {
  const std::string sel = t.string(key);
  try {
    return select_nodes(mesh, sel);
  } catch (const SelectorError& e) {
    t.fail(key, e.what());
  }
}

void read_loads(const Table& fem, FemProblem& p) {
  for (const Table& c : fem.tables("clamps")) {
    Constraint con;
    con.nodes = nodes_of(c, "nodes", p.mesh);
    if (c.has("dofs")) {
      con.fixed.fill(false);
      static const char* names[6] = {"x", "y", "z", "rx", "ry", "rz"};
      for (const auto& d : c.strings("dofs")) {
        const auto it = std::find(std::begin(names), std::end(names), lower(d));
        if (it == std::end(names)) {
          c.fail(
              "dofs",
              "\"" + d + "\" is not a DOF; accepted: \"x\", \"y\", \"z\", \"rx\", \"ry\", \"rz\"");
        }
        con.fixed[static_cast<std::size_t>(it - std::begin(names))] = true;
      }
    }
    c.finish();
    p.constraints.push_back(std::move(con));
  }
  for (const Table& l : fem.tables("pressures")) {
    PressureLoad load;
    load.faces = faces_of(l, "surface", p.mesh);
    if (l.has("magnitude") == l.has("total_force")) {
      l.fail("magnitude", "give exactly one of magnitude (Pa) or total_force (N)");
    }
    if (l.has("magnitude")) {
      load.magnitude = l.number("magnitude");
    } else {
      const double force = l.number("total_force");
      double area = 0.0;
      for (const auto& f : load.faces) area += face_area(p.mesh, f);
      if (!(area > 0.0)) l.fail("surface", "has zero area");
      load.magnitude = force / area;
    }
    load.amplitude = optional_amplitude(l);
    l.finish();
    p.pressures.push_back(std::move(load));
  }
  for (const Table& l : fem.tables("nodal_loads")) {
    NodalLoad load;
    load.nodes = nodes_of(l, "nodes", p.mesh);
    load.force = l.vec3("force");
    load.amplitude = optional_amplitude(l);
    l.finish();
    p.nodal_loads.push_back(std::move(load));
  }
}

/// Fails at the material's scene key (or at the mesh file for an .inp material).
[[noreturn]] void fail_material(const Table& fem, const MaterialOrigin& o, std::string_view key,
                                const std::string& message) {
  if (o.table) o.table->fail(key, message);
  fem.fail("mesh", o.inp + ": " + std::string(key) + " " + message);
}

/// Checks of the whole model that need more than one key: materials against the analysis
/// (mass where dynamics or gravity need it), Bossak stability, element shapes and loads
/// (validate_problem), orphan nodes (a note).
void check_model(const Table& fem, FemScene& s, const std::vector<MaterialOrigin>& origin) {
  FemProblem& p = s.problem;
  std::vector<char> used(p.materials.size(), 0);
  for (const auto& sec : p.sections) used[static_cast<std::size_t>(sec.material)] = 1;
  const bool gravity = p.gravity != std::array<double, 3>{0.0, 0.0, 0.0};
  for (std::size_t i = 0; i < p.materials.size(); ++i) {
    if (!used[i]) continue;
    const Material& m = p.materials[i];
    const MaterialOrigin& o = origin[i];
    auto range_text = [](double lo, double hi) {
      char b[64];
      std::snprintf(b, sizeof b, "[%g, %g]", lo, hi);
      return std::string(b);
    };
    if (!(m.youngs_modulus >= kMinYoungsModulus && m.youngs_modulus <= kMaxYoungsModulus))
      fail_material(fem, o, "youngs_modulus",
                    "Young's modulus " + std::to_string(m.youngs_modulus) +
                        " Pa is outside the accepted range " +
                        range_text(kMinYoungsModulus, kMaxYoungsModulus) + " Pa");
    if (!(m.density >= 0.0 && m.density <= kMaxDensity))
      fail_material(fem, o, "density",
                    "density " + std::to_string(m.density) +
                        " kg/m^3 is outside the accepted "
                        "range " +
                        range_text(0.0, kMaxDensity) + " kg/m^3");
    if (m.density > 0.0) continue;
    if (s.analysis != Analysis::static_analysis || s.backend != FemBackendKind::fem)
      fail_material(
          fem, o, "density",
          "is 0 (or not given), but " +
              (s.analysis != Analysis::static_analysis
                   ? std::string("fem.analysis = \"") + analysis_name(s.analysis) + "\""
                   : std::string("fem.backend = \"") + backend_kind_name(s.backend) + "\"") +
              " needs mass: give a density > 0 kg/m^3 (a massless part has no "
              "dynamics; the mass matrix would be singular)");
    if (gravity)
      fail_material(fem, o, "density",
                    "is 0 (or not given), but fem.gravity is set: the weight of the elements of "
                    "this material would be missing; give a density > 0 kg/m^3");
  }
  // User-set gamma and beta must keep the step unconditionally stable: the spectral radius
  // must not exceed 1 at any omega dt (the mesh's highest frequencies have omega dt >> 1).
  if (auto b = fem.table("bossak")) {
    for (double e = -3.0; e <= 8.0; e += 0.05) {
      const double w = std::pow(10.0, e);
      const double rho = bossak_spectral_radius(p.bossak, w);
      if (rho > 1.0 + 1e-9) {
        char msg[320];
        std::snprintf(msg, sizeof msg,
                      "with alpha = %g, gamma = %g, beta = %g the Bossak-Newmark step amplifies "
                      "frequencies with omega dt >= %.3g (spectral radius %.6f > 1): unstable. "
                      "Leave gamma and beta at their defaults (1/2 - alpha, (1 - alpha)^2 / 4)",
                      p.bossak.alpha, p.bossak.gamma, p.bossak.beta, w, rho);
        b->fail(b->has("beta") ? "beta" : "gamma", msg);
      }
    }
  }
  try {
    validate_problem(p);
  } catch (const std::invalid_argument& e) {
    fem.fail("mesh", e.what());
  }
  const auto orphans = orphan_nodes(p.mesh);
  if (!orphans.empty()) {
    std::string list;
    for (std::size_t i = 0; i < orphans.size() && i < 5; ++i)
      list += (i ? ", " : "") + node_name(p.mesh, static_cast<std::size_t>(orphans[i]));
    if (orphans.size() > 5) list += ", ...";
    s.notes.push_back(fem.where("mesh") + ": " + std::to_string(orphans.size()) +
                      " node(s) belong to no element and are left out of the model (" + list + ")");
  }
}

/// [fem.modal]: modes of the analysis and of the modal backend.
void read_modal(const Table& fem, FemScene& s) {
  auto m = fem.table("modal");
  if (!m) return;
  s.modal.modes = static_cast<int>(m->integer("modes", s.modal.modes, 1, 100000));
  s.modal.shift = m->number("shift", 0.0);
  s.modal.static_correction = m->boolean("static_correction", true);
  m->finish();
}

/// The mode count of a modal analysis whose deck has a *FREQUENCY step: the deck's number of
/// eigenvalues unless fem.modal.modes is given; a note says which wins. Returns the deck's
/// "file:line" when the count is the deck's, else "".
std::string modal_mode_source(const Table& fem, const InpStep& step, FemScene& s) {
  const auto modal = fem.table("modal");
  const bool scene_modes = modal && modal->has("modes");
  if (!step.frequency || step.modes == 0) return {};
  if (scene_modes) {
    if (s.modal.modes != step.modes)
      s.notes.push_back(modal->where("modes") + ": fem.modal.modes = " +
                        std::to_string(s.modal.modes) + " wins over the deck's *FREQUENCY (" +
                        std::to_string(step.modes) + " eigenvalues, " + step.procedure_where + ")");
    return {};
  }
  s.modal.modes = step.modes;
  s.notes.push_back(step.procedure_where + ": " + std::to_string(step.modes) +
                    " modes, as the deck's *FREQUENCY asks (fem.modal.modes is not given; when "
                    "given it wins)");
  return step.procedure_where;
}

/// A mode count above the free DOFs (the clamped ones eliminated) has no answer: refused
/// here, so that --check finds it too. `deck_where`: the deck's *FREQUENCY gave the count.
void check_mode_count(const Table& fem, const FemScene& s, const std::string& deck_where) {
  const std::size_t dofs = make_dof_map(s.problem).free.size();
  if (static_cast<std::size_t>(s.modal.modes) <= dofs) return;
  const std::string text = std::to_string(s.modal.modes) + " modes asked for, but the model has " +
                           std::to_string(dofs) + " free DOFs (the clamped ones eliminated); " +
                           "accepted: 1 to " + std::to_string(dofs);
  const auto modal = fem.table("modal");
  if (!deck_where.empty())
    fem.table("mesh")->fail(
        "file", deck_where + ": *FREQUENCY: " + text + " (or give fem.modal.modes, which wins)");
  if (modal && modal->has("modes")) modal->fail("modes", text);
  fem.fail("modal", "fem.modal.modes is not given, and its default " + text);
}

/// [fem.rigid]: springs, dashpots, fixed DOFs and the reference point of the rigid body.
void read_rigid(const Table& fem, FemScene& s) {
  auto r = fem.table("rigid");
  if (!r) return;
  for (const Table& t : r->tables("springs")) {
    RigidSpring sp;
    sp.point = t.vec3("point");
    sp.stiffness = t.vec3("stiffness", Range::closed(0.0, 1e15));
    sp.damping = t.vec3("damping", {0.0, 0.0, 0.0}, Range::closed(0.0, 1e15));
    t.finish();
    s.rigid.springs.push_back(sp);
  }
  if (r->has("fixed")) {
    static const char* names[6] = {"x", "y", "z", "rx", "ry", "rz"};
    for (const auto& d : r->strings("fixed")) {
      const auto it = std::find(std::begin(names), std::end(names), lower(d));
      if (it == std::end(names))
        r->fail("fixed", "\"" + d +
                             "\" is not a DOF of the body; accepted: \"x\", \"y\", \"z\", \"rx\", "
                             "\"ry\", \"rz\"");
      const auto k = static_cast<std::size_t>(it - std::begin(names));
      if (s.rigid.fixed[k])
        r->fail("fixed", "names \"" + std::string(names[k]) +
                             "\" twice: give each held DOF once (accepted: \"x\", \"y\", \"z\", "
                             "\"rx\", \"ry\", \"rz\", each at most once, not all six)");
      s.rigid.fixed[k] = true;
    }
    if (std::all_of(s.rigid.fixed.begin(), s.rigid.fixed.end(), [](bool b) { return b; }))
      r->fail("fixed", "fixes all six DOFs: the body could not move at all");
  }
  if (r->has("reference_point")) {
    s.rigid.reference_point = r->vec3("reference_point");
    s.rigid.has_reference_point = true;
  }
  r->finish();
}

/// fem.mesh.translate: every selector, surface, clamp and probe of the scene has chosen its
/// nodes in the mesh file's coordinates; the model (nodes, probe points, the rigid body's
/// reference point) then moves as one, so that a mesh placed by a computed offset
/// (fem.mesh.seat) keeps the scene's selectors as written for the file.
void translate_model(FemScene& s, const std::array<double, 3>& t) {
  if (t[0] == 0.0 && t[1] == 0.0 && t[2] == 0.0) return;
  for (auto& x : s.problem.mesh.nodes)
    for (std::size_t k = 0; k < 3; ++k) x[k] += t[k];
  for (auto& probe : s.monitor.probes)
    for (std::size_t k = 0; k < 3; ++k) probe.point[k] += t[k];
  if (s.rigid.has_reference_point)
    for (std::size_t k = 0; k < 3; ++k) s.rigid.reference_point[k] += t[k];
}

}  // namespace

const char* analysis_name(Analysis analysis) {
  switch (analysis) {
    case Analysis::static_analysis:
      return "static";
    case Analysis::dynamic:
      return "dynamic";
    case Analysis::modal:
      return "modal";
  }
  return "?";
}

const char* backend_kind_name(FemBackendKind kind) {
  switch (kind) {
    case FemBackendKind::fem:
      return "fem";
    case FemBackendKind::modal:
      return "modal";
    case FemBackendKind::rigid:
      return "rigid";
    case FemBackendKind::external:
      return "external";
  }
  return "?";
}

TimeFunction read_time_function(const Table& a) {
  const std::string type = a.choice("type", {"constant", "table", "sine", "sleeper"});
  TimeFunction f;
  try {
    if (type == "constant") {
      f = constant_function(a.number("value"));
    } else if (type == "table") {
      std::vector<std::pair<double, double>> points;
      for (const auto& row : a.number_rows("points", 2)) points.emplace_back(row[0], row[1]);
      for (std::size_t i = 1; i < points.size(); ++i) {
        if (!(points[i].first > points[i - 1].first)) {
          a.fail("points", "times must increase strictly (entry " + std::to_string(i) + ")");
        }
      }
      f = piecewise_linear_function(std::move(points));
    } else if (type == "sine") {
      f = sinusoid_function(a.number("mean", 0.0), a.number("amplitude"),
                            a.number("frequency", Range::non_negative()), a.number("phase", 0.0));
    } else {
      SleeperLoadPattern s;
      s.peak_force = a.number("peak_force", s.peak_force, Range::non_negative());
      s.cycle_min = a.number("cycle_min", s.cycle_min, Range::non_negative());
      s.cycle_max = a.number("cycle_max", s.cycle_max, Range::non_negative());
      s.ramp_duration = a.number("ramp_duration", s.ramp_duration, Range::positive());
      s.cycle_frequency = a.number("cycle_frequency", s.cycle_frequency, Range::positive());
      // the cyclic stage as a duration or as a whole number of cycles (a long run: 100 or more)
      if (a.has("cycles") && a.has("cycle_duration"))
        a.fail("cycles", "give one of 'cycles' and 'cycle_duration', not both");
      if (a.has("cycles")) {
        s.cycle_duration = double(a.integer("cycles", 1, 10000000)) / s.cycle_frequency;
      } else {
        s.cycle_duration = a.number("cycle_duration", s.cycle_duration, Range::positive());
      }
      s.unload_duration = a.number("unload_duration", s.unload_duration, Range::non_negative());
      s.time_scale = a.number("time_scale", s.time_scale, Range::positive());
      if (s.cycle_max < s.cycle_min) a.fail("cycle_max", "must not be smaller than cycle_min");
      // the levels are per rail seat, or the total over `seats` seats (each then gets 1/seats)
      const std::string per = a.choice("force_is", "per_seat", {"per_seat", "total"});
      const std::int64_t seats = a.integer("seats", 2, 1, 1000);
      if (per == "per_seat" && a.has("seats"))
        a.fail("seats", "is used with force_is = \"total\" only");
      if (per == "total") {
        const double k = 1.0 / double(seats);
        s.peak_force *= k, s.cycle_min *= k, s.cycle_max *= k;
      }
      // a delay before the pattern (the sleeper first settles under its seating load)
      const double start = a.number("start_time", 0.0, Range::non_negative());
      f = sleeper_load_function(s);
      if (start > 0.0) f = [g = f, start](double t) { return g(t - start); };
    }
  } catch (const std::invalid_argument& e) {
    a.fail("type", e.what());
  }
  a.finish();
  return f;
}

FemScene read_fem_scene(const Table& fem) {
  FemScene s;
  const bool analysis_given = fem.has("analysis");
  const std::string analysis = fem.choice("analysis", "dynamic", {"static", "dynamic", "modal"});
  s.analysis = analysis == "static"  ? Analysis::static_analysis
               : analysis == "modal" ? Analysis::modal
                                     : Analysis::dynamic;
  const std::string backend = fem.choice("backend", "fem", {"fem", "modal", "rigid", "external"});
  s.backend = backend == "modal"      ? FemBackendKind::modal
              : backend == "rigid"    ? FemBackendKind::rigid
              : backend == "external" ? FemBackendKind::external
                                      : FemBackendKind::fem;
  if (s.analysis == Analysis::modal && s.backend != FemBackendKind::fem)
    fem.fail("backend", "is \"" + backend +
                            "\", but fem.analysis = \"modal\" computes the natural frequencies of "
                            "the FEM model itself: leave fem.backend out (or \"fem\")");
  if (s.backend == FemBackendKind::external) {
    s.command = fem.strings("command");
    if (s.command.front().empty())
      fem.fail("command", "names no program (its first entry is empty)");
  } else {
    // Kept for when the scene runs with fem.backend = "external" (demfem run --fem-backend
    // chooses per run); unused by demfem's own backends.
    fem.skip("command");
  }
  fem.skip("external");  // the outside program's own keys
  s.dt = fem.number("dt", 0.0, Range::open_closed(0.0, 1e6));
  s.dt_location = fem.where("dt");

  bool deck_loads = true;
  std::array<double, 3> translate{};
  InpModel inp = read_mesh(fem, deck_loads, translate);
  FemProblem& p = s.problem;
  p.mesh = std::move(inp.mesh);
  p.materials = inp.materials;
  s.notes = inp.notes;
  std::vector<MaterialOrigin> origin;
  for (std::size_t i = 0; i < inp.materials.size(); ++i) {
    origin.push_back({std::nullopt, inp.material_where[i] + ": material " + inp.materials[i].name});
  }
  read_materials(fem, p, origin);
  read_sections(fem, inp, p);
  // Every material that a section uses must be complete (a .inp may leave density out).
  for (const auto& sec : p.sections) {
    const Material& m = p.materials[static_cast<std::size_t>(sec.material)];
    if (!(m.youngs_modulus > 0.0)) {
      fem.fail("materials", "material \"" + m.name + "\" has no Young's modulus (*ELASTIC)");
    }
  }
  read_loads(fem, p);

  p.gravity = fem.vec3("gravity", std::array<double, 3>{0.0, 0.0, 0.0});
  if (fem.table("mesh")->has("file")) {
    const Table mesh = *fem.table("mesh");
    const bool history = inp.step.present || !inp.boundaries.empty() ||
                         !inp.concentrated_loads.empty() || !inp.pressures.empty() ||
                         !inp.gravity.empty();
    if (deck_loads) {
      apply_inp_history(inp, fem, mesh, analysis_given, s);
    } else if (history) {
      s.notes.push_back(mesh.where("deck_loads") +
                        ": the deck's steps, boundary conditions and loads are not used "
                        "(fem.mesh.deck_loads = false)");
    }
  }
  p.mass = fem.choice("mass", "consistent", {"consistent", "lumped"}) == "lumped"
               ? MassLumping::lumped
               : MassLumping::consistent;
  if (auto b = fem.table("bossak")) {
    // Defaults follow alpha: gamma = 1/2 - alpha, beta = (1 - alpha)^2 / 4 (unconditionally
    // stable, second order for alpha in [-1/3, 0]).
    const double alpha = b->number("alpha", p.bossak.alpha, Range::closed(-1.0 / 3.0, 0.0));
    p.bossak.alpha = alpha;
    p.bossak.gamma = b->number("gamma", 0.5 - alpha, Range::closed(0.5, 1.5));
    p.bossak.beta =
        b->number("beta", 0.25 * (1.0 - alpha) * (1.0 - alpha), Range{0.0, 1.0, true, false});
    b->finish();
  }
  read_modal(fem, s);
  std::string modes_where;
  if (s.analysis == Analysis::modal)
    modes_where = modal_mode_source(fem, deck_loads ? inp.step : InpStep{}, s);
  read_rigid(fem, s);
  if (auto d = fem.table("damping")) {
    // Upper bounds: beyond them every mode of interest is overdamped (a typo guard, and the
    // effective matrix stays finite for any accepted dt).
    p.damping.mass_factor = d->number("mass_factor", 0.0, Range::closed(0.0, 1e6));
    p.damping.stiffness_factor = d->number("stiffness_factor", 0.0, Range::closed(0.0, 1.0));
    d->finish();
  }
  if (fem.has("interface_surface")) {
    const std::string sel = fem.string("interface_surface");
    bool named = false;
    for (const auto& [name, faces] : p.mesh.surfaces) {
      if (name == sel) named = true;
    }
    if (!named && lower(sel) != "exterior") {
      // A selector (or a name in another case): store the chosen faces as a named surface.
      auto faces = faces_of(fem, "interface_surface", p.mesh);
      p.mesh.surfaces["interface_surface"] = std::move(faces);
      p.interface_surface = "interface_surface";
    } else {
      p.interface_surface = lower(sel) == "exterior" ? "" : sel;
    }
  }
  if (auto o = fem.table("output")) {
    s.output.enabled = o->boolean("write", true);
    s.output.interval = o->number("interval", 0.0, Range::non_negative());
    s.output.csv = o->boolean("csv", true);
    if (o->has("fields")) {
      for (const auto& f : o->strings("fields")) {
        const bool known = std::any_of(std::begin(kFemOutputFields), std::end(kFemOutputFields),
                                       [&](const char* k) { return f == k; });
        if (!known) {
          std::string list;
          for (const char* k : kFemOutputFields)
            list += (list.empty() ? "\"" : ", \"") + std::string(k) + "\"";
          o->fail("fields", "\"" + f + "\" is not an output field; accepted: " + list);
        }
        s.output.fields.push_back(f);
      }
    }
    o->finish();
  }
  if (auto m = fem.table("monitor")) {
    if (s.backend != FemBackendKind::fem)
      fem.fail("monitor", std::string("needs fem.backend = \"fem\" (the full FEM), not \"") +
                              backend_kind_name(s.backend) +
                              "\": it reads the whole displacement field every step, which the "
                              "reduced backends do not hold; remove [fem.monitor] for this run");
    s.monitor = read_fem_monitor(*m, p.mesh);
  }
  if (s.output.fields.empty()) {
    for (const char* k : kFemOutputFields) s.output.fields.emplace_back(k);
  }
  translate_model(s, translate);
  check_model(fem, s, origin);
  if (s.analysis == Analysis::modal) check_mode_count(fem, s, modes_where);
  fem.finish();
  return s;
}

}  // namespace demfem::fem
