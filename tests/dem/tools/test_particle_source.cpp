// [dem.load]: a scene starts from particles in a file (CSV, particle snapshot, saved state).
// The state with its contact history continues bit for bit as the run that saved it; every
// kind of bad data is refused naming the file and line (or particle).

#include <catch2/catch.hpp>

#include <fstream>
#include <memory>
#include <sstream>

#include "demfem/dem/run/dem_output.hpp"
#include "demfem/dem/run/dem_run.hpp"
#include "demfem/dem/scene/particle_source.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem_test/box_scene.hpp"
#include "demfem_test/error_of.hpp"
#include "demfem_test/rock_fill.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem::dem;
using demfem::scene::Document;
using demfem::scene::Override;
using demfem::scene::SceneError;
using demfem::test::TempDir;

namespace {

// A box for a bed of 3-5 mm wheat spheres (the steel sheet's grain, docs/cases.md).
const std::string kHead = demfem::test::BoxScene{}.text();

const char* kInsert = R"(
[[dem.insert]]
material = "wheat"
lo = [0.0, 0.0, 0.0]
hi = [0.04, 0.04, 0.06]
count = 150
seed = 5
distribution = { kind = "uniform", d_min = 0.003, d_max = 0.005 }
)";

struct Scene {
  std::filesystem::path file;
  Document doc;
  DemScene dem;
};

Scene scene_file(const TempDir& dir, const std::string& name, const std::string& text) {
  const auto p = dir / name;
  std::ofstream(p) << text;
  Scene s{p, Document::load(p), {}};
  s.dem = read_dem_scene(s.doc.root().required_table("dem"));
  return s;
}

DemScene read(const TempDir& dir, const std::string& text) {
  return scene_file(dir, "scene.toml", text).dem;
}

std::string error_of(const TempDir& dir, const std::string& text, bool build = true) {
  return demfem::test::error_of<SceneError>(
      [&] {
        auto s = read(dir, text);
        if (build) DemRun run(s, {}, 1, 0.0, nullptr);
      },
      "(no error)");
}

// Every array of the particle state, bitwise.
void require_same_state(const ParticleState& a, const ParticleState& b) {
  REQUIRE(a.size() == b.size());
  for (auto m : {&ParticleState::px, &ParticleState::py, &ParticleState::pz, &ParticleState::vx,
                 &ParticleState::vy, &ParticleState::vz, &ParticleState::wx, &ParticleState::wy,
                 &ParticleState::wz, &ParticleState::fx, &ParticleState::fy, &ParticleState::fz})
    for (std::size_t i = 0; i < a.size(); ++i) REQUIRE((a.*m)[i] == (b.*m)[i]);
}

// The fill scene run twice for `steps`: `whole` goes on uninterrupted, `saved` writes its state
// (<dir>/fill/dem_state.h5) for a loading scene to continue.
struct FillRuns {
  std::unique_ptr<DemRun> whole, saved;
};
FillRuns run_and_save(const TempDir& dir, const DemScene& fill, std::int64_t steps) {
  FillRuns r{std::make_unique<DemRun>(fill, std::filesystem::path{}, 1, 0.0, nullptr),
             std::make_unique<DemRun>(fill, dir / "fill", 1, 0.0, nullptr)};
  r.whole->system().advance(steps);
  r.saved->system().advance(steps);
  r.saved->finish();
  return r;
}

}  // namespace

TEST_CASE("dem.load: a CSV of x, y, z, r [, vx, vy, vz] starts the scene", "[dem][load]") {
  TempDir dir("load_csv");
  std::ofstream(dir / "bed.csv") << "# a comment\nx, y, z, r, vx, vy, vz\n"
                                    "0.01, 0.01, 0.003, 0.002, 0, 0, -1\n"
                                    "\n0.03,0.03,0.003,0.0015,0.5,0,0\n";
  const auto s =
      read(dir, std::string(kHead) + "[dem.load]\nfile = \"bed.csv\"\nmaterial = \"wheat\"\n");
  DemRun run(s, {}, 1, 0.0, nullptr);
  const auto& p = run.system().particles();
  REQUIRE(p.size() == 2);
  CHECK(p.px[1] == 0.03);
  CHECK(p.radius[1] == 0.0015);
  CHECK(p.vz[0] == -1.0);
  CHECK(p.vx[1] == 0.5);
  CHECK(p.material[0] == 0);
  CHECK(p.mass[0] == Approx(1242.0 * 4.0 / 3.0 * 3.141592653589793 * 8e-9).epsilon(1e-12));
  REQUIRE(run.ids().size() == 2);

  // Without velocity columns, and with velocities = false, the particles are at rest.
  std::ofstream(dir / "rest.csv") << "r,z,y,x\n0.002,0.003,0.01,0.01\n";
  const auto r =
      read(dir, std::string(kHead) + "[dem.load]\nfile = \"rest.csv\"\nmaterial = \"wheat\"\n");
  DemRun run2(r, {}, 1, 0.0, nullptr);
  CHECK(run2.system().particles().px[0] == 0.01);
  CHECK(run2.system().particles().vz[0] == 0.0);
}

