// Walls: contacts at edges and vertices count once; the flexible mesh: barycentric force
// split and prescribed kinematics; prescribed wall motion.

#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>

#include "dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/io/h5_file.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;

namespace {
constexpr double kE = 1e8, kNu = 0.3, kRho = 2500.0;

// Force on a resting sphere (overlap delta) above the point (x, y) of a 2 x 2-cell plane.
double resting_force(double x, double y, double delta, bool flexible = false) {
  DemSystem sys(two_material_settings(kE, kNu, kRho, 0.5, 0.5, 1e-8));
  add_rigid_or_flexible(sys, plane_mesh(0.02, 2), flexible);
  const double r = 0.002;
  const std::vector<ParticleInit> p = {sphere({x, y, r - delta}, r)};
  sys.add_particles(p);
  sys.advance(1);
  return sys.particles().fz[0];
}
}  // namespace

TEST_CASE("A sphere across an edge or a vertex feels the face force", "[dem][wall]") {
  // Reference: the Hertz force of a sphere on a flat plane, F = 4/3 E* sqrt(r) delta^1.5
  // (wall: R = r). The plane (2 x 2 cells, 8 triangles) has a vertex shared by 6 triangles
  // at the origin and edges along x = 0, y = 0 and the cell diagonals. Tolerance 1e-9
  // relative (one step of 1e-8 s changes the overlap by < 1e-15 m).
  const double delta = 2e-5, r = 0.002;
  const double f_ref = 4.0 / 3.0 * kE / (2 * (1 - kNu * kNu)) * std::sqrt(r) * std::pow(delta, 1.5);
  for (bool flex : {false, true}) {
    INFO("flexible mesh: " << flex);
    CHECK(resting_force(0.0031, -0.0017, delta, flex) == Approx(f_ref).epsilon(1e-9));  // face
    CHECK(resting_force(0.0043, 0.0, delta, flex) == Approx(f_ref).epsilon(1e-9));      // edge
    CHECK(resting_force(0.003, 0.003, delta, flex) == Approx(f_ref).epsilon(1e-9));     // diagonal
    CHECK(resting_force(0.0, 0.0, delta, flex) == Approx(f_ref).epsilon(1e-9));         // vertex
    CHECK(resting_force(0.01, 0.0, delta, flex) == Approx(f_ref).epsilon(1e-9));  // rim vertex
  }
}

TEST_CASE("A sphere at a convex edge is pushed once, along the edge normal", "[dem][wall]") {
  // Two faces of a roof meeting at the ridge y = 0, z = 0 at 90 degrees; a sphere above the
  // ridge at distance r - delta touches only the edge: Hertz force of overlap delta along
  // +z. Reference: eq. 2.6 with R = r; tolerance 1e-9 relative.
  DemSystem sys(two_material_settings(kE, kNu, kRho, 0.5, 0.0, 1e-8));
  sys.add_wall(roof_mesh());
  const double r = 0.002, delta = 1e-5;
  const std::vector<ParticleInit> p = {sphere({0.001, 0, r - delta}, r)};
  sys.add_particles(p);
  sys.advance(1);
  const double f_ref = 4.0 / 3.0 * kE / (2 * (1 - kNu * kNu)) * std::sqrt(r) * std::pow(delta, 1.5);
  CHECK(sys.particles().fz[0] == Approx(f_ref).epsilon(1e-9));
  CHECK(std::abs(sys.particles().fy[0]) < 1e-9 * f_ref);
  // the wall feels the opposite force
  CHECK(sys.wall_force(0)[2] == Approx(-f_ref).epsilon(1e-9));
}

