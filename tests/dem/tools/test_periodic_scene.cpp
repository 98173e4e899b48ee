// Periodic boundaries in scenes and tools (docs/scene_dem.md, [dem.periodic]): a settled
// periodic bed has no seam (packing sensor), insertion across the seam, [dem.load] tile with
// crop, unwrapped output, and the refusals that name their key.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "../core/dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/placement/insertion.hpp"
#include "demfem/dem/run/dem_run.hpp"
#include "demfem/dem/scene/dem_scene.hpp"
#include "demfem/dem/sensors/packing.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem/scene/scene_reader.hpp"
#include "demfem_test/dem_material_text.hpp"
#include "demfem_test/dem_scene_text.hpp"
#include "demfem_test/error_of.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;
using demfem::scene::Document;
using demfem::scene::SceneError;

namespace {

const std::string kPeriodic = std::string(R"(
[run]
end_time = 0.001

[dem]
dt = 2e-6
threads = 1

[dem.periodic]
x = [0.0, 0.04]
y = [0.0, 0.03]

)") +
    // glass (E, density), steel (E), both pairs: friction, restitution
    demfem::test::grain_and_wall("glass", "1e8", "2500.0", "steel", "1e8", "0.3", "0.5") +
    R"(
[[dem.walls]]
name = "floor"
material = "steel"
plane = { point = [0.02, 0.015, 0.0], normal = [0, 0, 1], size = 1.0 }

[[dem.insert]]
material = "glass"
lo = [0.0, 0.0, 0.0]
hi = [0.04, 0.03, 0.02]
count = 400
seed = 5
distribution = { kind = "uniform", d_min = 0.002, d_max = 0.003 }
)";

DemScene parse(const std::string& text) { return demfem::test::parse_dem_scene(text, "periodic.toml"); }

std::string replace(const std::string& s, const std::string& from, const std::string& to) {
  return demfem::test::replace_first(s, from, to);
}

std::string run_error(const std::string& text) {
  const demfem::test::TempDir tmp("dem_periodic_scene_error");
  return demfem::test::error_of<SceneError>(
      [&] { DemRun run(parse(text), tmp.path / "out", 1, 0.0, nullptr); });
}

}  // namespace

TEST_CASE("[dem.periodic] is read, and what cannot work is refused naming its key",
          "[scene][periodic][badinput]") {
  const DemScene s = parse(kPeriodic);
  CHECK(s.settings.periodic.on == std::array<bool, 3>{true, true, false});
  CHECK(s.settings.periodic.hi[0] == 0.04);
  CHECK(s.periodic_where[1].find("dem.periodic.y") != std::string::npos);
  auto error_of = [](const std::string& text) {
    return demfem::test::error_of<SceneError>([&] { parse(text); });
  };
  CHECK_THAT(error_of(replace(kPeriodic, "x = [0.0, 0.04]", "x = [0.04, 0.0]")),
             Catch::Contains("dem.periodic.x") && Catch::Contains("hi > lo"));
  // both backends run periodic boundaries (the CUDA one: test_dem_cuda_emu, [gpu][periodic])
  CHECK(parse(replace(kPeriodic, "threads = 1", "threads = 1\nbackend = \"cuda\""))
            .settings.periodic.on[0]);
  // a box wall's x faces inside the periodic x range
  CHECK_THAT(error_of(replace(kPeriodic,
                              "plane = { point = [0.02, 0.015, 0.0], normal = [0, 0, 1], size = "
                              "1.0 }",
                              "box = { lo = [0.01, -0.1, 0.0], hi = [0.5, 0.5, 0.1] }")),
             Catch::Contains("box wall 'floor'") && Catch::Contains("normal to x") &&
                 Catch::Contains("dem.periodic.x"));
  // a box reaching beyond both ranges is a floor with faces far outside: accepted
  CHECK_NOTHROW(parse(replace(kPeriodic,
                              "plane = { point = [0.02, 0.015, 0.0], normal = [0, 0, 1], size = "
                              "1.0 }",
                              "box = { lo = [-0.1, -0.1, 0.0], hi = [0.5, 0.5, 0.1] }")));
  // a period shorter than twice the list cutoff: spheres of up to 3 mm, 2 (2 r_max + 0.2 r_max)
  // is up to 6.6 mm; y = 6 mm is refused after the insertion, naming the key
  std::string small = replace(kPeriodic, "y = [0.0, 0.03]", "y = [0.0, 0.006]");
  small = replace(small, "hi = [0.04, 0.03, 0.02]", "hi = [0.04, 0.006, 0.02]");
  small = replace(small, "count = 400", "count = 40");
  CHECK_THAT(run_error(small), Catch::Contains("dem.periodic.y") &&
                                   Catch::Contains("use a range of at least 0.006"));
}

