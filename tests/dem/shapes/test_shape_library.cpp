// Shape library: unit shapes, exact scaling, determinism, and rock populations drawn from the
// thesis's size distributions (normal with bounds, gradation by sieve size with mass
// fractions) with their statistics against the distribution.

#include <catch2/catch.hpp>

#include <cmath>
#include <stdexcept>

#include "demfem/dem/shapes/shapes.hpp"

using namespace demfem::dem;
using namespace demfem::dem::shapes;

TEST_CASE("a random-rock library holds unit shapes of the requested kind", "[shapes][library]") {
  const RockParams p{30, 0.8, 0.7};
  const auto lib = ShapeLibrary::random_rocks(p, 24, 7, SizeKind::sieve, 0.1);
  REQUIRE(lib.size() == 24);
  for (std::size_t k = 0; k < lib.size(); ++k) {
    const ParticleShape& u = lib.unit(k);
    CHECK(u.core.triangles().size() == 30);
    CHECK(u.sieve_size == Approx(1.0).epsilon(1e-12));
    CHECK(u.dilation_radius == Approx(0.1).epsilon(1e-15));
  }
  // Deterministic, and rock k does not depend on the library's size.
  const auto again = ShapeLibrary::random_rocks(p, 10, 7, SizeKind::sieve, 0.1);
  for (std::size_t k = 0; k < again.size(); ++k) {
    CHECK(again.unit(k).core.vertices() == lib.unit(k).core.vertices());
    CHECK(again.unit(k).volume == lib.unit(k).volume);
  }
  const auto vol = ShapeLibrary::random_rocks(p, 4, 7, SizeKind::volume_equivalent, 0.1);
  for (std::size_t k = 0; k < vol.size(); ++k)
    CHECK(vol.unit(k).volume_equivalent_diameter == Approx(1.0).epsilon(1e-13));
}

TEST_CASE("scaled shapes are exact similarities of the unit shapes", "[shapes][library]") {
  const std::vector<ConvexPolyhedron> cores{make_cube(1.0), make_regular_tetrahedron(1.0),
                                            ConvexPolyhedron::point()};
  const ShapeLibrary lib(cores, SizeKind::sieve, 0.1);
  for (std::size_t k = 0; k < lib.size(); ++k) {
    const double s = 0.043;
    const ScaledShape sc = lib.scaled(k, s);
    // The reference: the core sized directly to s.
    const ParticleShape direct = make_particle_shape(cores[k], s, SizeKind::sieve, 0.1, "direct");
    CHECK(sc.scale == s);
    CHECK(sc.volume == Approx(direct.volume).epsilon(1e-12));
    CHECK(sc.dilation_radius == Approx(direct.dilation_radius).epsilon(1e-15));
    CHECK(sc.bounding_radius == Approx(direct.bounding_radius).epsilon(1e-12));
    for (int i = 0; i < 3; ++i)
      CHECK(sc.principal_moments[i] == Approx(direct.principal_moments[i]).epsilon(1e-12));
    const ParticleShape p = lib.particle(k, s);
    CHECK(p.sieve_size == Approx(s).epsilon(1e-12));
    for (std::size_t v = 0; v < p.core.vertices().size(); ++v)
      for (int i = 0; i < 3; ++i)
        CHECK(p.core.vertices()[v][i] == s * lib.unit(k).core.vertices()[v][i]);
  }
  // The point core: a sphere of diameter s.
  CHECK(lib.scaled(2, 0.01).dilation_radius == Approx(0.005).epsilon(1e-15));
  CHECK_THROWS_AS(lib.scaled(3, 0.01), ShapeError);
  CHECK_THROWS_AS(lib.scaled(0, 0.0), ShapeError);
}