TEST_CASE("dem.load: bad CSV data is refused naming file and line", "[dem][load]") {
  TempDir dir("load_csv_bad");
  auto with = [&](const std::string& csv, const std::string& extra = "material = \"wheat\"\n") {
    std::ofstream(dir / "bed.csv") << csv;
    return error_of(dir, std::string(kHead) + "[dem.load]\nfile = \"bed.csv\"\n" + extra);
  };
  const std::string ok_line = "0.01,0.01,0.003,0.002\n";
  CHECK_THAT(with("x,y,z,r\n0.01,abc,0.003,0.002\n"),
             Catch::Contains("bed.csv:2") && Catch::Contains("not a number"));
  CHECK_THAT(with("x,y,z,r\n" + ok_line + "0.01,0.01,nan,0.002\n"),
             Catch::Contains("bed.csv:3") && Catch::Contains("not finite"));
  CHECK_THAT(with("x,y,z,r\n0.01,0.01,0.003,-0.002\n"),
             Catch::Contains("bed.csv:2") && Catch::Contains("must be > 0"));
  CHECK_THAT(with("x,y,z,r\n0.01,0.01,0.003\n"),
             Catch::Contains("bed.csv:2") && Catch::Contains("3 values, the header has 4"));
  CHECK_THAT(with("x,y,z,radius\n" + ok_line), Catch::Contains("unknown column \"radius\""));
  CHECK_THAT(with("x,y,z\n"), Catch::Contains("no column \"r\""));
  CHECK_THAT(with("x,y,z,r,vx\n"), Catch::Contains("vx, vy, vz or none"));
  CHECK_THAT(with(""), Catch::Contains("is empty"));
  CHECK_THAT(with("x,y,z,r\n"), Catch::Contains("holds no particles"));
  CHECK_THAT(with("x,y,z,r\n" + ok_line, ""), Catch::Contains("'dem.load.material'"));
  // Outside the walls' bounding box: refused, or removed when asked.
  CHECK_THAT(with("x,y,z,r\n" + ok_line + "0.5,0.01,0.003,0.002\n"),
             Catch::Contains("bed.csv:3") && Catch::Contains("outside the walls' bounding box"));
  std::ofstream(dir / "bed.csv") << "x,y,z,r\n" << ok_line << "0.5,0.01,0.003,0.002\n";
  const auto s = read(dir, std::string(kHead) +
                               "[dem.load]\nfile = \"bed.csv\"\n"
                               "material = \"wheat\"\noutside = \"remove\"\n");
  DemRun run(s, {}, 1, 0.0, nullptr);
  CHECK(run.system().particle_count() == 1);
  // Two particles in each other, or one in a wall, beyond max_overlap.
  CHECK_THAT(
      with("x,y,z,r\n" + ok_line + "0.0115,0.01,0.003,0.002\n"),
      Catch::Contains("bed.csv:2") && Catch::Contains("overlaps") && Catch::Contains("bed.csv:3"));
  CHECK_THAT(with("x,y,z,r\n0.01,0.01,0.0015,0.002\n"),
             Catch::Contains("overlaps a wall") && Catch::Contains("0.25 of the smaller radius"));
  // ... but a small overlap passes (a settled bed), and the limit is a key.
  CHECK(with("x,y,z,r\n0.01,0.01,0.00195,0.002\n") == "(no error)");
  CHECK(with("x,y,z,r\n0.01,0.01,0.0015,0.002\n", "material = \"wheat\"\nmax_overlap = 0.3\n") ==
        "(no error)");
  // Keys that do not fit the source.
  CHECK_THAT(with("x,y,z,r\n" + ok_line, "material = \"wheat\"\nhistory = true\n"),
             Catch::Contains("'dem.load.history'") && Catch::Contains("needs a state file"));
  CHECK_THAT(with("x,y,z,r\n" + ok_line, "material = \"granite\"\n"),
             Catch::Contains("'dem.load.material'") && Catch::Contains("granite"));
  CHECK_THAT(error_of(dir, std::string(kHead) + "[dem.load]\nfile = \"none.csv\"\n"),
             Catch::Contains("'dem.load.file'") && Catch::Contains("does not exist"));
}