TEST_CASE("Insertion in a periodic region overlaps no image across the seam",
          "[placement][periodic]") {
  const DemScene s = parse(kPeriodic);
  RandomInsertion q = s.inserts[0].request;
  for (int d = 0; d < 3; ++d) {
    q.period[d] = s.settings.periodic.period(d);
    q.period_lo[d] = s.settings.periodic.lo[d];
  }
  const std::vector<ParticleInit> p = insert_random(q);
  REQUIRE(p.size() == 400);
  int across = 0;  // particles lying across a seam
  for (std::size_t i = 0; i < p.size(); ++i) {
    const auto& a = p[i].position;
    across += a[0] < p[i].radius || a[0] > 0.04 - p[i].radius || a[1] < p[i].radius ||
              a[1] > 0.03 - p[i].radius;
    CHECK(a[0] >= 0.0);
    CHECK(a[0] < 0.04);
    for (std::size_t j = i + 1; j < p.size(); ++j) {
      const auto& b = p[j].position;
      double dx = b[0] - a[0], dy = b[1] - a[1];
      dx -= 0.04 * std::round(dx / 0.04);
      dy -= 0.03 * std::round(dy / 0.03);
      const double dz = b[2] - a[2], rs = p[i].radius + p[j].radius;
      REQUIRE(dx * dx + dy * dy + dz * dz >= rs * rs);
    }
  }
  CHECK(across > 20);  // the seam is used (a quarter of the area lies within r of it)
}

TEST_CASE("A settled periodic bed has no seam", "[dem][periodic][bed]") {
  // About 1,800 spheres (r = 1.5 mm +- 20 %) dropped into a box periodic in x and y (60 x
  // 30 mm) onto a floor and settled. The solid fraction and the coordination number of a
  // slab across the seam x = 0 (|x| < 6 mm, counted at its image) are compared with those of
  // the nine interior slabs of the same width (centres 6 .. 54 mm): the seam's values lie
  // within the interior slabs' range widened by half of it on each side (their scatter, of
  // about 0.04 in solid fraction and 0.2 in coordination: the slabs overlap, so the range
  // understates it; a seam without contacts across it would let the particles next to it
  // overlap their images, some 10 % more solid, and lose their contacts across it, far
  // outside this band).
  auto s = two_material_settings(5e6, 0.3, 2500.0, 0.3, 0.5, 2e-5);
  s.gravity = {0, 0, -9.81};
  s.threads = 2;
  s.periodic.on = {true, true, false};
  s.periodic.lo = {0.0, 0.0, 0.0};
  s.periodic.hi = {0.06, 0.03, 0.0};
  DemSystem bed(s);
  bed.add_wall(two_triangle_floor());
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<ParticleInit> p;
  // a lattice whose spacing divides the periods (3.75 mm), so that the start has no seam
  // either; jitter 0.05 mm keeps the largest spheres (3.6 mm) apart
  const double a = 0.00375;
  for (int k = 0; k < 14; ++k)
    for (int j = 0; j < 8; ++j)
      for (int i = 0; i < 16; ++i) {
        const double jit = 0.00005;
        p.push_back(sphere({a * i + jit * u(rng) + 0.001, a * j + jit * u(rng) + 0.001,
                            0.002 + a * k + jit * u(rng)},
                           0.0015 * (1.0 + 0.2 * u(rng)), {0.2 * u(rng), 0.2 * u(rng), 0}));
      }
  bed.add_particles(p);
  bed.advance(20000);  // 0.4 s
  CAPTURE(bed.kinetic_energy());
  REQUIRE(bed.kinetic_energy() < 1e-5);  // settled (the drop released ~0.01 J)
  double top = 0.0;
  for (std::size_t i = 0; i < bed.particle_count(); ++i)
    top = std::max(top, bed.particles().pz[i]);
  const double z0 = 0.006, z1 = top - 0.008, w = 0.006;  // below the loose top, above the floor
  REQUIRE(z1 > z0 + 0.01);
  const PackingResult seam = packing_in_box(bed, {-w, 0.0, z0}, {w, 0.03, z1});
  double phi_lo = 1.0, phi_hi = 0.0, z_lo = 100.0, z_hi = 0.0;
  for (int m = 1; m <= 9; ++m) {
    const double c = 0.006 * m;
    const PackingResult in = packing_in_box(bed, {c - w, 0.0, z0}, {c + w, 0.03, z1});
    phi_lo = std::min(phi_lo, in.solid_fraction), phi_hi = std::max(phi_hi, in.solid_fraction);
    z_lo = std::min(z_lo, in.coordination), z_hi = std::max(z_hi, in.coordination);
  }
  CAPTURE(seam.solid_fraction, phi_lo, phi_hi, seam.coordination, z_lo, z_hi, seam.particles);
  CHECK(seam.particles > 100);
  const double dphi = 0.5 * (phi_hi - phi_lo), dz = 0.5 * (z_hi - z_lo);
  CHECK(seam.solid_fraction >= phi_lo - dphi);
  CHECK(seam.solid_fraction <= phi_hi + dphi);
  CHECK(seam.coordination >= z_lo - dz);
  CHECK(seam.coordination <= z_hi + dz);
  CHECK(z_lo > 3.0);  // a bed, not a gas
}

