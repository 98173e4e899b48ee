// Time step study of dilated polyhedra (issue 18, "Time step"): a ballast bed of random rocks
// (30 triangles, elongation 0.8, flatness 0.8, r_d 0.1 of the sieve size; sieve sizes of the
// thesis's ballast, normal 40 mm, sd 10 mm, in [20, 80] mm) with the sleeper case's material
// (thesis table 6.1: E 10 GPa, nu 0.27, rho 2600, e 0.2, mu 0.6; the box walls alike), packed
// densely by bounding spheres (bench/common/ballast_bed.hpp). Reported per Δt^D: bed height
// h = 2 z̄ (z̄ the mass-weighted mean height of the centroids, for a bed of uniform density its
// half height), coordination number Z = 2 (rock-rock contacts) / N, the kinetic energy left,
// the largest overlap (as a fraction of the smallest dilation radius), and their relative
// differences to the first (reference) Δt^D.
//
// Two protocols:
//  * continue (default): the bed, with a rigid platen resting on it under a light preload (the
//    thesis positions its sleeper with a light load, §6.2), is settled ONCE at --settle-dt and
//    saved; the same state (contact history included) is then continued at every Δt^D through
//    the same disturbance, the sleeper's load: the platen (held level, free to move vertically,
//    an oedometer's loading plate) becomes a dead weight of --load-pressure (default 264 kPa:
//    the thesis's 132 kN load level over its 2.5 m x 0.2 m sleeper) for --load-time. A dead
//    weight starts at rest and accelerates at most at g; the same load as a force on the light
//    platen hit the bed at 1400 m/s^2 and pressed rocks together by a whole r_d (measured
//    while this was built). All Δt^D then start from one bed,
//    so the differences are the step's, plus the chaos the load stirs up: a control row
//    continues at the reference step with the load changed by 1e-9 relative, a physically
//    irrelevant change, to measure that floor. --seeds beds give the scatter of the Δt effect.
//    Also reported: the platen's settlement under the load (the sleeper settlement the thesis
//    reads) and its final height, and the means of h and Z over 20 samples in the second half
//    of the hold (the bed still rings under the load: one sample at the end is a phase of it).
//  * settle: the earlier protocol, a separate bed settled at each Δt^D (no platen); the
//    packing's chaos makes two steps settle to different beds. --seeds > 1 settles more beds
//    at the first step to measure that spread.

#include <unistd.h>
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <limits>

#include "ballast_bed.hpp"
#include "bench_report.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/io/h5_file.hpp"

using namespace demfem::dem;

namespace {

constexpr double kG = 9.81;
constexpr int kHoldSamples = 20;  // samples of h and Z in the second half of the hold

struct Outcome {
  double height = 0, z = 0, ke = 0, overlap = 0, rayleigh = 0, seconds = 0, cpu = 0;
  double platen = NAN, settlement = NAN;  // continue protocol: platen bottom height, its drop
  double z_mean = NAN, h_mean = NAN;      // continue protocol: means over the hold's 2nd half
  bool finite = true;
};

struct Setup {
  std::size_t n = 300;
  double E = 1e10;
  int threads = 1;
  double aspect = 1.0;      // footprint side / packed height (continue protocol)
  double preload = 1.2e3;   // Pa, the platen's weight over its area
  double load = 2.64e5;     // Pa
  double gap = 0.005;       // m, between the platen and each side wall
  double thickness = 0.04;  // m, platen
  MaterialPair::PolyLaw law = MaterialPair::PolyLaw::pressure_centre;
};

DemSettings settings(double dt, const Setup& su) {
  DemSettings s;
  s.dt = dt;
  s.gravity = {0, 0, -kG};
  s.materials = {{"ballast", su.E, 0.27, 2600.0}, {"wall", su.E, 0.27, 0.0}};
  s.pairs.assign(4, MaterialPair{0.6, 0.2, 0.0});
  for (auto& p : s.pairs) p.poly_law = su.law;
  s.threads = su.threads;
  return s;
}

shapes::ShapeLibrary rock_library(std::uint64_t seed) {
  shapes::RockParams rp;
  rp.triangles = 30;
  rp.elongation = 0.8;
  rp.flatness = 0.8;
  return shapes::ShapeLibrary::random_rocks(rp, 50, 2024 + seed, shapes::SizeKind::sieve, 0.1);
}

// A closed box of 12 triangles, outward normals, [x0, x1] x [y0, y1] x [z0, z1].
WallMesh box_mesh(double x0, double x1, double y0, double y1, double z0, double z1) {
  WallMesh w;
  w.name = "platen";
  w.material = 1;
  w.vertices = {x0, y0, z0, x1, y0, z0, x1, y1, z0, x0, y1, z0,
                x0, y0, z1, x1, y0, z1, x1, y1, z1, x0, y1, z1};
  w.triangles = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                 1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7};
  return w;
}