TEST_CASE("dem.load: a particle snapshot of another run, with its materials mapped",
          "[dem][load]") {
  TempDir dir("load_snapshot");
  ParticleState p;
  auto add = [&](double x, double r, std::int32_t m) {
    p.px.push_back(x), p.py.push_back(0.02), p.pz.push_back(0.01);
    p.vx.push_back(0.1), p.vy.push_back(0.0), p.vz.push_back(-0.2);
    p.wx.push_back(1.0), p.wy.push_back(0.0), p.wz.push_back(0.0);
    p.radius.push_back(r), p.mass.push_back(1.0), p.material.push_back(m);
  };
  add(0.01, 0.002, 3);
  add(0.03, 0.0025, 3);
  std::vector<std::int64_t> ids{7, 8};
  ParticleOutput(dir.path).write(p, ids, 0.5);
  const std::string load = "[dem.load]\nfile = \"particles_000000.h5\"\n";
  // The snapshot's material 3 does not exist here: a map is needed.
  CHECK_THAT(
      error_of(dir, std::string(kHead) + load),
      Catch::Contains("particles_000000.h5: particle 0") && Catch::Contains("material index 3"));
  CHECK_THAT(error_of(dir, std::string(kHead) + load + "material_map = [\"wheat\"]\n"),
             Catch::Contains("has no entry in dem.load.material_map"));
  const auto s = read(dir, std::string(kHead) + load +
                               "material_map = [\"wheat\", \"wheat\", \"wheat\", \"wheat\"]\n"
                               "velocities = false\n");
  DemRun run(s, {}, 1, 0.0, nullptr);
  const auto& q = run.system().particles();
  REQUIRE(q.size() == 2);
  CHECK(q.px[1] == 0.03);
  CHECK(q.radius[1] == 0.0025);
  CHECK(q.vx[0] == 0.0);
  CHECK(q.wx[0] == 0.0);
  CHECK(q.mass[0] == Approx(1242.0 * 4.0 / 3.0 * 3.141592653589793 * 8e-9).epsilon(1e-12));
  const auto v = read(dir, std::string(kHead) + load +
                               "material = \"wheat\"\n"
                               "shift = [0.001, 0, 0]\n");
  DemRun run2(v, {}, 1, 0.0, nullptr);
  CHECK(run2.system().particles().px[0] == 0.011);
  CHECK(run2.system().particles().vz[0] == -0.2);
  CHECK(run2.system().particles().wx[0] == 1.0);
}