// kPeriodic's scene without its periods and insertion: a walled box (lo at the origin, `hi`)
// that loads the periodic block saved in `block`, tiled `tile` times and cropped.
static std::string tiled_scene(const std::filesystem::path& block, const std::string& tile,
                               const std::string& hi) {
  std::string text = replace(kPeriodic, "[dem.periodic]\nx = [0.0, 0.04]\ny = [0.0, 0.03]\n", "");
  text = replace(text, "plane = { point = [0.02, 0.015, 0.0], normal = [0, 0, 1], size = 1.0 }",
                 "box = { lo = [0.0, 0.0, 0.0], hi = " + hi + ", open_top = true }");
  const std::string insert = text.substr(text.find("[[dem.insert]]"));
  return replace(text, insert,
                 "[dem.load]\nfile = \"" + block.string() +
                     "\"\nhistory = false\nvelocities = false\ntile = " + tile +
                     "\noutside = \"crop\"\n");
}

TEST_CASE("[dem.load] tile: a periodic block tiled and cropped to a box",
          "[scene][periodic][tile]") {
  const demfem::test::TempDir tmp("dem_periodic_tile_scene");
  // the block: the scene's insertion, a few steps, saved as a state
  std::size_t n = 0;
  {
    DemRun block(parse(kPeriodic), tmp.path / "block", 1, 0.0, nullptr);
    block.system().advance(200);
    n = block.system().particle_count();
    demfem::io::H5File h5(tmp.path / "block.h5", demfem::io::H5File::Mode::create);
    block.system().save(h5, "dem");
  }
  const std::string tiled = tiled_scene(tmp.path / "block.h5", "[2, 2, 1]", "[0.07, 0.05, 0.04]");
  DemRun run(parse(tiled), tmp.path / "tiled", 1, 0.0, nullptr);
  const auto& p = run.system().particles();
  CHECK(p.size() < 4 * n);      // cropped to the box
  CHECK(p.size() > 4 * n / 2);  // 0.07 x 0.05 of 0.08 x 0.06
  for (std::size_t i = 0; i < p.size(); ++i) {
    CHECK(p.px[i] <= 0.07);
    CHECK(p.py[i] <= 0.05);
    CHECK(p.vx[i] == 0.0);
  }
  // tile without a periodic block, or with a CSV: refused naming the key
  const std::string e = demfem::test::error_of<SceneError>(
      [&] { parse(replace(tiled, "tile = [2, 2, 1]", "tile = [2, 2, 2]")); });
  CHECK(e == "(no error)");  // read fine; the engine refuses z (the block is not periodic in z)
  CHECK_THAT(run_error(replace(tiled, "tile = [2, 2, 1]", "tile = [2, 2, 2]")),
             Catch::Contains("dem.load.tile") && Catch::Contains("not periodic"));
  CHECK_THAT(demfem::test::error_of<SceneError>(
                 [&] { parse(replace(tiled, "tile = [2, 2, 1]", "tile = [2, 1.5, 1]")); }),
             Catch::Contains("dem.load.tile") && Catch::Contains("whole numbers"));
}

