#pragma once
// The steel strip of the FEM monitor and static-check tests: 100 x 20 x 1 mm as 10 x 2 MITC4
// shells (E 185 GPa, nu 0.3, 7850 kg/m³) clamped over x <= 0, stepped at 1e-4 s. Its [fem]
// tables, to which a test adds its loads, damping, output and monitor.

#include <string>

namespace demfem::test {

/// The strip's [fem] tables; `fem_keys` are more lines of [fem] itself (each ending in '\n').
inline std::string steel_strip_fem(const std::string& fem_keys = "") {
  return "[fem]\n" + fem_keys +
         "dt = 1e-4\n"
         "[fem.mesh.plate]\nsize = [0.1, 0.02]\ncells = [10, 2]\n"
         "[[fem.materials]]\nname = \"steel\"\nyoungs_modulus = 1.85e11\npoisson_ratio = 0.3\n"
         "density = 7850.0\n"
         "[[fem.sections]]\nmaterial = \"steel\"\nthickness = 0.001\n"
         "[[fem.clamps]]\nnodes = \"x <= 0\"\n";
}

}  // namespace demfem::test
