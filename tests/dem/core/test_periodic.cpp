// Periodic boundaries (docs/dem.md, "Periodic boundaries and tiled beds"): a pair across the
// seam against the same pair away from it, a collision while the bodies wrap, contact history
// through a wrap, determinism over threads and restarts, tiling, and the refusals (the
// settled bed without a seam and the scene keys: tests/dem/tools/test_periodic_scene.cpp).

#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <random>
#include <tuple>
#include <vector>

#include "dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem_test/temp_dir.hpp"
#include "poly_test_util.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;

namespace {

constexpr double kL = 0.0625;  // period, m (a power of two: seam shifts are exact)

DemSettings periodic_settings(bool periodic, double mu, int threads = 1) {
  auto s = two_material_settings(1e8, 0.3, 2500.0, 1.0, mu, 1e-6);
  s.threads = threads;
  if (periodic) {
    s.periodic.on = {true, false, false};
    s.periodic.lo = {0.0, 0.0, 0.0};
    s.periodic.hi = {kL, 0.0, 0.0};
  }
  return s;
}

bool same(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

bool same_state(const ParticleState& a, const ParticleState& b) {
  return same(a.px, b.px) && same(a.py, b.py) && same(a.pz, b.pz) && same(a.vx, b.vx) &&
         same(a.vy, b.vy) && same(a.vz, b.vz) && same(a.wx, b.wx) && same(a.wy, b.wy) &&
         same(a.wz, b.wz) && same(a.qw, b.qw) && same(a.qx, b.qx) && same(a.fx, b.fx) &&
         same(a.fy, b.fy) && same(a.fz, b.fz);
}

// Two bodies (spheres, or rounded boxes) at speed along x that collide while crossing the
// seam at x = L (periodic) or the same place without a seam (the reference): A at x0, B
// 4.1 mm ahead and 0.3 mm aside, closing at 0.1 m/s while both move at about 5 m/s. B's
// centre crosses x = L after ~380 steps, the contact lasts from about step 1000 to 1260, and
// A's centre crosses x = L at ~step 1200, in the middle of it.
DemSystem collision(bool periodic, bool rocks, double mu) {
  DemSystem sys(periodic_settings(periodic, mu));
  const double x0 = kL - 0.006;
  if (rocks) {
    // half-sides 1.3 x 1.2 x 1.1 mm, dilation 0.4 mm; B turned a quarter about z: 0.1 mm apart
    const auto shape = sys.add_shape(box_shape(0.0013, 0.0012, 0.0011, 0.0004));
    const double h = std::sqrt(0.5);
    sys.add_particles(std::vector<ParticleInit>{
        poly(shape, {x0, 0, 0}, {1, 0, 0, 0}, {5.05, 0, 0}, {0, 0, 3}),
        poly(shape, {x0 + 0.0034, 0.0003, 0}, {h, 0, 0, h}, {4.95, 0, 0})});
  } else {
    sys.add_particles(std::vector<ParticleInit>{
        sphere({x0, 0, 0}, 0.002, {5.05, 0, 0}),
        sphere({x0 + 0.0041, 0.0003, 0}, 0.002, {4.95, 0, 0}, {0, 0, 5})});
  }
  return sys;
}

double wrapped(double x) { return x >= kL ? x - kL : x; }

}  // namespace

TEST_CASE("A pair across the seam has the force of the same pair away from it, bit for bit",
          "[dem][periodic]") {
  // Reference: the same pair at x = 1/32 m in a system without periods. Positions are
  // dyadic, so the seam's shift (x_j - x_i - L) is exact: tolerance none (bitwise).
  const double r = 1.0 / 512, gap = 1.0 / 65536;  // overlap 15 um of a 2 mm radius
  const double d = 2 * r - gap;
  for (double mu : {0.0, 0.5}) {
    DemSystem seam(periodic_settings(true, mu)), away(periodic_settings(false, mu));
    const double xi = 1.0 / 4096;
    seam.add_particles(std::vector<ParticleInit>{sphere({xi, 0, 0}, r, {0, 0, 0}, {0, 9, 0}),
                                                 sphere({xi - d + kL, 0, 0}, r)});
    const double xa = 1.0 / 32;
    away.add_particles(std::vector<ParticleInit>{sphere({xa, 0, 0}, r, {0, 0, 0}, {0, 9, 0}),
                                                 sphere({xa - d, 0, 0}, r)});
    seam.advance(1);
    away.advance(1);
    REQUIRE(seam.contact_count() == 1);
    CHECK(seam.particles().fx[0] > 0.0);  // pushed away from j's image at -d, not from j
    CHECK(same(seam.particles().fx, away.particles().fx));
    CHECK(same(seam.particles().fy, away.particles().fy));
    CHECK(same(seam.particles().fz, away.particles().fz));
  }
}

TEST_CASE("A collision across the seam at speed is the collision without a seam",
          "[dem][periodic]") {
  // Reference: the same bodies without periods. The wrap moves a body by L (rounded to its
  // coordinate's ulp, 7e-18 m), so the relative motion agrees to round-off: tolerance on the
  // pair force 1e-7 of its peak (the overlaps are ~1e-5 m, the round-off ~1e-17 m, amplified
  // by the 1300 steps' integration), on velocities 1e-9 m/s. Momentum: conserved to 1e-12
  // of |p|, as without a seam. Kinetic energy after the elastic collision: that of the
  // reference to 1e-9 (the integration's own error is the same in both).
  for (bool rocks : {false, true}) {
    CAPTURE(rocks);
    DemSystem per = collision(true, rocks, 0.5), ref = collision(false, rocks, 0.5);
    const double p0 = per.particles().mass[0] * per.particles().vx[0] +
                      per.particles().mass[1] * per.particles().vx[1];
    double peak = 0.0, worst = 0.0;
    bool wrapped_in_contact = false;  // A's centre crossed the seam while the pair touched
    std::int32_t image_a = 0;
    for (int k = 0; k < 2000; ++k) {
      per.advance(1);
      ref.advance(1);
      const auto& a = per.particles();
      const auto& b = ref.particles();
      peak = std::max(peak, std::abs(b.fx[0]) + std::abs(b.fy[0]));
      worst = std::max({worst, std::abs(a.fx[0] - b.fx[0]), std::abs(a.fy[0] - b.fy[0]),
                        std::abs(a.fx[1] - b.fx[1])});
      if (per.images()[0] != image_a && per.contact_count() == 1) wrapped_in_contact = true;
      image_a = per.images()[0];
      for (int i = 0; i < 2; ++i) {
        REQUIRE(std::abs(a.vx[i] - b.vx[i]) < 1e-9);
        REQUIRE(std::abs(a.vy[i] - b.vy[i]) < 1e-9);
        REQUIRE(std::abs(a.px[i] - wrapped(b.px[i])) < 1e-12);
        REQUIRE(a.px[i] >= 0.0);
        REQUIRE(a.px[i] < kL);
      }
    }
    CHECK(peak > 0.01);  // they collided (N)
    CHECK(worst <= 1e-7 * peak);
    CHECK(wrapped_in_contact);
    CHECK(per.images()[0] == 1);
    CHECK(per.images()[3] == 1);
    const auto& a = per.particles();
    const double p1 = a.mass[0] * a.vx[0] + a.mass[1] * a.vx[1];
    CHECK(std::abs(p1 - p0) <= 1e-12 * std::abs(p0));
    CHECK(std::abs(per.kinetic_energy() - ref.kinetic_energy()) <= 1e-9 * ref.kinetic_energy());
    // the unwrapped position is the reference's
    CHECK(std::abs(a.px[0] + per.images()[0] * kL - ref.particles().px[0]) < 1e-12);
  }
}

TEST_CASE("A sliding pair keeps its tangential spring when a body wraps", "[dem][periodic]") {
  // Two spheres drifting at 1 m/s along x across the seam, pressed together along y (20 um
  // overlap, closing at 0.01 m/s) and sliding past each other along x at 0.02 m/s: the
  // tangential spring grows step by step. A wraps after ~50 steps, B after ~300, both while
  // they touch. Reference: the run without a seam. A spring reset by a wrap would drop the
  // tangential force to one step's growth (a few per cent of it); tolerance 1e-7 of the
  // largest tangential force (round-off).
  auto make = [](bool periodic) {
    DemSystem sys(periodic_settings(periodic, 0.3));
    const double r = 0.002;
    sys.add_particles(std::vector<ParticleInit>{
        sphere({kL - 0.00005, 0, 0}, r, {1.01, 0.005, 0}),
        sphere({kL - 0.0003, 2 * r - 0.00002, 0}, r, {0.99, -0.005, 0})});
    return sys;
  };
  DemSystem per = make(true), ref = make(false);
  double ft_max = 0.0, worst = 0.0;
  int wraps_in_contact = 0;
  for (int k = 0; k < 400; ++k) {
    const std::int32_t before = per.images()[0] + per.images()[3];
    per.advance(1);
    ref.advance(1);
    ft_max = std::max(ft_max, std::abs(ref.particles().fx[0]));
    worst = std::max(worst, std::abs(per.particles().fx[0] - ref.particles().fx[0]));
    if (per.images()[0] + per.images()[3] != before && per.contact_count() == 1 &&
        std::abs(ref.particles().fx[0]) > 0.0)
      ++wraps_in_contact;
  }
  CHECK(wraps_in_contact >= 1);
  CHECK(ft_max > 1e-3);
  CHECK(worst <= 1e-7 * ft_max);
}

namespace {

// The cloud's rock: a rounded box of half-sides 1.9 x 1.6 x 1.3 mm, dilation 0.4 mm (bounding
// radius 3.2 mm: turned at random on a 6.6 mm lattice, no two overlap at the start).
PolyhedronShape cloud_rock() { return box_shape(0.0019, 0.0016, 0.0013, 0.0004); }

// A periodic (x and y) cloud of rounded boxes (turned at random) and spheres falling onto a
// floor that spans the period, with random sideways velocities so that many wrap: 144 bodies,
// which the CPU backend runs threaded (more than 2048 sphere-steps of work).
DemSystem periodic_cloud(int threads) {
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, 1e-5, 0.02);
  s.gravity = {0, 0, -9.81};
  s.threads = threads;
  s.periodic.on = {true, true, false};
  s.periodic.lo = {0.0, 0.0, 0.0};
  s.periodic.hi = {0.04, 0.04, 0.0};
  DemSystem sys(s);
  sys.add_wall(two_triangle_floor());
  const auto shape = sys.add_shape(cloud_rock());
  std::mt19937_64 rng(7);
  sys.add_particles(periodic_thrown_cloud(shape, rng));
  return sys;
}

}  // namespace

