// The [dem] scene section: a complete scene is read into the right settings, every kind of
// mistake is an error naming file, line and key, and DemRun builds the system (walls from
// STL, insertion, Rayleigh check).

#include <catch2/catch.hpp>

#include <fstream>
#include <sstream>

#include "demfem/dem/run/dem_run.hpp"
#include "demfem/dem/shapes/geometry/stl_reader.hpp"
#include "demfem_test/dem_material_text.hpp"
#include "demfem_test/dem_scene_text.hpp"
#include "demfem_test/error_of.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem::dem;
using demfem::scene::Document;
using demfem::scene::SceneError;
using demfem::test::TempDir;

namespace {

const std::string kBase = std::string(R"(
[run]
end_time = 0.01

[dem]
dt = 2e-6
gravity = [0.0, 0.0, -9.81]
threads = 1

)") +
    demfem::test::dem_material("wheat", "1e8", "1242.0") +
    demfem::test::dem_material("steel", "1.85e11") +
    demfem::test::dem_pair("wheat", "wheat", "0.17", "0.4") +
    demfem::test::dem_pair("wheat", "steel", "0.22", "0.4", "rolling_friction = 0.01\n") +
    R"(
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
  return demfem::test::parse_dem_scene(text, name);
}

std::string error_of(const std::string& text) {
  return demfem::test::error_of<SceneError>([&] { parse(text); }, "(no error)");
}

std::string replace(const std::string& s, const std::string& from, const std::string& to) {
  return demfem::test::replace_first(s, from, to);
}

using demfem::test::line_of;

}  // namespace

