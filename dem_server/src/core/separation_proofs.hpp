#pragma once
// The separation proofs of the CPU pair pass for polyhedra (polyhedra.hpp, PolyPairs::pslack):
// per pair the proven separation left, per particle the bound of its motion since the last
// pass and its pose then. Valid only from the pass of the step before (step == the current
// step) with no list update between; derived, never saved (a pass without them computes every
// pair).

#include <cstdint>
#include <vector>

namespace demfem::dem::detail {

struct SeparationProofs {
  /// per pair: the proven gap less the motion since, m (negative: none)
  std::vector<double> separation_left;
  std::vector<double> core_motion;  ///< per particle: bound of any core point's motion, m
  std::vector<double> position;     ///< 3 per particle: the position at the last pass, m
  std::vector<double> rotation;     ///< 9 per particle: the rotations of the latest pass
  std::int64_t step = -1;           ///< the step the proofs hold for
};

}  // namespace demfem::dem::detail
