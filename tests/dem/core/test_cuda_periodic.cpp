// CPU vs CUDA with periodic boundaries: a cloud of spheres (or of rocks and spheres) thrown
// sideways over a floor, periodic in x and y, so that many particles cross a seam and many
// pairs touch across one. The device wraps the positions after each drift (image counters),
// takes each pair at its nearest image in the pair kernels and builds its list in a grid that
// wraps (cuda/device_list.cu). Runs on the host under test_dem_cuda_emu (the kernels against a
// test double of the CUDA runtime); without a device only the CPU half runs.

#include <catch2/catch.hpp>
#include <cmath>
#include <random>

#include "dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"
#include "poly_test_util.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;

namespace {

constexpr double kPeriod = 0.04;  // m, in x and y
constexpr double kSkin = 4e-4;    // m

// 144 bodies on a 6.6 mm lattice (4 layers of 6 x 6) in the period [0, 40 mm)^2, falling onto
// a floor that spans it, with sideways velocities of up to 2 m/s: spheres of 2.2 mm, or (rocks)
// two thirds rounded boxes turned at random (bounding radius 3.2 mm). Friction 0.5, rolling
// resistance 0.02. One list level (list_skin = 1), as the device keeps.
DemSystem periodic_bed(DemBackendKind backend, bool rocks) {
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, 1e-5, 0.02);
  s.gravity = {0, 0, -9.81};
  s.threads = 1;
  s.backend = backend;
  s.skin = kSkin;
  s.list_skin = 1.0;
  s.periodic.on = {true, true, false};
  s.periodic.lo = {0.0, 0.0, 0.0};
  s.periodic.hi = {kPeriod, kPeriod, 0.0};
  DemSystem sys(s);
  sys.add_wall(two_triangle_floor());
  const auto shape = sys.add_shape(box_shape(0.0019, 0.0016, 0.0013, 0.0004));
  std::mt19937_64 rng(11);
  sys.add_particles(periodic_thrown_cloud(shape, rng, rocks));
  return sys;
}

// The list against all pairs at its build positions, each pair at its nearest image by
// rounding (x_j - x_i - L round((x_j - x_i) / L), independent of physics/periodic_image.hpp):
// the rows and partners must be equal (the same comparison as the build's).
void check_against_all_images(const DemSystem& sys) {
  const DemSystem::PairList l = sys.pair_list();
  const ParticleState& st = sys.particles();
  const std::size_t n = st.size();
  REQUIRE(l.row.size() == n + 1);
  auto nearest = [](double d, bool periodic) {
    return periodic ? d - kPeriod * std::round(d / kPeriod) : d;
  };
  std::vector<std::int64_t> row{0};
  std::vector<std::int32_t> partner;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      const double dx = nearest(l.bx[j] - l.bx[i], true), dy = nearest(l.by[j] - l.by[i], true);
      const double dz = l.bz[j] - l.bz[i];
      const double cut = st.radius[i] + st.radius[j] + kSkin;  // bounding radii
      if (dx * dx + dy * dy + dz * dz < cut * cut) partner.push_back(static_cast<std::int32_t>(j));
    }
    row.push_back(static_cast<std::int64_t>(partner.size()));
  }
  CHECK(l.row == row);
  CHECK(l.partner == partner);
}

// Pairs whose nearest image lies across a seam (x_j - x_i more than half a period apart).
int pairs_across_a_seam(const DemSystem& sys) {
  const DemSystem::PairList l = sys.pair_list();
  int across = 0;
  for (std::size_t i = 0; i + 1 < l.row.size(); ++i)
    for (std::int64_t p = l.row[i]; p < l.row[i + 1]; ++p) {
      const auto j = static_cast<std::size_t>(l.partner[p]);
      if (std::abs(l.bx[j] - l.bx[i]) > 0.5 * kPeriod || std::abs(l.by[j] - l.by[i]) > 0.5 * kPeriod)
        ++across;
    }
  return across;
}

}  // namespace

TEST_CASE("CPU and CUDA backends agree on a periodic bed", "[dem][gpu][periodic]") {
  // Reference: the CPU backend (its periodic runs are verified against a seamless twin in
  // test_periodic.cpp). 3 advances of 300 steps; each backend's list is checked against all
  // pairs at their nearest images after each. Tolerances: positions 1e-9 of the sphere radius
  // (2.2 mm), as the other CPU-vs-CUDA tests (round-off growth of a colliding packing; the
  // device rounds like the CPU, -fmad=false); image counters equal (a wrap is a comparison of
  // positions that agree far inside the clamp's ulp).
  const bool rocks = GENERATE(false, true);
  INFO("rocks: " << rocks);
  DemSystem cpu = periodic_bed(DemBackendKind::cpu, rocks);
  const bool device = cuda_available();
  if (!device) WARN("periodic CPU-vs-CUDA comparison skipped: no CUDA device (or no CUDA build)");
  std::vector<DemSystem> runs;
  runs.push_back(std::move(cpu));
  if (device) runs.push_back(periodic_bed(DemBackendKind::cuda, rocks));
  int across = 0;
  for (int c = 0; c < 3; ++c)
    for (DemSystem& sys : runs) {
      INFO("backend " << dem_backend_name(sys.settings().backend) << ", advance " << c);
      sys.advance(300);
      check_against_all_images(sys);
      across += pairs_across_a_seam(sys);
    }
  // the CPU run is a meaningful reference: many wrapped, pairs across the seams, contacts
  int wraps = 0;
  for (std::int32_t m : runs[0].images()) wraps += std::abs(m);
  REQUIRE(wraps > 10);
  REQUIRE(across > 10);
  REQUIRE(runs[0].max_overlap() > 0.0);
  if (!device) return;
  const auto& a = runs[0].particles();
  const auto& b = runs[1].particles();
  REQUIRE(a.size() == b.size());
  CHECK(max_position_difference(a, b) < 1e-9 * 0.0022);
  CHECK(std::equal(runs[0].images().begin(), runs[0].images().end(), runs[1].images().begin()));
  CHECK(runs[1].neighbour_rebuilds() >= 3);
}

TEST_CASE("The CUDA backend refuses a period below twice the list cutoff, as the CPU does",
          "[dem][gpu][periodic][badinput]") {
  // spheres of 2 mm, skin 0.4 mm: the least period is 2 (4 mm + 0.4 mm) = 8.8 mm
  if (!cuda_available()) {
    WARN("skipped: no CUDA device (or built without CUDA)");
    return;
  }
  for (const double period : {0.01, 0.008}) {
    INFO("period " << period << " m");
    auto s = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, 1e-5);
    s.backend = DemBackendKind::cuda;
    s.skin = kSkin;
    s.periodic.on = {true, false, false};
    s.periodic.hi = {period, 0.0, 0.0};
    DemSystem sys(s);
    sys.add_particles(std::vector<ParticleInit>{sphere({0.005, 0, 0}, 0.002)});
    if (period > 0.0088)
      CHECK_NOTHROW(sys.advance(1));
    else
      CHECK_THROWS_WITH(sys.advance(1),
                        Catch::Contains("period in x") && Catch::Contains("at least 0.0088"));
  }
}
