// [[dem.walls]]: the rigid walls of a scene (an STL, a box or a plane each), their prescribed
// motion and, for a wall that its contact forces move, its rigid body.

#include <array>
#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include "scene_sections.hpp"

namespace demfem::dem {

using scene::Range;
using scene::Table;

namespace {

WallMotion read_motion(const Table& m) {
  WallMotion w;
  const std::string kind =
      m.choice("kind", "fixed", {"fixed", "translation", "rotation", "sinusoid"});
  w.start_time = m.number("start_time", 0.0, Range::non_negative());
  w.end_time = m.number("end_time", 1e300, Range::positive());
  if (w.end_time <= w.start_time) m.fail("end_time", "must be greater than start_time");
  auto unit = [&](std::string_view key) {
    auto a = m.vec3(key);
    const double l = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    if (!(l > 0)) m.fail(key, "must not be the zero vector");
    return std::array<double, 3>{a[0] / l, a[1] / l, a[2] / l};
  };
  if (kind == "fixed") {
    w.kind = WallMotion::Kind::fixed;
  } else if (kind == "translation") {
    w.kind = WallMotion::Kind::translation;
    w.velocity = m.vec3("velocity");
  } else if (kind == "rotation") {
    w.kind = WallMotion::Kind::rotation;
    w.axis_point = m.vec3("axis_point");
    w.axis = unit("axis");
    w.angular_velocity = m.number("angular_velocity");
  } else {
    w.kind = WallMotion::Kind::sinusoid;
    w.axis = unit("direction");
    w.amplitude = m.number("amplitude", Range::non_negative());
    w.frequency = m.number("frequency", Range::positive());
    w.phase = m.number("phase", 0.0);
    w.velocity = m.vec3("velocity", std::array<double, 3>{0, 0, 0});
  }
  if (m.has("max_force")) {
    if (w.kind != WallMotion::Kind::translation && w.kind != WallMotion::Kind::sinusoid)
      m.fail("max_force", "limits a drift: only a translation or a sinusoid with a velocity");
    w.max_force = m.number("max_force", Range::positive());
    if (w.velocity == std::array<double, 3>{0, 0, 0})
      m.fail("max_force", "needs a non-zero velocity (the drift it limits)");
  }
  m.finish();
  return w;
}

// [dem.walls.body]: mass properties from a density (the closed mesh's, computed when the mesh
// is read) or given, constraints, applied force, initial velocities.
void read_body(const Table& b, WallSpec& ws) {
  RigidBodySpec& r = ws.body;
  r.enabled = true;
  ws.body_where = b.where(b.has("density") ? "density" : "mass");
  if (b.has("density") == b.has("mass"))
    b.fail("density",
           "a body needs exactly one of 'density' (mass properties from the closed "
           "mesh) and 'mass' (with 'inertia')");
  if (b.has("density")) {
    ws.body_density = b.number("density", Range::positive());
  } else {
    r.mass = b.number("mass", Range::positive());
    r.inertia = b.vec3("inertia", Range::positive());
    if (b.has("centre")) {
      r.centre = b.vec3("centre");
      ws.has_body_centre = true;
    }
  }
  r.velocity = b.vec3("velocity", std::array<double, 3>{0, 0, 0});
  r.angular_velocity = b.vec3("angular_velocity", std::array<double, 3>{0, 0, 0});
  r.force = b.vec3("force", std::array<double, 3>{0, 0, 0});
  r.gravity = b.boolean("gravity", true);
  if (b.has("fixed")) {
    for (const auto& f : b.strings("fixed")) {
      if (f == "x" || f == "y" || f == "z") {
        r.fix_translation[std::size_t(f[0] - 'x')] = true;
      } else if (f == "rotation") {
        r.fix_rotation = true;
      } else {
        b.fail("fixed",
               "unknown entry \"" + f + "\" (accepted: \"x\", \"y\", \"z\", \"rotation\")");
      }
    }
  }
  b.finish();
}

}  // namespace

std::vector<WallSpec> read_walls(const Table& dem, const std::vector<Material>& materials) {
  std::vector<WallSpec> specs;
  const auto walls = dem.tables("walls");
  for (std::size_t i = 0; i < walls.size(); ++i) {
    const Table& w = walls[i];
    WallSpec ws;
    ws.where = w.where("material");
    ws.name = w.string("name", "wall" + std::to_string(i));
    for (const auto& other : specs)
      if (other.name == ws.name) w.fail("name", "wall \"" + ws.name + "\" is defined twice");
    ws.material = material_index(w, "material", materials);
    const int shapes = int(w.has("stl")) + int(w.has("box")) + int(w.has("plane"));
    if (shapes != 1) {
      w.fail("stl", "a wall needs exactly one of 'stl', 'box' and 'plane' (found " +
                        std::to_string(shapes) + ")");
    }
    if (w.has("stl")) {
      ws.kind = WallSpec::Kind::stl;
      ws.stl = w.path("stl");
      ws.where = w.where("stl");
      ws.weld_tolerance = w.number("weld_tolerance", -1.0, Range::non_negative());
    } else if (auto b = w.table("box")) {
      ws.kind = WallSpec::Kind::box;
      ws.lo = b->vec3("lo");
      ws.hi = checked_hi(*b, ws.lo);
      ws.open_top = b->boolean("open_top", false);
      b->finish();
    } else if (auto pl = w.table("plane")) {
      ws.kind = WallSpec::Kind::plane;
      ws.point = pl->vec3("point");
      ws.normal = pl->vec3("normal");
      if (ws.normal == std::array<double, 3>{0, 0, 0}) pl->fail("normal", "must not be zero");
      ws.size = pl->number("size", Range::positive());
      pl->finish();
    }
    if (auto m = w.table("motion")) ws.motion = read_motion(*m);
    if (auto b = w.table("body")) {
      if (ws.motion.kind != WallMotion::Kind::fixed)
        w.fail("body", "a wall moved by its contact forces cannot also have a 'motion'");
      read_body(*b, ws);
    }
    w.finish();
    specs.push_back(std::move(ws));
  }
  return specs;
}

}  // namespace demfem::dem
