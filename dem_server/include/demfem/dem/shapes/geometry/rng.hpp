#pragma once
// A portable seeded random stream. std::uniform_real_distribution and
// std::normal_distribution differ between standard libraries, so the transforms here are our
// own: the same seed gives the same particles with any compiler.

#include <cstdint>
#include <random>

namespace demfem::dem {

/// @brief Deterministic random stream: mt19937_64 with explicit transforms.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : engine_(seed) {}
  /// Uniform in [0, 1) with 53 random bits.
  double uniform() { return double(engine_() >> 11) * 0x1.0p-53; }
  /// Uniform in [a, b).
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  /// Standard normal (Marsaglia polar method; the spare value is kept).
  double normal();

 private:
  std::mt19937_64 engine_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

}  // namespace demfem::dem
