// DEM checkpoints without processes: a DemRun saved at a step boundary, dropped (as a killed
// dem_server would be) and restored into a fresh DemRun continues its sensor series exactly
// as the uninterrupted run writes them. The mass_flow sensor is the hard case: a particle
// crosses its plane between the checkpoint and the next sample, so the counter's memory of
// each particle's side (and the cumulative mass) must survive the restore.
#include <catch2/catch.hpp>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "demfem/dem/placement/state_check.hpp"
#include "demfem/dem/run/dem_run.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem/scene/scene_reader.hpp"
#include "demfem_test/dem_material_text.hpp"
#include "demfem_test/temp_dir.hpp"

namespace fs = std::filesystem;
using namespace demfem;

namespace {

using demfem::test::read_text;
using demfem::test::TempDir;

// Soft spheres 50 mm apart on a lattice of [0, 0, 0] .. [lattice_x, 0.03, 0.03] m (0.1 m: two
// of them), in free fall under `gravity` lines of [dem]; a kinetic-energy sensor and a
// mass-flow plane at z = `plane_z`, both sampled every 10 ms. Read as the file `name`.
dem::DemScene soft_spheres(double plane_z, const std::string& lattice_x,
                           const std::string& gravity, const std::string& name) {
  std::ostringstream t;
  t.precision(17);
  t << "[dem]\ndt = 1e-4\n" << gravity << demfem::test::dem_material("soft", "1e7", "7800.0")
    << demfem::test::dem_pair("soft", "soft", "0.0", "0.5")
    << "[[dem.lattice]]\nmaterial = \"soft\"\nlo = [0.0, 0.0, 0.0]\nhi = [" << lattice_x
    << ", 0.03, 0.03]\n"
    << "diameter = 0.024\nspacing = 0.05\n"
    << "[[dem.sensors]]\nname = \"flow\"\nkind = \"mass_flow\"\ninterval = 0.01\n"
    << "point = [0.0, 0.0, " << plane_z << "]\ndirection = [0.0, 0.0, -1.0]\n"
    << "[[dem.sensors]]\nname = \"ke\"\nkind = \"kinetic_energy\"\ninterval = 0.01\n";
  const auto doc = scene::Document::parse(t.str(), name);
  return dem::read_dem_scene(*doc.root().table("dem"));
}

// Two soft spheres apart from each other in free fall; a kinetic-energy sensor and a mass-flow
// plane at z = `plane_z` below their centres, both sampled every 10 ms.
dem::DemScene scene_with_plane(double plane_z) {
  return soft_spheres(plane_z, "0.1", "gravity = [0.0, 0.0, -9.81]\n", "restore_test.toml");
}

}  // namespace

TEST_CASE("a restored DemRun continues the sensor series of the uninterrupted run bitwise") {
  // Where the sphere centres start (read back from a first build of the same lattice).
  double z0 = 0.0;
  {
    TempDir probe;
    dem::DemRun run(scene_with_plane(-1.0), probe.path, 1, 0.0, nullptr, true);
    REQUIRE(run.system().particle_count() >= 2);
    z0 = run.system().particles().pz[0];
  }
  // The centres cross the plane at t = 10.5 ms (free fall: z0 - g t^2 / 2), between the
  // checkpoint (10.2 ms, after the sample at 10 ms) and the next sample (20 ms).
  const double plane = z0 - 0.5 * 9.81 * 0.0105 * 0.0105;
  const dem::DemScene sc = scene_with_plane(plane);
  constexpr int kSteps = 300, kCheckpoint = 102;

  TempDir a, b;
  {
    dem::DemRun run(sc, a.path, 1, 0.0, nullptr, true);
    for (int i = 0; i < kSteps; ++i) run.advance(1);
    run.finish();
  }
  const fs::path cp = b.path / "dem.h5";
  {
    dem::DemRun run(sc, b.path, 1, 0.0, nullptr, true);
    for (int i = 0; i < kCheckpoint; ++i) run.advance(1);
    io::H5File h5(cp, io::H5File::Mode::create);
    run.save(h5, "dem");
    h5.close();
    for (int i = kCheckpoint; i < kCheckpoint + 37; ++i) run.advance(1);  // then "killed"
  }
  {
    dem::DemRun run(sc, b.path, 1, 0.0, nullptr, true);
    io::H5File h5(cp, io::H5File::Mode::read);
    run.restore(h5, "dem");
    for (int i = kCheckpoint; i < kSteps; ++i) run.advance(1);
    run.finish();
  }
  const std::string flow_a = read_text(a.path / "sensor_flow.csv");
  const std::string flow_b = read_text(b.path / "sensor_flow.csv");
  INFO(flow_a << "\n---\n" << flow_b);
  // The uninterrupted run saw the spheres cross (a positive cumulative mass in the last row),
  // so the comparison is not between two series of zeros.
  const auto last = flow_a.substr(flow_a.rfind(',', flow_a.size() - 2) + 1);
  CHECK(std::stod(last) > 0.0);
  CHECK(flow_a == flow_b);
  CHECK(read_text(a.path / "sensor_ke.csv") == read_text(b.path / "sensor_ke.csv"));
}

