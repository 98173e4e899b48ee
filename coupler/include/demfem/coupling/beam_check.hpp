#pragma once
// Verification of a clamped beam under a uniform load (thesis ch. 4, table 4.2): the coupled
// mid-span deflection against the same FEM structure solved with the load as a pressure and
// against the analytical clamped-clamped value w L^4 / (384 E I).

#include <string>

#include "demfem/coupling/coupling_run.hpp"
#include "demfem/coupling/coupling_settings.hpp"
#include "demfem/scene/scene_reader.hpp"

namespace demfem::coupling {

/// @brief Deflections at the probe node (z displacement, m; negative = down).
struct BeamCheckResult {
  double coupled = 0.0;
  double fem_pressure = 0.0;
  double analytical = 0.0;
  std::size_t node = 0;         ///< interface node index
  double probe_distance = 0.0;  ///< distance of that node from the probe point, m
  double coupled_load = 0.0;    ///< sum of interface forces along -z, N
  double pressure_load = 0.0;   ///< m g, N
};

/// @brief Solves the pure-FEM reference of `scene` and measures the coupled result.
BeamCheckResult run_beam_check(const BeamCheck& check, const scene::Document& scene,
                               const RunSummary& coupled);

/// @brief The side-by-side table (deflections and relative errors).
std::string beam_check_table(const BeamCheckResult& r, const BeamCheck& check);

}  // namespace demfem::coupling
