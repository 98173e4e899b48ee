// Particle shapes: the principal frame, sizing to a sieve size, a volume-equivalent diameter
// or a bounding diameter with r_d a fraction of the size, exact similarity, and the errors for r_d
// too large.

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <random>

#include "demfem/dem/shapes/shapes.hpp"
#include "demfem_test/error_of.hpp"
#include "shape_test_util.hpp"

using namespace demfem::dem::shapes;
using demfem::test::error_of;
using std::numbers::pi;

namespace {

ConvexPolyhedron random_hull(std::uint64_t seed, int n) {
  std::mt19937_64 gen(seed);
  return ConvexPolyhedron::hull(
      test::random_points(gen, static_cast<std::size_t>(n), {1.0, 0.6, 0.4}, {3.0, -1.0, 0.0}),
      "random hull");
}

}  // namespace

TEST_CASE("a cube sized by sieve: core edge (1 - 2f) size, rounded-cube volume",
          "[shapes][particle]") {
  const double size = 0.04, f = 0.1;
  const auto s = make_particle_shape(make_cube(1.0), size, SizeKind::sieve, f, "cube");
  const double r = f * size, a = (1 - 2 * f) * size;  // core edge
  CHECK(s.dilation_radius == Approx(r).epsilon(1e-15));
  CHECK(s.sieve_size == Approx(size).epsilon(1e-9));
  CHECK(s.core.width({1, 0, 0}) == Approx(a).epsilon(1e-9));
  // Steiner for a cube (closed form).
  const double v = a * a * a + 6 * a * a * r + 3 * pi * a * r * r + 4.0 / 3.0 * pi * r * r * r;
  CHECK(s.volume == Approx(v).epsilon(1e-9));
  CHECK(s.volume_equivalent_diameter == Approx(std::cbrt(6 * v / pi)).epsilon(1e-9));
  // Cubic symmetry: isotropic inertia.
  CHECK(s.principal_moments[0] == Approx(s.principal_moments[2]).epsilon(1e-12));
  CHECK(s.bounding_radius == Approx(0.5 * a * std::sqrt(3.0) + r).epsilon(1e-9));
  CHECK(s.elongation == Approx(1.0).epsilon(1e-12));
  CHECK(s.flatness == Approx(1.0).epsilon(1e-12));
}

TEST_CASE("a cube sized by its bounding diameter: core edge (1 - 2f) size / sqrt(3)",
          "[shapes][particle]") {
  // The dilated cube's bounding sphere: half the core's diagonal plus r_d, so a bounding
  // diameter d with r_d = f d leaves a core of edge (1 - 2f) d / sqrt(3).
  const double size = 0.04, f = 0.1;
  const auto s = make_particle_shape(make_cube(1.0), size, SizeKind::bounding, f, "cube");
  const double a = (1 - 2 * f) * size / std::sqrt(3.0);
  CHECK(s.dilation_radius == Approx(f * size).epsilon(1e-15));
  CHECK(s.core.width({1, 0, 0}) == Approx(a).epsilon(1e-12));
  CHECK(2 * s.bounding_radius == Approx(size).epsilon(1e-12));
  CHECK(s.size(SizeKind::bounding) == Approx(size).epsilon(1e-12));
  CHECK(s.sieve_size == Approx(a + 2 * f * size).epsilon(1e-9));
  CHECK(to_string(SizeKind::bounding) == "bounding");
}

TEST_CASE("a random hull in its principal frame with the size it was asked for",
          "[shapes][particle]") {
  const auto k = random_hull(4, 15);
  for (const SizeKind kind : {SizeKind::sieve, SizeKind::volume_equivalent, SizeKind::bounding}) {
    const double size = 0.05, f = 0.1;
    const auto s = make_particle_shape(k, size, kind, f, "hull");
    INFO(to_string(kind));
    CHECK(s.size(kind) == Approx(size).epsilon(1e-12));
    CHECK(s.dilation_radius == Approx(f * size).epsilon(1e-15));
    // Recomputed from the returned core: centroid at the origin, diagonal inertia with the
    // stated moments, the stated sizes.
    const auto mp = dilated_mass_properties(s.core, s.dilation_radius);
    const double scale = mp.inertia[0][0] + mp.inertia[1][1] + mp.inertia[2][2];
    for (int i = 0; i < 3; ++i) CHECK(std::abs(mp.centroid[i]) < 1e-14 * size);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        CHECK(mp.inertia[i][j] ==
              Approx(i == j ? s.principal_moments[i] : 0.0).margin(1e-13 * scale));
    CHECK(mp.volume == Approx(s.volume).epsilon(1e-13));
    CHECK(std::cbrt(6 * mp.volume / pi) == Approx(s.volume_equivalent_diameter).epsilon(1e-13));
    CHECK(sieve_size(s.core).size + 2 * s.dilation_radius == Approx(s.sieve_size).epsilon(1e-9));
    CHECK(s.principal_moments[0] <= s.principal_moments[1]);
    CHECK(s.principal_moments[1] <= s.principal_moments[2]);
    double rmax = 0;
    for (const Vec3& v : s.core.vertices()) rmax = std::max(rmax, norm(v));
    CHECK(s.bounding_radius == Approx(rmax + s.dilation_radius).epsilon(1e-15));
    // The core is similar to the input: same triangulation.
    CHECK(s.core.triangles() == k.triangles());
  }
}