TEST_CASE("Flexible mesh: barycentric forces sum to the contact forces", "[dem][flexible]") {
  // 40 spheres pressed into a 4 x 4-cell flexible mesh at arbitrary points; reference: the
  // total force and moment (about the origin) that the particles feel, with opposite sign.
  // The barycentric split preserves both exactly for contacts on faces (contact point =
  // sum b_k x_k); tolerance 1e-12 relative to the total force.
  DemSystem sys(two_material_settings(kE, kNu, kRho, 0.5, 0.3, 1e-8));
  const demfem::InterfaceMesh im = interface_mesh_of(plane_mesh(0.04, 4));
  sys.set_flexible_mesh(im, 1);
  std::vector<ParticleInit> p;
  const double r = 0.001;
  for (int k = 0; k < 40; ++k) {
    const double x = -0.018 + 0.036 * std::fmod(0.618 * k, 1.0);
    const double y = -0.018 + 0.036 * std::fmod(0.414 * k + 0.1, 1.0);
    p.push_back(sphere({x, y, r - 1e-6 * (1 + k % 7)}, r, {0.01 * (k % 3), 0, 0}));
  }
  sys.add_particles(p);
  sys.advance(1);
  std::vector<double> nf(3 * im.node_count());
  sys.flexible_forces(nf);
  const auto& st = sys.particles();
  double fp[3] = {0, 0, 0}, fn[3] = {0, 0, 0}, mn[3] = {0, 0, 0}, mp[3] = {0, 0, 0};
  for (std::size_t i = 0; i < st.size(); ++i) {
    fp[0] += st.fx[i], fp[1] += st.fy[i], fp[2] += st.fz[i];
    // contact point below the centre at the plane z = 0 (face contacts)
    const double c[3] = {st.px[i], st.py[i], 0.0};
    mp[0] += c[1] * st.fz[i] - c[2] * st.fy[i];
    mp[1] += c[2] * st.fx[i] - c[0] * st.fz[i];
    mp[2] += c[0] * st.fy[i] - c[1] * st.fx[i];
  }
  for (std::size_t k = 0; k < im.node_count(); ++k) {
    const double* x = &im.reference_positions[3 * k];
    const double* f = &nf[3 * k];
    for (int d = 0; d < 3; ++d) fn[d] += f[d];
    mn[0] += x[1] * f[2] - x[2] * f[1];
    mn[1] += x[2] * f[0] - x[0] * f[2];
    mn[2] += x[0] * f[1] - x[1] * f[0];
  }
  const double scale = std::abs(fp[2]);
  REQUIRE(scale > 0.0);
  for (int d = 0; d < 3; ++d) {
    CHECK(std::abs(fn[d] + fp[d]) <= 1e-12 * scale);
    CHECK(std::abs(mn[d] + mp[d]) <= 1e-12 * scale * 0.04);
  }
  CHECK(sys.flexible_max_overlap() == Approx(7e-6).epsilon(1e-6));
}

TEST_CASE("Flexible mesh follows its kinematics and pushes particles", "[dem][flexible]") {
  // x(tau) = x + v tau + a tau^2 / 2 over an advance() of n substeps: reference the formula,
  // tolerance 1e-15 m. A sphere resting on the mesh is carried upwards.
  auto s = two_material_settings(kE, kNu, kRho, 0.4, 0.3, 1e-6);
  s.gravity = {0, 0, -9.81};
  DemSystem sys(s);
  const demfem::InterfaceMesh im = interface_mesh_of(plane_mesh(0.02, 2));
  sys.set_flexible_mesh(im, 1);
  const double r = 0.002;
  const std::vector<ParticleInit> p = {sphere({0.001, 0.002, r}, r)};
  sys.add_particles(p);
  const std::size_t nn = im.node_count();
  std::vector<double> x = im.reference_positions, v(3 * nn, 0.0), a(3 * nn, 0.0);
  for (std::size_t k = 0; k < nn; ++k) v[3 * k + 2] = 0.05, a[3 * k + 2] = 2.0;
  for (int c = 0; c < 20; ++c) {
    sys.set_flexible_kinematics(x, v, a);
    sys.advance(500, demfem::ForceMode::average);
    const double tau = 500 * 1e-6;
    const auto xp = sys.flexible_positions();
    for (std::size_t k = 0; k < 3 * nn; ++k) {
      const double ref = x[k] + v[k] * tau + 0.5 * a[k] * tau * tau;
      REQUIRE(std::abs(xp[k] - ref) <= 1e-15);
      x[k] = ref;
      v[k] += a[k] * tau;
    }
  }
  // after 10 ms the mesh is at z = 0.05*0.01 + 0.5*2*1e-4 = 6e-4 m; the sphere rides on it
  const double zmesh = x[2];
  CHECK(zmesh == Approx(6e-4).epsilon(1e-12));
  const double gap = sys.particles().pz[0] - r - zmesh;
  CHECK(gap < 0.0);
  CHECK(gap > -5e-6);
  std::vector<double> nf(3 * nn);
  sys.flexible_forces(nf);
  double fz = 0.0;
  for (std::size_t k = 0; k < nn; ++k) fz += nf[3 * k + 2];
  CHECK(fz < 0.0);  // the particle presses down on the structure
}

