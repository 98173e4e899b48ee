// Random insertion (non-overlap, target count and mass, determinism, impossible requests),
// lattice fill and removal above a height.

#include <catch2/catch.hpp>

#include <cmath>
#include <string>

#include "demfem/dem/placement/insertion.hpp"

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

TEST_CASE("shortfall = warn: a full region keeps what it placed, and says so", "[insert]") {
  RandomInsertion q = wheat_request();
  q.count = 2400;  // as above: 20 tries per particle cannot place them all
  q.max_attempts = 20;
  q.accept_shortfall = true;
  std::string note;
  const auto a = insert_random(q, nullptr, {}, &note);
  CHECK(a.size() > 100);  // 661 here; the strict request throws after the same placements
  CHECK(a.size() < 2400);
  CHECK(overlaps(a) == 0);
  CHECK_THAT(note, Catch::Contains("cannot insert 2400 particles") &&
                       Catch::Contains("placed only " + std::to_string(a.size()) + " particles") &&
                       Catch::Contains("found no free place in 20 attempts"));
  // A request that fits is the same with or without the option, and leaves no note.
  RandomInsertion fits = wheat_request();
  fits.count = 1000;
  const auto strict = insert_random(fits);
  fits.accept_shortfall = true;
  std::string none;
  const auto lenient = insert_random(fits, nullptr, {}, &none);
  CHECK(none.empty());
  REQUIRE(lenient.size() == strict.size());
  for (std::size_t i = 0; i < strict.size(); ++i) {
    CHECK(lenient[i].position == strict[i].position);
    CHECK(lenient[i].radius == strict[i].radius);
  }
  // The kept ones are the draws before the one that found no place: asking for exactly that
  // many places the same particles.
  RandomInsertion exact = q;
  exact.count = static_cast<std::int64_t>(a.size());
  exact.accept_shortfall = false;
  const auto b = insert_random(exact);
  REQUIRE(b.size() == a.size());
  for (std::size_t i = 0; i < a.size(); ++i) CHECK(a[i].position == b[i].position);
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

namespace {

// Smallest centre distance minus the sum of radii over all pairs (the clearance; < 0 is an
// overlap), and the smallest clearance to the box faces.
double min_pair_clearance(const std::vector<ParticleInit>& p) {
  double c = 1e300;
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t j = i + 1; j < p.size(); ++j) {
      double d2 = 0;
      for (int k = 0; k < 3; ++k) d2 += std::pow(p[i].position[k] - p[j].position[k], 2);
      c = std::min(c, std::sqrt(d2) - p[i].radius - p[j].radius);
    }
  return c;
}

double min_box_clearance(const std::vector<ParticleInit>& p, const Box& b) {
  double c = 1e300;
  for (const auto& q : p)
    for (std::size_t k = 0; k < 3; ++k)
      c = std::min({c, q.position[k] - q.radius - b.lo[k], b.hi[k] - q.position[k] - q.radius});
  return c;
}

}  // namespace

