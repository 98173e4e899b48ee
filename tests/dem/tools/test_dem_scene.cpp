// The [dem] scene section: a complete scene is read into the right settings, every kind of
// mistake is an error naming file, line and key, and DemRun builds the system (walls from
// STL, insertion, Rayleigh check).

#include <catch2/catch.hpp>

#include <fstream>
#include <sstream>

#include "demfem/dem/dem_scene.hpp"
#include "demfem/dem/stl_reader.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem::dem;
using demfem::scene::Document;
using demfem::scene::SceneError;
using demfem::test::TempDir;

namespace {

const char* kBase = R"(
[run]
end_time = 0.01

[dem]
dt = 2e-6
gravity = [0.0, 0.0, -9.81]
threads = 1

[[dem.materials]]
name = "wheat"
youngs_modulus = 1e8
poisson_ratio = 0.3
density = 1242.0

[[dem.materials]]
name = "steel"
youngs_modulus = 1.85e11
poisson_ratio = 0.3

[[dem.pairs]]
a = "wheat"
b = "wheat"
friction = 0.17
restitution = 0.4

[[dem.pairs]]
a = "wheat"
b = "steel"
friction = 0.22
restitution = 0.4
rolling_friction = 0.01

[[dem.walls]]
name = "floor"
material = "steel"
box = { lo = [0.0, 0.0, 0.0], hi = [0.04, 0.04, 0.08], open_top = true }

[[dem.insert]]
material = "wheat"
lo = [0.0, 0.0, 0.0]
hi = [0.04, 0.04, 0.08]
count = 200
seed = 3
distribution = { kind = "uniform", d_min = 0.003, d_max = 0.005 }

[[dem.sensors]]
name = "floor_force"
kind = "wall_force"
wall = "floor"
interval = 0.001

[[dem.sensors]]
name = "outflow"
kind = "mass_flow"
point = [0.0, 0.0, 0.01]
interval = 0.002

[dem.output]
interval = 0.005
)";

DemScene parse(const std::string& text, const std::string& name = "scene.toml") {
  Document d = Document::parse(text, name);
  demfem::scene::read_run_settings(d);
  return read_dem_scene(d.root().required_table("dem"));
}

std::string error_of(const std::string& text) {
  try {
    parse(text);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "(no error)";
}

std::string replace(std::string s, const std::string& from, const std::string& to) {
  const auto p = s.find(from);
  REQUIRE(p != std::string::npos);
  return s.replace(p, from.size(), to);
}

/// Line (1-based) of the first occurrence of `what` in kBase after `replace`.
int line_of(const std::string& text, const std::string& what) {
  const auto p = text.find(what);
  return 1 + int(std::count(text.begin(), text.begin() + long(p), '\n'));
}

}  // namespace

TEST_CASE("a complete [dem] section is read into the settings", "[scene]") {
  const DemScene s = parse(kBase);
  CHECK(s.settings.dt == 2e-6);
  CHECK(s.settings.threads == 1);
  CHECK(s.settings.backend == "cpu");
  REQUIRE(s.settings.materials.size() == 2);
  CHECK(s.settings.materials[1].density == 0.0);
  REQUIRE(s.settings.pairs.size() == 4);
  CHECK(s.settings.pairs[1].friction == 0.22);  // wheat-steel, symmetric
  CHECK(s.settings.pairs[2].friction == 0.22);
  CHECK(s.settings.pairs[2].rolling_friction == 0.01);
  CHECK(s.settings.pairs[3].restitution == 0.5);  // steel-steel never meet: default
  REQUIRE(s.walls.size() == 1);
  CHECK(s.walls[0].kind == WallSpec::Kind::box);
  CHECK(s.walls[0].open_top);
  CHECK(s.walls[0].material == 1);
  REQUIRE(s.inserts.size() == 1);
  CHECK(s.inserts[0].request.count == 200);
  CHECK(s.inserts[0].request.density == 1242.0);
  CHECK(s.inserts[0].request.sizes.kind == SizeDistribution::Kind::uniform);
  REQUIRE(s.sensors.size() == 2);
  CHECK(s.sensors[0].wall == 0);
  CHECK(s.sensors[1].direction == std::array<double, 3>{0, 0, -1});
  CHECK(*s.output_interval == 0.005);
  CHECK(s.settings.list_skin == 0.0);  // adaptive unless given
  CHECK(parse(replace(kBase, "threads = 1", "threads = 1\nlist_skin = 1.0")).settings.list_skin ==
        1.0);
}

