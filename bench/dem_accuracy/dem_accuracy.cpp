// DEM accuracy against cost: the error of a head-on impact (sphere on a triangle-mesh wall,
// and two equal spheres) against Hertz theory for time steps from 0.02 to 0.8 of the
// Rayleigh time step. The cost of a simulated second is proportional to 1/dt, so the table
// says what a larger step buys and what it costs in accuracy (and where it breaks).
//
// References (Hertz impact of elastic spheres, e.g. Johnson, Contact Mechanics, 11.4):
//   largest overlap  delta_max = (15 m* v^2 / (16 E* sqrt(R*)))^(2/5)
//   contact time     t_c = 2.868 (m*^2 / (R* E*^2 v))^(1/5)
// and the restitution coefficient e of the damped law (eq. 2.10 of the thesis). The contact
// time is counted in whole steps (the steps that end with an overlap), so its error has a
// floor of about half a step over the contact (0.2-0.3 % at 150-170 steps per contact).
//
//   build/bench/dem_accuracy [--json out.json]

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <string>

#include "bench_report.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/shapes/geometry/stl_reader.hpp"

using namespace demfem::dem;

namespace {

constexpr double kE = 1e8, kNu = 0.3, kRho = 2500.0, kR = 0.002, kV = 1.0;

struct Impact {
  double e_meas = 0, delta_max = 0, contact_time = 0;
  bool ok = false;
};

// One impact at relative speed kV; `pair`: two equal spheres, else a sphere on a wall.
Impact impact(bool pair, double restitution, double dt) {
  DemSettings s;
  s.dt = dt;
  s.gravity = {0, 0, 0};
  s.materials = {{"grain", kE, kNu, kRho}, {"wall", kE, kNu, 0.0}};
  s.pairs.assign(4, MaterialPair{0.0, restitution, 0.0});
  s.threads = 1;
  DemSystem sys(s);
  const double gap = 0.05 * kV * dt;  // first touch within the first step
  if (pair) {
    ParticleInit a, b;
    a.radius = b.radius = kR;
    a.position = {0, 0, 0};
    b.position = {0, 0, 2 * kR + gap};
    a.velocity = {0, 0, 0.5 * kV};
    b.velocity = {0, 0, -0.5 * kV};
    sys.add_particles(std::vector<ParticleInit>{a, b});
  } else {
    const TriangleMesh plane = make_plane_mesh({0, 0, 0}, {0, 0, 1}, 0.05);
    WallMesh w;
    w.name = plane.name;
    w.vertices = plane.vertices;
    w.triangles = plane.triangles;
    w.material = 1;
    sys.add_wall(w);
    ParticleInit a;
    a.radius = kR;
    a.position = {0, 0, kR + gap};
    a.velocity = {0, 0, -kV};
    sys.add_particles(std::vector<ParticleInit>{a});
  }
  Impact r;
  bool touched = false;
  std::int64_t contact_steps = 0;
  for (int k = 0; k < 1000000; ++k) {
    sys.advance(1);
    const double ov = sys.max_overlap();
    if (ov > 0) {
      touched = true;
      ++contact_steps;
      r.delta_max = std::max(r.delta_max, ov);
    } else if (touched) {
      const auto& st = sys.particles();
      const double v_rel = pair ? st.vz[1] - st.vz[0] : st.vz[0];
      r.e_meas = v_rel / kV;
      r.contact_time = static_cast<double>(contact_steps) * dt;
      r.ok = true;
      break;
    }
  }
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "DEM accuracy of head-on impacts against Hertz theory, for time steps from "
      "0.02 to 0.8 of the Rayleigh time step"};
  std::string json;
  app.add_option("--json", json, "write the results as JSON");
  CLI11_PARSE(app, argc, argv);

  const double g = kE / (2 * (1 + kNu));
  const double t_rayleigh = 3.14159265358979 * kR / (0.1631 * kNu + 0.8766) * std::sqrt(kRho / g);
  const double m = kRho * 4.0 / 3.0 * 3.14159265358979 * kR * kR * kR;
  demfem::bench::Report rep(
      "dem_accuracy", {"contact", "e", "dt/T_rayleigh", "steps per contact", "e measured",
                       "e error", "delta_max error", "t_c error", "cost per simulated s (rel.)"});
  rep.set_info("model", std::string("Hertz-Mindlin, E 100 MPa, nu 0.3, rho 2500, r 2 mm, v 1 m/s"));
  rep.set_info("t_rayleigh_s", t_rayleigh);
  for (const bool pair : {false, true}) {
    // E*, R*, m* of the contact (the wall has the same E and nu, infinite radius and mass)
    const double e_star = kE / (2 * (1 - kNu * kNu));
    const double r_star = pair ? 0.5 * kR : kR;
    const double m_star = pair ? 0.5 * m : m;
    const double delta_ref =
        std::pow(15 * m_star * kV * kV / (16 * e_star * std::sqrt(r_star)), 0.4);
    const double tc_ref = 2.868 * std::pow(m_star * m_star / (r_star * e_star * e_star * kV), 0.2);
    for (const double e : {1.0, 0.4}) {
      for (const double f : {0.02, 0.05, 0.1, 0.2, 0.4, 0.8}) {
        const double dt = f * t_rayleigh;
        const Impact r = impact(pair, e, dt);
        if (!r.ok) continue;
        // the elastic references hold for e = 1; with damping only e is compared
        const bool elastic = e == 1.0;
        rep.add_row({std::string(pair ? "sphere-sphere" : "sphere-wall"), e, f, tc_ref / dt,
                     r.e_meas, std::abs(r.e_meas - e) / e,
                     elastic ? std::abs(r.delta_max - delta_ref) / delta_ref : 0.0,
                     elastic ? std::abs(r.contact_time - tc_ref) / tc_ref : 0.0, 0.02 / f});
      }
    }
  }
  rep.print();
  rep.write_json(json);
  return 0;
}
