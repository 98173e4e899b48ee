#include "rigid_mesh_bodies.hpp"

#include <cmath>
#include <stdexcept>

#include "demfem/io/h5_file.hpp"

namespace demfem::dem::detail {

namespace {
// the saved layout per body: c, v, q, w, force, torque
constexpr std::size_t kSaved = 19;
}  // namespace

int RigidMeshBodies::add(const WallMesh& mesh, const std::array<double, 3>& g,
                         const std::string& where) {
  const RigidBodySpec& s = mesh.body;
  auto bad = [&](const std::string& what) {
    throw std::invalid_argument("DemSystem: " + where + ": rigid body: " + what);
  };
  if (!(s.mass > 0.0) || !std::isfinite(s.mass)) bad("mass must be a finite number > 0");
  for (double i : s.inertia)
    if (!(i > 0.0) || !std::isfinite(i)) bad("principal moments of inertia must be finite and > 0");
  const auto& q = s.orientation;
  const double q2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
  if (!(std::abs(q2 - 1.0) < 1e-6))
    bad("orientation must be a unit quaternion (|q|^2 = 1 +- 1e-6)");
  if (mesh.motion.kind != WallMotion::Kind::fixed)
    bad("a body moved by its contact forces cannot also have a prescribed motion");
  phys::MeshBody b{};
  for (int d = 0; d < 3; ++d) {
    b.c[d] = s.centre[d];
    b.v[d] = s.fix_translation[d] ? 0.0 : s.velocity[d];
    b.w[d] = s.fix_rotation ? 0.0 : s.angular_velocity[d];
    b.inertia[d] = s.inertia[d];
    b.external[d] = s.force[d];
    b.gravity[d] = s.gravity ? g[d] : 0.0;
    b.fix_translation[d] = s.fix_translation[d] ? 1 : 0;
  }
  for (int k = 0; k < 4; ++k) b.q[k] = q[k];
  b.mass = s.mass;
  b.fix_rotation = s.fix_rotation ? 1 : 0;
  // body-frame vertices: Rᵀ (x - c)
  const phys::Rot r = phys::rotation(q[0], q[1], q[2], q[3]);
  std::vector<double> local(mesh.vertices.size());
  for (std::size_t k = 0; k + 2 < mesh.vertices.size(); k += 3) {
    const phys::Vec3 a =
        phys::to_body(r, phys::Vec3{mesh.vertices[k] - b.c[0], mesh.vertices[k + 1] - b.c[1],
                                    mesh.vertices[k + 2] - b.c[2]});
    local[k] = a.x, local[k + 1] = a.y, local[k + 2] = a.z;
  }
  bodies_.push_back(b);
  local_.push_back(std::move(local));
  return static_cast<int>(bodies_.size() - 1);
}

void RigidMeshBodies::kick_drift(double dt) {
  for (auto& b : bodies_) {
    phys::body_kick(b, 0.5 * dt);
    phys::body_drift(b, dt);
  }
}

void RigidMeshBodies::kick(double dt) {
  for (auto& b : bodies_) phys::body_kick(b, 0.5 * dt);
}

void RigidMeshBodies::set_loads(int b, const std::array<double, 3>& f,
                                const std::array<double, 3>& t) {
  phys::body_loads(bodies_[std::size_t(b)], phys::Vec3{f[0], f[1], f[2]},
                   phys::Vec3{t[0], t[1], t[2]});
}

void RigidMeshBodies::place(int bi, double* x, double* v) const {
  const phys::MeshBody& b = bodies_[std::size_t(bi)];
  const auto& local = local_[std::size_t(bi)];
  const phys::Rot r = phys::rotation(b.q[0], b.q[1], b.q[2], b.q[3]);
  for (std::size_t k = 0; k + 2 < local.size(); k += 3)
    phys::body_vertex(b, r, local.data() + k, x + k, v + k);
}

RigidBodyState RigidMeshBodies::state(int bi) const {
  const phys::MeshBody& b = bodies_[std::size_t(bi)];
  RigidBodyState s;
  for (int d = 0; d < 3; ++d) {
    s.centre[d] = b.c[d], s.velocity[d] = b.v[d], s.angular_velocity[d] = b.w[d];
    s.force[d] = b.force[d], s.torque[d] = b.torque[d];
  }
  for (int k = 0; k < 4; ++k) s.orientation[k] = b.q[k];
  return s;
}

std::vector<double> RigidMeshBodies::pack() const {
  std::vector<double> out;
  out.reserve(kSaved * bodies_.size());
  for (const auto& b : bodies_) {
    out.insert(out.end(), {b.c[0], b.c[1], b.c[2], b.v[0], b.v[1], b.v[2], b.q[0], b.q[1], b.q[2],
                           b.q[3], b.w[0], b.w[1], b.w[2], b.force[0], b.force[1], b.force[2],
                           b.torque[0], b.torque[1], b.torque[2]});
  }
  return out;
}

bool RigidMeshBodies::unpack(std::span<const double> in) {
  if (in.size() != kSaved * bodies_.size()) return false;
  for (std::size_t k = 0; k < bodies_.size(); ++k) {
    auto& b = bodies_[k];
    const double* p = in.data() + kSaved * k;
    for (int d = 0; d < 3; ++d) {
      b.c[d] = p[d], b.v[d] = p[3 + d], b.w[d] = p[10 + d];
      b.force[d] = p[13 + d], b.torque[d] = p[16 + d];
    }
    for (int m = 0; m < 4; ++m) b.q[m] = p[6 + m];
  }
  return true;
}

void RigidMeshBodies::save(io::H5File& f, const std::string& g) const {
  if (bodies_.empty()) return;
  const std::vector<double> out = pack();
  f.write(g + "rigid_bodies", std::span<const double>(out));
}

void RigidMeshBodies::restore(const io::H5File& f, const std::string& g) {
  if (bodies_.empty()) return;
  if (!f.exists(g + "rigid_bodies"))
    throw std::invalid_argument("DemSystem: restore: " + f.path().string() +
                                " holds no rigid-body state, but this system has " +
                                std::to_string(bodies_.size()) + " rigid bodies");
  const auto in = f.read_doubles(g + "rigid_bodies");
  if (!unpack(in))
    throw std::invalid_argument("DemSystem: restore: " + f.path().string() + " holds " +
                                std::to_string(in.size() / kSaved) +
                                " rigid bodies, this system has " + std::to_string(bodies_.size()));
}

}  // namespace demfem::dem::detail
