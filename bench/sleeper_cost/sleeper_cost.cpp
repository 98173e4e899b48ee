// Sleeper cost: what the DEM of the full-scale sleeper load case (cases/sleeper.toml, about
// 83,000 rocks, thesis ch. 6) costs on this machine, and what its speed-ups save. Measures
// rock-steps per second of a settled bed of the thesis's ballast (table 6.1: rocks of a
// 12-rock library of `--triangles` triangles, elongation and flatness 0.8, sieve sizes
// normal 40 ± 10 mm in [20, 80] mm, dilation 0.1 of the size; granite E 10 GPa, ν 0.27,
// 2600 kg/m³, μ 0.6, e 0.2) at each DEM step of --dt (the thesis's 1e-6 s and the larger
// steps a time-step study would allow) and with the lowest --frozen fraction of the rocks
// frozen (DemSystem::freeze, what [dem.freeze] does to the rocks far from the sleeper; the
// rate still counts every rock, as the user's run of the whole bed does), and extrapolates
// the load case's DEM wall time: --full-rocks x (--load-time / dt) / rate. The extrapolation
// assumes the rate per rock of this bed holds at 83,000 rocks (poly_throughput measures the
// rate from 10^3 to 10^5 rocks) and leaves out the FEM and the coupling (17 % and 0.4 % of
// the CI load case's wall time, docs/cases.md "Cost").
//
// The bed: make_bed's dense packing by bounding spheres (bench/common/ballast_bed.hpp),
// fallen and settled at --settle-dt until its kinetic energy is below --settle-ke N m g d of
// the mean rock (cached by rock count, triangles and settling in --cache). Each configuration
// is measured --repeat times in turns (best and median), after 10 steps that are not timed.
// A step beyond the stable range shows in the "KE after" column (kinetic energy over
// N m g d after the measured steps: a settled bed stays far below 1).
//
//   build/bench/sleeper_cost --rocks 1000 --threads 2 --repeat 3

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "ballast_bed.hpp"
#include "freeze_lowest.hpp"
#include "bench_report.hpp"
#include "median.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/omp_wait.hpp"
#include "demfem/dem/shapes/shape_library.hpp"
#include "demfem/io/h5_file.hpp"

using namespace demfem::dem;
using demfem::bench::Bed;
using demfem::bench::freeze_lowest;
using demfem::bench::make_bed;

