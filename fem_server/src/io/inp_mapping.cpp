#include "inp_mapping.hpp"

#include <cmath>
#include <cstdio>

#include "demfem/fem/time_function.hpp"

namespace demfem::fem {

namespace {

/// Value of a tabular amplitude at t (linear, clamped outside), for static steps.
double amplitude_at(const InpAmplitude& a, double t) {
  return piecewise_linear_function(a.points)(t);
}

}  // namespace

void apply_inp_history(const InpModel& inp, const scene::Table& fem, const scene::Table& mesh,
                       bool analysis_given, FemScene& s) {
  FemProblem& p = s.problem;
  const InpStep& step = inp.step;
  const std::string file_where = mesh.where("file");
  auto fail = [&](const std::string& where, const std::string& message) {
    mesh.fail("file", where + ": " + message);
  };
  if (step.present && step.frequency) {
    // The coupler reads fem.analysis from the scene alone: the deck cannot change it.
    if (s.analysis != Analysis::modal)
      fail(step.procedure_where,
           std::string("the deck's step is *FREQUENCY (natural frequencies), but fem.analysis ") +
               (analysis_given ? "= \"" + std::string(analysis_name(s.analysis)) + "\""
                               : std::string("is not given (default \"dynamic\")")) +
               ": set fem.analysis = \"modal\" to compute the modes, or replace the deck's "
               "*FREQUENCY by *STATIC or *DYNAMIC");
    // The mode count: the deck's unless the scene's fem.modal.modes is given (read_fem_scene
    // says which one wins).
  } else if (step.present) {
    const Analysis deck = step.dynamic ? Analysis::dynamic : Analysis::static_analysis;
    if (s.analysis == Analysis::modal) {
      s.notes.push_back(fem.where("analysis") +
                        ": fem.analysis = \"modal\" computes the natural "
                        "frequencies; the deck's " +
                        step.procedure() + " step and its loads do not change them (" +
                        step.procedure_where + ")");
    } else if (!analysis_given && deck != s.analysis) {
      // The coupler reads fem.analysis from the scene alone: the deck cannot change it.
      fail(step.procedure_where,
           std::string("the deck's step is ") + step.procedure() +
               " but fem.analysis is not given (default \"dynamic\"): set fem.analysis = \"" +
               (step.dynamic ? "dynamic" : "static") +
               "\" to follow the deck, or the other "
               "value to override it");
    } else if (deck != s.analysis) {
      s.notes.push_back(fem.where("analysis") + ": fem.analysis = \"" + analysis_name(s.analysis) +
                        "\" overrides the deck's " + step.procedure() + " (" +
                        step.procedure_where + ")");
    }
  }
  const bool dynamic = s.analysis != Analysis::static_analysis;
  // Abaqus' amplitude semantics in demfem's terms: `factor` multiplies the magnitude, the
  // returned function (empty = constant 1) varies it in time.
  auto amplitude = [&](const std::string& name, const std::string& where, double& factor,
                       bool allow_time_function) -> TimeFunction {
    factor = 1.0;
    if (!dynamic) {
      // The end state of a static step: a(period); a ramp ends at 1.
      if (!name.empty()) factor = amplitude_at(inp.amplitudes.at(name), step.period);
      return {};
    }
    if (!name.empty() || step.ramp) {
      if (!allow_time_function)
        fail(where, "this load cannot vary in time in demfem (" +
                        (name.empty() ? std::string("the step ramps it") : "AMPLITUDE=" + name) +
                        "); remove the amplitude, or put the load into the scene");
      if (!name.empty()) return piecewise_linear_function(inp.amplitudes.at(name).points);
      return piecewise_linear_function({{0.0, 0.0}, {step.period, 1.0}});
    }
    return {};
  };
  int bcs = 0, forces = 0, pressures = 0;
  for (const auto& b : inp.boundaries) {
    Constraint c;
    c.nodes = b.nodes;
    c.fixed = b.fixed;
    c.value = b.value;
    bool nonzero = false;
    for (double v : b.value) nonzero = nonzero || v != 0.0;
    if (nonzero) {
      if (dynamic)
        fail(b.where,
             "*BOUNDARY with a non-zero value: prescribed displacements are supported "
             "in a static analysis only (fem.analysis = \"static\")");
      double factor = 1.0;
      amplitude(b.amplitude, b.where, factor, false);
      for (double& v : c.value) v *= factor;
    }
    p.constraints.push_back(std::move(c));
    ++bcs;
  }
  for (const auto& l : inp.concentrated_loads) {
    NodalLoad n;
    n.nodes = l.nodes;
    double factor = 1.0;
    n.amplitude = amplitude(l.amplitude, l.where, factor, true);
    n.force[static_cast<std::size_t>(l.dof)] = l.magnitude * factor;
    p.nodal_loads.push_back(std::move(n));
    ++forces;
  }
  for (const auto& l : inp.pressures) {
    PressureLoad pl;
    pl.faces = l.faces;
    double factor = 1.0;
    pl.amplitude = amplitude(l.amplitude, l.where, factor, true);
    pl.magnitude = l.magnitude * factor;
    p.pressures.push_back(std::move(pl));
    ++pressures;
  }
  if (!inp.gravity.empty()) {
    if (p.gravity != std::array<double, 3>{0.0, 0.0, 0.0})
      fail(inp.gravity[0].where, "*DLOAD GRAV and fem.gravity both give gravity; keep one");
    // demfem's gravity acts on every element alike: the GRAV loads must add up to the same
    // vector on each element.
    std::vector<std::array<double, 3>> g(p.mesh.elements.size(), {0.0, 0.0, 0.0});
    for (const auto& gr : inp.gravity) {
      double factor = 1.0;
      amplitude(gr.amplitude, gr.where, factor, false);
      for (auto e : gr.elements)
        for (int c = 0; c < 3; ++c)
          g[static_cast<std::size_t>(e)][c] += gr.magnitude * factor * gr.direction[c];
    }
    for (std::size_t e = 1; e < g.size(); ++e)
      if (g[e] != g[0])
        fail(inp.gravity[0].where,
             "*DLOAD GRAV acts on part of the model only (or differs between parts); demfem's "
             "gravity acts on all elements alike: give it for the whole model, or in the scene");
    p.gravity = g.empty() ? std::array<double, 3>{0.0, 0.0, 0.0} : g[0];
  }
  if (bcs + forces + pressures > 0 || !inp.gravity.empty()) {
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  ": taken from the deck: %d boundary condition(s), %d concentrated load(s), %d "
                  "pressure load(s)%s",
                  bcs, forces, pressures, inp.gravity.empty() ? "" : ", gravity");
    s.notes.push_back(
        file_where + buf +
        (step.present ? " (step at " + step.where + ", " + step.procedure() + ")" : std::string()));
  }
}

}  // namespace demfem::fem
