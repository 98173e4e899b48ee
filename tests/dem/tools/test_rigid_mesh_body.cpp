// Rigid mesh bodies moved by the particles' contact forces (WallMesh::body,
// physics/rigid_mesh_body.hpp): mass properties of a closed mesh against the formulas of a
// box, free fall against z0 - g t^2 / 2, conservation of linear and angular momentum in an
// off-centre impact, constraints, a body resting on a sphere layer (reactions = weights),
// bitwise save/restore, and the scene keys with their errors.

#include <catch2/catch.hpp>

#include <cmath>
#include <utility>

#include "../core/dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/physics/rigid_body.hpp"
#include "demfem/dem/scene/dem_scene.hpp"
#include "demfem/dem/shapes/mesh_body.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem/scene/scene_reader.hpp"
#include "demfem_test/dem_material_text.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem;
using namespace demfem::dem;

namespace {

WallMesh box_body(std::array<double, 3> lo, std::array<double, 3> hi, std::int32_t material = 1) {
  WallMesh w = demfem::dem::test::box_mesh(lo, hi, material);
  w.name = "body";
  return w;
}

DemSettings settings(std::array<double, 3> g, double dt = 1e-5) {
  DemSettings s;
  s.dt = dt;
  s.gravity = g;
  s.materials = {{"grain", 1e7, 0.3, 2000.0}, {"steel", 1e7, 0.3, 0.0}};
  s.pairs.assign(4, MaterialPair{0.5, 0.5, 0.0});
  s.threads = 1;
  return s;
}

void make_body(WallMesh& w, double density) {
  const auto p = shapes::closed_mesh_properties(w.vertices, w.triangles, density, w.name);
  w.body.enabled = true;
  w.body.mass = p.mass;
  w.body.inertia = p.moments;
  w.body.centre = p.centre;
  w.body.orientation = p.orientation;
}

ParticleInit ball(std::array<double, 3> x, double r, std::array<double, 3> v = {}) {
  ParticleInit p;
  p.position = x;
  p.velocity = v;
  p.radius = r;
  return p;
}

// A floor, nine balls of 5 cm in a 3 x 3 grid (pitch 0.14 m in x, y_pitch in y) and a free
// plate (0.4 x 0.4 x 0.04 m, 2000 kg/m³) above them, which lands on them under gravity. Returns
// the plate's wall index and mesh.
std::pair<std::int32_t, WallMesh> plate_on_nine_balls(DemSystem& d, double y_pitch) {
  WallMesh floor = box_body({-0.5, -0.5, -0.1}, {0.5, 0.5, 0.0});
  floor.name = "floor";
  d.add_wall(floor);
  WallMesh plate = box_body({-0.2, -0.2, 0.1}, {0.2, 0.2, 0.14});
  make_body(plate, 2000.0);
  plate.body.fix_rotation = false;
  std::vector<ParticleInit> ps;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      ps.push_back(ball({-0.14 + 0.14 * i, -0.14 + y_pitch * j, 0.05}, 0.05));
  d.add_particles(ps);
  return {d.add_wall(plate), plate};
}

/// Linear momentum and angular momentum about the origin of the particles and the body.
std::array<double, 6> momenta(const DemSystem& d, std::int32_t wall, const WallMesh& w) {
  std::array<double, 6> m{};
  const auto& p = d.particles();
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double px = p.mass[i] * p.vx[i], py = p.mass[i] * p.vy[i], pz = p.mass[i] * p.vz[i];
    m[0] += px, m[1] += py, m[2] += pz;
    m[3] += p.py[i] * pz - p.pz[i] * py + p.inertia[i] * p.wx[i];
    m[4] += p.pz[i] * px - p.px[i] * pz + p.inertia[i] * p.wy[i];
    m[5] += p.px[i] * py - p.py[i] * px + p.inertia[i] * p.wz[i];
  }
  const RigidBodyState b = d.body_state(wall);
  const double M = w.body.mass;
  const double px = M * b.velocity[0], py = M * b.velocity[1], pz = M * b.velocity[2];
  m[0] += px, m[1] += py, m[2] += pz;
  m[3] += b.centre[1] * pz - b.centre[2] * py;
  m[4] += b.centre[2] * px - b.centre[0] * pz;
  m[5] += b.centre[0] * py - b.centre[1] * px;
  // spin: R I Rᵀ ω
  const auto& q = b.orientation;
  const auto r = phys::rotation(q[0], q[1], q[2], q[3]);
  const auto wb = phys::to_body(
      r, phys::Vec3{b.angular_velocity[0], b.angular_velocity[1], b.angular_velocity[2]});
  const auto l = phys::to_world(
      r, phys::Vec3{w.body.inertia[0] * wb.x, w.body.inertia[1] * wb.y, w.body.inertia[2] * wb.z});
  m[3] += l.x, m[4] += l.y, m[5] += l.z;
  return m;
}

}  // namespace