// The platen: held level and in place horizontally, free to move vertically (an oedometer's
// loading plate), a dead weight: its weight over its area is `pressure`.
WallMesh platen(const demfem::bench::Bed& bed, double z0, const Setup& su, double pressure) {
  const double g = su.gap;
  WallMesh w = box_mesh(g, bed.lx - g, g, bed.ly - g, z0, z0 + su.thickness);
  const double ax = bed.lx - 2 * g, ay = bed.ly - 2 * g, area = ax * ay;
  RigidBodySpec& b = w.body;
  b.enabled = true;
  b.mass = pressure * area / kG;
  b.centre = {0.5 * bed.lx, 0.5 * bed.ly, z0 + 0.5 * su.thickness};
  const double t = su.thickness;
  b.inertia = {b.mass * (ay * ay + t * t) / 12, b.mass * (ax * ax + t * t) / 12,
               b.mass * (ax * ax + ay * ay) / 12};
  b.fix_translation = {true, true, false};
  b.fix_rotation = true;
  return w;
}

struct Measure {
  double height, z, rd;
};

Measure measure(const DemSystem& sys) {
  const auto& p = sys.particles();
  double m = 0, mz = 0, rd = 1e300;
  for (std::size_t i = 0; i < p.size(); ++i) {
    m += p.mass[i], mz += p.mass[i] * p.pz[i];
    rd = std::min(rd, p.scale[i] * sys.shape(p.shape_id[i]).dilation);
  }
  // contact_count() counts particle-particle pairs only (walls have their own slots)
  return {2.0 * mz / m,
          2.0 * static_cast<double>(sys.contact_count()) / static_cast<double>(p.size()), rd};
}

// Advances `time` in chunks, watching for a blow-up; returns the largest overlap seen, m.
double run_for(DemSystem& sys, double time, double dt, bool& finite, const char* what) {
  const auto steps = static_cast<std::int64_t>(std::llround(time / dt));
  const std::int64_t chunk = std::max<std::int64_t>(1, std::llround(0.01 / dt));
  double overlap = 0.0;
  for (std::int64_t done = 0; done < steps;) {
    const std::int64_t k = std::min(chunk, steps - done);
    sys.advance(k);
    done += k;
    overlap = std::max(overlap, sys.advance_max_overlap());
    const double ke = sys.kinetic_energy();
    if (what && sys.wall_count() > 5) {  // with the platen (the last wall)
      const auto b = sys.body_state(static_cast<int>(sys.wall_count()) - 1);
      std::fprintf(stderr, "    %s: t = %.3f s, KE %.4g J, platen z %.6f m, v %.3g m/s\n", what,
                   sys.time(), ke, b.centre[2], b.velocity[2]);
    } else if (what) {
      std::fprintf(stderr, "    %s: t = %.3f s, KE %.4g J\n", what, sys.time(), ke);
    }
    if (!std::isfinite(ke)) {
      finite = false;
      break;
    }
  }
  return overlap;
}

Outcome settle(double dt, double time, const Setup& su, std::uint64_t seed) {
  DemSystem sys(settings(dt, su));
  const auto lib = rock_library(seed);
  add_library_shapes(sys, lib, "rock");
  const auto bed = demfem::bench::make_bed(su.n, &lib, 0, 11 + seed);
  for (const auto& w : bed.walls) sys.add_wall(w);
  sys.add_particles(bed.particles);
  Outcome o;
  o.rayleigh = sys.rayleigh_time_step();
  const auto t0 = std::chrono::steady_clock::now();
  const double overlap = run_for(sys, time, dt, o.finite, nullptr);
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const Measure m = measure(sys);
  o.height = m.height, o.z = m.z, o.ke = sys.kinetic_energy(), o.overlap = overlap / m.rd;
  return o;
}

// The continue protocol's bed of one seed: its shapes, packing and platen start height.
struct LoadedBed {
  shapes::ShapeLibrary lib;
  demfem::bench::Bed bed;
  double platen_z0 = 0;
};