TEST_CASE("Prescribed wall motion moves the vertices", "[dem][wall]") {
  // Reference: the motion formulas of WallMotion; tolerance 1e-15 m.
  DemSystem sys(two_material_settings(kE, kNu, kRho, 0.5, 0.3, 1e-4));
  WallMesh w = plane_mesh(0.02, 1);
  w.motion.kind = WallMotion::Kind::sinusoid;
  w.motion.axis = {0, 0, 2};  // normalised by add_wall
  w.motion.amplitude = 0.001;
  w.motion.frequency = 5.0;
  w.motion.start_time = 0.01;
  w.motion.end_time = 0.05;
  const auto id = sys.add_wall(w);
  WallMesh rot = plane_mesh(0.02, 1);
  rot.motion.kind = WallMotion::Kind::rotation;
  rot.motion.axis = {0, 0, 1};
  rot.motion.angular_velocity = 2.0;
  const auto id2 = sys.add_wall(rot);
  sys.advance(300);  // t = 0.03 s: 0.02 s into the window
  const auto v = sys.wall_vertices(id);
  CHECK(std::abs(v[2] - 0.001 * std::sin(2 * std::numbers::pi * 5 * 0.02)) < 1e-15);
  sys.advance(500);  // t = 0.08 s: motion stopped at 0.05 s
  const auto v2 = sys.wall_vertices(id);
  CHECK(std::abs(v2[2] - 0.001 * std::sin(2 * std::numbers::pi * 5 * 0.04)) < 1e-15);
  const auto r = sys.wall_vertices(id2);
  const double th = 2.0 * 0.08;
  CHECK(std::abs(r[0] - (std::cos(th) * -0.01 - std::sin(th) * -0.01)) < 1e-15);
  CHECK(std::abs(r[1] - (std::sin(th) * -0.01 + std::cos(th) * -0.01)) < 1e-15);
}

