#include "coupling_series.hpp"

namespace demfem::coupling {

const std::vector<std::string>& coupling_columns() {
  static const std::vector<std::string> columns = {"step",
                                                   "time",
                                                   "drift",
                                                   "work_dem",
                                                   "work_fem",
                                                   "energy_error",
                                                   "max_overlap",
                                                   "dem_max_overlap",
                                                   "kinetic_energy",
                                                   "fem_max_displacement",
                                                   "force_sum_z",
                                                   "wall_dem",
                                                   "wall_fem",
                                                   "wall_coupling",
                                                   "iterations",
                                                   "residual_displacement",
                                                   "residual_force",
                                                   "converged",
                                                   "wall_dem_compute",
                                                   "wall_fem_compute"};
  return columns;
}

std::vector<double> row_of(const StepDiagnostics& d) {
  return {static_cast<double>(d.step),
          d.time,
          d.drift,
          d.work_dem,
          d.work_fem,
          d.energy_error,
          d.max_overlap,
          d.dem_max_overlap,
          d.kinetic_energy,
          d.fem_max_displacement,
          d.force_sum_z,
          d.wall_dem,
          d.wall_fem,
          d.wall_coupling,
          static_cast<double>(d.iterations),
          d.residual_displacement,
          d.residual_force,
          d.converged ? 1.0 : 0.0,
          d.wall_dem_compute,
          d.wall_fem_compute};
}

StepDiagnostics diagnostics_of(std::span<const double> r) {
  StepDiagnostics d;
  d.step = static_cast<std::int64_t>(r[0]);
  d.time = r[1];
  d.drift = r[2];
  d.work_dem = r[3];
  d.work_fem = r[4];
  d.energy_error = r[5];
  d.max_overlap = r[6];
  d.dem_max_overlap = r[7];
  d.kinetic_energy = r[8];
  d.fem_max_displacement = r[9];
  d.force_sum_z = r[10];
  d.wall_dem = r[11];
  d.wall_fem = r[12];
  d.wall_coupling = r[13];
  d.iterations = static_cast<std::int64_t>(r[14]);
  d.residual_displacement = r[15];
  d.residual_force = r[16];
  d.converged = r[17] != 0.0;
  d.wall_dem_compute = r[18];
  d.wall_fem_compute = r[19];
  return d;
}

}  // namespace demfem::coupling