TEST_CASE("dem.load: a saved state with its contact history continues bit for bit", "[dem][load]") {
  TempDir dir("load_state");
  // The uninterrupted run: insert, settle for 20000 steps (0.2 s: the bed has formed), go on for
  // 400.
  const std::string fill = std::string(kHead) + kInsert + "[dem.output]\nstate = true\n";
  const Scene a = scene_file(dir, "fill.toml", fill);
  const FillRuns runs = run_and_save(dir, a.dem, 20000);
  DemRun& whole = *runs.whole;
  DemRun& saved = *runs.saved;
  REQUIRE(std::filesystem::exists(dir / "fill" / kStateFileName));
  require_same_state(whole.system().particles(), saved.system().particles());
  // The bed rests: the history (springs of touching pairs and wall contacts) matters.
  REQUIRE(saved.system().contact_count() > 100);
  whole.system().advance(400);

  const std::string load = "[dem.load]\nfile = \"fill/dem_state.h5\"\n";
  SECTION("history: every particle array equal after 400 more steps, the clock at 0") {
    const auto s = read(dir, std::string(kHead) + load);
    REQUIRE(s.load->history);
    DemRun run(s, {}, 1, 0.0, nullptr);
    CHECK(run.system().time() == 0.0);
    run.system().advance(400);
    require_same_state(whole.system().particles(), run.system().particles());
    CHECK(run.system().time() == Approx(400 * 1e-5).epsilon(1e-12));
  }
  SECTION("keep_time continues the saved clock") {
    const auto s = read(dir, std::string(kHead) + load + "keep_time = true\n");
    DemRun run(s, {}, 1, 0.0, nullptr);
    CHECK(run.system().time() == saved.system().time());
    run.system().advance(400);
    require_same_state(whole.system().particles(), run.system().particles());
    CHECK(run.system().time() == whole.system().time());
  }
  SECTION("without history the positions are the saved ones, the continuation is not exact") {
    const auto s = read(dir, std::string(kHead) + load + "history = false\n");
    DemRun run(s, {}, 1, 0.0, nullptr);
    const auto& p = run.system().particles();
    const auto& q = saved.system().particles();
    for (std::size_t i = 0; i < p.size(); ++i) {
      REQUIRE(p.px[i] == q.px[i]);
      REQUIRE(p.vz[i] == q.vz[i]);
    }
    run.system().advance(400);
    bool differs = false;
    for (std::size_t i = 0; i < p.size(); ++i)
      differs = differs || p.px[i] != whole.system().particles().px[i];
    CHECK(differs);
  }
  SECTION("history needs the same walls and materials") {
    std::string moved = std::string(kHead) + load;
    moved.replace(moved.find("hi = [0.04, 0.04, 0.1]"), 22, "hi = [0.04, 0.04, 0.2]");
    CHECK_THAT(error_of(dir, moved),
               Catch::Contains("wall vertex") && Catch::Contains("history = false"));
    std::string heavier = std::string(kHead) + load;
    heavier.replace(heavier.find("density = 1242.0"), 16, "density = 1300.0");
    CHECK_THAT(error_of(dir, heavier), Catch::Contains("differs from this scene's density") &&
                                           Catch::Contains("dem_state.h5: particle 0"));
    CHECK_THAT(error_of(dir, std::string(kHead) + load + "material = \"wheat\"\n", false),
               Catch::Contains("'dem.load.material'") && Catch::Contains("history = true"));
  }
  SECTION("a prepare scene: its state is found and must be current") {
    const auto s =
        scene_file(dir, "use.toml", std::string(kHead) + "[dem.load]\nscene = \"fill.toml\"\n");
    // run.output_dir of fill.toml is out/fill relative to the current folder.
    CHECK(s.dem.load->file == std::filesystem::path("out/fill") / kStateFileName);
    CHECK(s.dem.load->prepare_scene == dir / "fill.toml");
    CHECK(state_is_current(dir / "fill" / kStateFileName, dir / "fill.toml"));
    // A comment, blank lines or another spelling of a number leave the content as it was: the
    // prepared bed stays current. A changed value does not.
    std::ofstream(dir / "fill.toml", std::ios::app) << "\n# a comment\n\n";
    CHECK(state_is_current(dir / "fill" / kStateFileName, dir / "fill.toml"));
    std::string text = fill;
    text.replace(text.find("density = 1242.0"), 16, "density = 1.242e3");
    (void)scene_file(dir, "fill.toml", text + "# spelled otherwise\n");
    CHECK(state_is_current(dir / "fill" / kStateFileName, dir / "fill.toml"));
    text.replace(text.find("density = 1.242e3"), 17, "density = 1243.0");
    (void)scene_file(dir, "fill.toml", text);
    CHECK_FALSE(state_is_current(dir / "fill" / kStateFileName, dir / "fill.toml"));
    (void)scene_file(dir, "nostate.toml", std::string(kHead) + kInsert);
    CHECK_THAT(error_of(dir, std::string(kHead) + "[dem.load]\nscene = \"nostate.toml\"\n", false),
               Catch::Contains("does not write its end state"));
  }
}

