// Energy conservation of dilated polyhedra: a gas of rocks (random hulls of 30 triangles,
// sizes normal 20 mm, sd 3 mm, in [14, 26] mm, r_d 0.1 of the size) in a closed box of
// triangle walls, without gravity, elastic (e = 1) and frictionless (mu = 0), started with
// random velocities (0.5 m/s) and spins (10 rad/s). The energy (translational + rotational)
// is sampled at the steps with no contact at all (largest overlap 0: no elastic energy
// stored), and its drift over the run is reported against the time step.
//
// --point runs the same gas with point cores (spheres through the polyhedron path, no face
// contacts): the drift of the time integration alone, for comparison.
//
// Both contact laws of polyhedra run (--law): the pressure-centre law, whose face contacts are
// not the gradient of an energy, and the smooth law (physics/smooth_contact.hpp), the exact
// gradient of a C¹ energy, whose drift is the time integration's error alone (velocity Verlet,
// NO_SQUISH rotation), as that of the point cores. --seeds runs other gases (packings and
// velocities) of the same distributions: the drift of one gas is a sum of many collisions'
// errors of either sign, and a few large ones can decide it.
//
//   build/bench/poly_energy --fraction 0.05 0.1 0.2 --seeds 0 1 2 3 --json out.json

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>

#include "ballast_bed.hpp"
#include "bench_report.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/placement/insertion.hpp"
#include "demfem/dem/shapes/shape_library.hpp"

using namespace demfem::dem;

