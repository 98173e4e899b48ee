// Particle and wall output: HDF5 snapshots re-read, the XDMF index lists every snapshot, stays
// valid after each write, and resume() trims it; DemRun takes the snapshots at the requested
// times and labels them with exactly those times, with the walls where they are then
// (tests/system/check_paraview_output.py opens the files with ParaView itself).

#include <catch2/catch.hpp>

#include <fstream>
#include <sstream>

#include "demfem/dem/run/dem_output.hpp"
#include "demfem/dem/run/dem_run.hpp"
#include "demfem/dem/run/wall_output.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem_test/dem_material_text.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem::dem;
using demfem::io::H5File;
using demfem::test::TempDir;

namespace {

ParticleState make_state(std::size_t n, double shift) {
  ParticleState s;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = double(i) + shift;
    s.px.push_back(x);
    s.py.push_back(2 * x);
    s.pz.push_back(3 * x);
    s.vx.push_back(-x);
    s.vy.push_back(0.5);
    s.vz.push_back(0.25);
    s.wx.push_back(1);
    s.wy.push_back(2);
    s.wz.push_back(3);
    s.radius.push_back(0.001 * double(i + 1));
    s.mass.push_back(0.01);
    s.material.push_back(std::int32_t(i % 2));
  }
  return s;
}