TEST_CASE("the volume-equivalent size of a box solves Steiner's cubic", "[shapes][particle]") {
  // Box a x b x c scaled by lambda, r = 0.15 d: V(lambda) = pi d^3 / 6 with the closed-form
  // Steiner coefficients of a box: A = 2(ab + bc + ca), M = pi (a + b + c).
  const double a = 1.0, b = 0.5, c = 0.25, d = 0.03, f = 0.15;
  const auto s = make_particle_shape(make_box(a, b, c), d, SizeKind::volume_equivalent, f, "box");
  // body x: the least principal moment, i.e. the longest axis
  const double lambda = s.core.width({1, 0, 0}) / a;
  const double r = f * d;
  const double v = std::pow(lambda, 3) * a * b * c +
                   lambda * lambda * 2 * (a * b + b * c + c * a) * r +
                   lambda * pi * (a + b + c) * r * r + 4.0 / 3.0 * pi * r * r * r;
  CHECK(v == Approx(pi * d * d * d / 6).epsilon(1e-13));
  CHECK(s.extents[0] == Approx(lambda * a + 2 * r).epsilon(1e-13));
  CHECK(s.extents[2] == Approx(lambda * c + 2 * r).epsilon(1e-13));
  CHECK(s.elongation == Approx((lambda * b + 2 * r) / (lambda * a + 2 * r)).epsilon(1e-13));
  CHECK(s.flatness == Approx((lambda * c + 2 * r) / (lambda * b + 2 * r)).epsilon(1e-13));
}

TEST_CASE("the point core sized is a sphere of that diameter", "[shapes][particle]") {
  for (const SizeKind kind : {SizeKind::sieve, SizeKind::volume_equivalent, SizeKind::bounding}) {
    const auto s =
        make_particle_shape(ConvexPolyhedron::point({1, 2, 3}), 0.01, kind, 0.1, "sphere");
    const double r = 0.005, v = 4.0 / 3.0 * pi * r * r * r;
    CHECK(s.core.is_point());
    CHECK(s.core.vertices()[0] == Vec3{0, 0, 0});
    CHECK(s.dilation_radius == 0.005);
    CHECK(s.volume == Approx(v).epsilon(1e-15));
    for (double m : s.principal_moments) CHECK(m == Approx(0.4 * v * r * r).epsilon(1e-14));
    CHECK(s.sieve_size == Approx(0.01).epsilon(1e-15));
    CHECK(s.volume_equivalent_diameter == Approx(0.01).epsilon(1e-15));
    CHECK(s.bounding_radius == 0.005);
  }
}

TEST_CASE("scaling a particle shape is an exact similarity", "[shapes][particle]") {
  const auto k = random_hull(8, 12);
  const auto s1 = make_particle_shape(k, 1.0, SizeKind::sieve, 0.1, "a");
  const auto s2 = make_particle_shape(k, 0.037, SizeKind::sieve, 0.1, "b");
  const auto s3 = scale(s1, 0.037);
  CHECK(s3.volume == Approx(s2.volume).epsilon(1e-12));
  for (int i = 0; i < 3; ++i)
    CHECK(s3.principal_moments[i] == Approx(s2.principal_moments[i]).epsilon(1e-12));
  CHECK(s3.dilation_radius == Approx(s2.dilation_radius).epsilon(1e-15));
  CHECK(s3.bounding_radius == Approx(s2.bounding_radius).epsilon(1e-12));
  CHECK(s3.sieve_size == Approx(0.037).epsilon(1e-12));
  for (std::size_t v = 0; v < s2.core.vertices().size(); ++v)
    for (int i = 0; i < 3; ++i)
      CHECK(s3.core.vertices()[v][i] == Approx(s2.core.vertices()[v][i]).margin(1e-12 * 0.037));
}

TEST_CASE("a dilation radius too large for the size is refused with its value",
          "[shapes][particle]") {
  const auto cube = make_cube(1.0);
  CHECK_THAT(error_of<ShapeError>(
                 [&] { (void)make_particle_shape(cube, 0.04, SizeKind::sieve, 1.2, "ballast"); }),
             Catch::Contains("ballast: dilation radius r_d = 1.2 x size = 0.048 m is not smaller "
                             "than the size 0.04 m"));
  CHECK_THAT(error_of<ShapeError>(
                 [&] { (void)make_particle_shape(cube, 0.04, SizeKind::sieve, 1.0, "b"); }),
             Catch::Contains("not smaller than the size"));
  CHECK_THAT(error_of<ShapeError>([&] {
               (void)make_particle_shape(cube, 0.04, SizeKind::volume_equivalent, 0.5, "b");
             }),
             Catch::Contains("r_d = 0.5 x size = 0.02 m") &&
                 Catch::Contains("the core would vanish") && Catch::Contains("must be < 0.5"));
  CHECK_THAT(error_of<ShapeError>(
                 [&] { (void)make_particle_shape(cube, 0.04, SizeKind::sieve, 0.0, "b"); }),
             Catch::Contains("fraction 0 must be > 0"));
  CHECK_THAT(error_of<ShapeError>(
                 [&] { (void)make_particle_shape(cube, -1.0, SizeKind::sieve, 0.1, "b"); }),
             Catch::Contains("size -1 m must be > 0"));
  CHECK_THAT(error_of<ShapeError>([&] { (void)describe_dilated(ConvexPolyhedron::point(), 0.0); }),
             Catch::Contains("point core needs a dilation radius > 0"));
  CHECK_THAT(error_of<ShapeError>([&] { (void)describe_dilated(cube, -0.1); }),
             Catch::Contains("must be finite and >= 0"));
  // Just below one half: a tiny core, still valid.
  const auto s = make_particle_shape(cube, 0.04, SizeKind::sieve, 0.49, "b");
  CHECK(s.core.width({1, 0, 0}) == Approx(0.02 * 0.04).epsilon(1e-9));
}