TEST_CASE("a complete [dem] section is read into the settings", "[scene]") {
  const DemScene s = parse(kBase);
  CHECK(s.settings.dt == 2e-6);
  CHECK(s.settings.threads == 1);
  CHECK(s.settings.backend == DemBackendKind::cpu);
  REQUIRE(s.settings.materials.size() == 2);
  CHECK(s.settings.materials[1].density == 0.0);
  REQUIRE(s.settings.pairs.size() == 4);
  CHECK(s.settings.pairs[1].friction == 0.22);  // wheat-steel, symmetric
  CHECK(s.settings.pairs[2].friction == 0.22);
  CHECK(s.settings.pairs[2].rolling_friction == 0.01);
  CHECK(s.settings.pairs[2].rocking_damping == 1.0);  // polyhedra: critical by default
  CHECK(s.settings.pairs[2].poly_law == MaterialPair::PolyLaw::pressure_centre);  // the default
  const DemScene sm = parse(
      replace(kBase, "rolling_friction = 0.01", "rolling_friction = 0.01\npoly_law = \"smooth\""));
  CHECK(sm.settings.pairs[1].poly_law == MaterialPair::PolyLaw::smooth);
  CHECK(sm.settings.pairs[2].poly_law == MaterialPair::PolyLaw::smooth);
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
      {"rolling_friction = 0.01", "rolling_friction = 0.01\nrocking_damping = -0.5",
       "key 'dem.pairs[1].rocking_damping': is -0.5, outside the accepted range [0, 10]"},
      {"rolling_friction = 0.01", "rolling_friction = 0.01\npoly_law = \"energy\"",
       "key 'dem.pairs[1].poly_law': is \"energy\", accepted: \"pressure_centre\", \"smooth\""},
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

TEST_CASE("motion.max_force: read for a drift, refused elsewhere naming the key", "[scene]") {
  const std::string wall =
      "box = { lo = [0.0, 0.0, 0.0], hi = [0.04, 0.04, 0.08], open_top = true }";
  auto with = [&](const std::string& motion) {
    return replace(kBase, wall, wall + "\nmotion = " + motion);
  };
  const DemScene s = parse(
      with("{ kind = \"sinusoid\", direction = [0, 0, 1], amplitude = 0.001, frequency = 20.0, "
           "velocity = [0, 0, -0.1], max_force = 50.0 }"));
  CHECK(s.walls[0].motion.max_force == 50.0);
  CHECK_THAT(
      error_of(with("{ kind = \"rotation\", axis_point = [0, 0, 0], axis = [0, 0, 1], "
                    "angular_velocity = 1.0, max_force = 50.0 }")),
      Catch::Contains("key 'dem.walls[0].motion.max_force'") && Catch::Contains("limits a drift"));
  CHECK_THAT(error_of(with("{ kind = \"sinusoid\", direction = [0, 0, 1], amplitude = 0.001, "
                           "frequency = 20.0, max_force = 50.0 }")),
             Catch::Contains("key 'dem.walls[0].motion.max_force'") &&
                 Catch::Contains("non-zero velocity"));
  CHECK_THAT(error_of(with("{ kind = \"translation\", velocity = [0, 0, -0.1], max_force = 0 }")),
             Catch::Contains("key 'dem.walls[0].motion.max_force'"));
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
    // beyond half their own radius (0.75-1.25 mm), which the soft-sphere contact cannot resolve.
    std::string fast = replace(text, "dt = 2e-6", "dt = 1e-5");
    fast = replace(fast, "count = 200", "count = 200\nvelocity = [0.0, 0.0, -150.0]");
    std::ofstream(dir / "scene.toml") << fast;
    Document d = Document::load(dir / "scene.toml");
    DemRun run(read_dem_scene(d.root().required_table("dem")), dir / "fast", 1, 0.0, nullptr);
    CHECK_THROWS_WITH(run.run_to(0.004),
                      Catch::Contains("DEM run unstable") &&
                          Catch::Contains("of the smaller contact radius of its two bodies") &&
                          Catch::Contains("key 'dem.dt'") &&
                          Catch::Contains("Rayleigh time step") &&
                          Catch::Contains("kinetic energy") && Catch::Contains("a bed at rest"));
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
  SECTION("shortfall: \"warn\" keeps what fits and says so; a bad value names the key") {
    std::ofstream(dir / "scene.toml")
        << replace(text, "count = 200", "count = 1300\nmax_attempts = 1\nshortfall = \"warn\"");
    Document d = Document::load(dir / "scene.toml");
    const DemScene s = read_dem_scene(d.root().required_table("dem"));
    std::ostringstream log;
    const DemRun run(s, "", 1, 0.0, &log);
    CHECK(run.system().particles().size() > 0);
    CHECK(run.system().particles().size() < 1300);
    CHECK_THAT(log.str(), Catch::Contains("dem: warning: ") &&
                              Catch::Contains("key 'dem.insert[0].lo'") &&
                              Catch::Contains("cannot insert 1300 particles") &&
                              Catch::Contains("the run goes on with these (shortfall = \"warn\")"));
    std::ofstream(dir / "scene.toml")
        << replace(text, "count = 200", "count = 200\nshortfall = \"skip\"");
    Document bad = Document::load(dir / "scene.toml");
    CHECK_THROWS_WITH(read_dem_scene(bad.root().required_table("dem")),
                      Catch::Contains("key 'dem.insert[0].shortfall'") && Catch::Contains("warn"));
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

namespace {

// kBase with its insertion replaced by `lattice` (a [[dem.lattice]] body).
std::string with_lattice(const std::string& lattice) {
  std::string text = kBase;
  const auto from = text.find("[[dem.insert]]");
  const auto to = text.find("[[dem.sensors]]");
  return text.replace(from, to - from, "[[dem.lattice]]\n" + lattice + "\n");
}

const char* kJittered = R"(material = "wheat"
lo = [0.0, 0.0, 0.0]
hi = [0.04, 0.04, 0.04]
diameter = 0.004
spacing = 0.005
jitter = 0.6)";

std::vector<std::array<double, 3>> positions(const DemRun& run) {
  const auto& p = run.system().particles();
  std::vector<std::array<double, 3>> out;
  for (std::size_t i = 0; i < p.size(); ++i) out.push_back({p.px[i], p.py[i], p.pz[i]});
  return out;
}

}  // namespace

TEST_CASE("[[dem.lattice]] jitter: seeded from run.seed or its own seed, checked up front",
          "[scene][lattice]") {
  const DemScene s = parse(with_lattice(kJittered));
  REQUIRE(s.lattices.size() == 1);
  CHECK(s.lattices[0].request.jitter == 0.6);
  CHECK_FALSE(s.lattices[0].has_seed);
  DemRun a(s, "", 1, 0.0, nullptr), b(s, "", 1, 0.0, nullptr), c(s, "", 2, 0.0, nullptr);
  // (0.04 - 2 x (2 mm + 0.6 x 0.5 mm)) / 5 mm + 1 = 8 sites per axis
  CHECK(a.system().particle_count() == 8 * 8 * 8);
  CHECK(positions(a) == positions(b));  // same run.seed: the same bed
  CHECK(positions(a) != positions(c));  // another run.seed: another
  // Its own seed wins over run.seed.
  const DemScene seeded = parse(with_lattice(std::string(kJittered) + "\nseed = 11"));
  DemRun d(seeded, "", 1, 0.0, nullptr), e(seeded, "", 2, 0.0, nullptr);
  CHECK(positions(d) == positions(e));
  // A distribution instead of one diameter.
  const DemScene sized =
      parse(with_lattice(replace(kJittered, "diameter = 0.004",
                                 "distribution = { kind = \"uniform\", d_min = 0.003, "
                                 "d_max = 0.0045 }")));
  CHECK(sized.lattices[0].request.has_sizes);
  CHECK(sized.lattices[0].request.diameter == 0.0045);
  DemRun f(sized, "", 1, 0.0, nullptr);
  const auto& r = f.system().particles().radius;
  CHECK(*std::min_element(r.begin(), r.end()) < *std::max_element(r.begin(), r.end()));

  // Mistakes.
  CHECK_THAT(error_of(with_lattice(replace(kJittered, "spacing = 0.005\n", ""))),
             Catch::Contains("key 'dem.lattice[0].jitter'") &&
                 Catch::Contains("spacing' >= 1.01 x diameter"));
  CHECK_THAT(error_of(with_lattice(replace(kJittered, "jitter = 0.6", "jitter = 1.0"))),
             Catch::Contains("key 'dem.lattice[0].jitter'") && Catch::Contains("[0, 1)"));
  CHECK_THAT(error_of(with_lattice(replace(kJittered, "diameter = 0.004",
                                           "diameter = 0.004\ndistribution = { kind = "
                                           "\"constant\", diameter = 0.004 }"))),
             Catch::Contains("key 'dem.lattice[0].diameter'") &&
                 Catch::Contains("exactly one of 'diameter'"));
  CHECK_THAT(error_of(with_lattice(replace(kJittered, "diameter = 0.004", "diamter = 0.004"))),
             Catch::Contains("key 'dem.lattice[0].diameter': is required but missing (or "
                             "'distribution')") &&
                 Catch::Contains("'diamter'") && Catch::Contains("did you mean 'diameter'?"));
}

TEST_CASE("particles placed outside or inside the walls are refused, naming the entry",
          "[scene][lattice]") {
  // The wall is the box [0, 0.04] x [0, 0.04] x [0, 0.08] with an open top.
  SECTION("a lattice reaching through a side wall") {
    const DemScene s = parse(with_lattice(
        replace(replace(kJittered, "lo = [0.0, 0.0, 0.0]", "lo = [0.019, 0.0, 0.0]"),
                "hi = [0.04, 0.04, 0.04]", "hi = [0.07, 0.04, 0.04]")));  // a site at x = 0.0413
    CHECK_THROWS_WITH(DemRun(s, "", 1, 0.0, nullptr), Catch::Contains("key 'dem.lattice[0].lo'") &&
                                                          Catch::Contains("overlaps wall 'floor'"));
  }
  SECTION("a lattice beside the box, clear of it: it would fall for ever") {
    const std::string text =
        with_lattice(replace(replace(kJittered, "lo = [0.0, 0.0, 0.0]", "lo = [0.05, 0.0, 0.0]"),
                             "hi = [0.04, 0.04, 0.04]", "hi = [0.09, 0.04, 0.04]"));
    CHECK_THROWS_WITH(DemRun(parse(text), "", 1, 0.0, nullptr),
                      Catch::Contains("key 'dem.lattice[0].lo'") &&
                          Catch::Contains("lies outside the walls") &&
                          Catch::Contains("fall for ever"));
    // In a coupled scene the structure may catch them: a warning, not an error.
    std::ostringstream log;
    const std::string coupled =
        replace(text, "threads = 1", "threads = 1\ninterface_material = \"steel\"");
    DemRun run(parse(coupled), "", 1, 0.0, &log);
    CHECK_THAT(log.str(), Catch::Contains("warning") && Catch::Contains("dem.lattice[0]"));
  }
  SECTION("without gravity nothing says where particles belong: beside the box is accepted") {
    const std::string text =
        with_lattice(replace(replace(kJittered, "lo = [0.0, 0.0, 0.0]", "lo = [0.05, 0.0, 0.0]"),
                             "hi = [0.04, 0.04, 0.04]", "hi = [0.09, 0.04, 0.04]"));
    DemRun run(parse(replace(text, "gravity = [0.0, 0.0, -9.81]", "gravity = [0.0, 0.0, 0.0]")), "",
               1, 0.0, nullptr);
    CHECK(run.system().particle_count() == 8 * 8 * 8);
  }
  SECTION("above an open box the lattice falls in: accepted") {
    const DemScene s = parse(
        with_lattice(replace(replace(kJittered, "lo = [0.0, 0.0, 0.0]", "lo = [0.0, 0.0, 0.1]"),
                             "hi = [0.04, 0.04, 0.04]", "hi = [0.04, 0.04, 0.14]")));
    DemRun run(s, "", 1, 0.0, nullptr);
    CHECK(run.system().particle_count() == 8 * 8 * 8);
  }
  SECTION("two lattices on top of each other") {
    const DemScene s =
        parse(with_lattice(std::string(kJittered) + "\n\n[[dem.lattice]]\n" + kJittered));
    CHECK_THROWS_WITH(DemRun(s, "", 1, 0.0, nullptr),
                      Catch::Contains("key 'dem.lattice[1].lo'") &&
                          Catch::Contains("overlaps a sphere of an earlier [[dem.lattice]]"));
  }
  SECTION("an insertion region reaching outside the box") {
    const std::string text =
        replace(kBase, "hi = [0.04, 0.04, 0.08]\ncount", "hi = [0.06, 0.04, 0.08]\ncount");
    CHECK_THROWS_WITH(DemRun(parse(text), "", 1, 0.0, nullptr),
                      Catch::Contains("key 'dem.insert[0].lo'") &&
                          Catch::Contains("the region's corner [0.06, 0, 0] m") &&
                          Catch::Contains("lies outside the walls"));
  }
  SECTION("an insertion region across a wall: the particles avoid it") {
    // A plane splitting the box at x = 0.02.
    const std::string text =
        replace(kBase, "[[dem.insert]]",
                "[[dem.walls]]\nname = \"divider\"\nmaterial = \"steel\"\nplane = { point = [0.02, "
                "0.02, 0.04], normal = [1.0, 0.0, 0.0], size = 0.1 }\n\n[[dem.insert]]");
    DemRun run(parse(text), "", 1, 0.0, nullptr);
    const auto& p = run.system().particles();
    REQUIRE(p.size() == 200);
    std::size_t left = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
      CHECK(std::abs(p.px[i] - 0.02) >= p.radius[i]);
      if (p.px[i] < 0.02) ++left;
    }
    CHECK(left > 50);
    CHECK(left < 150);
  }
}

TEST_CASE("impossible particle counts are refused when the scene is read, naming the key",
          "[scene][lattice]") {
  // The issue's example: a lattice of ~1e15 spheres used to start the solvers and die in
  // bad_alloc. 10 m cubed of 0.1 mm spheres.
  const std::string huge = with_lattice(
      "material = \"wheat\"\nlo = [0.0, 0.0, 0.0]\nhi = [10.0, 10.0, 10.0]\ndiameter = 1e-4");
  CHECK_THAT(error_of(huge), Catch::Contains("key 'dem.lattice[0].diameter'") &&
                                 Catch::Contains("about 9.97e+14 particles") &&
                                 Catch::Contains("32-bit particle indices"));
  // Below the index limit but beyond any workstation's memory (2e9 x 2 kB = 4 TB).
  CHECK_THAT(error_of(replace(kBase, "count = 200", "count = 2000000000")),
             Catch::Contains("key 'dem.insert[0].count'") && Catch::Contains("TB of memory") &&
                 Catch::Contains("more than this machine's"));
  // By mass and repeated: 1 t of 4 mm wheat, 1000 times.
  CHECK_THAT(error_of(replace(kBase, "count = 200", "mass = 1000.0\nevery = 0.001\nuntil = 0.999")),
             Catch::Contains("key 'dem.insert[0].mass'"));
  // Issue 19 (QA): spheres so small that their mass is 0 in double precision made a mass
  // target unreachable: the insertion looped for ever (the count estimate said 0).
  CHECK_THAT(error_of(replace(replace(kBase, "count = 200", "mass = 0.25"),
                              "d_min = 0.003, d_max = 0.005", "d_min = 1e-300, d_max = 1e-300")),
             Catch::Contains("key 'dem.insert[0].mass'") &&
                 Catch::Contains("more particles than can be counted"));
  const DemScene ok = parse(kBase);
  CHECK(estimated_particle_count(ok) == 200.0);
}
