// [[dem.pack]] and packed_fill(): particles drawn as an insertion draws them, packed by their
// bounding spheres in rows and layers; its count, containment, overlaps, bits per seed, bad
// input naming file, line and key, and a packed rock layer settling as a poured one does.

#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <sstream>

#include "demfem/dem/placement/packed_fill.hpp"
#include "demfem/dem/run/dem_run.hpp"
#include "demfem/dem/sensors/packing.hpp"
#include "demfem_test/box_scene.hpp"
#include "demfem_test/dem_scene_text.hpp"
#include "demfem_test/error_of.hpp"
#include "demfem_test/rock_fill.hpp"

using namespace demfem::dem;
using demfem::scene::Document;
using demfem::scene::SceneError;

namespace {

PackedFill ballast_spheres(std::int64_t count) {
  PackedFill q;
  q.region.lo = {0.1, -0.2, 0.05};
  q.region.hi = {0.5, 0.1, 1.0};
  q.sizes = SizeDistribution::normal(0.04, 0.01, 0.02, 0.08);
  q.count = count;
  q.seed = 7;
  return q;
}

// The first pair of bounding spheres that overlap (by more than 1e-12 m), or "none".
std::string first_overlap(const std::vector<ParticleInit>& p) {
  for (std::size_t i = 0; i < p.size(); ++i) {
    for (std::size_t j = i + 1; j < p.size(); ++j) {
      double d2 = 0.0;
      for (int k = 0; k < 3; ++k) d2 += std::pow(p[i].position[k] - p[j].position[k], 2);
      if (std::sqrt(d2) < p[i].radius + p[j].radius - 1e-12)
        return std::to_string(i) + " and " + std::to_string(j);
    }
  }
  return "none";
}

// Six random rocks of 10 triangles, sieve-sized, dilated by 10 % of their size.
const std::string kBallastShapes = demfem::test::sieved_rocks("0.8").text();

// A [[dem.pack]] of the rocks in [0, 0, 0] .. `hi`, seeded from run.seed.
demfem::test::RockFill packed_rocks(std::string hi, std::string count) {
  demfem::test::RockFill f(std::move(hi), std::move(count));
  f.table = "dem.pack";
  return f;
}

const std::string kPackedRocks = demfem::test::rock_box("[0.5, 0.5, 1.0]").text() +
                                 kBallastShapes + packed_rocks("[0.5, 0.5, 1.0]", "200").text();

std::string replace(const std::string& s, const std::string& from, const std::string& to) {
  return demfem::test::replace_first(s, from, to);
}

using demfem::test::line_of;

DemScene parse(const std::string& text) { return demfem::test::parse_dem_scene(text, "pack.toml"); }

std::string error_of(const std::string& text) {
  return demfem::test::error_of<SceneError>(
      [&] {
        const DemScene s = parse(text);
        DemRun run(s, "", 11, 0.0, nullptr);
      },
      "(no error)");
}

}  // namespace