std::string read_text(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::size_t occurrences(const std::string& s, const std::string& what) {
  std::size_t n = 0;
  for (auto p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

}  // namespace

TEST_CASE("particle snapshots re-read from HDF5 and indexed in XDMF", "[output]") {
  TempDir dir;
  ParticleOutput out(dir.path);
  const auto a = make_state(4, 0.0);
  const std::vector<std::int64_t> ids_a{10, 11, 12, 13};
  out.write(a, ids_a, 0.0);
  const auto b = make_state(3, 0.5);
  const std::vector<std::int64_t> ids_b{10, 12, 13};
  out.write(b, ids_b, 0.125);
  CHECK(out.count() == 2);

  H5File f(out.snapshot_path(1), H5File::Mode::read);
  std::vector<std::size_t> dims;
  const auto pos = f.read_doubles("position", &dims);
  REQUIRE(dims == std::vector<std::size_t>{3, 3});
  CHECK(pos[3] == 1.5);  // particle 1: x
  CHECK(pos[5] == 4.5);  // particle 1: z = 3 x
  const auto vel = f.read_doubles("velocity");
  CHECK(vel[3] == -1.5);
  CHECK(f.read_doubles("radius") == b.radius);
  CHECK(f.read_int64("id") == ids_b);
  CHECK(f.read_int64("material") == std::vector<std::int64_t>{0, 1, 0});
  CHECK(f.attribute_double("/", "time") == 0.125);
  CHECK(f.attribute_double("/", "state_time") == 0.125);
  CHECK(f.attribute_int64("/", "count") == 3);
  // The Polyvertex connectivity: one vertex cell per particle.
  CHECK(f.read_int64("vertex") == std::vector<std::int64_t>{0, 1, 2});
  f.close();

  const std::string x = read_text(out.index_path());
  CHECK_THAT(x, Catch::Contains("<Xdmf Version=\"3.0\">"));
  CHECK_THAT(x, Catch::Contains("CollectionType=\"Temporal\""));
  CHECK(occurrences(x, "TopologyType=\"Polyvertex\"") == 2);
  CHECK(occurrences(x, "particles_000001.h5:/vertex</DataItem></Topology>") == 1);
  CHECK_THAT(x, Catch::Contains("<Time Value=\"0.125\"/>"));
  CHECK_THAT(
      x, Catch::Contains("Dimensions=\"3 3\"") && Catch::Contains("particles_000001.h5:/position"));
  CHECK_THAT(x, Catch::Contains("</Xdmf>"));
  // No partial files left behind.
  for (const auto& e : std::filesystem::directory_iterator(dir.path))
    CHECK(e.path().extension() != ".part");

  // Resume after a restore to one snapshot: the index lists only the first.
  ParticleOutput again(dir.path);
  again.resume(1);
  CHECK(again.count() == 1);
  CHECK(occurrences(read_text(again.index_path()), "<Grid Name=\"step_") == 1);
  again.write(b, ids_b, 0.25);
  CHECK(occurrences(read_text(again.index_path()), "<Time Value=\"0.25\"/>") == 1);
  CHECK(again.count() == 2);
}

namespace {

// 12 spheres falling freely (no walls), dt = 2e-6 s.
const std::string kFalling = std::string(R"([run]
end_time = 0.002
[dem]
dt = 2e-6
threads = 1
)") +
    demfem::test::dem_material("steel", "2e11", "7800.0") +
    demfem::test::dem_pair("steel", "steel", "0.3", "0.5") +
    R"([[dem.lattice]]
material = "steel"
lo = [0.0, 0.0, 0.0]
hi = [0.03, 0.02, 0.01]
diameter = 0.01
)";

/// The scene with `extra` keys of [dem].
DemScene falling(const std::string& extra = "") {
  std::string text = kFalling;
  text.insert(text.find("threads = 1\n"), extra);
  const auto doc = demfem::scene::Document::parse(text, "falling.toml");
  return read_dem_scene(doc.root().required_table("dem"));
}

std::vector<double> snapshot_attribute(const ParticleOutput& out, const char* name) {
  std::vector<double> v;
  for (std::size_t k = 0; std::filesystem::exists(out.snapshot_path(k)); ++k) {
    v.push_back(H5File(out.snapshot_path(k), H5File::Mode::read).attribute_double("/", name));
  }
  return v;
}

}  // namespace

TEST_CASE("snapshots are labelled with the requested times, not the running sum of dt",
          "[output]") {
  TempDir dir;
  const ParticleOutput files(dir.path);  // names only
  SECTION("alone: every 5e-4 s = 250 steps") {
    DemRun run(falling(), dir.path, 1, 5e-4, nullptr);
    run.run_to(0.002);
    CHECK(snapshot_attribute(files, "time") ==
          std::vector<double>{0.0, 0.0005, 0.001, 0.0015, 0.002});
    // The states are those of steps 250, 500, ...: the running sum of dt carries rounding
    // (0.0004999999999999991 at step 250), the label does not.
    const auto state = snapshot_attribute(files, "state_time");
    REQUIRE(state.size() == 5);
    for (std::size_t k = 0; k < 5; ++k) CHECK(state[k] == Approx(5e-4 * double(k)).margin(1e-15));
    const std::string x = read_text(files.index_path());
    CHECK_THAT(x, Catch::Contains("<Time Value=\"0.0005\"/>") &&
                      Catch::Contains("<Time Value=\"0.0015\"/>"));
  }
  SECTION("after settle_time: the initial state at the settled time, then the multiples") {
    DemRun run(falling("settle_time = 0.0003\n"), dir.path, 1, 5e-4, nullptr);
    run.run_to(0.0012);
    CHECK(snapshot_attribute(files, "time") == std::vector<double>{0.0003, 0.0005, 0.001, 0.0012});
  }
  SECTION("coupled: a coupling step of 50 steps takes the nearest step end, ties to the later") {
    DemRun run(falling(), dir.path, 1, 2.5e-4, nullptr, true);
    for (int i = 0; i < 8; ++i) run.advance(50);  // 8 coupling steps of 1e-4 s
    run.finish();
    // 2.5e-4 lies half way between 2e-4 and 3e-4: taken at 3e-4, labelled 2.5e-4; 7.5e-4
    // likewise at 8e-4, which is also the end state (not written twice).
    CHECK(snapshot_attribute(files, "time") == std::vector<double>{0.0, 0.00025, 0.0005, 0.00075});
    const auto state = snapshot_attribute(files, "state_time");
    REQUIRE(state.size() == 4);
    CHECK(state[1] == Approx(3e-4));
    CHECK(state[2] == Approx(5e-4));
    CHECK(state[3] == Approx(8e-4));
  }
  SECTION("a restored run takes the same snapshots with the same labels") {
    const std::string ckpt = (dir.path / "ckpt.h5").string();
    {
      DemRun run(falling(), dir.path, 1, 2.5e-4, nullptr, true);
      for (int i = 0; i < 3; ++i) run.advance(50);  // t = 3e-4: output 1 taken here
      H5File f(ckpt, H5File::Mode::create);
      run.save(f, "dem");
      f.close();
      for (int i = 0; i < 5; ++i) run.advance(50);
      run.finish();
    }
    const auto times = snapshot_attribute(files, "time");
    const auto states = snapshot_attribute(files, "state_time");
    DemRun again(falling(), dir.path, 1, 2.5e-4, nullptr, true);
    again.restore(H5File(ckpt, H5File::Mode::read), "dem");
    for (int i = 0; i < 5; ++i) again.advance(50);
    again.finish();
    CHECK(snapshot_attribute(files, "time") == times);
    CHECK(snapshot_attribute(files, "state_time") == states);
  }
}

TEST_CASE("walls are written with the particle snapshots, where they are at each", "[output]") {
  TempDir dir;
  // A floor, and a plate that comes down at 2 m/s while the 12 spheres fall.
  const std::string walls = R"([[dem.walls]]
name = "floor"
material = "steel"
plane = { point = [0.015, 0.01, -0.05], normal = [0.0, 0.0, 1.0], size = 0.2 }
[[dem.walls]]
name = "plate <1>"
material = "steel"
plane = { point = [0.015, 0.01, 0.05], normal = [0.0, 0.0, -1.0], size = 0.1 }
motion = { kind = "translation", velocity = [0.0, 0.0, -2.0] }
)";
  const auto scene = [&](const std::string& output) {
    std::string text = std::string(kFalling) + walls + output;
    const auto doc = demfem::scene::Document::parse(text, "walls.toml");
    return read_dem_scene(doc.root().required_table("dem"));
  };
  const WallOutput files(dir.path, {});  // names only
  auto z_of = [&](std::size_t k, int wall) {
    const H5File f(files.snapshot_path(k), H5File::Mode::read);
    std::vector<std::size_t> dims;
    const auto p = f.read_doubles("wall_" + std::to_string(wall) + "/points", &dims);
    REQUIRE(dims.size() == 2);
    REQUIRE(dims[1] == 3);
    double lo = 1e300, hi = -1e300;
    for (std::size_t i = 2; i < p.size(); i += 3) lo = std::min(lo, p[i]), hi = std::max(hi, p[i]);
    CHECK(hi - lo < 1e-15);  // a plane stays flat
    return lo;
  };
  SECTION("positions, names and the index; a restored run continues the series") {
    const std::string ckpt = (dir.path / "ckpt.h5").string();
    {
      DemRun run(scene(""), dir.path, 1, 5e-4, nullptr, true);
      for (int i = 0; i < 3; ++i) run.advance(250);  // t = 1.5e-3 s
      H5File f(ckpt, H5File::Mode::create);
      run.save(f, "dem");
      f.close();
      run.advance(250);
      run.finish();
    }
    REQUIRE(std::filesystem::exists(files.snapshot_path(4)));
    CHECK_FALSE(std::filesystem::exists(files.snapshot_path(5)));
    for (std::size_t k = 0; k < 5; ++k) {
      CHECK(z_of(k, 0) == Approx(-0.05).margin(1e-12));
      // the plate: 0.05 - 2 m/s * t at t = k * 5e-4 s (the step ends fall on the outputs)
      CHECK(z_of(k, 1) == Approx(0.05 - 2.0 * 5e-4 * double(k)).margin(1e-12));
    }
    const H5File f0(files.snapshot_path(0), H5File::Mode::read);
    CHECK(f0.attribute_string("wall_1", "name") == "plate <1>");
    std::vector<std::size_t> dims;
    f0.read_doubles("wall_1/force", &dims);
    CHECK(dims == std::vector<std::size_t>{2, 3});  // a plane: two triangles
    const std::string x = read_text(files.index_path());
    CHECK(occurrences(x, "<Grid Name=\"floor\"") == 5);
    CHECK(occurrences(x, "<Grid Name=\"plate &lt;1&gt;\"") == 5);
    CHECK(occurrences(x, "walls_000004.h5:/wall_1/points</DataItem>") == 1);
    const std::string whole = x;
    DemRun again(scene(""), dir.path, 1, 5e-4, nullptr, true);
    again.restore(H5File(ckpt, H5File::Mode::read), "dem");
    CHECK(occurrences(read_text(files.index_path()), "<Grid Name=\"floor\"") == 4);
    again.advance(250);
    again.finish();
    CHECK(read_text(files.index_path()) == whole);
    CHECK(z_of(4, 1) == Approx(0.05 - 2.0 * 2e-3).margin(1e-12));
  }
  SECTION("[dem.output] walls = false writes none") {
    DemRun run(scene("[dem.output]\nwalls = false\n"), dir.path, 1, 5e-4, nullptr, true);
    run.advance(250);
    run.finish();
    CHECK(std::filesystem::exists(ParticleOutput(dir.path).snapshot_path(1)));
    CHECK_FALSE(std::filesystem::exists(files.snapshot_path(0)));
    CHECK_FALSE(std::filesystem::exists(files.index_path()));
  }
}

