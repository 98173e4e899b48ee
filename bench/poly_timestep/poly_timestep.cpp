// Time step study of dilated polyhedra (issue 18, "Time step"): a ballast bed of random rocks
// (30 triangles, elongation 0.8, flatness 0.8, r_d 0.1 of the sieve size; sieve sizes of the
// thesis's ballast, normal 40 mm, sd 10 mm, in [20, 80] mm) with the sleeper case's material
// (thesis table 6.1: E 10 GPa, nu 0.27, rho 2600, e 0.2, mu 0.6; the box walls alike), packed
// densely by bounding spheres (bench/common/ballast_bed.hpp) and settled under gravity for
// the same time at each Δt^D. Reported per Δt^D: bed height h = 2 z̄ (z̄ the mass-weighted mean
// height of the centroids, for a bed of uniform density its half height), coordination number
// Z = 2 (rock-rock contacts) / N, the kinetic energy left, the largest overlap (as a fraction
// of the smallest dilation radius), and their relative differences to the smallest Δt^D.
//
// The packing is chaotic: two steps settle to different beds, so part of the differences is
// the spread of equally valid beds. --seeds > 1 settles more beds (other orientations and
// shapes) at the smallest step to measure that spread.

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "ballast_bed.hpp"
#include "bench_report.hpp"
#include "demfem/dem/dem_system.hpp"

using namespace demfem::dem;

namespace {

struct Outcome {
  double height = 0, z = 0, ke = 0, overlap = 0, rayleigh = 0, seconds = 0;
  bool finite = true;
};

Outcome settle(std::size_t n, double dt, double time, int threads, double E, std::uint64_t seed) {
  DemSettings s;
  s.dt = dt;
  s.gravity = {0, 0, -9.81};
  s.materials = {{"ballast", E, 0.27, 2600.0}, {"wall", E, 0.27, 0.0}};
  s.pairs.assign(4, MaterialPair{0.6, 0.2, 0.0});
  s.threads = threads;
  DemSystem sys(s);
  shapes::RockParams rp;
  rp.triangles = 30;
  rp.elongation = 0.8;
  rp.flatness = 0.8;
  const auto lib =
      shapes::ShapeLibrary::random_rocks(rp, 50, 2024 + seed, shapes::SizeKind::sieve, 0.1);
  add_library_shapes(sys, lib, "rock");
  const auto bed = demfem::bench::make_bed(n, &lib, 0, 11 + seed);
  for (const auto& w : bed.walls) sys.add_wall(w);
  sys.add_particles(bed.particles);
  Outcome o;
  o.rayleigh = sys.rayleigh_time_step();
  const auto t0 = std::chrono::steady_clock::now();
  const auto steps = static_cast<std::int64_t>(std::llround(time / dt));
  double overlap = 0.0;
  for (std::int64_t done = 0; done < steps;) {
    const std::int64_t k = std::min<std::int64_t>(1000, steps - done);
    sys.advance(k);
    done += k;
    overlap = std::max(overlap, sys.advance_max_overlap());
    if (!std::isfinite(sys.kinetic_energy())) {
      o.finite = false;
      break;
    }
  }
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto& p = sys.particles();
  double m = 0, mz = 0, rd = 1e300;
  for (std::size_t i = 0; i < p.size(); ++i) {
    m += p.mass[i], mz += p.mass[i] * p.pz[i];
    rd = std::min(rd, p.scale[i] * sys.shape(p.shape_id[i]).dilation);
  }
  o.height = 2.0 * mz / m;
  o.z = 2.0 * static_cast<double>(sys.contact_count()) / static_cast<double>(p.size());
  o.ke = sys.kinetic_energy();
  o.overlap = overlap / rd;
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Settled ballast bed of rocks against the DEM time step"};
  std::size_t n = 300;
  std::vector<double> dts = {1e-6, 2e-6, 5e-6, 1e-5};
  double time = 0.25, E = 1e10;
  int threads = 2, seeds = 1;
  std::string json;
  app.add_option("--rocks", n, "rocks in the bed");
  app.add_option("--dt", dts, "time steps, s (the first is the reference)");
  app.add_option("--time", time, "settling time, s");
  app.add_option("--youngs-modulus", E, "rock and wall Young's modulus, Pa");
  app.add_option("--threads", threads, "CPU threads");
  app.add_option("--seeds", seeds, "beds settled at the first step (spread of the packing)")
      ->check(CLI::Range(1, 100));
  app.add_option("--json", json, "write the results as JSON");
  CLI11_PARSE(app, argc, argv);
  demfem::bench::Report rep(
      "poly_timestep", {"rocks", "dt s", "dt / dt_R", "seed", "bed height m", "rel. to ref",
                        "coordination Z", "rel. to ref", "KE J", "max overlap / r_d", "wall s"});
  rep.set_info("model", std::string("30-triangle rocks, E ") + std::to_string(E) +
                            " Pa, nu 0.27, rho 2600, e 0.2, mu 0.6 (thesis table 6.1); sizes "
                            "normal(40, 10) mm in [20, 80] (sieve), r_d 0.1");
  rep.set_info("settling time s", time);
  rep.set_info("machine", demfem::bench::machine_description());
  Outcome ref;
  auto row = [&](double dt, int seed, const Outcome& o) {
    rep.add_row({static_cast<long long>(n), dt, dt / o.rayleigh, static_cast<long long>(seed),
                 o.finite ? o.height : NAN, o.height / ref.height - 1.0, o.finite ? o.z : NAN,
                 o.z / ref.z - 1.0, o.ke, o.overlap, o.seconds});
  };
  for (std::size_t k = 0; k < dts.size(); ++k) {
    const Outcome o = settle(n, dts[k], time, threads, E, 0);
    if (k == 0) ref = o;
    row(dts[k], 0, o);
    std::fprintf(stderr, "dt %g: h %.5f m, Z %.4f, %.0f s\n", dts[k], o.height, o.z, o.seconds);
  }
  for (int s = 1; s < seeds; ++s)
    row(dts[0], s, settle(n, dts[0], time, threads, E, static_cast<std::uint64_t>(s)));
  rep.print();
  rep.write_json(json);
  return 0;
}