TEST_CASE("packed_fill: the count, inside the region, no overlaps, the same bits per seed",
          "[placement][pack]") {
  const PackedFill q = ballast_spheres(400);
  const PackedBed bed = packed_fill(q);
  REQUIRE(bed.particles.size() == 400);
  for (const auto& p : bed.particles) {
    for (int k = 0; k < 3; ++k) {
      // the region's offset is added last: a rounding of 1e-17 m either way
      CHECK(p.position[k] - p.radius >= q.region.lo[k] - 1e-12);
      CHECK(p.position[k] + p.radius <= q.region.hi[k] + 1e-12);
    }
    CHECK(p.radius >= 0.01);  // spheres: the drawn diameter in [20, 80] mm
    CHECK(p.radius <= 0.04);
  }
  CHECK(first_overlap(bed.particles) == "none");
  CHECK(bed.particles.front().radius >= bed.particles.back().radius);  // largest first
  // the layers are as tall as the particles need: the highest top is the packed height
  double top = 0.0;
  for (const auto& p : bed.particles) top = std::max(top, p.position[2] + p.radius);
  CHECK(top - q.region.lo[2] <= bed.height);
  CHECK(top - q.region.lo[2] > bed.height - 0.08);
  // rows and layers of polydisperse spheres: more than random insertion's 0.38, less than a
  // simple cubic lattice of equal spheres (pi / 6)
  CHECK(bed.bounding_fraction > 0.40);
  CHECK(bed.bounding_fraction < M_PI / 6);
  const PackedBed again = packed_fill(q);
  bool same = true;
  for (std::size_t i = 0; i < bed.particles.size(); ++i)
    same = same && bed.particles[i].position == again.particles[i].position &&
           bed.particles[i].radius == again.particles[i].radius;
  CHECK(same);
  PackedFill other = q;
  other.seed = 8;
  CHECK(packed_fill(other).particles[0].radius != bed.particles[0].radius);
  SECTION("mixed: the same rows in the order drawn, every depth holding every size") {
    PackedFill m = q;
    m.method = PackedFill::Method::mixed;
    const PackedBed mixed = packed_fill(m);
    REQUIRE(mixed.particles.size() == 400);
    CHECK(first_overlap(mixed.particles) == "none");
    for (const auto& p : mixed.particles) {
      for (int k = 0; k < 3; ++k) {
        CHECK(p.position[k] - p.radius >= m.region.lo[k] - 1e-12);
        CHECK(p.position[k] + p.radius <= m.region.hi[k] + 1e-12);
      }
    }
    // the lower and the upper half hold about the same mean size (rows: graded)
    auto mean_radius = [](const std::vector<ParticleInit>& p, std::size_t a, std::size_t b) {
      double sum = 0.0;
      for (std::size_t i = a; i < b; ++i) sum += p[i].radius;
      return sum / double(b - a);
    };
    const double low = mean_radius(mixed.particles, 0, 200);
    const double high = mean_radius(mixed.particles, 200, 400);
    CHECK(std::abs(low - high) < 0.1 * low);
    CHECK(mean_radius(bed.particles, 0, 200) > 1.2 * mean_radius(bed.particles, 200, 400));
    CHECK(mixed.bounding_fraction < bed.bounding_fraction);
    CHECK(mixed.bounding_fraction > 0.2);
    // layers: graded within runs of about a layer only, between mixed and rows in density
    m.method = PackedFill::Method::layers;
    const PackedBed layers = packed_fill(m);
    REQUIRE(layers.particles.size() == 400);
    CHECK(first_overlap(layers.particles) == "none");
    CHECK(std::abs(mean_radius(layers.particles, 0, 200) -
                   mean_radius(layers.particles, 200, 400)) < 0.1 * low);
    CHECK(layers.bounding_fraction > mixed.bounding_fraction);
    CHECK(layers.bounding_fraction < bed.bounding_fraction);
  }
}

TEST_CASE("packed_fill: a count the region cannot hold is refused, naming what fits",
          "[placement][pack]") {
  PackedFill q = ballast_spheres(400);
  q.region.hi[2] = 0.2;
  const std::string m = demfem::test::error_of<InsertionError>([&] { packed_fill(q); });
  CHECK_THAT(m, Catch::Contains("cannot pack 400 particles"));
  CHECK_THAT(m, Catch::Contains("fit (raise hi z or lower the count)"));
  q = ballast_spheres(10);
  q.region.hi[1] = q.region.lo[1] + 0.05;  // narrower than the largest sphere
  CHECK_THAT(demfem::test::error_of<InsertionError>([&] { packed_fill(q); }),
             Catch::Contains("exceeds the region"));
  q = ballast_spheres(0);
  CHECK_THAT(demfem::test::error_of<InsertionError>([&] { packed_fill(q); }),
             Catch::Contains("count > 0"));
}