// A layer frozen while the next one was poured ([dem.freeze]) is saved with its mask; the
// scene that loads the state (the trim, the load case) holds only what its own [dem.freeze]
// holds, so the load case runs with every rock free.
TEST_CASE("dem.load: a state's frozen particles are free in the scene that loads it",
          "[dem][load][frozen]") {
  TempDir dir("load_frozen");
  // The bed settles for 0.2 s, then the grains whose centre lies below 5 mm are frozen.
  const std::string freeze =
      "[dem.freeze]\ntime = 0.2\nactive = { lo = [-1.0, -1.0, 0.005], hi = [1.0, 1.0, 1.0] }\n"
      "max_speed = 1e9\n";
  const Scene a = scene_file(dir, "fill.toml", std::string(kHead) + kInsert + freeze +
                                                   "[dem.output]\nstate = true\n");
  DemRun saved(a.dem, dir / "fill", 1, 0.0, nullptr);
  saved.run_to(0.2);
  const std::size_t held = saved.system().frozen_count();
  REQUIRE(held > 10);
  REQUIRE(held < saved.system().particles().size());
  saved.finish();  // writes fill/dem_state.h5 with the mask
  const auto held_pz = saved.system().particles().pz;
  const std::string load = "[dem.load]\nfile = \"fill/dem_state.h5\"\n";

  // Of the grains held in the saved run, how many move in 200 steps of the loading scene.
  auto moved_of_held = [&](DemRun& run) {
    run.system().advance(200);
    std::size_t moved = 0;
    for (std::size_t i = 0; i < held_pz.size(); ++i)
      moved += held_pz[i] < 0.005 && run.system().particles().pz[i] != held_pz[i] ? 1 : 0;
    return moved;
  };
  SECTION("without [dem.freeze], or with it disabled, every grain is free and moves") {
    const std::string disabled =
        "[dem.freeze]\nenabled = false\ntime = 0.0\nactive = { lo = [0, 0, 0], hi = [1, 1, 1] }\n";
    for (const std::string& own : {std::string(), disabled}) {
      const auto s = read(dir, std::string(kHead) + load + own);
      REQUIRE(s.load->history);
      DemRun run(s, {}, 1, 0.0, nullptr);
      CHECK(run.system().frozen_count() == 0);
      CHECK(run.system().frozen_support() == std::array<double, 3>{0.0, 0.0, 0.0});
      // the grains below 5 mm settle a little further under the bed's weight, now computed
      CHECK(moved_of_held(run) > held / 2);
    }
  }
  SECTION("the loading scene's own [dem.freeze] holds its own grains, not the state's") {
    const std::string own = "[dem.freeze]\ntime = 0.0\n"
                            "active = { lo = [-1.0, -1.0, 0.003], hi = [1.0, 1.0, 1.0] }\n"
                            "max_speed = 1e9\n";
    // at its start (t = 0) the scene freezes the centres below 3 mm, fewer than were held
    DemRun run(read(dir, std::string(kHead) + load + own), {}, 1, 0.0, nullptr);
    std::size_t below = 0;
    for (double z : held_pz) below += z < 0.003 ? 1 : 0;
    REQUIRE(below > 0);
    REQUIRE(below < held);
    CHECK(run.system().frozen_count() == below);
  }
}

// A sweep varies a bed's settings: [dem.load] set (fixed overrides of the prepare scene) and
// pass (this run's own --set overrides under the given keys go on to it). Each variant has a
// folder of its own, and its state is current only for the overrides that made it.
TEST_CASE("dem.load keep_time: a moving wall goes on with its motion; another motion is refused "
          "naming the wall",
          "[dem][load]") {
  TempDir dir("load_wall_motion");
  // A force-limited plate drifting down above the grains (it never reaches them here): the
  // drift a state saves is the time it advanced, so a scene that changes its velocity and
  // keeps the clock would place the plate elsewhere at the first step (into the bed, in the
  // full-scale sleeper's second layer: a blow-up blamed on the step).
  const auto plate = [](const std::string& velocity) {
    return "[[dem.walls]]\nname = \"plate\"\nmaterial = \"steel\"\n"
           "box = { lo = [0.001, 0.001, 0.09], hi = [0.039, 0.039, 0.095] }\n"
           "motion = { kind = \"sinusoid\", direction = [0, 0, 1], amplitude = 0.0005, "
           "frequency = 20.0, velocity = [0, 0, " +
           velocity + "], max_force = 5.0 }\n";
  };
  const std::string fill =
      std::string(kHead) + plate("-0.05") + kInsert + "[dem.output]\nstate = true\n";
  const Scene a = scene_file(dir, "fill.toml", fill);
  const FillRuns runs = run_and_save(dir, a.dem, 3000);
  DemRun& whole = *runs.whole;
  whole.system().advance(200);
  const std::string load = "[dem.load]\nfile = \"fill/dem_state.h5\"\n";
  const auto bottom = [](const std::vector<double>& x) {  // the plate's lowest vertex, m
    double z = x[2];
    for (std::size_t k = 2; k < x.size(); k += 3) z = std::min(z, x[k]);
    return z;
  };

  SECTION("the same motion, the clock kept: bitwise the uninterrupted run, plate included") {
    const auto s = read(dir, std::string(kHead) + plate("-0.05") + load + "keep_time = true\n");
    DemRun run(s, {}, 1, 0.0, nullptr);
    run.system().advance(200);
    require_same_state(whole.system().particles(), run.system().particles());
    CHECK(run.system().wall_vertices(1) == whole.system().wall_vertices(1));
    // 0.03 s of drift at 0.05 m/s moved it 1.5 mm down (and the vibration within 0.5 mm)
    const double z = bottom(run.system().wall_vertices(1));
    CHECK(z < 0.09 - 0.0015 + 0.0005 + 1e-9);
    CHECK(z > 0.09 - 0.0015 - 0.0005 - 1e-9);
  }
  SECTION("another velocity with the clock kept: refused, naming the wall and the distance") {
    const std::string text =
        std::string(kHead) + plate("-0.5") + load + "keep_time = true\n";
    const std::string e = error_of(dir, text);
    CHECK_THAT(e, Catch::Contains("fill/dem_state.h5") && Catch::Contains("wall 'plate'") &&
                      Catch::Contains("keep_time") && Catch::Contains("0.0135 m"));
  }
  SECTION("another velocity, the clock at 0: the motion starts again at the plate's box") {
    const auto s = read(dir, std::string(kHead) + plate("-0.5") + load);
    DemRun run(s, {}, 1, 0.0, nullptr);
    CHECK(bottom(run.system().wall_vertices(1)) == 0.09);
  }
}