TEST_CASE("closed mesh mass properties equal a box's formulas", "[rigid_body]") {
  // 0.4 x 0.2 x 0.1 box, rho = 800: m = 6.4 kg, I = m (b² + c²) / 12 ...
  WallMesh w = box_body({1.0, 2.0, 3.0}, {1.4, 2.2, 3.1});
  const auto p = shapes::closed_mesh_properties(w.vertices, w.triangles, 800.0, "box");
  const double m = 800.0 * 0.4 * 0.2 * 0.1;
  CHECK(p.mass == Approx(m).epsilon(1e-12));
  CHECK(p.centre[0] == Approx(1.2).epsilon(1e-12));
  CHECK(p.centre[1] == Approx(2.1).epsilon(1e-12));
  CHECK(p.centre[2] == Approx(3.05).epsilon(1e-12));
  // ascending: about x (0.2, 0.1), ... about z (0.4, 0.2) largest
  CHECK(p.moments[0] == Approx(m * (0.04 + 0.01) / 12).epsilon(1e-10));
  CHECK(p.moments[1] == Approx(m * (0.16 + 0.01) / 12).epsilon(1e-10));
  CHECK(p.moments[2] == Approx(m * (0.16 + 0.04) / 12).epsilon(1e-10));
  // inward normals (a box wall) give the same
  WallMesh inv = w;
  for (std::size_t t = 0; t < inv.triangles.size(); t += 3)
    std::swap(inv.triangles[t + 1], inv.triangles[t + 2]);
  CHECK(shapes::closed_mesh_properties(inv.vertices, inv.triangles, 800.0, "box").mass ==
        Approx(m).epsilon(1e-12));
  // an open mesh is refused
  WallMesh open = w;
  open.triangles.resize(open.triangles.size() - 3);
  CHECK_THROWS_WITH(shapes::closed_mesh_properties(open.vertices, open.triangles, 800.0, "box"),
                    Catch::Contains("not closed"));
}

TEST_CASE("a free rigid body falls as z0 - g t^2 / 2", "[rigid_body]") {
  DemSystem d(settings({0, 0, -9.81}, 1e-4));
  WallMesh w = box_body({0, 0, 1}, {0.2, 0.2, 1.1});
  make_body(w, 1000.0);
  const auto id = d.add_wall(w);
  d.advance(5000);  // 0.5 s
  const auto b = d.body_state(id);
  const double t = 0.5;
  // velocity Verlet is exact for a constant force (to rounding)
  CHECK(b.centre[2] == Approx(1.05 - 0.5 * 9.81 * t * t).epsilon(1e-12));
  CHECK(b.velocity[2] == Approx(-9.81 * t).epsilon(1e-12));
  CHECK(b.centre[0] == 0.1);
  const auto v = d.wall_vertices(id);  // the mesh moved with it
  CHECK(v[2] == Approx(1.0 - 0.5 * 9.81 * t * t).epsilon(1e-12));
}

TEST_CASE("an off-centre impact on a free body conserves linear and angular momentum",
          "[rigid_body]") {
  // Frictionless: the shared wall contact law gives the particle the torque of its tangential
  // force about an arm of length r, the wall that of the same force at the contact point on
  // the triangle (r - overlap from the centre); the two differ by overlap x f_t, so with
  // friction the angular momentum is kept only to O(overlap / r) of the tangential impulse.
  DemSettings s = settings({0, 0, 0});
  s.pairs.assign(4, MaterialPair{0.0, 0.5, 0.0});
  DemSystem d(s);
  WallMesh w = box_body({-0.2, -0.1, -0.05}, {0.2, 0.1, 0.05});
  make_body(w, 500.0);
  const auto id = d.add_wall(w);
  // a sphere hits the top face 0.12 m off the centre, obliquely
  std::vector<ParticleInit> ps{ball({0.12, 0.03, 0.1}, 0.04, {-0.3, 0.1, -1.0})};
  d.add_particles(ps);
  const auto m0 = momenta(d, id, w);
  d.advance(20000);  // 0.2 s: the contact is over
  const auto m1 = momenta(d, id, w);
  const auto b = d.body_state(id);
  CHECK(std::abs(b.angular_velocity[0]) + std::abs(b.angular_velocity[1]) > 1e-3);  // it spins
  CHECK(d.particles().vz[0] > 0.0);                                                 // bounced
  for (int k = 0; k < 6; ++k) {
    INFO("component " << k << ": " << m0[k] << " -> " << m1[k]);
    CHECK(std::abs(m1[k] - m0[k]) < 1e-10 * 0.4);  // |p| = m v ≈ 0.56 kg m/s
  }
}

