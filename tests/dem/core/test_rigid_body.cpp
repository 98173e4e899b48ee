// Free rigid bodies with a full inertia tensor (physics/rigid_body.hpp: NO_SQUISH splitting).

#include <catch2/catch.hpp>
#include <cmath>

#include "demfem/dem/physics/rigid_body.hpp"

using namespace demfem::dem;
using phys::Vec3;

namespace {

struct Body {
  double q[4] = {1, 0, 0, 0};
  double w[3];
  Vec3 I;
};

Vec3 angular_momentum(const Body& b) {
  const phys::Rot r = phys::rotation(b.q[0], b.q[1], b.q[2], b.q[3]);
  const Vec3 wb = phys::to_body(r, Vec3{b.w[0], b.w[1], b.w[2]});
  return phys::to_world(r, Vec3{b.I.x * wb.x, b.I.y * wb.y, b.I.z * wb.z});
}

double energy(const Body& b) {
  return phys::rotational_energy(phys::rotation(b.q[0], b.q[1], b.q[2], b.q[3]), b.I,
                                 Vec3{b.w[0], b.w[1], b.w[2]});
}

void step(Body& b, double dt) {
  phys::free_rotation(b.q[0], b.q[1], b.q[2], b.q[3], b.w[0], b.w[1], b.w[2], b.I, dt);
}

// Largest relative drift of energy and |L| over n steps; body angular velocity about the
// middle axis changes sign `flips` times (the body tumbles).
void run(Body b, double dt, long n, double& de, double& dl, int& flips) {
  const double e0 = energy(b);
  const Vec3 l0 = angular_momentum(b);
  const double l0n = std::sqrt(phys::norm2(l0));
  de = dl = 0.0;
  flips = 0;
  double last = 0.0;
  for (long k = 0; k < n; ++k) {
    step(b, dt);
    de = std::max(de, std::abs(energy(b) - e0) / e0);
    dl = std::max(dl, std::sqrt(phys::norm2(angular_momentum(b) - l0)) / l0n);
    const phys::Rot r = phys::rotation(b.q[0], b.q[1], b.q[2], b.q[3]);
    const double wm = phys::to_body(r, Vec3{b.w[0], b.w[1], b.w[2]}).y;
    if (k > 0 && (wm > 0) != (last > 0)) ++flips;
    last = wm;
  }
}

}  // namespace

TEST_CASE("A free asymmetric body tumbling keeps its energy and angular momentum",
          "[dem][poly][rigid]") {
  // Reference: the conservation laws of a free rigid body. A rock-like body (principal moments
  // 1, 2, 3 x 1e-6 kg m^2) spun at 20 rad/s about its unstable middle axis with a small
  // perturbation tumbles (the middle-axis rate changes sign, the Dzhanibekov effect) over
  // 10^5 steps of 1e-5 s: tolerance 1e-6 relative for the energy and for the angular momentum
  // vector (the bound; measured values are printed). A second-order scheme: halving
  // the step quarters the energy error (checked within 20 %).
  Body b;
  b.I = Vec3{1e-6, 2e-6, 3e-6};
  b.w[0] = 0.02, b.w[1] = 20.0, b.w[2] = 0.03;
  b.q[0] = std::cos(0.3), b.q[1] = std::sin(0.3) * 0.6, b.q[2] = std::sin(0.3) * 0.8, b.q[3] = 0;
  double de, dl;
  int flips;
  run(b, 1e-5, 100000, de, dl, flips);
  CHECK(flips >= 2);
  CHECK(de < 1e-6);
  CHECK(dl < 1e-6);
  WARN("free body, 1e5 steps of 1e-5 s: energy " << de << ", angular momentum " << dl
                                                 << " (relative), " << flips << " flips");
  // second order: largest energy error over the same time at 4e-4 and 2e-4 s
  double de1, de2, dl1, dl2;
  run(b, 4e-4, 2500, de1, dl1, flips);
  run(b, 2e-4, 5000, de2, dl2, flips);
  CHECK(de1 / de2 == Approx(4.0).epsilon(0.2));
}

TEST_CASE("A free symmetric top precesses at the analytical rate", "[dem][poly][rigid]") {
  // Reference: a free symmetric top (I1 = I2 = 1e-6, I3 = 2.5e-6 kg m^2) turns its symmetry
  // axis about the fixed angular momentum L at the rate |L| / I1 (Landau & Lifshitz §33).
  // Measured: the angle swept by the axis about L over 2 s, divided by 2 s. Tolerance 0.1 %.
  Body b;
  b.I = Vec3{1e-6, 1e-6, 2.5e-6};
  b.w[0] = 3.0, b.w[1] = 0.0, b.w[2] = 7.0;  // body = world at t = 0
  const Vec3 L = angular_momentum(b);
  const double ln = std::sqrt(phys::norm2(L));
  const Vec3 l = (1.0 / ln) * L;
  const double rate = ln / b.I.x;
  // a frame (u, v) perpendicular to l
  Vec3 u = phys::cross(l, Vec3{0, 1, 0});
  u = (1.0 / std::sqrt(phys::norm2(u))) * u;
  const Vec3 v = phys::cross(l, u);
  auto angle = [&](const Body& s) {
    const phys::Rot r = phys::rotation(s.q[0], s.q[1], s.q[2], s.q[3]);
    const Vec3 e3 = phys::to_world(r, Vec3{0, 0, 1});
    return std::atan2(phys::dot(e3, v), phys::dot(e3, u));
  };
  const double dt = 1e-5;
  const long n = 200000;
  double swept = 0.0, last = angle(b);
  for (long k = 0; k < n; ++k) {
    step(b, dt);
    const double a = angle(b);
    double d = a - last;
    if (d > M_PI) d -= 2 * M_PI;
    if (d < -M_PI) d += 2 * M_PI;
    swept += d;
    last = a;
  }
  const double measured = swept / (n * dt);
  CHECK(measured == Approx(rate).epsilon(1e-3));
  WARN("symmetric top: precession " << measured << " rad/s, analytical " << rate
                                    << " rad/s, relative error " << std::abs(measured / rate - 1));
}
