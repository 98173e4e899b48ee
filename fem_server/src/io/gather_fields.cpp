// Kept apart from fem_output.cpp so that the writer does not need the solver to link.
#include "demfem/fem/fem_output.hpp"

namespace demfem::fem {

FemFields gather_fields(const FemSolver& solver) {
  FemFields f;
  f.time = solver.time();
  f.displacement = solver.displacements();
  f.velocity = solver.velocities();
  f.acceleration = solver.accelerations();
  f.reaction_force = solver.reaction_forces();
  f.elements = solver.element_results();
  return f;
}

FemFields gather_fields(const ModalSolver& solver) {
  FemFields f;
  f.time = solver.time();
  f.displacement = solver.displacements();
  f.velocity = solver.velocities();
  f.acceleration = solver.accelerations();
  f.elements = solver.element_results();
  return f;
}

FemFields gather_fields(const RigidSolver& solver) {
  FemFields f;
  f.time = solver.time();
  f.displacement = solver.displacements();
  f.velocity = solver.velocities();
  f.acceleration = solver.accelerations();
  return f;
}

}  // namespace demfem::fem
