#include "step_checks.hpp"

#include <cmath>
#include <span>
#include <sstream>
#include <string>
#include <utility>

#include "interface_checks.hpp"
#include "run_text.hpp"

namespace demfem::coupling {

namespace {

BlowUp blow_up(const StepDiagnostics& d, const std::string& quantity, double value, double bound,
               const std::string& why) {
  std::ostringstream m;
  m << "blow-up at coupling step " << d.step << " (t = " << format_number(d.time) << " s): " << why;
  return BlowUp(d.step, d.time, quantity, value, bound, m.str());
}

}  // namespace

std::optional<BlowUp> blow_up_of(const StepDiagnostics& d, const SchemeState& state,
                                 const CouplingSettings& s) {
  const std::pair<const char*, std::span<const double>> arrays[] = {
      {"interface force", state.dem_force},
      {"FEM interface position", state.positions},
      {"DEM interface position", state.dem_end}};
  for (const auto& [what, v] : arrays) {
    if (auto k = first_non_finite(v); k >= 0) {
      return blow_up(d, what, v[k], 0.0,
                     std::string(what) + " of node " + std::to_string(k / 3) + " (component " +
                         std::to_string(k % 3) + ") is not finite (" + format_number(v[k]) + ")");
    }
  }
  const std::pair<const char*, double> scalars[] = {
      {"max_overlap", d.max_overlap},         {"kinetic_energy", d.kinetic_energy},
      {"dem_max_overlap", d.dem_max_overlap}, {"fem_max_displacement", d.fem_max_displacement},
      {"energy_error", d.energy_error},       {"drift", d.drift}};
  for (const auto& [what, v] : scalars) {
    if (!std::isfinite(v)) return blow_up(d, what, v, 0.0, std::string(what) + " is not finite");
  }
  if (d.max_overlap > s.max_overlap) {
    return blow_up(d, "max_overlap", d.max_overlap, s.max_overlap,
                   "particle-interface overlap " + format_number(d.max_overlap) +
                       " m exceeds coupling.blowup.max_overlap = " + format_number(s.max_overlap) +
                       " m");
  }
  if (s.scheme != Scheme::one_way_static && std::abs(d.energy_error) > s.max_energy_error) {
    return blow_up(
        d, "energy_error", d.energy_error, s.max_energy_error,
        "interface energy error |W_dem - W_fem| = " + format_number(std::abs(d.energy_error)) +
            " J exceeds coupling.blowup.max_energy_error = " + format_number(s.max_energy_error) +
            " J");
  }
  return std::nullopt;
}

}  // namespace demfem::coupling