TEST_CASE("[dem] mistakes are errors naming file, line and key", "[scene]") {
  struct Case {
    std::string from, to, expect;
  };
  const std::vector<Case> cases = {
      {"dt = 2e-6", "dt = -1.0", "key 'dem.dt': is -1, outside the accepted range > 0"},
      {"threads = 1", "threds = 1", "key 'dem.threds': is not a known key"},
      {"threads = 1", "threads = 1\nlist_skin = 1.5",
       "key 'dem.list_skin': is 1.5, outside the accepted range [0, 1]"},
      {"poisson_ratio = 0.3\ndensity", "poisson_ratio = 0.5\ndensity",
       "key 'dem.materials[0].poisson_ratio': is 0.5, outside the accepted range [0, 0.5)"},
      {"b = \"steel\"", "b = \"stel\"",
       "key 'dem.pairs[1].b': names material \"stel\", which [[dem.materials]] does not define"},
      {"friction = 0.22\nrestitution = 0.4", "friction = 0.22\nrestitution = 0.0",
       "key 'dem.pairs[1].restitution': is 0, outside the accepted range (0, 1]"},
      {"count = 200", "count = 200\nmass = 1.0", "key 'dem.insert[0].count': give exactly one"},
      {"d_max = 0.005", "d_max = 0.002",
       "key 'dem.insert[0].distribution.d_max': must be >= d_min"},
      {"kind = \"uniform\"", "kind = \"weibull\"",
       "key 'dem.insert[0].distribution.kind': is \"weibull\", accepted: \"constant\""},
      {"wall = \"floor\"", "wall = \"roof\"", "key 'dem.sensors[0].wall': names wall \"roof\""},
      {"open_top = true", "open_top = true, opne = 1", "key 'dem.walls[0].box.opne'"},
      {"hi = [0.04, 0.04, 0.08], open", "hi = [0.04, 0.0, 0.08], open",
       "key 'dem.walls[0].box.hi': must be greater than 'lo'"},
      {"interval = 0.005", "interval = -0.005", "key 'dem.output.interval'"},
      {"kind = \"mass_flow\"", "kind = \"mass_flux\"", "key 'dem.sensors[1].kind'"},
  };
  for (const auto& c : cases) {
    const std::string text = replace(kBase, c.from, c.to);
    INFO("replacing '" << c.from << "' by '" << c.to << "'");
    const std::string msg = error_of(text);
    CHECK_THAT(msg, Catch::Contains(c.expect));
    // The file and the line of the offending key (or of its table) come first.
    CHECK_THAT(msg, Catch::StartsWith("scene.toml:"));
  }
  // Line numbers: the misspelt key's own line.
  const std::string text = replace(kBase, "threads = 1", "threds = 1");
  CHECK_THAT(error_of(text),
             Catch::StartsWith("scene.toml:" + std::to_string(line_of(text, "threds")) + ":"));
  // A pair that particles need but nobody gave.
  const std::string no_pair =
      replace(kBase, "a = \"wheat\"\nb = \"steel\"", "a = \"steel\"\nb = \"steel\"");
  CHECK_THAT(error_of(no_pair),
             Catch::Contains(
                 "key 'dem.pairs': no [[dem.pairs]] entry for materials \"wheat\" and \"steel\""));
  // A particle material without density.
  const std::string no_density = replace(kBase, "density = 1242.0\n", "");
  CHECK_THAT(error_of(no_density),
             Catch::Contains("key 'dem.insert[0].material': material \"wheat\" is used for "
                             "particles but has no density"));
}

TEST_CASE("a repeated insertion pours batches at its times", "[scene]") {
  TempDir dir;
  std::string text =
      replace(kBase, "count = 200\nseed = 3", "count = 10\nseed = 3\nevery = 0.001\nuntil = 0.004");
  const DemScene s = parse(text);
  CHECK(s.inserts[0].every == 0.001);
  DemRun run(s, "", 1, 0.0, nullptr);
  CHECK(run.system().particle_count() == 10);
  run.run_to(0.0025);
  CHECK(run.system().particle_count() == 30);  // t = 0, 1, 2 ms
  run.run_to(0.006);
  CHECK(run.system().particle_count() == 50);  // and 3, 4 ms; none after 'until'
  // Ids stay unique and increasing.
  const auto ids = run.ids();
  for (std::size_t i = 1; i < ids.size(); ++i) CHECK(ids[i] > ids[i - 1]);
  CHECK_THAT(error_of(replace(kBase, "count = 200", "count = 200\nuntil = 1.0")),
             Catch::Contains("key 'dem.insert[0].until': needs 'every'"));
}

