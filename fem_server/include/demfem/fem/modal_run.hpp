#pragma once
// fem.analysis = "modal": the natural frequencies and mode shapes of a scene's structure,
// written for users (docs/scene_fem.md, "Modal analysis"):
//   <dir>/fem_modes.csv     one row per mode: frequency, angular frequency, period, the
//                           relative residual, participation factors and effective masses
//                           along x, y, z (and their fractions of the free mass)
//   <dir>/fem_modes.xdmf    Xdmf 3 temporal collection whose "time" is the mode number: the
//                           point arrays mode_shape (mass-normalised, m / sqrt(kg)) and
//                           mode_shape_unit (largest nodal |u| = 1), for ParaView
//   <dir>/fem_modes_mesh.h5, fem_modes_NNNNNN.h5 (NNNNNN = mode number - 1)

#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include "demfem/fem/fem_scene.hpp"

namespace demfem::fem {

struct ModalRunSummary {
  std::vector<double> frequencies_hz;
  std::string method;  ///< "shift-invert Lanczos (Spectra)" or "dense"
  std::size_t free_dofs = 0;
  double wall_seconds = 0.0;
};

/// @brief Computes scene.modal.modes modes nearest scene.modal.shift of the scene's structure
/// (its clamps eliminated; consistent or lumped mass as fem.mass says) and writes the files
/// above into `dir`. A table of the frequencies goes to `progress` when not null. Throws
/// FemModelError for a model that cannot be solved (with a hint to shift a free structure).
ModalRunSummary run_modal_analysis(const FemScene& scene, const std::filesystem::path& dir,
                                   std::ostream* progress);

}  // namespace demfem::fem