TEST_CASE("a body constrained to z moves only in z", "[rigid_body]") {
  DemSystem d(settings({0, 0, 0}));
  WallMesh w = box_body({-0.2, -0.1, -0.05}, {0.2, 0.1, 0.05});
  make_body(w, 500.0);
  w.body.fix_translation = {true, true, false};
  w.body.fix_rotation = true;
  const auto id = d.add_wall(w);
  std::vector<ParticleInit> ps{ball({0.12, 0.03, 0.1}, 0.04, {-0.3, 0.1, -1.0})};
  d.add_particles(ps);
  const double pz0 = d.particles().mass[0] * d.particles().vz[0];
  d.advance(20000);
  const auto b = d.body_state(id);
  CHECK(b.centre[0] == w.body.centre[0]);
  CHECK(b.centre[1] == w.body.centre[1]);
  CHECK(b.orientation == w.body.orientation);
  CHECK(b.centre[2] < w.body.centre[2] - 1e-4);  // pushed down
  const double pz1 = d.particles().mass[0] * d.particles().vz[0] + w.body.mass * b.velocity[2];
  CHECK(pz1 == Approx(pz0).epsilon(1e-10));  // z momentum is conserved, x and y are not
}

TEST_CASE("a body resting on spheres: reactions equal the weights; restore is bitwise",
          "[rigid_body]") {
  const double g = 9.81;
  DemSettings s = settings({0, 0, -g}, 2e-5);
  s.pairs.assign(4, MaterialPair{0.5, 0.2, 0.0});
  DemSystem d(s);
  auto [id, plate] = plate_on_nine_balls(d, 0.14);
  d.advance(100000);  // 2 s: settled (restitution 0.2)
  const auto b = d.body_state(id);
  double spheres = 0.0;
  for (double m : d.particles().mass) spheres += m;
  const double weight = (plate.body.mass + spheres) * g;
  INFO("plate " << plate.body.mass << " kg, spheres " << spheres << " kg");
  CHECK(d.wall_force(0)[2] == Approx(-weight).epsilon(1e-3));  // the floor carries everything
  CHECK(b.force[2] == Approx(plate.body.mass * g).epsilon(1e-3));
  CHECK(std::abs(b.velocity[2]) < 1e-4);

  // save half-way, restore into a fresh system, continue: bitwise equal
  demfem::test::TempDir dir("rigid_body");
  DemSystem a(s), c(s);
  plate_on_nine_balls(a, 0.14);
  plate_on_nine_balls(c, 0.14);
  a.advance(1000);
  {
    io::H5File h5(dir.path / "s.h5", io::H5File::Mode::create);
    a.save(h5, "/dem");
  }
  {
    io::H5File h5(dir.path / "s.h5", io::H5File::Mode::read);
    c.restore(h5, "/dem");
  }
  a.advance(1000);
  c.advance(1000);
  const auto ba = a.body_state(1), bc = c.body_state(1);
  CHECK(ba.centre == bc.centre);
  CHECK(ba.velocity == bc.velocity);
  CHECK(ba.orientation == bc.orientation);
  CHECK(ba.angular_velocity == bc.angular_velocity);
  CHECK(a.particles().pz == c.particles().pz);
  CHECK(a.particles().vx == c.particles().vx);
  // a state without the body is refused by a system with one
  DemSystem nobody(s);
  WallMesh floor = box_body({-0.5, -0.5, -0.1}, {0.5, 0.5, 0.0});
  nobody.add_wall(floor);
  {
    io::H5File h5(dir.path / "n.h5", io::H5File::Mode::create);
    nobody.save(h5, "/dem");
  }
  io::H5File h5(dir.path / "n.h5", io::H5File::Mode::read);
  CHECK_THROWS_WITH(c.restore(h5, "/dem"), Catch::Contains("rigid"));
}