TEST_CASE("a restored DEM state is checked as strictly as a scene") {
  // Issue 19, defect 7: a checkpoint with NaN positions (and a matching manifest) resumed.
  dem::ParticleState st;
  auto add = [&](double z) {
    for (auto* v : {&st.px, &st.py, &st.vx, &st.vy, &st.vz, &st.wx, &st.wy, &st.wz, &st.qx,
                    &st.qy, &st.qz, &st.fx, &st.fy, &st.fz})
      v->push_back(0.0);
    st.pz.push_back(z);
    st.qw.push_back(1.0);
    st.radius.push_back(0.01);
    st.mass.push_back(0.1);
    st.inertia.push_back(4e-6);
    st.material.push_back(0);
    st.shape.push_back(0);
  };
  add(0.0);
  add(0.1);
  CHECK_NOTHROW(dem::check_particle_state(st, "cp.h5:/dem"));
  auto refused = [&](auto change, const std::string& expect) {
    dem::ParticleState bad = st;
    change(bad);
    CHECK_THROWS_WITH(dem::check_particle_state(bad, "cp.h5:/dem"),
                      Catch::Contains("cp.h5:/dem") && Catch::Contains(expect));
  };
  refused([](auto& s) { s.pz[1] = std::nan(""); }, "particle 1: position z is nan");
  refused([](auto& s) { s.vx[0] = INFINITY; }, "particle 0: velocity x is inf");
  refused([](auto& s) { s.radius[1] = 0.0; }, "particle 1: radius is 0 (must be finite and > 0)");
  refused([](auto& s) { s.mass[0] = -1.0; }, "particle 0: mass is -1");
  refused([](auto& s) { s.inertia[0] = std::nan(""); }, "moment of inertia is nan");
  refused([](auto& s) { s.qw[1] = 0.5; }, "|orientation|^2 is 0.25");
  refused([](auto& s) { s.vy.pop_back(); }, "velocity y has 1 entries for 2 particles");
}

TEST_CASE("a DEM checkpoint of a scene that made other particles is refused on restore") {
  // Issue 19, defect 7: docs/reliability.md said the particle count was checked; it was not
  // (the checkpoint's particles silently replaced those of the changed scene).
  TempDir d;
  const fs::path cp = d.path / "dem.h5";
  {
    dem::DemRun run(scene_with_plane(-1.0), d.path, 1, 0.0, nullptr, true);
    run.advance(3);
    io::H5File h5(cp, io::H5File::Mode::create);
    run.save(h5, "dem");
    h5.close();
  }
  // Twice the lattice's length in x: more spheres at set-up.
  const dem::DemScene bigger = soft_spheres(-1.0, "0.2", "", "bigger.toml");
  dem::DemRun run(bigger, d.path, 1, 0.0, nullptr, true);
  REQUIRE(run.setup_particles() == 4);
  io::H5File h5(cp, io::H5File::Mode::read);
  CHECK_THROWS_WITH(run.restore(h5, "dem"),
                    Catch::Contains("dem.h5: the checkpoint's scene made 2 particles at set-up") &&
                        Catch::Contains("bigger.toml) makes 4"));
  // The launcher's check before any process starts counts the same.
  CHECK(dem::DemRun::check_setup(bigger, 1) == 4);
}
