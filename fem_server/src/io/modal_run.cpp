#include "demfem/fem/modal_run.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <ostream>

#include "demfem/fem/assembly.hpp"
#include "demfem/fem/fem_output.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/fem/modal_analysis.hpp"
#include "demfem/io/csv_writer.hpp"

namespace demfem::fem {

namespace {

/// Densities of real solids run from foams to osmium, about 10 to 2.3e4 kg/m^3. A model whose
/// densities in use are all in [kTonneLow, kTonneHigh] is in the mm-tonne-s system of many
/// Abaqus and CalculiX decks (tonne/mm^3: steel 7.85e-9; 1e-12 .. 1e-7 is 1 .. 1e5 kg/m^3), and
/// its masses come out in tonnes. A density of at most kNoSolidDensity is no SI density of a
/// solid: outside that band the model's mass unit is not known (in-lbf-s has 7.3e-4 for steel).
constexpr double kTonneLow = 1e-12, kTonneHigh = 1e-7, kNoSolidDensity = 1e-3;

/// The model's mass unit in kg: 1 (SI), 1000 (tonne) or 0 (not known: not converted).
double model_mass_unit(const FemProblem& p, double* density_seen) {
  bool si = false, tonne = false, other = false;
  for (const auto& sec : p.sections) {
    const double rho = p.materials[static_cast<std::size_t>(sec.material)].density;
    if (!(rho > 0.0)) continue;
    *density_seen = rho;
    if (rho > kNoSolidDensity)
      si = true;
    else if (rho >= kTonneLow && rho <= kTonneHigh)
      tonne = true;
    else
      other = true;
  }
  if (!tonne && !other) return 1.0;
  return tonne && !si && !other ? 1000.0 : 0.0;
}

}  // namespace

ModalRunSummary run_modal_analysis(const FemScene& scene, const std::filesystem::path& dir,
                                   std::ostream* progress) {
  using clock = std::chrono::steady_clock;
  const auto start = clock::now();
  const FemProblem& p = scene.problem;
  validate_problem(p);
  const DofMap dofs = make_dof_map(p);
  if (dofs.free.empty())
    throw FemModelError("FEM: every DOF is clamped: the structure has no modes");
  const SparseMatrix k = reduce_matrix(assemble_stiffness(p, dofs), dofs);
  const SparseMatrix m = reduce_matrix(assemble_mass(p, dofs), dofs);
  ModalOptions o;
  o.count = scene.modal.modes;
  o.shift = scene.modal.shift;
  if (o.count > static_cast<int>(dofs.free.size()))
    throw FemModelError("FEM: fem.modal.modes = " + std::to_string(o.count) +
                        " modes asked for, but the model has only " +
                        std::to_string(dofs.free.size()) + " free DOFs");
  const std::string dense =
      dense_modes_warning(static_cast<std::int64_t>(dofs.free.size()), o.count);
  if (!dense.empty()) std::cerr << "fem: warning: " << dense << "\n" << std::flush;
  ModeSet modes;
  try {
    modes = compute_modes(k, m, o);
  } catch (const SingularMatrixError& e) {
    throw FemModelError(std::string(e.what()) +
                        (o.shift == 0.0
                             ? ". With fem.modal.shift = 0 the stiffness itself is factorised: a "
                               "structure that its clamps do not hold has rigid-body modes at "
                               "omega = 0; give a negative fem.modal.shift (e.g. -1) to find them"
                             : ". fem.modal.shift lies on an eigenvalue: move it a little"));
  }
  ModalRunSummary sum;
  sum.method = modes.method;
  sum.free_dofs = dofs.free.size();
  // Participation along x, y, z: Gamma_d = phi^T M r_d with r_d the unit translation d of
  // every free DOF; the effective mass Gamma_d^2 (mass-normalised modes).
  Eigen::MatrixXd r = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(dofs.free.size()), 3);
  for (std::size_t n = 0; n < p.mesh.nodes.size(); ++n)
    for (int c = 0; c < 3; ++c) {
      const auto row = dofs.reduced[static_cast<std::size_t>(dofs.node_offset[n] + c)];
      if (row >= 0) r(row, c) = 1.0;
    }
  const Eigen::MatrixXd mr = m * r;
  const Eigen::Vector3d free_mass = (r.transpose() * mr).diagonal();
  const Eigen::MatrixXd gamma = modes.shapes.transpose() * mr;  // modes x 3