TEST_CASE("[dem.output] positions = \"unwrapped\" writes x + n L", "[scene][periodic][output]") {
  // The spheres move sideways at 3 and 2 m/s for 4 ms: many cross a seam. The last snapshot
  // holds each particle's wrapped position plus its image counter times the period, exactly
  // (the same sum); the default writes the wrapped positions.
  const demfem::test::TempDir tmp("dem_periodic_unwrapped");
  std::string text = replace(kPeriodic, "count = 400", "count = 400\nvelocity = [3.0, 2.0, 0.0]");
  for (const bool unwrapped : {false, true}) {
    const std::string scene =
        unwrapped ? text + "\n[dem.output]\npositions = \"unwrapped\"\n" : text;
    const auto out = tmp.path / (unwrapped ? "unwrapped" : "wrapped");
    DemRun run(parse(scene), out, 1, 0.0, nullptr);
    run.system().advance(2000);
    run.finish();
    std::filesystem::path last;
    for (const auto& e : std::filesystem::directory_iterator(out))
      if (e.path().extension() == ".h5" && e.path().filename().string().rfind("particles_", 0) == 0)
        last = std::max(last, e.path());
    REQUIRE(!last.empty());
    demfem::io::H5File f(last, demfem::io::H5File::Mode::read);
    const auto x = f.read_doubles("position");
    const auto& p = run.system().particles();
    const auto img = run.system().images();
    REQUIRE(x.size() == 3 * p.size());
    int crossed = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
      crossed += img[3 * i] != 0 || img[3 * i + 1] != 0;
      const double want[3] = {p.px[i] + (unwrapped ? img[3 * i] * 0.04 : 0.0),
                              p.py[i] + (unwrapped ? img[3 * i + 1] * 0.03 : 0.0), p.pz[i]};
      for (int d = 0; d < 3; ++d) REQUIRE(x[3 * i + d] == want[d]);
    }
    CHECK(crossed > 50);
  }
}

TEST_CASE("[dem.load] outside = \"crop\" cuts a block across every seam it had, tiled or not",
          "[scene][periodic][tile]") {
  // The block is periodic in x and y; the bed tiles it twice in x and once in y. A rock
  // across the block's y seam (its centre wrapped inside, its sphere through y = 0 or 0.03)
  // would be cut by the box's side walls at the seam: crop drops it as it drops those the
  // x cut goes through.
  const demfem::test::TempDir tmp("dem_periodic_crop_seam");
  std::size_t across_y = 0;
  {
    DemRun block(parse(kPeriodic), tmp.path / "block", 1, 0.0, nullptr);
    block.system().advance(200);
    const auto& q = block.system().particles();
    for (std::size_t i = 0; i < q.size(); ++i)
      if (q.py[i] - q.radius[i] < 0.0 || q.py[i] + q.radius[i] > 0.03) ++across_y;
    demfem::io::H5File h5(tmp.path / "block.h5", demfem::io::H5File::Mode::create);
    block.system().save(h5, "dem");
  }
  REQUIRE(across_y > 0);  // else the test would prove nothing
  const std::string tiled = tiled_scene(tmp.path / "block.h5", "[2, 1, 1]", "[0.07, 0.03, 0.04]");
  DemRun run(parse(tiled), tmp.path / "tiled", 1, 0.0, nullptr);
  const auto& p = run.system().particles();
  CAPTURE(across_y, p.size());
  REQUIRE(p.size() > 0);
  std::size_t crossing = 0;
  for (std::size_t i = 0; i < p.size(); ++i)
    if (p.py[i] - p.radius[i] < 0.0 || p.py[i] + p.radius[i] > 0.03 ||
        p.px[i] - p.radius[i] < 0.0 || p.px[i] + p.radius[i] > 0.07)
      ++crossing;
  CHECK(crossing == 0);
}