TEST_CASE("[[dem.pack]]: rocks packed in a box, seeded from run.seed", "[scene][pack]") {
  const DemScene s = parse(kPackedRocks);
  REQUIRE(s.packs.size() == 1);
  CHECK(s.packs[0].shape == 0);
  CHECK(s.packs[0].request.gap_factor == 1.001);
  CHECK(s.packs[0].request.method == PackedFill::Method::mixed);
  std::ostringstream log;
  DemRun run(s, "", 11, 0.0, &log);
  const auto& p = run.system().particles();
  REQUIRE(p.size() == 200);
  for (std::size_t i = 0; i < p.size(); ++i) {
    CHECK(p.shape[i] == static_cast<std::uint8_t>(ParticleShape::polyhedron));
    CHECK(p.px[i] - p.radius[i] >= 0.0);
    CHECK(p.px[i] + p.radius[i] <= 0.5);
    CHECK(p.pz[i] - p.radius[i] >= 0.0);
  }
  CHECK(p.qw[0] != p.qw[1]);  // random orientations
  CHECK_THAT(log.str(), Catch::Contains("bounding-sphere fraction"));
  DemRun same(s, "", 11, 0.0, nullptr);
  DemRun other(s, "", 12, 0.0, nullptr);
  CHECK(same.system().particles().px == p.px);
  CHECK(same.system().particles().qx == p.qx);
  CHECK(other.system().particles().qx != p.qx);
}

TEST_CASE("[[dem.pack]]: bad input names file, line, key and the accepted range", "[scene][pack]") {
  const int pack_line = line_of(kPackedRocks, "count = 200");
  const std::string at = "pack.toml:" + std::to_string(pack_line);
  SECTION("gap factor out of range") {
    const auto t = replace(kPackedRocks, "count = 200", "count = 200\ngap_factor = 0.9");
    const auto m = error_of(t);
    CHECK_THAT(m, Catch::Contains("dem.pack[0].gap_factor"));
    CHECK_THAT(m, Catch::Contains("[1, 2]"));
  }
  SECTION("an unknown method") {
    const auto t = replace(kPackedRocks, "count = 200", "count = 200\nmethod = \"hex\"");
    CHECK_THAT(error_of(t), Catch::Contains("dem.pack[0].method"));
  }
  SECTION("a count of 0") {
    CHECK_THAT(error_of(replace(kPackedRocks, "count = 200", "count = 0")),
               Catch::Contains("dem.pack[0].count"));
  }
  SECTION("more rocks than the region holds") {
    const auto t =
        replace(kPackedRocks, "hi = [0.5, 0.5, 1.0]\ncount", "hi = [0.5, 0.5, 0.1]\ncount");
    const auto m = error_of(t);
    CHECK_THAT(m, Catch::Contains(at));
    CHECK_THAT(m, Catch::Contains("dem.pack[0].count"));
    CHECK_THAT(m, Catch::Contains("cannot pack 200 particles"));
  }
  SECTION("a region through a wall") {
    const auto t = replace(kPackedRocks, "lo = [0.0, 0.0, 0.0]\nhi = [0.5",
                           "lo = [-0.05, 0.0, 0.0]\nhi = [0.5");
    const auto m = error_of(t);
    CHECK_THAT(m, Catch::Contains(at));
    CHECK_THAT(m, Catch::Contains("overlaps wall 'box'"));
  }
  SECTION("a region over an earlier pack") {
    const auto pack = kPackedRocks.substr(kPackedRocks.find("[[dem.pack]]"));
    const auto m = error_of(kPackedRocks + "\n" + pack);
    CHECK_THAT(m, Catch::Contains("dem.pack[1].count"));
    CHECK_THAT(m, Catch::Contains("regions must not overlap"));
  }
  SECTION("a region beside the walls") {
    auto t = replace(kPackedRocks, "lo = [0.0, 0.0, 0.0]\nhi = [0.5, 0.5, 1.0]",
                     "lo = [1.0, 0.0, 0.0]\nhi = [1.5, 0.5, 1.0]");
    CHECK_THAT(error_of(t), Catch::Contains("would fall for ever"));
  }
}

