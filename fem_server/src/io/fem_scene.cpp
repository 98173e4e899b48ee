#include "demfem/fem/fem_scene.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <stdexcept>

#include "demfem/fem/inp_reader.hpp"
#include "demfem/fem/mesher.hpp"
#include "demfem/fem/node_selector.hpp"
#include "demfem/fem/time_function.hpp"

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

/// The mesh, and the materials and sections of a .inp file when it has them.
InpModel read_mesh(const Table& fem) {
  const Table mesh = fem.required_table("mesh");
  const int kinds = int(mesh.has("file")) + int(mesh.has("box")) + int(mesh.has("plate"));
  if (kinds != 1) {
    fem.fail("mesh", "needs exactly one of file = \"...inp\", box = {...} or plate = {...}");
  }
  InpModel model;
  if (mesh.has("file")) {
    const auto path = mesh.path("file");
    try {
      model = read_inp_model(path);
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
    box->finish();
    model.mesh = element == "hex8" ? box_mesh_hex(lo, hi, cells) : box_mesh_tet(lo, hi, cells);
  } else if (auto plate = mesh.table("plate")) {
    const auto origin = plate->vec3("origin", std::array<double, 3>{0.0, 0.0, 0.0});
    const auto size = plate->numbers("size", 2, Range::positive());
    const auto cells = cell_counts(*plate, "cells", 2);
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

void read_materials(const Table& fem, FemProblem& p) {
  for (const Table& m : fem.tables("materials")) {
    Material mat;
    mat.name = m.string("name");
    if (mat.name.empty()) m.fail("name", "must not be empty");
    if (find_material(p.materials, mat.name) >= 0) {
      m.fail("name", "material \"" + mat.name + "\" is defined twice (names are case-insensitive)");
    }
    mat.youngs_modulus = m.number("youngs_modulus", Range::positive());
    mat.poisson_ratio = m.number("poisson_ratio", Range{-1.0, 0.5, true, true});
    mat.density = m.number("density", Range::non_negative());
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

}  // namespace

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
      s.cycle_duration = a.number("cycle_duration", s.cycle_duration, Range::positive());
      s.cycle_frequency = a.number("cycle_frequency", s.cycle_frequency, Range::positive());
      s.time_scale = a.number("time_scale", s.time_scale, Range::positive());
      if (s.cycle_max < s.cycle_min) a.fail("cycle_max", "must not be smaller than cycle_min");
      f = sleeper_load_function(s);
    }
  } catch (const std::invalid_argument& e) {
    a.fail("type", e.what());
  }
  a.finish();
  return f;
}

FemScene read_fem_scene(const Table& fem) {
  FemScene s;
  s.analysis = fem.choice("analysis", "dynamic", {"static", "dynamic"}) == "static"
                   ? Analysis::static_analysis
                   : Analysis::dynamic;
  s.dt = fem.number("dt", 0.0, Range::positive());
  s.dt_location = fem.where("dt");

  InpModel inp = read_mesh(fem);
  FemProblem& p = s.problem;
  p.mesh = std::move(inp.mesh);
  p.materials = inp.materials;
  read_materials(fem, p);
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
  if (auto d = fem.table("damping")) {
    p.damping.mass_factor = d->number("mass_factor", 0.0, Range::non_negative());
    p.damping.stiffness_factor = d->number("stiffness_factor", 0.0, Range::non_negative());
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
  if (auto m = fem.table("monitor")) s.monitor = read_fem_monitor(*m, p.mesh);
  if (s.output.fields.empty()) {
    for (const char* k : kFemOutputFields) s.output.fields.emplace_back(k);
  }
  fem.finish();
  return s;
}

}  // namespace demfem::fem