LoadedBed loaded_bed(const Setup& su, std::uint64_t seed) {
  LoadedBed b{rock_library(seed), {}, 0};
  b.bed = demfem::bench::make_bed(su.n, &b.lib, 0, 11 + seed, su.aspect);
  double top = 0;
  for (const auto& p : b.bed.particles) top = std::max(top, p.position[2] + p.radius);
  b.platen_z0 = top + 0.005;
  return b;
}

DemSystem loaded_system(const LoadedBed& b, double dt, const Setup& su, double pressure) {
  DemSystem sys(settings(dt, su));
  add_library_shapes(sys, b.lib, "rock");
  for (const auto& w : b.bed.walls) sys.add_wall(w);
  sys.add_wall(platen(b.bed, b.platen_z0, su, pressure));
  sys.add_particles(b.bed.particles);
  return sys;
}

int platen_index(const DemSystem& sys) {
  return static_cast<int>(sys.wall_count()) - 1;
}

double platen_bottom(const DemSystem& sys, const Setup& su) {
  return sys.body_state(platen_index(sys)).centre[2] - 0.5 * su.thickness;
}

// Continues the saved state at `dt`: the dead weight grows from the preload to `pressure` in
// `stages` equal steps over `ramp` s (a new system per stage: the platen's mass is a property
// of the wall, the state goes over through save and restore, which continue bitwise), then
// is held for `hold` s.
Outcome load(const LoadedBed& b, const std::filesystem::path& state, double dt, double ramp,
             int stages, double hold, const Setup& su, double pressure, bool verbose) {
  Outcome o;
  const std::filesystem::path chain = state.string() + ".stage";
  double start = 0, overlap = 0;
  const auto t0 = std::chrono::steady_clock::now();
  const std::clock_t c0 = std::clock();
  Measure m{};
  for (int k = 1; k <= stages + 1 && o.finite; ++k) {
    const bool held = k == stages + 1;
    const double p = held ? pressure : su.preload + (pressure - su.preload) * k / stages;
    DemSystem sys = loaded_system(b, dt, su, p);
    {
      demfem::io::H5File f(k == 1 ? state : chain, demfem::io::H5File::Mode::read);
      sys.restore(f, "/bed");
    }
    if (k == 1) o.rayleigh = sys.rayleigh_time_step(), start = platen_bottom(sys, su);
    if (!held) {
      overlap =
          std::max(overlap, run_for(sys, ramp / stages, dt, o.finite, verbose ? "load" : nullptr));
      demfem::io::H5File f(chain, demfem::io::H5File::Mode::create);
      sys.save(f, "/bed");
    } else {
      // the hold: its first half, then the second half in kHoldSamples equal parts with h and
      // Z sampled after each (a bed still ringing under the load: their means are steadier
      // than one sample at the end)
      overlap = std::max(overlap, run_for(sys, hold / 2, dt, o.finite, verbose ? "load" : nullptr));
      double zs = 0, hs = 0;
      for (int j = 0; j < kHoldSamples && o.finite; ++j) {
        overlap = std::max(overlap, run_for(sys, hold / 2 / kHoldSamples, dt, o.finite, nullptr));
        const Measure mj = measure(sys);
        zs += mj.z, hs += mj.height;
      }
      o.z_mean = zs / kHoldSamples, o.h_mean = hs / kHoldSamples;
      m = measure(sys);
      o.ke = sys.kinetic_energy();
      o.platen = platen_bottom(sys, su);
    }
  }
  std::filesystem::remove(chain);
  o.cpu = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  o.height = m.height, o.z = m.z, o.overlap = overlap / m.rd;
  o.settlement = start - o.platen;
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Settled ballast bed of rocks against the DEM time step"};
  Setup su;
  std::vector<double> dts = {1e-6, 2e-6, 5e-6, 1e-5};
  std::string protocol = "continue";
  double time = 0.25, settle_dt = 5e-6, settle_time = 0.6, ramp_time = 0.03, hold_time = 0.02;
  int stages = 10, first_seed = 0;
  int seeds = 1;
  bool control = true, verbose = false;
  std::string json, cache;
  app.add_option("--protocol", protocol,
                 "continue: one bed settled once, continued at each step under the platen's "
                 "load; settle: a bed settled at each step")
      ->check(CLI::IsMember({"continue", "settle"}));
  app.add_option("--rocks", su.n, "rocks in the bed");
  app.add_option("--dt", dts, "time steps, s (the first is the reference)");
  app.add_option("--time", time, "settle protocol: settling time, s");
  app.add_option("--settle-dt", settle_dt, "continue protocol: step of the one settling, s");
  app.add_option("--settle-time", settle_time, "continue protocol: settling time, s");
  app.add_option("--ramp-time", ramp_time, "continue protocol: time the load grows, s");
  app.add_option("--stages", stages, "continue protocol: steps of the load's growth")
      ->check(CLI::Range(1, 1000));
  app.add_option("--hold-time", hold_time, "continue protocol: time the full load is held, s");
  app.add_option("--load-pressure", su.load, "continue protocol: platen pressure, Pa");
  app.add_option("--preload-pressure", su.preload,
                 "continue protocol: the platen's weight over its area during settling, Pa");
  app.add_option("--aspect", su.aspect, "continue protocol: the box's side over the packed height");
  app.add_option("--control", control,
                 "continue protocol: a control run at the reference step with the load "
                 "changed by 1e-9 (the chaos floor)");
  app.add_option("--cache", cache,
                 "continue protocol: folder keeping the settled beds for reuse (default: none)");
  app.add_option("--youngs-modulus", su.E, "rock and wall Young's modulus, Pa");
  app.add_option("--threads", su.threads, "CPU threads");
  std::string law = "pressure_centre";
  app.add_option("--law", law, "contact law of the rocks (pressure_centre, smooth), settling too")
      ->check(CLI::IsMember({"pressure_centre", "smooth"}));
  app.add_option("--seeds", seeds, "beds (seeds of shapes, sizes and orientations)")
      ->check(CLI::Range(1, 100));
  app.add_option("--first-seed", first_seed, "continue protocol: seed of the first bed")
      ->check(CLI::Range(0, 10000));
  app.add_flag("--verbose", verbose, "print the kinetic energy every 0.01 s");
  app.add_option("--json", json, "write the results as JSON");
  CLI11_PARSE(app, argc, argv);
  const bool cont = protocol == "continue";
  su.law = poly_law_from_name(law);
  std::vector<std::string> cols = {
      "rocks",       "dt s",           "dt / dt_R",   "seed", "bed height m",
      "rel. to ref", "coordination Z", "rel. to ref", "KE J", "max overlap / r_d"};
  if (cont)
    for (const char* c : {"platen height m", "settlement m", "rel. to ref", "Z hold mean",
                          "rel. to ref", "h hold mean m", "rel. to ref", "CPU s"})
      cols.emplace_back(c);
  cols.emplace_back("wall s");
  demfem::bench::Report rep("poly_timestep", cols);
  rep.set_info("model", std::string("30-triangle rocks, E ") + std::to_string(su.E) +
                            " Pa, nu 0.27, rho 2600, e 0.2, mu 0.6 (thesis table 6.1); sizes "
                            "normal(40, 10) mm in [20, 80] (sieve), r_d 0.1");
  rep.set_info("protocol", protocol);
  rep.set_info("law", law);
  rep.set_info("machine", demfem::bench::machine_description());
  rep.set_info("commit", demfem::bench::git_commit());
  rep.set_info("threads", static_cast<long long>(su.threads));
  Outcome ref;
  auto row = [&](double dt, std::string seed, const Outcome& o) {
    std::vector<demfem::bench::Cell> r = {static_cast<long long>(su.n),
                                          dt,
                                          dt / o.rayleigh,
                                          seed,
                                          o.finite ? o.height : NAN,
                                          o.height / ref.height - 1.0,
                                          o.finite ? o.z : NAN,
                                          o.z / ref.z - 1.0,
                                          o.ke,
                                          o.overlap};
    if (cont) {
      r.insert(r.end(),
               {o.platen, o.settlement, o.settlement / ref.settlement - 1.0, o.z_mean,
                o.z_mean / ref.z_mean - 1.0, o.h_mean, o.h_mean / ref.h_mean - 1.0, o.cpu});
    }
    r.emplace_back(o.seconds);
    rep.add_row(std::move(r));
  };

  if (!cont) {
    rep.set_info("settling time s", time);
    for (std::size_t k = 0; k < dts.size(); ++k) {
      const Outcome o = settle(dts[k], time, su, 0);
      if (k == 0) ref = o;
      row(dts[k], "0", o);
      std::fprintf(stderr, "dt %g: h %.5f m, Z %.4f, %.0f s\n", dts[k], o.height, o.z, o.seconds);
    }
    for (int s = 1; s < seeds; ++s)
      row(dts[0], std::to_string(s), settle(dts[0], time, su, static_cast<std::uint64_t>(s)));
    rep.print();
    rep.write_json(json);
    return 0;
  }

  rep.set_info("settle dt s", settle_dt);
  rep.set_info("settle time s", settle_time);
  rep.set_info("ramp time s", ramp_time);
  rep.set_info("ramp stages", static_cast<long long>(stages));
  rep.set_info("hold time s", hold_time);
  rep.set_info("load pressure Pa", su.load);
  rep.set_info("preload pressure Pa", su.preload);
  rep.set_info("aspect", su.aspect);
  const auto tmp = std::filesystem::temp_directory_path() /
                   ("poly_timestep_" + std::to_string(static_cast<long long>(::getpid())));
  const std::filesystem::path dir = cache.empty() ? tmp : std::filesystem::path(cache);
  std::filesystem::create_directories(dir);
  int status = 0;
  try {
    for (int s = first_seed; s < first_seed + seeds; ++s) {
      const auto seed = static_cast<std::uint64_t>(s);
      const LoadedBed b = loaded_bed(su, seed);
      // every parameter of the settled state is in its name
      char key[256];
      std::snprintf(key, sizeof key, "bed_n%zu_s%d_a%g_E%g_p%g_dt%g_t%g%s.h5", su.n, s, su.aspect,
                    su.E, su.preload, settle_dt, settle_time,
                    su.law == MaterialPair::PolyLaw::smooth ? "_smooth" : "");
      const auto state = dir / key;
      if (std::filesystem::exists(state)) {
        std::fprintf(stderr, "seed %d: settled bed from %s\n", s, state.c_str());
      } else {
        DemSystem sys = loaded_system(b, settle_dt, su, su.preload);
        bool finite = true;
        const std::clock_t c0 = std::clock();
        const double ov =
            run_for(sys, settle_time, settle_dt, finite, verbose ? "settle" : nullptr);
        const Measure m = measure(sys);
        std::fprintf(stderr,
                     "seed %d: %zu rocks in a %.3f m box, settled %.2f s at %g s (%.0f CPU s): "
                     "h %.5f m, Z %.3f, platen at %.5f m, KE %.3g J, overlap %.3f r_d\n",
                     s, sys.particle_count(), b.bed.lx, settle_time, settle_dt,
                     static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC, m.height, m.z,
                     platen_bottom(sys, su), sys.kinetic_energy(), ov / m.rd);
        if (!finite) throw std::runtime_error("the bed blew up while settling");
        const auto part = dir / (std::string(key) + ".part");  // no half-written cache entry
        {
          demfem::io::H5File f(part, demfem::io::H5File::Mode::create);
          sys.save(f, "/bed");
        }
        std::filesystem::rename(part, state);
      }
      for (std::size_t k = 0; k < dts.size(); ++k) {
        const Outcome o =
            load(b, state, dts[k], ramp_time, stages, hold_time, su, su.load, verbose);
        if (k == 0) ref = o;
        row(dts[k], std::to_string(s), o);
        std::fprintf(stderr,
                     "  dt %g: h %.6f m (%+.2e), Z %.4f (%+.2e), settlement %.4e m (%+.2e), "
                     "hold means Z %.4f (%+.2e) h %.6f m (%+.2e), overlap %.3f r_d, %.0f CPU s\n",
                     dts[k], o.height, o.height / ref.height - 1, o.z, o.z / ref.z - 1,
                     o.settlement, o.settlement / ref.settlement - 1, o.z_mean,
                     o.z_mean / ref.z_mean - 1, o.h_mean, o.h_mean / ref.h_mean - 1, o.overlap,
                     o.cpu);
      }
      if (control) {
        const Outcome o =
            load(b, state, dts[0], ramp_time, stages, hold_time, su, su.load * (1 + 1e-9), false);
        row(dts[0], std::to_string(s) + " control", o);
        std::fprintf(stderr,
                     "  control: h %+.2e, Z %+.2e, settlement %+.2e, hold means Z %+.2e h %+.2e\n",
                     o.height / ref.height - 1, o.z / ref.z - 1, o.settlement / ref.settlement - 1,
                     o.z_mean / ref.z_mean - 1, o.h_mean / ref.h_mean - 1);
      }
      if (cache.empty()) std::filesystem::remove(state);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poly_timestep: %s\n", e.what());
    status = 1;
  }
  std::filesystem::remove_all(tmp);
  rep.print();
  rep.write_json(json);
  return status;
}