TEST_CASE("dem.load: a prepare scene with overrides ('set', 'pass')", "[dem][load]") {
  TempDir dir("load_prepare_overrides");
  const std::string fill = std::string(kHead) + kInsert + "[dem.output]\nstate = true\n";
  (void)scene_file(dir, "fill.toml", fill);
  const std::string use = std::string(kHead) +
                          "[dem.load]\nscene = \"fill.toml\"\n"
                          "set = [\"dem.insert[0].count=120\"]\n"
                          "pass = [\"run.seed\", \"dem.pairs\"]\n";
  std::ofstream(dir / "use.toml") << use;
  auto source = [&](const std::vector<Override>& cli) {
    const Document d = Document::load(dir / "use.toml", cli);
    return *read_dem_scene(d.root().required_table("dem")).load;
  };
  const Override seed7{"run.seed", "7"}, mu{"dem.pairs[0].friction", "0.3"};
  const Override dt{"dem.dt", "1e-6"};  // not under a passed key: stays with this run
  const ParticleSource a = source({seed7, dt, mu});
  REQUIRE(a.prepare_overrides.size() == 4);
  CHECK(a.prepare_overrides[0].key == "dem.insert[0].count");
  CHECK(a.prepare_overrides[1].key == "run.seed");
  CHECK(a.prepare_overrides[2].key == "dem.pairs[0].friction");
  CHECK(a.prepare_overrides[3].key == "run.output_dir");
  // out/fill/set-<16 hex digits of the content>/dem_state.h5
  const std::string folder = a.file.parent_path().filename().string();
  CHECK(a.file.parent_path().parent_path() == std::filesystem::path("out/fill"));
  CHECK(folder.size() == 4 + 16);
  CHECK(folder.rfind("set-", 0) == 0);
  // the same content spelt otherwise: the same folder; another seed: another one
  CHECK(source({Override{"run.seed", "+7"}, mu}).file == a.file);
  CHECK(source({Override{"run.seed", "8"}, mu}).file != a.file);
  CHECK(source({}).prepare_overrides.size() == 2);  // set and the folder

  // The state a prepare run with these overrides writes is current for them only.
  std::vector<Override> made = a.prepare_overrides;
  made.back() = Override{"run.output_dir", "\"" + (dir / "variant").string() + "\""};
  const Document fd = Document::load(dir / "fill.toml", made);
  DemRun prepared(read_dem_scene(fd.root().required_table("dem")), dir / "variant", 1, 0.0,
                  nullptr);
  prepared.write_state();
  const auto state = dir / "variant" / kStateFileName;
  REQUIRE(std::filesystem::exists(state));
  CHECK(state_is_current(state, dir / "fill.toml", made));
  CHECK_FALSE(state_is_current(state, dir / "fill.toml"));
  made[1].value = "8";
  CHECK_FALSE(state_is_current(state, dir / "fill.toml", made));
  // and a state of the plain scene is not current for a variant
  DemRun plain(read_dem_scene(Document::load(dir / "fill.toml").root().required_table("dem")),
               dir / "plain", 1, 0.0, nullptr);
  plain.write_state();
  CHECK(state_is_current(dir / "plain" / kStateFileName, dir / "fill.toml"));
  CHECK_FALSE(state_is_current(dir / "plain" / kStateFileName, dir / "fill.toml", made));

  SECTION("seed_offset: a passed run.seed arrives shifted, a set one as written") {
    std::ofstream(dir / "shift.toml") << std::string(kHead) +
                                             "[dem.load]\nscene = \"fill.toml\"\n"
                                             "pass = [\"run.seed\"]\nseed_offset = -1\n";
    auto shifted = [&](const std::vector<Override>& cli) {
      const Document d = Document::load(dir / "shift.toml", cli);
      return read_dem_scene(d.root().required_table("dem")).load->prepare_overrides;
    };
    const auto s12 = shifted({Override{"run.seed", "12"}});
    REQUIRE(s12.size() == 2);  // the seed and the folder
    CHECK(s12[0].key == "run.seed");
    CHECK(s12[0].value == "11");
    CHECK(shifted({Override{"run.seed", "+1_000"}})[0].value == "999");
    CHECK(shifted({}).empty());  // nothing passed: the prepare scene's own seed
    // the folder of "seed 12 shifted" is the folder of --set run.seed=11 passed unshifted
    std::ofstream(dir / "noshift.toml")
        << std::string(kHead) + "[dem.load]\nscene = \"fill.toml\"\npass = [\"run.seed\"]\n";
    const Document d11 = Document::load(dir / "noshift.toml", {Override{"run.seed", "11"}});
    const Document d12 = Document::load(dir / "shift.toml", {Override{"run.seed", "12"}});
    CHECK(read_dem_scene(d11.root().required_table("dem")).load->file ==
          read_dem_scene(d12.root().required_table("dem")).load->file);
    // a set run.seed is not shifted (only what pass passes on)
    std::ofstream(dir / "setseed.toml")
        << std::string(kHead) +
               "[dem.load]\nscene = \"fill.toml\"\nset = [\"run.seed=5\"]\n"
               "pass = [\"dem.pairs\"]\nseed_offset = -1\n";
    const Document ds = Document::load(dir / "setseed.toml", {Override{"run.seed", "5"}});
    const auto set_only = read_dem_scene(ds.root().required_table("dem")).load->prepare_overrides;
    CHECK(set_only[0].value == "5");
    // below 0: refused, naming the key, the override and the least seed
    std::ofstream(dir / "low.toml") << std::string(kHead) +
                                           "[dem.load]\nscene = \"fill.toml\"\n"
                                           "pass = [\"run.seed\"]\nseed_offset = -3\n";
    try {
      const Document dl = Document::load(dir / "low.toml", {Override{"run.seed", "2"}});
      (void)read_dem_scene(dl.root().required_table("dem"));
      FAIL("a seed shifted below 0 was accepted");
    } catch (const SceneError& e) {
      CHECK_THAT(std::string(e.what()), Catch::Contains("'dem.load.seed_offset'") &&
                                            Catch::Contains("run.seed=2") &&
                                            Catch::Contains("at least 3"));
    }
  }
  SECTION("bad entries name the key") {
    const std::string head = std::string(kHead) + "[dem.load]\nscene = \"fill.toml\"\n";
    CHECK_THAT(error_of(dir, head + "seed_offset = -1\n", false),
               Catch::Contains("'dem.load.seed_offset'") && Catch::Contains("pass"));
    CHECK_THAT(error_of(dir, head + "pass = [\"run.seed\"]\nseed_offset = 1.5\n", false),
               Catch::Contains("'dem.load.seed_offset'"));
    CHECK_THAT(error_of(dir, head + "set = [\"no assignment\"]\n", false),
               Catch::Contains("'dem.load.set'") && Catch::Contains("KEY=VALUE"));
    CHECK_THAT(error_of(dir, head + "pass = [\"run.output_dir\"]\n", false),
               Catch::Contains("'dem.load.pass'") && Catch::Contains("never passed"));
    CHECK_THAT(error_of(dir, head + "set = [\"dem.nothing[3].x=1\"]\n", false),
               Catch::Contains("fill.toml") && Catch::Contains("'set' and 'pass'"));
    CHECK_THAT(error_of(dir,
                        std::string(kHead) +
                            "[dem.load]\nfile = \"plain/dem_state.h5\"\nset = [\"a=1\"]\n",
                        false),
               Catch::Contains("'dem.load.set'") && Catch::Contains("only used with 'scene'"));
  }
}

