// Random rocks: exact triangle counts, exact elongation and flatness of the core, principal
// frame, determinism, and the errors for impossible counts and ratios.

#include <catch2/catch.hpp>

#include <cmath>

#include "demfem/dem/shapes/shapes.hpp"
#include "demfem_test/error_of.hpp"

using namespace demfem::dem::shapes;
using demfem::test::error_of;

TEST_CASE("random rocks have exactly the requested triangles and ratios", "[shapes][rock]") {
  for (int triangles : {4, 10, 30, 40, 100}) {
    for (const auto& [e, f] : {std::pair{1.0, 1.0}, {0.7, 0.6}, {0.5, 0.3}}) {
      for (std::uint64_t seed : {1u, 2u, 3u}) {
        const RockParams p{triangles, e, f};
        const auto k = random_rock(p, seed);
        INFO(triangles << " triangles, e " << e << ", f " << f << ", seed " << seed);
        CHECK(k.triangles().size() == std::size_t(triangles));
        CHECK(k.vertices().size() == std::size_t(triangles / 2 + 2));
        // Extents along x, y, z: 1, e, e f (to round-off).
        CHECK(k.width({1, 0, 0}) == Approx(1.0).epsilon(1e-12));
        CHECK(k.width({0, 1, 0}) == Approx(e).epsilon(1e-12));
        CHECK(k.width({0, 0, 1}) == Approx(e * f).epsilon(1e-12));
        // Centroid at the origin, x y z principal axes.
        const auto mp = core_mass_properties(k);
        const double scale = mp.inertia[0][0] + mp.inertia[1][1] + mp.inertia[2][2];
        for (int i = 0; i < 3; ++i) CHECK(std::abs(mp.centroid[i]) < 1e-14);
        CHECK(std::abs(mp.inertia[0][1]) < 1e-12 * scale);
        CHECK(std::abs(mp.inertia[0][2]) < 1e-12 * scale);
        CHECK(std::abs(mp.inertia[1][2]) < 1e-12 * scale);
      }
    }
  }
}

TEST_CASE("random rocks are deterministic per seed", "[shapes][rock]") {
  const RockParams p{30, 0.8, 0.7};
  const auto a = random_rock(p, 42), b = random_rock(p, 42), c = random_rock(p, 43);
  CHECK(a.vertices() == b.vertices());
  CHECK(a.triangles() == b.triangles());
  CHECK(a.vertices() != c.vertices());
}

TEST_CASE("impossible rock parameters are refused naming them", "[shapes][rock]") {
  CHECK_THAT(error_of<ShapeError>([] {
               (void)random_rock({31, 1, 1}, 1);
             }),
             Catch::Contains("rock triangles = 31") && Catch::Contains("2V - 4") &&
                 Catch::Contains("even and >= 4"));
  CHECK_THAT(error_of<ShapeError>([] {
               (void)random_rock({2, 1, 1}, 1);
             }),
             Catch::Contains("rock triangles = 2"));
  CHECK_THAT(error_of<ShapeError>([] {
               (void)random_rock({30, 1.5, 1}, 1);
             }),
             Catch::Contains("rock elongation = 1.5: must be in (0, 1]"));
  CHECK_THAT(error_of<ShapeError>([] {
               (void)random_rock({30, 1, 0}, 1);
             }),
             Catch::Contains("rock flatness = 0: must be in (0, 1]"));
}