namespace {

using demfem::bench::quad;

struct Run {
  double drift = 0.0, worst = 0.0, e0 = 0.0;
  long samples = 0, contacts = 0;
};

// The gas at time step dt; `probe` only builds it (for its Rayleigh step).
Run run(std::size_t n, double dt, long steps, int threads, bool point, MaterialPair::PolyLaw law,
        int seed, double* rayleigh = nullptr) {
  DemSettings s;
  s.dt = dt;
  s.gravity = {0, 0, 0};
  s.materials = {{"rock", 1e8, 0.3, 2600.0}, {"wall", 1e8, 0.3, 0.0}};
  MaterialPair elastic{0.0, 1.0, 0.0};
  elastic.poly_law = law;
  s.pairs.assign(4, elastic);
  s.threads = threads;
  DemSystem sys(s);
  shapes::RockParams rp;
  rp.triangles = 30;
  rp.elongation = 0.8;
  rp.flatness = 0.8;
  const std::vector<shapes::ConvexPolyhedron> dot{shapes::ConvexPolyhedron::point()};
  const auto lib =
      point ? shapes::ShapeLibrary(dot, shapes::SizeKind::sieve, 0.1)
            : shapes::ShapeLibrary::random_rocks(rp, 10, 77, shapes::SizeKind::sieve, 0.1);
  const std::int32_t base = add_library_shapes(sys, lib, "rock");
  const double L = 0.4;
  // closed box, normals inwards
  sys.add_wall(quad({0, 0, 0}, {L, 0, 0}, {L, L, 0}, {0, L, 0}, ""));
  sys.add_wall(quad({0, 0, L}, {0, L, L}, {L, L, L}, {L, 0, L}, ""));
  sys.add_wall(quad({0, 0, 0}, {0, L, 0}, {0, L, L}, {0, 0, L}, ""));
  sys.add_wall(quad({L, 0, 0}, {L, 0, L}, {L, L, L}, {L, L, 0}, ""));
  sys.add_wall(quad({0, 0, 0}, {0, 0, L}, {L, 0, L}, {L, 0, 0}, ""));
  sys.add_wall(quad({0, L, 0}, {L, L, 0}, {L, L, L}, {0, L, L}, ""));
  RandomInsertion q;
  q.region = Box{{0.0, 0.0, 0.0}, {L, L, L}};
  q.sizes = SizeDistribution::normal(0.02, 0.003, 0.014, 0.026);
  q.count = static_cast<std::int64_t>(n);
  q.density = 2600.0;
  q.seed = 5 + 1000 * static_cast<std::uint64_t>(seed);
  q.library = &lib;
  q.shape_base = base;
  auto ps = insert_random(q);
  Rng rng(9 + 1000 * static_cast<std::uint64_t>(seed));
  for (auto& p : ps) {
    const auto o = random_orientation(rng);  // a random direction: the rotated x axis
    const double dx = 1 - 2 * (o[2] * o[2] + o[3] * o[3]), dy = 2 * (o[1] * o[2] + o[0] * o[3]),
                 dz = 2 * (o[1] * o[3] - o[0] * o[2]);
    p.velocity = {0.5 * dx, 0.5 * dy, 0.5 * dz};
    p.angular_velocity = {10 * rng.uniform(-1, 1), 10 * rng.uniform(-1, 1),
                          10 * rng.uniform(-1, 1)};
  }
  sys.add_particles(ps);
  if (rayleigh) *rayleigh = sys.rayleigh_time_step();
  Run r;
  r.e0 = sys.kinetic_energy();
  double last = r.e0;
  for (long k = 0; k < steps; ++k) {
    sys.advance(1);
    if (sys.max_overlap() > 0.0) {
      ++r.contacts;
      continue;
    }
    last = sys.kinetic_energy();
    r.worst = std::max(r.worst, std::abs(last - r.e0) / r.e0);
    ++r.samples;
  }
  r.drift = (last - r.e0) / r.e0;
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Energy drift of an elastic, frictionless gas of rocks against the time step"};
  std::size_t n = 200;
  long steps = 100000;
  std::vector<double> fractions = {0.025, 0.05, 0.1, 0.2};
  std::vector<double> dts;
  int threads = 1;
  std::string json;
  app.add_option("--rocks", n, "rocks in the box");
  app.add_option("--steps", steps, "steps per time step");
  app.add_option("--fraction", fractions, "time steps as fractions of the Rayleigh step");
  app.add_option("--dt", dts, "time steps, s (instead of --fraction)");
  app.add_option("--threads", threads, "CPU threads");
  bool point = false;
  app.add_flag("--point", point,
               "point cores (spheres through the polyhedron path): no face contacts, so the "
               "drift is the time integration's alone");
  std::vector<std::string> laws = {"pressure_centre", "smooth"};
  std::vector<int> seeds = {0};
  app.add_option("--seeds", seeds, "gas seeds (packing, velocities); 0 is the gas of the docs");
  app.add_option("--law", laws, "contact laws of the polyhedra (pressure_centre, smooth)")
      ->check(CLI::IsMember({"pressure_centre", "smooth"}));
  app.add_option("--json", json, "write the results as JSON");
  CLI11_PARSE(app, argc, argv);
  double rayleigh = 0.0;
  (void)run(n, 1e-6, 0, threads, point, MaterialPair::PolyLaw::pressure_centre, 0, &rayleigh);
  if (dts.empty())
    for (double f : fractions) dts.push_back(f * rayleigh);
  demfem::bench::Report rep(
      "poly_energy", {"law", "seed", "rocks", "dt s", "dt / dt_R", "steps", "contact-free samples",
                      "steps with contacts", "drift (E_end - E_0)/E_0", "largest |E - E_0|/E_0"});
  rep.set_info("machine", demfem::bench::machine_description());
  rep.set_info("rayleigh dt s", rayleigh);
  rep.set_info("particles",
               point ? std::string("point cores (spheres)") : std::string("30-triangle rocks"));
  for (double dt : dts)
    for (int seed : seeds)
      for (const std::string& law : laws) {
        const Run r = run(n, dt, steps, threads, point, poly_law_from_name(law), seed);
        rep.add_row({law, static_cast<long long>(seed), static_cast<long long>(n), dt,
                     dt / rayleigh, static_cast<long long>(steps),
                     static_cast<long long>(r.samples), static_cast<long long>(r.contacts), r.drift,
                     r.worst});
      }
  rep.print();
  rep.write_json(json);
  return 0;
}
