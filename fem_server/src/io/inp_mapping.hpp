#pragma once
// Maps what an Abaqus deck applies (its step, *BOUNDARY, *CLOAD, *DLOAD, *DSLOAD with their
// amplitudes) onto the FEM's load model (internal to demfem_fem; used by the scene reader).

#include "demfem/fem/fem_scene.hpp"
#include "demfem/fem/inp_reader.hpp"
#include "demfem/scene/scene_reader.hpp"

namespace demfem::fem {

/// Adds the deck's boundary conditions and loads to `scene.problem` (on top of the scene's)
/// and appends notes saying what was taken. fem.analysis stays the scene's (the coupler reads
/// it from there): a deck step of the other kind is refused when the scene does not say, and
/// noted when it does. Static analysis: a load's amplitude is evaluated at the end of the step (its
/// period), as the end state of an Abaqus static step; dynamic: tabular amplitudes become time
/// functions, and loads without one ramp or step as the step says. Fails at `mesh` (key
/// 'file') for what cannot be mapped faithfully, naming the deck's line.
void apply_inp_history(const InpModel& inp, const scene::Table& fem, const scene::Table& mesh,
                       bool analysis_given, FemScene& scene);

}  // namespace demfem::fem