TEST_CASE("A periodic run is bitwise the same on 1 and 3 threads and across a restart",
          "[dem][periodic][restart]") {
  // Reference: the uninterrupted run on one thread. Tolerance: none (bitwise).
  DemSystem ref = periodic_cloud(1);
  ref.advance(1200);
  DemSystem three = periodic_cloud(3);
  three.advance(1200);
  CHECK(same_state(ref.particles(), three.particles()));
  CHECK(std::equal(ref.images().begin(), ref.images().end(), three.images().begin()));
  int wraps = 0;
  for (std::int32_t m : ref.images()) wraps += std::abs(m);
  CHECK(wraps > 10);  // many crossed a seam

  // Restarts: the same cloud (rocks and spheres). The state carries the rock pairs'
  // narrow-phase caches (warm starts), without which a restored run could round a rock
  // pair's contact otherwise (GJK's path).
  const demfem::test::TempDir tmp("dem_periodic_restart");
  const auto file = tmp.path / "state.h5";
  DemSystem first = periodic_cloud(2);
  first.advance(600);
  {
    demfem::io::H5File h5(file, demfem::io::H5File::Mode::create);
    first.save(h5, "/dem");
  }
  DemSystem second = periodic_cloud(2);
  {
    demfem::io::H5File h5(file, demfem::io::H5File::Mode::read);
    second.restore(h5, "/dem");
    const PeriodicRange r = read_state_periodic(h5, "/dem");
    CHECK(r.on[0]);
    CHECK(r.on[1]);
    CHECK_FALSE(r.on[2]);
    CHECK(r.hi[0] == 0.04);
  }
  second.advance(600);
  CHECK(same_state(ref.particles(), second.particles()));
  CHECK(std::equal(ref.images().begin(), ref.images().end(), second.images().begin()));
  // the in-memory save point too
  DemSystem third = periodic_cloud(1);
  third.advance(600);
  DemStateCopy copy;
  third.save_state(copy);
  third.advance(300);
  third.restore_state(copy);
  third.advance(600);
  CHECK(same_state(ref.particles(), third.particles()));
  CHECK(std::equal(ref.images().begin(), ref.images().end(), third.images().begin()));
}