// Rocks (dilated polyhedra, docs/dem.md): a settled bed of them is what the ballast cases
// load. Their masses are rho V s^3 and their bounding spheres overlap, so the sphere checks
// must not apply; the state restores its shape table and the continuation is exact.
TEST_CASE("dem.load: a state of rocks continues bit for bit", "[dem][load][poly]") {
  TempDir dir("load_rocks");
  // Four rocks of 30 triangles (seeded from run.seed), 40 of wheat's density inserted.
  demfem::test::RandomRockShapes rock("rock", "4", "30");
  rock.elongation = "0.8";
  rock.flatness = "0.8";
  rock.seed = "";
  demfem::test::RockFill wheat_rocks("[0.04, 0.04, 0.1]", "40", "5");
  wheat_rocks.material = "wheat";
  wheat_rocks.shape = "rock";
  wheat_rocks.distribution = "{ kind = \"uniform\", d_min = 0.006, d_max = 0.009 }";
  const std::string shapes = rock.text() + wheat_rocks.text();
  const std::string fill = std::string(kHead) + shapes + "[dem.output]\nstate = true\n";
  const Scene a = scene_file(dir, "fill.toml", fill);
  const FillRuns runs = run_and_save(dir, a.dem, 15000);
  DemRun& whole = *runs.whole;
  DemRun& saved = *runs.saved;
  REQUIRE(saved.system().contact_count() > 10);  // rocks rest on rocks (18): history matters
  whole.system().advance(300);
  // The loading scene names the same shapes (its later insertions would draw from them).
  std::string load = std::string(kHead) + shapes.substr(0, shapes.find("[[dem.insert]]")) +
                     "[dem.load]\nfile = \"fill/dem_state.h5\"\n";
  const auto s = read(dir, load);
  DemRun run(s, {}, 1, 0.0, nullptr);
  REQUIRE(run.system().particles().shape[0] ==
          static_cast<std::uint8_t>(ParticleShape::polyhedron));
  run.system().advance(300);
  require_same_state(whole.system().particles(), run.system().particles());
  const auto& p = run.system().particles();
  const auto& q = whole.system().particles();
  for (std::size_t i = 0; i < p.size(); ++i) REQUIRE((p.qw[i] == q.qw[i] && p.qx[i] == q.qx[i]));
  // Another density: the rocks' masses (rho V s^3) no longer match.
  std::string heavier = load;
  heavier.replace(heavier.find("density = 1242.0"), 16, "density = 1300.0");
  CHECK_THAT(error_of(dir, heavier), Catch::Contains("differs from this scene's density"));
}