TEST_CASE("DemRun builds walls from STL, inserts, and checks dt against Rayleigh", "[scene]") {
  TempDir dir;
  write_stl_binary(dir / "floor.stl", make_plane_mesh({0.02, 0.02, 0.0}, {0, 0, 1}, 0.2));
  std::string text =
      replace(kBase, "box = { lo = [0.0, 0.0, 0.0], hi = [0.04, 0.04, 0.08], open_top = true }",
              "stl = \"floor.stl\"");
  {
    std::ofstream(dir / "scene.toml") << text;
    Document d = Document::load(dir / "scene.toml");
    const DemScene s = read_dem_scene(d.root().required_table("dem"));
    std::ostringstream log;
    DemRun run(s, dir / "out", 1, 0.0, &log);
    CHECK(run.system().particle_count() == 200);
    CHECK(run.system().wall_count() == 1);
    CHECK(run.ids().size() == 200);
    // Rayleigh time of the 1.5 mm radius, E = 1e8, nu = 0.3, rho = 1242: (pi R / (0.1631 nu +
    // 0.8766)) sqrt(rho / G), G = E / 2.6, = 2.89e-5 s; dt = 2e-6 is 0.07 of it, no warning.
    CHECK_THAT(log.str(), Catch::Contains("Rayleigh time step"));
    CHECK_THAT(log.str(), !Catch::Contains("warning"));
    run.run_to(0.004);
    CHECK(run.system().time() == Approx(0.004));
    CHECK(std::filesystem::exists(dir / "out" / "sensor_floor_force.csv"));
    CHECK(std::filesystem::exists(dir / "out" / "particles.xdmf"));
  }
  SECTION("dt above the Rayleigh time is an error naming dem.dt") {
    std::ofstream(dir / "scene.toml") << replace(text, "dt = 2e-6", "dt = 5e-5");
    Document d = Document::load(dir / "scene.toml");
    const DemScene s = read_dem_scene(d.root().required_table("dem"));
    CHECK_THROWS_WITH(
        DemRun(s, "", 1, 0.0, nullptr),
        Catch::Contains("scene.toml:" + std::to_string(line_of(text, "dt =")) + ":") &&
            Catch::Contains("key 'dem.dt'") && Catch::Contains("exceeds the Rayleigh time step"));
  }
  SECTION("a run whose spheres pass through the floor stops, naming the overlap and dem.dt") {
    // 150 m/s downwards and dt = 1e-5 s: 1.5 mm per step against radii of 1.5-2.5 mm, so a
    // sphere's first contact step puts it up to 1.5 mm into the floor; many of the 200 land
    // beyond half the smallest radius (0.75 mm), which the soft-sphere contact cannot resolve.
    std::string fast = replace(text, "dt = 2e-6", "dt = 1e-5");
    fast = replace(fast, "count = 200", "count = 200\nvelocity = [0.0, 0.0, -150.0]");
    std::ofstream(dir / "scene.toml") << fast;
    Document d = Document::load(dir / "scene.toml");
    DemRun run(read_dem_scene(d.root().required_table("dem")), dir / "fast", 1, 0.0, nullptr);
    CHECK_THROWS_WITH(run.run_to(0.004), Catch::Contains("DEM run unstable") &&
                                             Catch::Contains("of the smallest radius") &&
                                             Catch::Contains("key 'dem.dt'") &&
                                             Catch::Contains("Rayleigh time step"));
  }
  SECTION("dt above 0.2 of it warns") {
    std::ofstream(dir / "scene.toml") << replace(text, "dt = 2e-6", "dt = 1e-5");
    Document d = Document::load(dir / "scene.toml");
    std::ostringstream log;
    DemRun run(read_dem_scene(d.root().required_table("dem")), "", 1, 0.0, &log);
    CHECK_THAT(log.str(), Catch::Contains("warning") && Catch::Contains("key 'dem.dt'"));
  }
  SECTION("an unavailable CUDA backend names dem.backend") {
    if (!cuda_available()) {
      std::ofstream(dir / "scene.toml")
          << replace(text, "threads = 1", "threads = 1\nbackend = \"cuda\"");
      Document d = Document::load(dir / "scene.toml");
      const DemScene s = read_dem_scene(d.root().required_table("dem"));
      CHECK_THROWS_WITH(DemRun(s, "", 1, 0.0, nullptr),
                        Catch::Contains("key 'dem.backend'") && Catch::Contains("cuda"));
    }
  }
  SECTION("a bad STL names the scene key and the STL problem") {
    std::ofstream(dir / "floor.stl") << "solid x\nfacet normal 0 0 1\n";
    std::ofstream(dir / "scene.toml") << text;
    Document d = Document::load(dir / "scene.toml");
    const DemScene s = read_dem_scene(d.root().required_table("dem"));
    CHECK_THROWS_WITH(DemRun(s, "", 1, 0.0, nullptr),
                      Catch::Contains("key 'dem.walls[0].stl'") &&
                          Catch::Contains("floor.stl:2: ends inside a solid"));
  }
  SECTION("an impossible insertion names the scene entry") {
    std::ofstream(dir / "scene.toml") << replace(text, "count = 200", "count = 20000");
    Document d = Document::load(dir / "scene.toml");
    const DemScene s = read_dem_scene(d.root().required_table("dem"));
    CHECK_THROWS_WITH(DemRun(s, "", 1, 0.0, nullptr),
                      Catch::Contains("key 'dem.insert[0].lo'") &&
                          Catch::Contains("cannot insert 20000 particles"));
  }
}