TEST_CASE("A tiled periodic block is periodic with the larger period and has its forces",
          "[dem][periodic][tile]") {
  // Block: the periodic cloud after 800 steps (contacts with springs, several across the
  // seams). Tiled 2 x 2 into a system periodic over twice the ranges, restored from the
  // block's state. Reference: the block's own next step. Copy c of particle i sits at
  // x + c L, rounded to its coordinate: the forces agree to round-off, tolerance 1e-9 of the
  // largest force (overlaps ~1e-5 m against a rounding of ~1e-17 m); the contact count is
  // exactly four times the block's.
  const demfem::test::TempDir tmp("dem_periodic_tile");
  const auto file = tmp.path / "block.h5";
  DemSystem block = periodic_cloud(1);
  block.advance(800);
  {
    demfem::io::H5File h5(file, demfem::io::H5File::Mode::create);
    block.save(h5, "/dem");
  }
  auto s = block.settings();
  s.periodic.hi = {0.08, 0.08, 0.0};
  DemSystem tiled(s);
  tiled.add_wall(two_triangle_floor());
  tiled.add_shape(cloud_rock());
  {
    demfem::io::H5File h5(file, demfem::io::H5File::Mode::read);
    tiled.restore(h5, "/dem");
    tiled.tile(read_state_periodic(h5, "/dem"), {2, 2, 1}, true);
  }
  const std::size_t n = block.particle_count();
  REQUIRE(tiled.particle_count() == 4 * n);
  block.advance(1);
  tiled.advance(1);
  CHECK(tiled.contact_count() == 4 * block.contact_count());
  double fmax = 0.0, worst = 0.0;
  const auto& b = block.particles();
  const auto& t = tiled.particles();
  for (std::size_t k = 0; k < 4 * n; ++k) {
    const std::size_t i = k % n;
    fmax = std::max({fmax, std::abs(b.fx[i]), std::abs(b.fy[i]), std::abs(b.fz[i])});
    worst = std::max({worst, std::abs(t.fx[k] - b.fx[i]), std::abs(t.fy[k] - b.fy[i]),
                      std::abs(t.fz[k] - b.fz[i])});
  }
  CHECK(worst <= 1e-9 * fmax);
  // and on: the tiled bed goes on as four blocks (to round-off, amplified by the chaos of
  // the rocks' contacts: 1e-6 of the block's speeds after 20 steps)
  block.advance(20);
  tiled.advance(20);
  double vmax = 0.0, dv = 0.0;
  for (std::size_t k = 0; k < 4 * n; ++k) {
    const std::size_t i = k % n;
    vmax = std::max(vmax, std::abs(b.vz[i]));
    dv = std::max(dv, std::abs(t.vz[k] - b.vz[i]));
  }
  CHECK(dv <= 1e-6 * vmax);
  // refusals: copies in a direction that is not periodic, a system range that is not the
  // tiled one
  demfem::io::H5File h5(file, demfem::io::H5File::Mode::read);
  const PeriodicRange r = read_state_periodic(h5, "/dem");
  for (const auto& [hi, copies, what] :
       {std::tuple{0.04, std::array<int, 3>{1, 1, 2}, "not periodic"},
        std::tuple{0.08, std::array<int, 3>{3, 2, 1}, "tiled range"},
        std::tuple{0.08, std::array<int, 3>{0, 2, 1}, "< 1"}}) {
    auto sw = s;
    sw.periodic.hi = {hi, hi, 0.0};
    DemSystem wrong(sw);
    wrong.add_wall(two_triangle_floor());
    wrong.restore(h5, "/dem");
    CHECK_THROWS_WITH(wrong.tile(r, copies, true), Catch::Contains(what));
  }
}

TEST_CASE("Periodic settings that cannot work are refused", "[dem][periodic][badinput]") {
  SECTION("a period below twice the list cutoff") {
    auto s = periodic_settings(true, 0.0);
    s.periodic.hi[0] = 0.01;  // spheres of 2 mm: least 2 (4 mm + 0.4 mm) = 8.8 mm; ok
    DemSystem ok(s);
    ok.add_particles(std::vector<ParticleInit>{sphere({0.005, 0, 0}, 0.002)});
    CHECK(ok.least_period() == Approx(0.0088));
    CHECK_NOTHROW(ok.advance(1));
    s.periodic.hi[0] = 0.008;
    DemSystem small(s);
    small.add_particles(std::vector<ParticleInit>{sphere({0.005, 0, 0}, 0.002)});
    CHECK_THROWS_WITH(small.advance(1), Catch::Contains("period in x") &&
                                            Catch::Contains("at least 0.0088"));
  }
  SECTION("an empty range") {
    auto s = periodic_settings(true, 0.0);
    s.periodic.hi[0] = -1.0;
    CHECK_THROWS_WITH(DemSystem(s), Catch::Contains("hi > lo"));
  }
}