  // Effective masses and participations go out in kg and sqrt(kg) when the model's units are
  // known (SI, mm-tonne-s), else in the model's own mass unit, said so.
  double density_seen = 0.0;
  const double mass_unit = model_mass_unit(p, &density_seen);
  if (mass_unit != 1.0) {
    char text[600];
    if (mass_unit > 0.0)
      std::snprintf(text, sizeof text,
                    "fem: note: the densities (e.g. %.3g) are tonne/mm^3 (mm-tonne-s units: no "
                    "solid is lighter than %g kg/m^3): the effective masses are converted from "
                    "tonnes to kg (x 1000) and the participations to sqrt(kg); the mode shapes "
                    "stay in the model's units (mm/sqrt(tonne)); frequencies are in Hz either "
                    "way\n",
                    density_seen, kNoSolidDensity);
    else
      std::snprintf(text, sizeof text,
                    "fem: note: the densities (e.g. %.3g) are neither kg/m^3 (no solid is lighter "
                    "than %g) nor tonne/mm^3 (%g to %g), or mix systems: the effective masses and "
                    "participations are in the model's own mass unit (its density unit x length "
                    "unit^3), not kg; frequencies are in Hz if its units are consistent\n",
                    density_seen, kNoSolidDensity, kTonneLow, kTonneHigh);
    std::cerr << text << std::flush;
  }
  const Eigen::MatrixXd gamma_si = mass_unit > 0.0 ? gamma * std::sqrt(mass_unit) : gamma;
  std::filesystem::create_directories(dir);
  io::CsvWriter csv(
      dir / "fem_modes.csv",
      {"mode", "frequency", "omega", "period", "residual", "participation_x", "participation_y",
       "participation_z", "effective_mass_x", "effective_mass_y", "effective_mass_z",
       "effective_mass_fraction_x", "effective_mass_fraction_y", "effective_mass_fraction_z"});
  FemOutputSettings os;
  os.csv = false;
  os.fields = {"displacement"};  // none of the standard fields is given: only the shapes
  FemOutput out(dir, "fem_modes", p.mesh, os);
  if (progress)
    *progress << "fem: modal analysis, " << modes.method << ", " << dofs.free.size()
              << " free DOF\n   mode   frequency (Hz)   eff. mass x, y, z ("
              << (mass_unit > 0.0 ? "kg" : "the model's mass unit") << ")\n";
  for (int j = 0; j < o.count; ++j) {
    const double w2 = modes.omega2(j);
    const double w = std::sqrt(std::max(w2, 0.0)), f = w / (2 * M_PI);
    sum.frequencies_hz.push_back(f);
    std::vector<double> row = {static_cast<double>(j + 1), f, w, w > 0 ? 1.0 / f : INFINITY,
                               modes.residual(j)};
    for (int c = 0; c < 3; ++c) row.push_back(gamma_si(j, c));
    for (int c = 0; c < 3; ++c) row.push_back(gamma_si(j, c) * gamma_si(j, c));
    for (int c = 0; c < 3; ++c)
      row.push_back(free_mass(c) > 0 ? gamma(j, c) * gamma(j, c) / free_mass(c) : 0.0);
    csv.row(row);
    // Mode shape over all nodes (clamped DOFs zero), and scaled to a largest |u| of 1.
    std::vector<double> shape(3 * p.mesh.nodes.size(), 0.0);
    double big = 0.0;
    for (std::size_t n = 0; n < p.mesh.nodes.size(); ++n) {
      for (int c = 0; c < 3; ++c) {
        const auto rr = dofs.reduced[static_cast<std::size_t>(dofs.node_offset[n] + c)];
        if (rr >= 0) shape[3 * n + static_cast<std::size_t>(c)] = modes.shapes(rr, j);
      }
      big = std::max(big, std::hypot(shape[3 * n], shape[3 * n + 1], shape[3 * n + 2]));
    }
    std::vector<double> unit = shape;
    if (big > 0.0)
      for (double& v : unit) v /= big;
    FemFields fields;
    fields.time = j + 1;
    fields.state_time = j + 1;
    fields.node_vectors = {{"mode_shape", std::move(shape)}, {"mode_shape_unit", std::move(unit)}};
    out.write(fields);
    if (progress) {
      char line[160];
      std::snprintf(line, sizeof line, "   %4d   %14.6g   %.4g, %.4g, %.4g\n", j + 1, f,
                    gamma_si(j, 0) * gamma_si(j, 0), gamma_si(j, 1) * gamma_si(j, 1),
                    gamma_si(j, 2) * gamma_si(j, 2));
      *progress << line;
    }
  }
  csv.flush();
  sum.wall_seconds = std::chrono::duration<double>(clock::now() - start).count();
  if (progress) {
    char line[300];
    std::snprintf(line, sizeof line,
                  "fem: %d modes in %.2f s (largest residual %.1e); %s/fem_modes.csv, "
                  "fem_modes.xdmf (ParaView: one time step per mode)\n",
                  o.count, sum.wall_seconds, modes.residual.maxCoeff(), dir.c_str());
    *progress << line << std::flush;
  }
  return sum;
}

}  // namespace demfem::fem