TEST_CASE("dem.load: a state of polyhedra, with and without history", "[dem][load][poly]") {
  TempDir dir("load_poly");
  const std::string head = demfem::test::rock_box("[0.3, 0.3, 0.6]").text();
  const std::string rocks = demfem::test::RandomRockShapes().text() +
                            demfem::test::RockFill("[0.3, 0.3, 0.3]", "30", "3").text() +
                            "[dem.output]\nstate = true\n";
  const Scene a = scene_file(dir, "fill.toml", head + rocks);
  const FillRuns runs = run_and_save(dir, a.dem, 20000);  // 0.2 s: the rocks have landed and touch
  DemRun& whole = *runs.whole;
  DemRun& saved = *runs.saved;
  REQUIRE(saved.system().contact_count() > 0);  // resting contacts: the history matters
  // The loader's overlap check measures spheres only: the rocks are reported as unchecked
  // (the log says so), not as free of overlaps.
  const OverlapReport ov = largest_overlap(saved.system().particles(), {});
  CHECK(ov.unchecked == saved.system().particle_count());
  CHECK(ov.touching == 0);
  whole.system().advance(300);
  const auto& q = saved.system().particles();
  const std::string load = "[dem.load]\nfile = \"fill/dem_state.h5\"\n";
  SECTION("without history: shapes, scales and poses are the saved ones") {
    const auto s = read(dir, head + load + "history = false\n");
    DemRun run(s, {}, 1, 0.0, nullptr);
    const auto& p = run.system().particles();
    REQUIRE(p.size() == q.size());
    REQUIRE(run.system().shape_count() == saved.system().shape_count());
    for (std::size_t i = 0; i < p.size(); ++i) {
      REQUIRE(p.shape[i] == q.shape[i]);
      REQUIRE(p.scale[i] == q.scale[i]);
      REQUIRE(p.px[i] == q.px[i]);
      REQUIRE(p.qx[i] == Approx(q.qx[i]).margin(1e-15));  // add_particles renormalises q
      REQUIRE(p.mass[i] == q.mass[i]);
      REQUIRE(run.system().shape(p.shape_id[i]).vertices ==
              saved.system().shape(q.shape_id[i]).vertices);
    }
    run.system().advance(300);  // it runs, nothing explodes; without the springs it differs
    CHECK(run.system().kinetic_energy() < 1.0);
    bool differs = false;
    for (std::size_t i = 0; i < p.size(); ++i)
      differs = differs || p.px[i] != whole.system().particles().px[i];
    CHECK(differs);
  }
  SECTION("with history: the continuation is bitwise") {
    const auto s = read(dir, head + load);
    DemRun run(s, {}, 1, 0.0, nullptr);
    run.system().advance(300);
    require_same_state(whole.system().particles(), run.system().particles());
  }
}
