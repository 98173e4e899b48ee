// The neighbour list of each backend against an independent reference: every pair i < j
// within r_i + r_j + skin at the positions the list was built at, found by testing all
// pairs (no grid), and every wall triangle within r_i + skin of a particle, found by testing
// all triangles. On the CUDA backend the list is built on the device (cuda/device_list.cu);
// here it must be the CPU's, pair for pair, through the rebuilds of a settling bed of spheres
// and of rocks, with the tangential springs carried across the rebuilds (compared with the
// CPU run's pair by pair). Runs on the host under test_dem_cuda_emu (Thrust's CPP backend
// for the device's sorts and searches); the CPU half runs in test_dem_core too.

#include <catch2/catch.hpp>
#include <cmath>
#include <map>
#include <random>
#include <utility>

#include "dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/physics/triangle_bins.hpp"
#include "poly_test_util.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;

namespace {

constexpr double kSkin = 4e-4;  // m: rebuilds every few tens of steps in these beds

// A floor and a wall inclined at 30 degrees across one side of it.
std::vector<WallMesh> walls() {
  WallMesh slope = plane_mesh(0.04, 3, 0.5236);
  for (std::size_t k = 0; k < slope.vertices.size(); k += 3) slope.vertices[k] += 0.012;
  return {plane_mesh(0.05, 4), slope};
}

// 160 spheres (r 1.5-2.5 mm) or 96 rocks and spheres thrown together onto the walls;
// friction 0.5, rolling resistance 0.02. The CPU keeps one list level (list_skin = 1), as
// the device does, so that both lists hold the pairs within the whole skin.
DemSystem bed(DemBackendKind backend, bool rocks) {
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, 1e-5, 0.02);
  s.gravity = {0, 0, -9.81};
  s.backend = backend;
  s.skin = kSkin;
  s.list_skin = 1.0;
  DemSystem sys(s);
  for (const WallMesh& w : walls()) sys.add_wall(w);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  if (rocks)
    for (int k = 0; k < 3; ++k)
      sys.add_shape(random_rock(rng, 8 + 2 * k, 0.0025, 0.002, 0.0015, 0.0004));
  std::vector<ParticleInit> p;
  const int layers = rocks ? 4 : 5;
  for (int l = 0; l < layers; ++l)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < (rocks ? 6 : 8); ++i) {
        const std::array<double, 3> x{-0.018 + 0.0055 * i + 3e-4 * u(rng),
                                      -0.009 + 0.006 * j + 3e-4 * u(rng), 0.004 + 0.006 * l};
        const std::array<double, 3> v{-40 * x[0], -40 * x[1], -0.4 - 30 * (x[2] - 0.013)};
        if (rocks && (i + j + l) % 3 != 0) {
          p.push_back(poly((i + 2 * j + l) % 3, x, random_quaternion(rng), v,
                           {20 * u(rng), 20 * u(rng), 20 * u(rng)}));
        } else {
          p.push_back(sphere(x, 0.002 + 5e-4 * u(rng), v, {20 * u(rng), 0, 0}));
        }
      }
  sys.add_particles(p);
  return sys;
}

// The reference list at the list's own build positions: all pairs, all triangles.
void check_against_all_pairs(const DemSystem& sys) {
  const DemSystem::PairList l = sys.pair_list();
  const ParticleState& st = sys.particles();
  const std::size_t n = st.size();
  REQUIRE(l.row.size() == n + 1);
  REQUIRE(l.bx.size() == n);
  std::vector<std::int64_t> row{0};
  std::vector<std::int32_t> partner;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      const double dx = l.bx[j] - l.bx[i], dy = l.by[j] - l.by[i], dz = l.bz[j] - l.bz[i];
      const double cut = st.radius[i] + st.radius[j] + kSkin;
      if (dx * dx + dy * dy + dz * dz < cut * cut) partner.push_back(static_cast<std::int32_t>(j));
    }
    row.push_back(static_cast<std::int64_t>(partner.size()));
  }
  CHECK(l.row == row);
  CHECK(l.partner == partner);
  // triangles: the walls do not move, so their vertices are those they were built with
  std::vector<double> vpos;
  std::vector<std::int32_t> tri_v;
  for (const WallMesh& w : walls()) {
    const auto base = static_cast<std::int32_t>(vpos.size() / 3);
    vpos.insert(vpos.end(), w.vertices.begin(), w.vertices.end());
    for (std::int32_t v : w.triangles) tri_v.push_back(base + v);
  }
  std::vector<std::int64_t> trow{0};
  std::vector<std::int32_t> tris;
  for (std::size_t i = 0; i < n; ++i) {
    const phys::Vec3 x{l.bx[i], l.by[i], l.bz[i]};
    for (std::size_t k = 0; k < tri_v.size() / 3; ++k)
      if (phys::near_triangle(x, st.radius[i], kSkin, vpos.data(), tri_v.data() + 3 * k))
        tris.push_back(static_cast<std::int32_t>(k));
    trow.push_back(static_cast<std::int64_t>(tris.size()));
  }
  CHECK(l.triangle_row == trow);
  CHECK(l.triangles == tris);
}