namespace {

constexpr double kRho = 2600.0;   // table 6.1
constexpr double kMeanSize = 0.04;  // m: the mean sieve size (table 6.1's distribution)

// Granite (table 6.1) and the box's steel (cases/sleeper.toml).
DemSettings granite(int threads, double dt, double restitution) {
  DemSettings s;
  s.dt = dt;
  s.gravity = {0, 0, -9.81};
  s.materials = {{"granite", 1e10, 0.27, kRho}, {"steel", 2.1e11, 0.3, 0.0}};
  s.pairs = {MaterialPair{0.6, restitution, 0.0}, MaterialPair{0.5, restitution, 0.0},
             MaterialPair{0.5, restitution, 0.0}, MaterialPair{0.6, restitution, 0.0}};
  s.threads = threads;
  return s;
}

DemSystem make_system(const Bed& bed, const shapes::ShapeLibrary& lib, int threads, double dt,
                      double restitution) {
  DemSystem sys(granite(threads, dt, restitution));
  add_library_shapes(sys, lib, "rock");
  for (const auto& w : bed.walls) sys.add_wall(w);
  sys.add_particles(bed.particles);
  return sys;
}

// Kinetic energy over N m g d of the mean rock.
double relative_ke(const DemSystem& sys) {
  const double m = kRho * M_PI / 6.0 * std::pow(kMeanSize, 3);
  return sys.kinetic_energy() / (static_cast<double>(sys.particle_count()) * m * 9.81 * kMeanSize);
}

struct Settled {
  double time = 0.0, ke = 0.0, rayleigh = 0.0;
};

// Settles the bed into `state` (or reads it from there when `cached`).
Settled settle(const Bed& bed, const shapes::ShapeLibrary& lib, const std::filesystem::path& state,
               bool cached, int threads, double dt, double least, double most, double ke) {
  DemSystem sys = make_system(bed, lib, threads, dt, 0.2);
  if (cached) {
    demfem::io::H5File f(state, demfem::io::H5File::Mode::read);
    sys.restore(f, "/bed");
  } else {
    const std::int64_t piece = std::max<std::int64_t>(1, std::llround(0.01 / dt));
    while (sys.time() < most - 1e-12) {
      sys.advance(piece);
      std::fprintf(stderr, "  settling %zu rocks: t = %.3f s, KE/(N m g d) = %.3g\n",
                   sys.particle_count(), sys.time(), relative_ke(sys));
      if (sys.time() >= least - 1e-12 && relative_ke(sys) < ke) break;
    }
    demfem::io::H5File f(state, demfem::io::H5File::Mode::create);
    sys.save(f, "/bed");
  }
  return {sys.time(), relative_ke(sys), sys.rayleigh_time_step()};
}

struct Measured {
  double rate = 0.0, contacts = 0.0, ke_after = 0.0;
};

// Rock-steps per second of `steps` steps at `dt` from the settled state, the lowest `frozen`
// fraction of the rocks (by centre height) frozen.
Measured measure(const Bed& bed, const shapes::ShapeLibrary& lib,
                 const std::filesystem::path& state, int threads, double dt, double frozen,
                 std::int64_t steps) {
  DemSystem sys = make_system(bed, lib, threads, dt, 0.2);
  {
    demfem::io::H5File f(state, demfem::io::H5File::Mode::read);
    sys.restore(f, "/bed");
  }
  freeze_lowest(sys, frozen);
  sys.advance(10);
  const auto t0 = std::chrono::steady_clock::now();
  sys.advance(steps);
  const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  Measured m;
  m.rate = static_cast<double>(sys.particle_count()) * static_cast<double>(steps) / el;
  m.contacts = 2.0 * static_cast<double>(sys.contact_count()) /
               static_cast<double>(sys.particle_count());
  m.ke_after = relative_ke(sys);
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  demfem::dem::ensure_omp_wait_policy(argv);  // first: it may re-execute the program
  CLI::App app{"Sleeper cost: rock-steps/s of a settled ballast bed per DEM step, frozen or not, "
               "and the full load case's DEM wall time"};
  std::size_t rocks = 1000;
  int triangles = 30, threads = 2, repeat = 3;
  std::int64_t steps = 200;
  std::vector<double> dts = {1e-6, 2e-6, 5e-6, 1e-5};
  std::vector<double> frozen = {0.0, 0.7};
  double settle_dt = 5e-6, settle_least = 0.05, settle_most = 0.5, settle_ke = 1e-3;
  double full_rocks = 83000.0, load_time = 1.6;
  std::string json = "sleeper_cost.json";
  std::error_code ec;
  const auto exe = std::filesystem::canonical("/proc/self/exe", ec);
  std::string cache_dir =
      ((ec ? std::filesystem::temp_directory_path() : exe.parent_path()) / "sleeper_cost_cache")
          .string();
  app.add_option("--rocks", rocks, "rocks in the bed (default 1000)")
      ->check(CLI::Range(10, 1000000));
  app.add_option("--triangles", triangles, "triangles per rock (default 30, table 6.1's study)")
      ->check(CLI::Range(4, 200));
  app.add_option("--threads", threads, "CPU threads (default 2)")->check(CLI::Range(1, 1024));
  app.add_option("--dt", dts, "DEM steps to measure, s (default 1e-6 2e-6 5e-6 1e-5)")
      ->check(CLI::Range(1e-8, 1e-4));
  app.add_option("--frozen", frozen,
                 "fractions of the rocks frozen, the lowest first (default 0 0.7: the full "
                 "bed's rocks outside a band 0.3 m either side of the sleeper and below 0.4 m)")
      ->check(CLI::Range(0.0, 0.99));
  app.add_option("--steps", steps, "measured steps per configuration (default 200)")
      ->check(CLI::Range(1, 100000000));
  app.add_option("--repeat", repeat, "measurements per configuration, in turns (default 3)")
      ->check(CLI::Range(1, 1000));
  app.add_option("--settle-dt", settle_dt, "step while settling, s (default 5e-6)")
      ->check(CLI::Range(1e-8, 1e-4));
  app.add_option("--settle-time", settle_least, "least settling time, s (default 0.05)")
      ->check(CLI::Range(0.0, 100.0));
  app.add_option("--settle-max", settle_most, "longest settling time, s (default 0.5)")
      ->check(CLI::Range(0.0, 100.0));
  app.add_option("--settle-ke", settle_ke, "settled below this KE / (N m g d) (default 1e-3)")
      ->check(CLI::Range(0.0, 1e6));
  app.add_option("--full-rocks", full_rocks, "rocks of the full load case (default 83000)")
      ->check(CLI::Range(1.0, 1e9));
  app.add_option("--load-time", load_time,
                 "simulated time of the full load case, s (default 1.6: cases/sleeper.toml)")
      ->check(CLI::Range(1e-6, 1e6));
  app.add_option("--cache", cache_dir,
                 "folder for settled beds (default: sleeper_cost_cache beside the executable)");
  app.add_option("--json", json, "JSON file (default sleeper_cost.json in the current folder)");
  CLI11_PARSE(app, argc, argv);

  shapes::RockParams p;
  p.triangles = triangles;
  p.elongation = 0.8;
  p.flatness = 0.8;
  const auto lib = std::make_unique<shapes::ShapeLibrary>(
      shapes::ShapeLibrary::random_rocks(p, 12, 2024, shapes::SizeKind::sieve, 0.1));
  const Bed bed = make_bed(rocks, lib.get(), 0);
  std::filesystem::create_directories(cache_dir);
  char key[160];
  std::snprintf(key, sizeof key, "sleeper_bed_%zu_%d_%.3g_%.3g_%.3g_%.3g_v1.h5", rocks, triangles,
                settle_dt, settle_least, settle_most, settle_ke);
  const auto state = std::filesystem::path(cache_dir) / key;
  const Settled s = settle(bed, *lib, state, std::filesystem::exists(state), threads, settle_dt,
                           settle_least, settle_most, settle_ke);

  demfem::bench::Report rep(
      "sleeper_cost", {"rocks", "dt s", "dt / Rayleigh", "frozen", "contacts/rock",
                       "rock-steps/s", "median", "runs", "KE after", "full load case DEM h"});
  rep.set_info("model", "table 6.1 ballast: granite E 10 GPa, nu 0.27, rho 2600, mu 0.6, e 0.2; " +
                            std::to_string(triangles) +
                            " triangles, normal(40, 10) mm in [20, 80] (sieve), r_d 0.1");
  rep.set_info("threads", static_cast<long long>(threads));
  rep.set_info("settled s", s.time);
  rep.set_info("settled KE/(N m g d)", s.ke);
  rep.set_info("Rayleigh step s", s.rayleigh);
  rep.set_info("full rocks", full_rocks);
  rep.set_info("load time s", load_time);
  rep.set_info("machine", demfem::bench::machine_description());
  struct Config {
    double dt, frozen;
    std::vector<double> rates;
    Measured last;
  };
  std::vector<Config> configs;
  for (double dt : dts)
    for (double f : frozen) configs.push_back({dt, f, {}, {}});
  for (int r = 0; r < repeat; ++r) {
    for (auto& c : configs) {  // in turns: a load that comes and goes hits every one alike
      c.last = measure(bed, *lib, state, threads, c.dt, c.frozen, steps);
      c.rates.push_back(c.last.rate);
    }
  }
  for (const auto& c : configs) {
    const double best = *std::max_element(c.rates.begin(), c.rates.end());
    const double mid = demfem::bench::median(c.rates);
    const double hours = full_rocks * (load_time / c.dt) / mid / 3600.0;
    rep.add_row({static_cast<long long>(rocks), c.dt, c.dt / s.rayleigh, c.frozen, c.last.contacts,
                 best, mid, static_cast<long long>(c.rates.size()), c.last.ke_after, hours});
  }
  rep.print();
  rep.write_json(json);
  return 0;
}