TEST_CASE("rigid bodies are refused with a reason: bad mass, prescribed motion", "[rigid_body]") {
  DemSystem d(settings({0, 0, 0}));
  WallMesh w = box_body({0, 0, 0}, {1, 1, 1});
  w.body.enabled = true;
  w.body.mass = 0.0;
  w.body.inertia = {1, 1, 1};
  CHECK_THROWS_WITH(d.add_wall(w), Catch::Contains("mass must be"));
  w.body.mass = 1.0;
  w.motion.kind = WallMotion::Kind::translation;
  CHECK_THROWS_WITH(d.add_wall(w), Catch::Contains("prescribed motion"));
}

TEST_CASE("scene: [dem.walls.body] keys and their errors", "[rigid_body][scene]") {
  auto parse_body = [&](const std::string& body) {
    const std::string text = std::string(R"(
[run]
end_time = 0.01
[dem]
dt = 1e-5
gravity = [0, 0, -9.81]
)") +
    // grain (E, density), steel (E), both pairs: friction, restitution
    demfem::test::grain_and_wall("grain", "1e7", "2000", "steel", "1e7", "0.5", "0.5") +
    R"([[dem.walls]]
name = "cell"
material = "steel"
box = { lo = [0, 0, 0], hi = [0.22, 0.22, 0.1] }
)" + body;
    demfem::scene::Document d = demfem::scene::Document::parse(text, "s.toml");
    demfem::scene::read_run_settings(d);
    return read_dem_scene(d.root().required_table("dem"));
  };
  const DemScene s =
      parse_body("body = { density = 7800, fixed = [\"x\", \"y\", \"rotation\"] }\n");
  REQUIRE(s.walls.size() == 1);
  CHECK(s.walls[0].body.enabled);
  CHECK(s.walls[0].body_density == 7800);
  CHECK(s.walls[0].body.fix_translation == std::array<bool, 3>{true, true, false});
  CHECK(s.walls[0].body.fix_rotation);
  CHECK_THROWS_WITH(parse_body("body = { density = 7800, mass = 3 }\n"),
                    Catch::Contains("exactly one of 'density'"));
  CHECK_THROWS_WITH(parse_body("body = { density = 7800, fixed = [\"w\"] }\n"),
                    Catch::Contains("unknown entry \"w\""));
  CHECK_THROWS_WITH(parse_body("body = { mass = 3 }\n"), Catch::Contains("inertia"));
  CHECK_THROWS_WITH(
      parse_body(
          "body = { density = 1 }\nmotion = { kind = \"translation\", velocity = [0, 0, 1] }\n"),
      Catch::Contains("cannot also have a 'motion'"));
}

TEST_CASE("a sinusoid wall motion with a drift: x0 + A sin(2 pi f t + phase) d + v t",
          "[rigid_body][walls]") {
  DemSystem d(settings({0, 0, 0}, 1e-4));
  WallMesh w = box_body({0, 0, 1}, {1, 1, 1.02});
  w.motion.kind = WallMotion::Kind::sinusoid;
  w.motion.axis = {0, 0, 1};
  w.motion.amplitude = 0.01;
  w.motion.frequency = 5.0;
  w.motion.phase = 0.5;
  w.motion.velocity = {0, 0, -0.2};
  w.motion.end_time = 0.3;
  const auto id = d.add_wall(w);
  d.advance(2000);  // 0.2 s
  const double pi = 3.14159265358979323846;
  auto z_at = [&](double t) { return 1.0 + 0.01 * std::sin(2 * pi * 5.0 * t + 0.5) - 0.2 * t; };
  CHECK(d.wall_vertices(id)[2] == Approx(z_at(0.2)).epsilon(1e-12));
  d.advance(2000);  // 0.4 s: stopped at the pose of end_time
  CHECK(d.wall_vertices(id)[2] == Approx(z_at(0.3)).epsilon(1e-12));
}

