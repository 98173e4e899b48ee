// Random insertion (non-overlap, target count and mass, determinism, impossible requests),
// lattice fill and removal above a height.

#include <catch2/catch.hpp>

#include <cmath>

#include "demfem/dem/insertion.hpp"

using namespace demfem::dem;

namespace {

std::size_t overlaps(const std::vector<ParticleInit>& p) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t j = i + 1; j < p.size(); ++j) {
      double d2 = 0;
      for (int k = 0; k < 3; ++k) d2 += std::pow(p[i].position[k] - p[j].position[k], 2);
      if (d2 < std::pow(p[i].radius + p[j].radius, 2)) ++n;
    }
  return n;
}

RandomInsertion wheat_request() {
  RandomInsertion q;
  q.region = {{0, 0, 0}, {0.05, 0.05, 0.1}};
  q.sizes = SizeDistribution::uniform(0.003, 0.005);
  q.density = 1242.0;
  q.seed = 5;
  q.velocity = {0, 0, -1};
  return q;
}

}  // namespace

TEST_CASE("random insertion by count: inside the box, no overlaps, deterministic", "[insert]") {
  RandomInsertion q = wheat_request();
  q.count = 1000;  // solid fraction 0.14
  const auto a = insert_random(q);
  REQUIRE(a.size() == 1000);
  CHECK(overlaps(a) == 0);  // brute-force O(n^2) check, independent of the grid
  for (const auto& p : a) {
    for (int k = 0; k < 3; ++k) {
      CHECK(p.position[k] - p.radius >= q.region.lo[k]);
      CHECK(p.position[k] + p.radius <= q.region.hi[k]);
    }
    CHECK(p.velocity[2] == -1.0);
  }
  const auto b = insert_random(q);
  REQUIRE(b.size() == a.size());
  for (std::size_t i = 0; i < a.size(); ++i) CHECK(a[i].position == b[i].position);
}

TEST_CASE("random insertion by mass reaches the target and avoids existing particles", "[insert]") {
  RandomInsertion q = wheat_request();
  q.mass = 0.05;  // kg, about 1100 particles, solid fraction 0.16
  // Existing particles: a lattice in the lower part of the same box.
  LatticeFill l;
  l.region = {{0, 0, 0}, {0.05, 0.05, 0.02}};
  l.diameter = 0.004;
  const auto lat = lattice_fill(l);
  ParticleState st;
  for (const auto& p : lat) {
    st.px.push_back(p.position[0]);
    st.py.push_back(p.position[1]);
    st.pz.push_back(p.position[2]);
    st.radius.push_back(p.radius);
  }
  const auto ins = insert_random(q, &st);
  double m = 0;
  for (const auto& p : ins) m += sphere_mass(2 * p.radius, q.density);
  // Stops as soon as the target is reached: over by less than one largest particle.
  CHECK(m >= 0.05);
  CHECK(m < 0.05 + sphere_mass(0.005, q.density));
  std::vector<ParticleInit> all = lat;
  all.insert(all.end(), ins.begin(), ins.end());
  CHECK(overlaps(all) == 0);
}

TEST_CASE("impossible insertions name what was asked and what was achieved", "[insert]") {
  RandomInsertion q = wheat_request();
  SECTION("packing fraction out of reach") {
    q.mass = 0.4;  // solid volume 3.2e-4 m^3 in 2.5e-4 m^3
    CHECK_THROWS_WITH(insert_random(q), Catch::Contains("cannot insert 0.4 kg") &&
                                            Catch::Contains("solid fraction of about 1.2") &&
                                            Catch::Contains("0.4 that random"));
  }
  SECTION("attempts exhausted") {
    q.count = 2400;  // solid fraction 0.34: below the up-front limit, beyond what 20 tries reach
    q.max_attempts = 20;
    CHECK_THROWS_WITH(insert_random(q), Catch::Contains("cannot insert 2400 particles") &&
                                            Catch::Contains("placed only") &&
                                            Catch::Contains("found no free place in 20 attempts"));
  }
  SECTION("region narrower than a particle") {
    q.region.hi[0] = 0.004;
    q.count = 1;
    CHECK_THROWS_WITH(insert_random(q), Catch::Contains("narrower than the largest diameter"));
  }
}

TEST_CASE("lattice fill and removal above a height", "[insert]") {
  LatticeFill l;
  l.region = {{0, 0, 0}, {0.101, 0.0505, 0.0303}};
  l.diameter = 0.01;
  l.spacing = 0.0101;
  const auto p = lattice_fill(l);
  // 10 x 5 x 3 sites: (extent - diameter) / spacing + 1 per axis.
  REQUIRE(p.size() == 150);
  CHECK(overlaps(p) == 0);
  CHECK(p.front().position == std::array<double, 3>{0.005, 0.005, 0.005});
  ParticleState st;
  for (const auto& q : p) {
    st.px.push_back(q.position[0]);
    st.pz.push_back(q.position[2]);
  }
  const auto keep = keep_at_or_below(st, 0.02);
  CHECK(std::count(keep.begin(), keep.end(), 1) == 100);  // the layers at z = 0.005, 0.0151
  l.diameter = 0.2;
  l.spacing = 0.0;
  CHECK_THROWS_WITH(lattice_fill(l), Catch::Contains("not one sphere fits"));
}