TEST_CASE("a jittered lattice: displaced, deterministic for a seed, no overlaps, inside the box",
          "[insert][lattice]") {
  LatticeFill l;
  l.region = {{0, 0, 0}, {0.095, 0.095, 0.095}};
  l.diameter = 0.01;
  l.spacing = 0.012;  // a gap of 2 mm
  const auto straight = lattice_fill(l);
  l.jitter = 0.9;
  l.seed = 7;
  const auto a = lattice_fill(l);
  REQUIRE(a.size() > 300);
  // Inset by the largest displacement (0.9 x 1 mm): (0.095 - 2 x 5.9 mm) / 12 mm + 1 = 7 sites
  // per axis, one fewer than unjittered ((0.095 - 10 mm) / 12 mm + 1 = 8).
  CHECK(a.size() == 7 * 7 * 7);
  CHECK(straight.size() == 8 * 8 * 8);
  // Every sphere moved, by at most 0.9 x (spacing - d) / 2 per axis, and not all the same way.
  const double site0 = 0.005 + 0.5 * 0.9 * 0.002;
  double largest = 0.0, mean_x = 0.0;
  std::size_t moved = 0;
  for (std::size_t n = 0; n < a.size(); ++n) {
    const std::size_t i = n % 7, j = (n / 7) % 7, k = n / 49;
    const std::array<double, 3> site{site0 + double(i) * 0.012, site0 + double(j) * 0.012,
                                     site0 + double(k) * 0.012};
    double off = 0.0;
    for (std::size_t c = 0; c < 3; ++c) {
      off = std::max(off, std::abs(a[n].position[c] - site[c]));
    }
    largest = std::max(largest, off);
    mean_x += (a[n].position[0] - site[0]) / double(a.size());
    if (off > 1e-6) ++moved;
  }
  CHECK(moved == a.size());
  CHECK(largest <= 0.5 * 0.9 * 0.002 + 1e-15);
  CHECK(largest > 0.8 * 0.5 * 0.9 * 0.002);  // uniform draws come close to the bound
  CHECK(std::abs(mean_x) < 1e-4);            // no drift: symmetric displacements
  CHECK(min_pair_clearance(a) > 0.0);
  CHECK(min_box_clearance(a, l.region) >= -1e-15);
  // Same seed, same bed; another seed, another.
  const auto b = lattice_fill(l);
  REQUIRE(b.size() == a.size());
  for (std::size_t n = 0; n < a.size(); ++n) CHECK(a[n].position == b[n].position);
  l.seed = 8;
  const auto c = lattice_fill(l);
  CHECK(c[0].position != a[0].position);
  // The largest jitter allowed, with touching spheres possible only at the bound (< 1).
  l.jitter = 0.999999;
  CHECK(min_pair_clearance(lattice_fill(l)) > 0.0);
  l.jitter = 1.0;
  CHECK_THROWS_WITH(lattice_fill(l), Catch::Contains("outside [0, 1)"));
}

TEST_CASE("a lattice with a size distribution: each site its own diameter, no overlaps",
          "[insert][lattice]") {
  LatticeFill l;
  l.region = {{0, 0, 0}, {0.1, 0.1, 0.05}};
  l.has_sizes = true;
  l.sizes = SizeDistribution::uniform(0.006, 0.01);
  l.diameter = l.sizes.largest();
  l.spacing = 0.0105;
  l.jitter = 0.8;
  l.seed = 3;
  const auto p = lattice_fill(l);
  REQUIRE(p.size() > 100);
  double rmin = 1, rmax = 0, mean = 0;
  for (const auto& q : p) {
    rmin = std::min(rmin, q.radius);
    rmax = std::max(rmax, q.radius);
    mean += 2 * q.radius / double(p.size());
  }
  CHECK(rmin >= 0.003);
  CHECK(rmax <= 0.005);
  CHECK(rmax - rmin > 0.0015);                // sizes spread over the range
  CHECK(mean == Approx(0.008).margin(3e-4));  // uniform [6, 10] mm: mean 8 mm
  CHECK(min_pair_clearance(p) > 0.0);
  CHECK(min_box_clearance(p, l.region) >= -1e-15);
  const auto again = lattice_fill(l);
  for (std::size_t n = 0; n < p.size(); ++n) {
    CHECK(again[n].radius == p[n].radius);
    CHECK(again[n].position == p[n].position);
  }
}

TEST_CASE("size estimates up front, and a lattice beyond the particle limit is refused",
          "[insert][lattice]") {
  LatticeFill l;
  l.region = {{0, 0, 0}, {0.101, 0.0505, 0.0303}};
  l.diameter = 0.01;
  l.spacing = 0.0101;
  CHECK(lattice_count(l) == 150.0);
  l.max_count = 20;
  CHECK(lattice_count(l) == 20.0);
  l.max_count = 0;
  l.region = {{0, 0, 0}, {100, 100, 100}};
  l.diameter = 1e-4;
  l.spacing = 0.0;
  CHECK(lattice_count(l) > 1e17);  // no overflow: counted in double
  CHECK_THROWS_WITH(lattice_fill(l), Catch::Contains("more than the 2.14748e+09"));
  RandomInsertion q = wheat_request();
  q.mass = 1.0;
  // 1 kg of wheat of mean cube E[d^3] over uniform [3, 5] mm: (5^4 - 3^4) / (4 x 2) mm^3.
  const double mean_mass = 1242.0 * M_PI / 6.0 * (std::pow(5e-3, 4) - std::pow(3e-3, 4)) / 8e-3;
  CHECK(expected_count(q) == std::ceil(1.0 / mean_mass));
}