// Implicit coupling goes back to a coupling step's start in memory (DemSystem::save_state):
// the bodies' poses, velocities and last loads are part of that state, or an iterated step
// would start the body from where the last iterate left it.
TEST_CASE("a rigid body returns to the in-memory save point bit for bit", "[rigid_body]") {
  DemSettings s = settings({0, 0, -9.81}, 2e-5);
  s.pairs.assign(4, MaterialPair{0.5, 0.2, 0.0});
  DemSystem d(s);
  const std::int32_t id = plate_on_nine_balls(d, 0.13).first;
  d.advance(3000);  // the plate has landed on the spheres and rocks on them
  DemStateCopy copy;
  d.save_state(copy);
  d.advance(500);
  const RigidBodyState first = d.body_state(id);
  const auto pz = d.particles().pz;
  d.restore_state(copy);
  d.advance(500);
  const RigidBodyState again = d.body_state(id);
  CHECK(again.centre == first.centre);
  CHECK(again.velocity == first.velocity);
  CHECK(again.orientation == first.orientation);
  CHECK(again.angular_velocity == first.angular_velocity);
  CHECK(again.force == first.force);
  CHECK(d.particles().pz == pz);
}

// A pressure cell (docs/cases.md, sleeper): a body held in x, y and rotation between a layer
// under it and spheres on top. The net force of the particles on it is its weight (it
// floats); the force on its top face is the weight of the spheres resting on it, on its
// bottom face that plus the cell's weight (DemSystem::wall_face_load).
TEST_CASE("force on one face of a wall: the top and bottom of a cell in a layer",
          "[rigid_body][sensor]") {
  const double g = 9.81;
  DemSettings s = settings({0, 0, -g}, 2e-5);
  s.pairs.assign(4, MaterialPair{0.5, 0.2, 0.0});
  DemSystem d(s);
  WallMesh floor = box_body({-0.5, -0.5, -0.1}, {0.5, 0.5, 0.0});
  floor.name = "floor";
  d.add_wall(floor);
  WallMesh cell = box_body({-0.2, -0.2, 0.1}, {0.2, 0.2, 0.14});
  make_body(cell, 2000.0);
  cell.body.fix_translation = {true, true, false};
  cell.body.fix_rotation = true;
  std::vector<ParticleInit> ps;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      ps.push_back(ball({-0.14 + 0.14 * i, -0.14 + 0.14 * j, 0.05}, 0.05));
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j) ps.push_back(ball({-0.1 + 0.2 * i, -0.1 + 0.2 * j, 0.19}, 0.04));
  d.add_particles(ps);
  const std::int32_t id = d.add_wall(cell);
  d.advance(100000);  // 2 s: settled, but for a ringing of about 1e-4 m/s (0.3 % of the
                      // loads) that the contacts' dashpots hardly damp: mean over 0.2 s
  double on_top = 0.0, all = 0.0;
  for (std::size_t i = 0; i < d.particles().size(); ++i) {
    all += d.particles().mass[i];
    if (i >= 9) on_top += d.particles().mass[i];
  }
  WallFaceLoad top, bottom;
  std::array<double, 3> net{}, floor_top{};
  const int n = 1000;
  for (int k = 0; k < n; ++k) {
    d.advance(10);
    const auto t = d.wall_face_load(id, {0, 0, 1}), b = d.wall_face_load(id, {0, 0, -1});
    const auto f = d.wall_force(id), ft = d.wall_face_load(0, {0, 0, 1}).force;
    top.area = t.area, bottom.area = b.area;
    for (int e = 0; e < 3; ++e) {
      top.force[e] += t.force[e] / n, bottom.force[e] += b.force[e] / n;
      net[e] += f[e] / n, floor_top[e] += ft[e] / n;
    }
  }
  CHECK(top.area == Approx(0.16).epsilon(1e-12));
  CHECK(bottom.area == Approx(0.16).epsilon(1e-12));
  CHECK(top.force[2] == Approx(-on_top * g).epsilon(1e-3));
  CHECK(bottom.force[2] == Approx((cell.body.mass + on_top) * g).epsilon(1e-3));
  CHECK(net[2] == Approx(cell.body.mass * g).epsilon(1e-3));
  CHECK(floor_top[2] == Approx(-(cell.body.mass + all) * g).epsilon(1e-3));
  CHECK(d.wall_face_load(id, {1, 0, 0}).force[0] == 0.0);  // nothing touches its sides
  CHECK_THROWS_AS(d.wall_face_load(id, {0, 0, 0}), std::invalid_argument);
}
