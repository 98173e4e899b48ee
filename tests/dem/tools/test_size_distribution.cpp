// Size distributions: bounds, moments against their closed forms, gradation mass fractions,
// determinism of the seeded stream.

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <vector>

#include "demfem/dem/shapes/geometry/size_distribution.hpp"

using namespace demfem::dem;

TEST_CASE("Rng is deterministic and its transforms have the right moments", "[distribution]") {
  Rng a(42), b(42), c(43);
  for (int i = 0; i < 100; ++i) {
    const double x = a.uniform();
    CHECK(x == b.uniform());
    CHECK(x >= 0.0);
    CHECK(x < 1.0);
  }
  CHECK(a.uniform() != c.uniform());
  // Standard normal: mean 0, variance 1; with N = 200000 the standard error of the mean is
  // 1/sqrt(N) = 0.0022 and of the variance sqrt(2/N) = 0.0032; 5 sigma tolerances.
  Rng r(7);
  const int n = 200000;
  double s = 0, s2 = 0;
  for (int i = 0; i < n; ++i) {
    const double z = r.normal();
    s += z;
    s2 += z * z;
  }
  CHECK(std::abs(s / n) < 5 * 0.0022);
  CHECK(std::abs(s2 / n - 1.0) < 5 * 0.0032);
}

TEST_CASE("uniform sizes stay in bounds with the right mean and mean cube", "[distribution]") {
  const auto d = SizeDistribution::uniform(0.003, 0.005);
  Rng r(1);
  const int n = 100000;
  double s = 0, s3 = 0;
  for (int i = 0; i < n; ++i) {
    const double x = d.sample(r);
    REQUIRE(x >= 0.003);
    REQUIRE(x <= 0.005);
    s += x;
    s3 += x * x * x;
  }
  // Mean 0.004, sd 0.002/sqrt(12) = 5.77e-4; standard error 1.8e-6; 5 sigma.
  CHECK(std::abs(s / n - 0.004) < 5 * 1.83e-6);
  // E[d^3] = (b^4 - a^4) / (4 (b - a)) = 6.8e-8 (closed form); 1 % covers the sampling error
  // (relative sd of d^3 is ~0.35, / sqrt(N) = 0.11 %).
  CHECK(d.mean_cube() == Approx(6.8e-8).epsilon(1e-12));
  CHECK(s3 / n == Approx(6.8e-8).epsilon(0.01));
}

TEST_CASE("truncated normal sizes respect the bounds and the truncated mean", "[distribution]") {
  // Thesis ch. 6: mean 0.04 m, sd 0.01 m, bounds [0.02, 0.08] m.
  const auto d = SizeDistribution::normal(0.04, 0.01, 0.02, 0.08);
  Rng r(3);
  const int n = 100000;
  double s = 0, lo = 1, hi = 0;
  for (int i = 0; i < n; ++i) {
    const double x = d.sample(r);
    s += x;
    lo = std::min(lo, x);
    hi = std::max(hi, x);
  }
  CHECK(lo >= 0.02);
  CHECK(hi <= 0.08);
  // Mean of a normal truncated to [a, b]: mu + sigma (phi(alpha) - phi(beta)) / (Phi(beta) -
  // Phi(alpha)), alpha = -2, beta = 4: 0.04 + 0.01 * (0.053991 - 0.000134) / (0.999968 -
  // 0.022750) = 0.0405511. Standard error ~0.01/sqrt(N) = 3.2e-5; 5 sigma.
  CHECK(std::abs(s / n - 0.0405511) < 5 * 3.2e-5);
  CHECK_THROWS_WITH(SizeDistribution::normal(0.04, 0.001, 0.06, 0.08),
                    Catch::Contains("within [d_min, d_max]"));
}

TEST_CASE("gradation reproduces the sieve table's mass fractions", "[distribution]") {
  // A ballast-like gradation (m): classes [20, 31.5), [31.5, 40), [40, 50), [50, 63) mm.
  const std::vector<double> sieves{0.020, 0.0315, 0.040, 0.050, 0.063};
  const std::vector<double> frac{0.10, 0.25, 0.40, 0.25};
  const auto d = SizeDistribution::gradation(sieves, frac);
  Rng r(11);
  const int n = 200000;
  std::vector<double> mass(4, 0.0);
  double total = 0;
  for (int i = 0; i < n; ++i) {
    const double x = d.sample(r);
    REQUIRE(x >= 0.020);
    REQUIRE(x <= 0.063);
    std::size_t c = 0;
    while (c + 1 < 4 && x >= sieves[c + 1]) ++c;
    mass[c] += x * x * x;
    total += x * x * x;
  }
  // Sampling error of a mass fraction with ~2e5 particles is below 0.003 (the class counts
  // are >= 1.5e4 each); 0.01 is > 3 sigma.
  for (int c = 0; c < 4; ++c) CHECK(std::abs(mass[c] / total - frac[c]) < 0.01);
  CHECK_THROWS_WITH(SizeDistribution::gradation({0.02, 0.03}, {0.5}), Catch::Contains("sum to 1"));
  CHECK_THROWS_WITH(SizeDistribution::gradation({0.02, 0.03, 0.025}, {0.5, 0.5}),
                    Catch::Contains("increase"));
  CHECK_THROWS_WITH(SizeDistribution::gradation({0.02, 0.03}, {0.5, 0.5}),
                    Catch::Contains("one mass fraction per class"));
}