TEST_CASE("a wall's snapshot holds its sensor's face reading beside its total force", "[output]") {
  // Issue 34, item 11: a pressure cell's wall field was its net body force, not the face
  // reading of its sensor CSV. A closed box under the 6 resting spheres, read by a sensor on
  // its lid (face [0, 0, 1]: nothing touches it): sensor_force is the lid's 0 while force is
  // the floor's load; each equals what the system reports for the state written.
  TempDir dir;
  const std::string extra = R"([[dem.walls]]
name = "box"
material = "steel"
box = { lo = [0.0, 0.0, 0.0], hi = [0.03, 0.02, 0.05] }
[[dem.sensors]]
name = "lid"
kind = "wall_force"
interval = 5e-4
wall = "box"
face = [0.0, 0.0, 1.0]
)";
  const auto doc = demfem::scene::Document::parse(std::string(kFalling) + extra, "box.toml");
  DemRun run(read_dem_scene(doc.root().required_table("dem")), dir.path, 1, 5e-4, nullptr, true);
  run.advance(250);
  run.finish();
  const WallOutput files(dir.path, {{"box", {}}});  // names only
  REQUIRE(std::filesystem::exists(files.snapshot_path(1)));
  const H5File f(files.snapshot_path(1), H5File::Mode::read);
  std::vector<std::size_t> dims;
  const auto force = f.read_doubles("wall_0/force", &dims);
  const auto sensor = f.read_doubles("wall_0/sensor_force", &dims);
  REQUIRE(dims == std::vector<std::size_t>{12, 3});
  const auto total = run.system().wall_force(0);
  const auto lid = run.system().wall_face_load(0, {0.0, 0.0, 1.0}).force;
  for (std::size_t t = 0; t < 12; ++t)
    for (std::size_t c = 0; c < 3; ++c) {
      CHECK(force[3 * t + c] == total[c]);
      CHECK(sensor[3 * t + c] == lid[c]);
    }
  CHECK(total[2] < 0.0);  // the spheres press on the floor
  CHECK(lid == std::array<double, 3>{0.0, 0.0, 0.0});
  const std::string x = read_text(files.wall_index_path(0));
  CHECK(occurrences(x, "<Attribute Name=\"sensor_force\"") == 2);  // snapshots 0 and 1
}