TEST_CASE("rocks drawn from the thesis's normal distribution", "[shapes][library]") {
  // Thesis ch. 6: sieve size normal, mean 40 mm, sd 10 mm, in [20, 80] mm; r_d = 10 %.
  const auto lib = ShapeLibrary::random_rocks({30, 0.8, 0.7}, 16, 3, SizeKind::sieve, 0.1);
  const auto dist = SizeDistribution::normal(0.04, 0.01, 0.02, 0.08);
  Rng rng(11);
  const int n = 50000;
  double sum = 0, sum2 = 0, lo = 1, hi = 0;
  std::vector<int> used(lib.size(), 0);
  for (int i = 0; i < n; ++i) {
    const ScaledShape s = lib.sample(rng, dist);
    sum += s.scale;
    sum2 += s.scale * s.scale;
    lo = std::min(lo, s.scale);
    hi = std::max(hi, s.scale);
    ++used[s.shape];
    CHECK(s.dilation_radius == Approx(0.1 * s.scale).epsilon(1e-15));
  }
  CHECK(lo >= 0.02);
  CHECK(hi <= 0.08);
  // Truncated-normal mean 0.0405511 (test_size_distribution.cpp); standard error
  // 0.01 / sqrt(n) = 4.5e-5; 5 sigma.
  CHECK(std::abs(sum / n - 0.0405511) < 5 * 4.5e-5);
  // Truncated-normal sd: sigma sqrt(1 + (a phi(a) - b phi(b)) / Z - ((phi(a) - phi(b)) / Z)^2)
  // with a = -2, b = 4, Z = Phi(b) - Phi(a): 0.0094123. Standard error of the sample sd
  // ~ sd / sqrt(2 n) = 3.0e-5 (the truncated normal's kurtosis is near 3); 5 sigma.
  const double mean = sum / n;
  CHECK(std::abs(std::sqrt(sum2 / n - mean * mean) - 0.0094123) < 5 * 3.0e-5);
  // Shapes uniform: each index n/16 = 3125 times, binomial sd sqrt(n p (1-p)) = 54; 5 sigma.
  for (int u : used) CHECK(std::abs(u - n / 16.0) < 5 * 54.0);
}

TEST_CASE("rocks drawn from a gradation reproduce its mass fractions", "[shapes][library]") {
  // A ballast-like grading curve by sieve size (m) with mass fractions per class. The rocks'
  // volumes differ by shape (V_k at unit size), drawn independently of the size, so each
  // class's share of the total rock mass is the table's fraction.
  const std::vector<double> sieves{0.02, 0.0315, 0.04, 0.05, 0.063};
  const std::vector<double> fractions{0.1, 0.3, 0.4, 0.2};
  const auto dist = SizeDistribution::gradation(sieves, fractions);
  const auto lib = ShapeLibrary::random_rocks({10, 0.6, 0.5}, 12, 5, SizeKind::sieve, 0.1);
  double vmin = INFINITY, vmax = 0;
  for (std::size_t k = 0; k < lib.size(); ++k) {
    vmin = std::min(vmin, lib.unit(k).volume);
    vmax = std::max(vmax, lib.unit(k).volume);
  }
  REQUIRE(vmax > 1.2 * vmin);  // the shapes' volumes really differ
  Rng rng(19);
  // 20 batches: the batch-to-batch spread gives the standard error of each fraction.
  const int batches = 20, per_batch = 5000;
  std::vector<std::vector<double>> f(batches, std::vector<double>(4, 0.0));
  for (int b = 0; b < batches; ++b) {
    double total = 0;
    for (int i = 0; i < per_batch; ++i) {
      const ScaledShape s = lib.sample(rng, dist);
      REQUIRE(s.scale >= 0.02);
      REQUIRE(s.scale < 0.063);
      std::size_t c = 0;
      while (s.scale >= sieves[c + 1]) ++c;
      f[b][c] += s.volume;  // mass / density
      total += s.volume;
    }
    for (double& x : f[b]) x /= total;
  }
  for (std::size_t c = 0; c < 4; ++c) {
    double m = 0, m2 = 0;
    for (int b = 0; b < batches; ++b) {
      m += f[b][c];
      m2 += f[b][c] * f[b][c];
    }
    m /= batches;
    const double se = std::sqrt((m2 / batches - m * m) / (batches - 1));
    INFO("class " << c << ": mass fraction " << m << " +- " << se << ", table " << fractions[c]);
    CHECK(std::abs(m - fractions[c]) < 5 * se + 1e-12);
    CHECK(se < 0.01);  // the test can tell a wrong sampler (e.g. fractions by number)
  }
}

TEST_CASE("a gradation whose fractions do not sum to 1 is refused naming the key",
          "[shapes][library]") {
  CHECK_THROWS_WITH(SizeDistribution::gradation({0.02, 0.03, 0.04}, {0.5, 0.4999999}),
                    Catch::Contains("mass_fractions must sum to 1 (within 1e-9)") &&
                        Catch::Contains("they sum to 0.9999999"));
  CHECK_NOTHROW(SizeDistribution::gradation({0.02, 0.03, 0.04, 0.05}, {0.1, 0.2, 0.7}));
}