namespace {

struct Settled {
  double time;            ///< s of simulated time until the kinetic energy fell below the bar
  PackingResult packing;  ///< in a control box away from the walls and the top
};

// Runs the scene in pieces of 0.05 s until its kinetic energy is below 1e-3 of N m g d (the
// benches' settled bar: each rock's energy that of lifting it 1/1000 of its size), at most
// to `limit`; then measures the packing away from the side walls, the floor and the top.
Settled settle(const std::string& text, double limit) {
  const DemScene s = parse(text);
  DemRun run(s, "", 11, 0.0, nullptr);
  const auto& p = run.system().particles();
  double mass = 0.0;
  for (const double m : p.mass) mass += m;
  const double bar = 1e-3 * mass * 9.81 * 0.04;
  double t = 0.0;
  do {
    t += 0.05;
    run.run_to(t);
  } while (run.system().kinetic_energy() > bar && t < limit);
  const double top = packing_in_box(run.system(), {0, 0, 0}, {0.3, 0.3, 2.0}).top;
  return {t, packing_in_box(run.system(), {0.05, 0.05, 0.02}, {0.25, 0.25, top - 0.05})};
}

}  // namespace

TEST_CASE("[[dem.pack]]: a packed rock layer settles sooner, as dense as a poured one",
          "[scene][pack][settle]") {
  // 150 rocks of the thesis's sizes (up to 60 mm here) in a 0.3 x 0.3 m box:
  // poured from random insertion up to 1.5 m (as the sleeper chain inserts), and packed.
  // E 1 GPa: at 100 MPa rocks landing from 1.5 m overlap by more than half their dilation
  auto box = demfem::test::rock_box("[0.3, 0.3, 1.6]");
  box.grain_youngs = "1e9";
  std::string base = replace(box.text(), "dt = 1e-5", "dt = 2e-5");  // 0.2 of Rayleigh's
  base += kBallastShapes;
  const Settled poured =
      settle(base + demfem::test::RockFill("[0.3, 0.3, 1.5]", "150").text(), 3.0);
  demfem::test::RockFill rows = packed_rocks("[0.3, 0.3, 1.5]", "150");
  rows.extra = "method = \"rows\"\n";
  const Settled packed = settle(base + rows.text(), 3.0);
  INFO("poured: settled at " << poured.time << " s, solid fraction "
                             << poured.packing.solid_fraction << ", coordination "
                             << poured.packing.coordination << ", top " << poured.packing.top
                             << " m, " << poured.packing.particles << " rocks measured");
  INFO("packed: settled at " << packed.time << " s, solid fraction "
                             << packed.packing.solid_fraction << ", coordination "
                             << packed.packing.coordination << ", top " << packed.packing.top
                             << " m, " << packed.packing.particles << " rocks measured");
  // Measured: poured settled at 0.8 s, solid fraction 0.553, coordination 4.47; packed at
  // 0.7 s, 0.540, 4.38 (59 and 66 rocks in the control box). The tolerances are the poured
  // layer's own scatter in a control box of about 60 rocks: the same pour at dt = 1e-5 s
  // (other bits) gave 0.584 and 4.53. The box is too narrow for "mixed" (rows sized for
  // the largest rock start it 1 m high; docs/reports/cases_history.md measures it on 400).
  CHECK(packed.time < 3.0);
  CHECK(packed.time < poured.time);
  CHECK(std::abs(packed.packing.solid_fraction - poured.packing.solid_fraction) < 0.05);
  CHECK(std::abs(packed.packing.coordination - poured.packing.coordination) < 0.5);
  CHECK(packed.packing.particles > 40);  // the control box holds a bed, not a few rocks
}