// Tangential springs by pair (i, j); a pair absent from a list has none.
std::map<std::pair<std::int32_t, std::int32_t>, std::array<double, 3>> springs(
    const DemSystem& sys) {
  const DemSystem::PairList l = sys.pair_list();
  std::map<std::pair<std::int32_t, std::int32_t>, std::array<double, 3>> out;
  for (std::size_t i = 0; i + 1 < l.row.size(); ++i)
    for (std::int64_t p = l.row[i]; p < l.row[i + 1]; ++p)
      out[{static_cast<std::int32_t>(i), l.partner[p]}] = {l.spring[3 * p], l.spring[3 * p + 1],
                                                           l.spring[3 * p + 2]};
  return out;
}

}  // namespace

TEST_CASE("The neighbour list holds every pair within the skin at its build, through rebuilds",
          "[dem][gpu][list]") {
  // Reference: all pairs and all triangles tested at the list's build positions (exact: the
  // same comparison as the build, so the sets must be equal). Each backend runs 4 advances of
  // 150 steps and is checked after each; the list must have been rebuilt several times.
  // Springs: the CUDA run's against the CPU run's, pair by pair (a pair missing from one
  // list has a zero spring), within 1e-6 of the largest: both rebuild at their own steps, so
  // only a spring carried across every rebuild agrees (one reset is off by itself).
  const bool rocks = GENERATE(false, true);
  INFO("rocks: " << rocks);
  DemSystem cpu = bed(DemBackendKind::cpu, rocks);
  const bool device = cuda_available();
  if (!device) WARN("the device list is not checked here: no CUDA device (or built without CUDA)");
  std::vector<DemSystem> runs;
  runs.push_back(std::move(cpu));
  if (device) runs.push_back(bed(DemBackendKind::cuda, rocks));
  for (int c = 0; c < 4; ++c)
    for (DemSystem& sys : runs) {
      INFO("backend " << dem_backend_name(sys.settings().backend) << ", advance " << c);
      sys.advance(150);
      check_against_all_pairs(sys);
    }
  for (DemSystem& sys : runs) {
    CHECK(sys.neighbour_rebuilds() >= 5);
    CHECK(sys.max_overlap() > 0.0);  // in contact
  }
  CHECK(runs[0].contact_count() > 3);  // (contact_count() is the CPU backend's)
  if (!device) return;
  const auto a = springs(runs[0]), b = springs(runs[1]);
  double scale = 0.0;
  for (const auto& [key, s] : a)
    scale = std::max({scale, std::abs(s[0]), std::abs(s[1]), std::abs(s[2])});
  REQUIRE(scale > 0.0);
  auto spring_of = [](const auto& m, const auto& key) {
    const auto it = m.find(key);
    return it == m.end() ? std::array<double, 3>{0, 0, 0} : it->second;
  };
  double worst = 0.0;
  for (const auto* m : {&a, &b})
    for (const auto& [key, s] : *m) {
      const auto x = spring_of(a, key), y = spring_of(b, key);
      for (int d = 0; d < 3; ++d) worst = std::max(worst, std::abs(x[d] - y[d]));
    }
  CHECK(worst <= 1e-6 * scale);
  CHECK(max_position_difference(runs[0].particles(), runs[1].particles()) < 1e-9 * 0.005);
}
