// A run that the overlap guard stops (DemRun::check_stable) says where: the deepest contact
// of the state it stopped in (DemSystem::deepest_contact), by particle, its id in the output
// and its centre, and the particle or the walls it touches. The full-scale sleeper bed's
// compaction stopped twice with only "a contact overlapped by 0.503 of its contact radius";
// a diagnostic build was needed to find the column of small rocks over a pressure cell.

#include <catch2/catch.hpp>

#include <fstream>
#include <string>

#include "demfem/dem/run/dem_run.hpp"
#include "demfem/dem/scene/dem_scene.hpp"
#include "demfem_test/box_scene.hpp"
#include "demfem_test/rock_fill.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem::dem;
using demfem::test::TempDir;

namespace {

// The message of the Unstable that advancing `scene` for up to `steps` throws ("" if none).
std::string blow_up(const TempDir& dir, const std::string& scene, std::int64_t steps) {
  const auto path = dir / "scene.toml";
  std::ofstream(path) << scene;
  const auto doc = demfem::scene::Document::load(path);
  const DemScene s = read_dem_scene(doc.root().required_table("dem"));
  DemRun run(s, {}, 1, 0.0, nullptr);
  try {
    for (std::int64_t k = 0; k < steps; ++k) run.advance(1);  // stopped in the contact
  } catch (const Unstable& e) {
    return e.what();
  }
  return "";
}

// A sphere of 2 mm on the floor of BoxScene's box under a plate coming down at 1 m/s: the
// scene's walls and load after the head (its one.csv written into `dir`).
std::string squeezed_sphere(const TempDir& dir) {
  std::ofstream(dir / "one.csv") << "x, y, z, r\n0.02, 0.02, 0.002, 0.002\n";
  return "[[dem.walls]]\nname = \"plate\"\nmaterial = \"steel\"\n"
         "box = { lo = [0.001, 0.001, 0.0045], hi = [0.039, 0.039, 0.006] }\n"
         "motion = { kind = \"translation\", velocity = [0, 0, -1.0] }\n"
         "[dem.load]\nfile = \"one.csv\"\nmaterial = \"wheat\"\n";
}

// The relative overlap the guard's message states ("a contact overlapped by X of"), or -1.
double stated_overlap(const std::string& e) {
  const std::string key = "a contact overlapped by ";
  const auto at = e.find(key);
  return at == std::string::npos ? -1.0 : std::stod(e.substr(at + key.size()));
}

}  // namespace

TEST_CASE("A blow-up names its deepest contact: two particles, or a particle and walls",
          "[dem][guard]") {
  TempDir dir("blow_up_report");
  const std::string head = demfem::test::BoxScene{}.text();
  SECTION("two spheres shot at each other: the pair, by index, id and centre") {
    std::ofstream(dir / "two.csv") << "x, y, z, r, vx, vy, vz\n"
                                   << "0.01, 0.02, 0.05, 0.002, 50, 0, 0\n"
                                   << "0.03, 0.02, 0.05, 0.002, -50, 0, 0\n";
    const std::string e = blow_up(
        dir, head + "[dem.load]\nfile = \"two.csv\"\nmaterial = \"wheat\"\n", 200);
    INFO(e);
    CHECK_THAT(e, Catch::Contains("a contact overlapped by") &&
                      Catch::Contains("the deepest contact after the step") &&
                      Catch::Contains("particle 0 (id 0 in the output) at [") &&
                      Catch::Contains(" and particle 1 (id 1 in the output) at ["));
  }
  SECTION("a sphere squeezed by a plate against the floor: the particle and both walls") {
    const std::string e = blow_up(dir, head + squeezed_sphere(dir), 2000);
    INFO(e);
    CHECK_THAT(e, Catch::Contains("the deepest contact after the step") &&
                      Catch::Contains("particle 0 (id 0 in the output) at [0.02, 0.02, ") &&
                      Catch::Contains("the walls ") && Catch::Contains("'box'") &&
                      Catch::Contains("'plate'"));
  }
  SECTION("rocks crushed by a plate: the deepest contact of dilated polyhedra") {
    const std::string rocks = demfem::test::rock_box("[0.3, 0.3, 0.6]").text() +
                              demfem::test::RandomRockShapes().text() +
                              demfem::test::RockFill("[0.3, 0.3, 0.3]", "30", "3").text() +
                              "[[dem.walls]]\nname = \"plate\"\nmaterial = \"steel\"\n"
                              "box = { lo = [0.005, 0.005, 0.31], hi = [0.295, 0.295, 0.32] }\n"
                              "motion = { kind = \"translation\", velocity = [0, 0, -2.0] }\n";
    const std::string e = blow_up(dir, rocks, 20000);
    INFO(e);
    CHECK_THAT(e, Catch::Contains("the deepest contact after the step") &&
                      Catch::Contains("of its contact radius (") &&
                      Catch::Contains("(id ") && Catch::Contains(" in the output) at ["));
  }
}

TEST_CASE("dem.guard_overlap: the guard stops a squeezed contact at the scene's limit",
          "[dem][guard]") {
  // A sphere of 2 mm squeezed between the floor and a plate coming down at 1 m/s: its overlap
  // grows by up to 0.005 of its radius per step (10 um of plate per 1e-5 s step), so the
  // guard stops the run within a few hundredths past the limit.
  TempDir dir("guard_overlap");
  const std::string plate = squeezed_sphere(dir);
  const std::string head = demfem::test::BoxScene{}.text();
  auto with_guard = [&](const std::string& value) {
    std::string h = head;
    const std::string dt = "[dem]\ndt = 1e-5\n";
    const auto at = h.find(dt);
    REQUIRE(at != std::string::npos);
    if (!value.empty()) h.insert(at + dt.size(), "guard_overlap = " + value + "\n");
    return h + plate;
  };
  SECTION("the default: half of the radius") {
    const std::string e = blow_up(dir, with_guard(""), 3000);
    INFO(e);
    CHECK_THAT(e, Catch::Contains("at most 0.5, "));
    CHECK(stated_overlap(e) >= 0.5);  // past it, stated to six digits
    CHECK(stated_overlap(e) < 0.55);
  }
  SECTION("a lower limit stops it sooner, a higher one later, each just past its limit") {
    for (const double limit : {0.3, 0.8}) {
      const std::string e = blow_up(dir, with_guard(std::to_string(limit)), 6000);
      INFO(limit << ": " << e);
      CHECK_THAT(e, Catch::Contains("key 'dem.guard_overlap'"));
      CHECK(stated_overlap(e) >= limit);
      CHECK(stated_overlap(e) < limit + 0.05);
    }
  }
  SECTION("out of (0, 1]: refused, naming the key") {
    for (const std::string bad : {"0", "1.5", "-0.2"}) {
      const auto path = dir / "bad.toml";
      std::ofstream(path) << with_guard(bad);
      const auto doc = demfem::scene::Document::load(path);
      INFO(bad);
      CHECK_THROWS_WITH(read_dem_scene(doc.root().required_table("dem")),
                        Catch::Contains("dem.guard_overlap"));
    }
  }
}