TEST_CASE("A force-limited plate presses a sphere with its max_force and stops",
          "[dem][walls][motion]") {
  // A sphere (r = 5 mm) on a floor, a plate 1 mm above it moving down at 0.05 m/s. With
  // motion.max_force = F the drift goes on at (1 - R/F) of its speed, R the sphere's push
  // against it, and stops at R >= F: at rest, floor and plate each press it with F
  // (reference: the Hertz sphere-wall law, F = 4/3 E* sqrt(r) delta^1.5, so the plate's bottom
  // is at 2 r - 2 delta). Tolerances: the force within 0.1 % of F, the plate within 1 % of
  // 2 delta. (A drift that paused at R >= F and went on at full speed otherwise ended at
  // 1.065 F: each bounce let it on.) Without the limit the plate drives 9 mm into the sphere
  // (the overlap guard's case). A continuation from a saved state (in memory and HDF5) is
  // bitwise.
  const double r = 0.005, gap = 0.001, v = 0.05, F = 1.0;
  auto make = [&](double max_force) {
    DemSettings s = two_material_settings(kE, kNu, kRho, 0.5, 0.3, 1e-6);
    DemSystem sys(s);
    sys.add_wall(plane_mesh(0.05, 2));
    WallMesh plate = plane_mesh(0.05, 2);
    plate.name = "plate";
    for (std::size_t k = 2; k < plate.vertices.size(); k += 3) plate.vertices[k] = 2 * r + gap;
    plate.motion.kind = WallMotion::Kind::translation;
    plate.motion.velocity = {0, 0, -v};
    plate.motion.max_force = max_force;
    sys.add_wall(plate);
    const std::vector<ParticleInit> p = {sphere({0.001, 0.002, r}, r)};
    sys.add_particles(p);
    return sys;
  };
  const double estar = kE / (2 * (1 - kNu * kNu));
  const double delta = std::pow(F / (4.0 / 3.0 * estar * std::sqrt(r)), 2.0 / 3.0);

  DemSystem limited = make(F);
  limited.advance(200000);  // 0.2 s: 20 ms to touch, then pressed and at rest
  CHECK(limited.wall_force(1)[2] == Approx(F).epsilon(1e-3));
  CHECK(limited.wall_force(0)[2] == Approx(-limited.wall_force(1)[2]).epsilon(1e-6));
  CHECK(limited.wall_vertices(1)[2] == Approx(2 * r - 2 * delta).margin(0.01 * 2 * delta));
  CHECK(limited.advance_max_relative_overlap() < 0.01);

  DemSystem driven = make(0.0);
  double deepest = 0.0;
  for (int k = 0; k < 200; ++k) {
    driven.advance(1000);
    deepest = std::max(deepest, driven.advance_max_relative_overlap());
  }
  CHECK(deepest > 0.5);
  CHECK(driven.wall_vertices(1)[2] == Approx(2 * r + gap - 0.2 * v).margin(1e-12));

  SECTION("continued from a saved state: bitwise") {
    DemSystem a = make(F);
    a.advance(25000);  // pressing: the drift pauses and goes on
    DemStateCopy copy;
    a.save_state(copy);
    const auto file = std::filesystem::temp_directory_path() / "demfem_force_limited_plate.h5";
    {
      demfem::io::H5File h5(file, demfem::io::H5File::Mode::create);
      a.save(h5, "/dem");
    }
    a.advance(25000);
    DemSystem b = make(F);
    {
      demfem::io::H5File h5(file, demfem::io::H5File::Mode::read);
      b.restore(h5, "/dem");
    }
    std::filesystem::remove(file);
    b.advance(25000);
    DemSystem c = make(F);
    c.advance(25000);
    c.advance(7);  // elsewhere, then back to the copy
    c.restore_state(copy);
    c.advance(25000);
    for (DemSystem* s : {&b, &c}) {
      CHECK(s->particles().pz[0] == a.particles().pz[0]);
      CHECK(s->particles().vz[0] == a.particles().vz[0]);
      CHECK(s->wall_vertices(1) == a.wall_vertices(1));
      CHECK(s->wall_force(1) == a.wall_force(1));
    }
  }
  SECTION("refused where it has no meaning") {
    DemSystem s(two_material_settings(kE, kNu, kRho, 0.5, 0.3, 1e-6));
    WallMesh w = plane_mesh(0.05, 2);
    w.motion.kind = WallMotion::Kind::rotation;
    w.motion.angular_velocity = 1.0;
    w.motion.max_force = 1.0;
    CHECK_THROWS_WITH(s.add_wall(w), Catch::Contains("max_force limits a drift"));
    w.motion.kind = WallMotion::Kind::translation;
    CHECK_THROWS_WITH(s.add_wall(w), Catch::Contains("non-zero motion.velocity"));
    w.motion.velocity = {0, 0, -1};
    w.motion.max_force = -1.0;
    CHECK_THROWS_WITH(s.add_wall(w), Catch::Contains("must be > 0 N"));
  }
}
