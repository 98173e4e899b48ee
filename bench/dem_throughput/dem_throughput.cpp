// DEM throughput: particle-steps per second of a settled bed (Hertz–Mindlin with history,
// dt = 1e-5 s) from 10^3 to 10^6 spheres (10^7 with --max-particles 1e7, for a device), on
// the CPU with 1 and 2 threads (--threads; none with --no-cpu) and, where
// available, on the GPU; the share of time in contact detection, force computation and
// integration. Includes the target case of the issue: 20,000 spheres of radius 2 mm,
// E = 100 MPa, nu = 0.3, e = 0.4, mu = 0.5.
//
// The bed, in a box of triangle-mesh walls (floor + 4 sides), either
//   poured:  spheres inserted at random positions (solid fraction 0.2) above the floor, fallen
//            and settled: a random packing, as in a real bed (coordination about 6);
//   lattice: spheres on a hexagonal close-packed lattice (spacing = mean diameter), settled in
//            place: a crystal, denser than any poured bed (coordination up to 12), so more
//            contacts per particle; quick to settle, used for the large beds.
// Either is settled under gravity (restitution 0.1) until its kinetic energy is below
// --settle-ke N m g d, saved (cached in --cache for later runs), and restored into one
// system per backend so that every backend runs the same state. With --repeat N each
// backend and thread count is measured N times in turns; the row gives the fastest run and
// the median rate.

#include <unistd.h>
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <limits>
#include <random>
#include <unordered_map>

#include "ballast_bed.hpp"
#include "bench_report.hpp"
#include "median.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/omp_wait.hpp"
#include "demfem/dem/placement/insertion.hpp"
#include "demfem/io/h5_file.hpp"

using namespace demfem::dem;

namespace {

struct BedSpec {
  std::size_t n;
  double rmin, rmax;
  std::string label;
  bool poured = false;
};

DemSettings settings(int threads, const std::string& backend, double restitution = 0.4) {
  DemSettings s;
  s.dt = 1e-5;
  s.gravity = {0, 0, -9.81};
  s.materials = {{"grain", 1e8, 0.3, 2500.0}, {"wall", 1e8, 0.3, 0.0}};
  s.pairs.assign(4, MaterialPair{0.5, restitution, 0.0});
  s.threads = threads;
  s.backend = dem_backend_from_name(backend);
  return s;
}

// The box of triangle-mesh walls (floor + 4 sides, open top) and the bed in it, as the
// polyhedron benches build them.
using demfem::bench::Bed;
using demfem::bench::box_walls;

Bed make_bed(const BedSpec& b) {
  Bed bed;
  // Lattice spacing = mean diameter; a sphere's radius is drawn from [rmin, rmax] and
  // clipped so that it at most touches its already placed nearest neighbours (a dense,
  // polydisperse packing whose contacts load within a short settling time).
  const double a = (b.rmin + b.rmax) * (1.0 + 1e-9);
  // footprint about twice the height
  const auto side = static_cast<std::size_t>(std::ceil(std::cbrt(4.0 * b.n)));
  const std::size_t nx = side, ny = side;
  const double dy = a * std::sqrt(3.0) / 2.0, dz = a * std::sqrt(2.0 / 3.0);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(b.rmin, b.rmax);
  std::unordered_map<std::int64_t, std::vector<std::size_t>> grid;  // cell a -> particles
  auto key = [&](double x, double y, double z) {
    return (static_cast<std::int64_t>(z / a) * 1000003 + static_cast<std::int64_t>(y / a)) *
               1000003 +
           static_cast<std::int64_t>(x / a);
  };
  for (std::size_t k = 0; bed.particles.size() < b.n; ++k)
    for (std::size_t j = 0; j < ny && bed.particles.size() < b.n; ++j)
      for (std::size_t i = 0; i < nx && bed.particles.size() < b.n; ++i) {
        ParticleInit p;
        const double ox = (j % 2) * 0.5 * a + (k % 2) * 0.5 * a;
        const double oy = (k % 2) * dy / 3.0;
        p.position = {b.rmax + i * a + ox, b.rmax + j * dy + oy, b.rmax + k * dz};
        double r = b.rmin == b.rmax ? b.rmin : u(rng);
        const auto& x = p.position;
        for (int cz = -1; cz <= 1; ++cz)
          for (int cy = -1; cy <= 1; ++cy)
            for (int cx = -1; cx <= 1; ++cx) {
              const auto it = grid.find(key(x[0] + cx * a, x[1] + cy * a, x[2] + cz * a));
              if (it == grid.end()) continue;
              for (std::size_t q : it->second) {
                const auto& y = bed.particles[q].position;
                const double d =
                    std::sqrt((x[0] - y[0]) * (x[0] - y[0]) + (x[1] - y[1]) * (x[1] - y[1]) +
                              (x[2] - y[2]) * (x[2] - y[2]));
                r = std::min(r, d - bed.particles[q].radius);
              }
            }
        p.radius = std::max(r, b.rmin);
        p.material = 0;
        grid[key(x[0], x[1], x[2])].push_back(bed.particles.size());
        bed.particles.push_back(p);
      }
  const double lx = nx * a + a, ly = ny * dy + a, h = (b.n / (nx * ny) + 2) * dz + a;
  bed.lx = lx, bed.ly = ly;
  bed.walls = box_walls(lx, ly, h);
  return bed;
}

// Random insertion (solid fraction 0.2) over the footprint of the lattice bed; the box is
// tall enough to hold the insertion region.
Bed make_poured_bed(const BedSpec& b) {
  Bed bed;
  const double a = b.rmin + b.rmax;  // mean diameter
  const auto side = static_cast<std::size_t>(std::ceil(std::cbrt(4.0 * b.n)));
  const double lx = side * a + a, ly = lx;
  RandomInsertion q;
  q.sizes = b.rmin == b.rmax ? SizeDistribution::constant(2.0 * b.rmin)
                             : SizeDistribution::uniform(2.0 * b.rmin, 2.0 * b.rmax);
  q.count = static_cast<std::int64_t>(b.n);
  q.density = 2500.0;
  q.seed = 7;
  const double solid = static_cast<double>(b.n) * 3.14159265358979 / 6.0 * q.sizes.mean_cube();
  const double hz = solid / (0.2 * lx * ly);
  q.region = Box{{0, 0, 0}, {lx, ly, hz}};
  bed.particles = insert_random(q);
  bed.lx = lx, bed.ly = ly;
  const double h = hz + 2 * a;
  bed.walls = box_walls(lx, ly, h);
  return bed;
}

struct Result {
  double rate = 0, cpu_rate = 0, det = 0, force = 0, integ = 0, contacts = 0, pairs = 0;
  double steps_per_build = 0, steps_per_refilter = 0;  // inf: none while measuring
  bool ok = false;
  std::string note;
};

Result measure(const Bed& bed, const std::filesystem::path& state, int threads,
               const std::string& backend, std::int64_t steps) {
  Result r;
  try {
    DemSystem sys(settings(threads, backend));
    for (const auto& w : bed.walls) sys.add_wall(w);
    sys.add_particles(bed.particles);
    {
      demfem::io::H5File f(state, demfem::io::H5File::Mode::read);
      sys.restore(f, "/bed");
    }
    sys.advance(10);  // warm-up: neighbour list, caches
    const auto t0 = sys.timings();
    const std::int64_t b0 = sys.neighbour_rebuilds(), f0 = sys.neighbour_refilters();
    const auto c0 = std::chrono::steady_clock::now();
    const std::clock_t k0 = std::clock();
    sys.advance(steps);
    const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - c0).count();
    const double cpu = static_cast<double>(std::clock() - k0) / CLOCKS_PER_SEC;
    const auto t1 = sys.timings();
    const auto per = [&](std::int64_t count) {
      return count > 0 ? static_cast<double>(steps) / static_cast<double>(count)
                       : std::numeric_limits<double>::infinity();
    };
    r.steps_per_build = per(sys.neighbour_rebuilds() - b0);
    r.steps_per_refilter = per(sys.neighbour_refilters() - f0);
    const double tot =
        (t1.detection - t0.detection) + (t1.forces - t0.forces) + (t1.integration - t0.integration);
    r.rate = static_cast<double>(sys.particle_count()) * static_cast<double>(steps) / el;
    // per CPU-second of all threads: on a shared machine the single-thread value estimates
    // the rate of an otherwise idle core
    r.cpu_rate = static_cast<double>(sys.particle_count()) * static_cast<double>(steps) / cpu;
    r.det = (t1.detection - t0.detection) / tot;
    r.force = (t1.forces - t0.forces) / tot;
    r.integ = (t1.integration - t0.integration) / tot;
    r.pairs =
        static_cast<double>(sys.neighbour_pairs()) / static_cast<double>(sys.particle_count());
    r.contacts =
        2.0 * static_cast<double>(sys.contact_count()) / static_cast<double>(sys.particle_count());
    r.ok = true;
  } catch (const std::exception& e) {
    r.note = e.what();
  }
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  demfem::dem::ensure_omp_wait_policy(argv);  // first: it may re-execute the program
  CLI::App app{"DEM throughput (particle-steps per second) of a settled bed"};
  std::size_t max_particles = 1000000;
  double settle_time = 0.02;
  std::string json;
  bool gpu = true;
  std::size_t only = 0;
  int settle_threads = 2;
  std::vector<int> threads = {1, 2};
  app.add_option("--max-particles", max_particles, "largest bed to run")
      ->check(CLI::PositiveNumber);
  double settle_max = 0.5, settle_ke = 1e-4;
  std::string cache_dir =
      (std::filesystem::temp_directory_path() / "demfem_dem_throughput_cache").string();
  app.add_option("--settle-time", settle_time, "least settling time before measuring, s")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--settle-max", settle_max, "longest settling time, s")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--settle-ke", settle_ke,
                 "settled when the kinetic energy is below this fraction of N m g d")
      ->check(CLI::PositiveNumber);
  app.add_option("--cache", cache_dir, "folder for settled beds (reused; empty = no cache)");
  app.add_option("--json", json, "write the results as JSON");
  app.add_option("--settle-threads", settle_threads, "CPU threads for settling the bed")
      ->check(CLI::PositiveNumber);
  app.add_option("--only", only, "run only the bed with this many particles");
  double work = 4e6;
  app.add_option("--work", work,
                 "particle-steps per measurement (steps = work / particles, 200 to 20000: fewer "
                 "steps would measure the list adapting after the restore)")
      ->check(CLI::PositiveNumber);
  app.add_option("--threads", threads, "CPU thread counts to run (default 1 2)");
  int repeat = 1;
  app.add_option("--repeat", repeat,
                 "measurements per backend and thread count, taken in turns; the table gives "
                 "the best and the median (on a shared machine one run varies by up to 25 %)")
      ->check(CLI::Range(1, 1000));
  app.add_flag("!--no-gpu", gpu, "skip the GPU even when one is present");
  bool cpu_rows = true;
  app.add_flag("!--no-cpu", cpu_rows,
               "the GPU row only (a device sweep; concurrent runs sharing one device)");
  std::string settle_backend = "auto";
  app.add_option("--settle-backend", settle_backend,
                 "backend that settles the beds: cpu, cuda, or auto (cuda when the GPU runs, "
                 "else cpu; a 10^6 bed takes hours to settle on two CPU cores)")
      ->check(CLI::IsMember({"auto", "cpu", "cuda"}));
  std::string bed_kind = "auto";
  app.add_option("--bed", bed_kind,
                 "poured (random packing), lattice (settled crystal) or auto (poured up to "
                 "20,000 spheres, lattice above: pouring a larger bed takes too long on a CPU)")
      ->check(CLI::IsMember({"auto", "poured", "lattice"}));
  CLI11_PARSE(app, argc, argv);

  const std::vector<BedSpec> specs = {
      {1000, 0.0015, 0.0025, "d 3-5 mm"},     {10000, 0.0015, 0.0025, "d 3-5 mm"},
      {20000, 0.002, 0.002, "target r 2 mm"}, {100000, 0.0015, 0.0025, "d 3-5 mm"},
      {200000, 0.0015, 0.0025, "d 3-5 mm"},   {1000000, 0.0015, 0.0025, "d 3-5 mm"},
      {10000000, 0.0015, 0.0025, "d 3-5 mm"}};
  demfem::bench::Report rep(
      "dem_throughput",
      {"particles", "bed", "settled s", "KE/(N m g d)", "backend", "threads", "contacts/particle",
       "list pairs/particle", "steps/build", "steps/refilter", "particle-steps/s", "per cpu-s",
       "runs", "median particle-steps/s", "detection", "forces", "integration"});
  rep.set_info("dt", 1e-5);
  rep.set_info("model",
               std::string("Hertz-Mindlin with history, E 100 MPa, nu 0.3, e 0.4, mu 0.5"));
  rep.set_info("settle_time_s", settle_time);
  rep.set_info("settle_max_s", settle_max);
  rep.set_info("settle_ke", settle_ke);
  rep.set_info("machine", demfem::bench::machine_description());
  const auto dir = std::filesystem::temp_directory_path() /
                   ("demfem_dem_throughput_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const bool have_gpu = gpu && cuda_available();
  const std::string settle_on =
      settle_backend == "auto" ? (have_gpu ? "cuda" : "cpu") : settle_backend;
  rep.set_info("settle_backend", settle_on);
  for (auto spec : specs) {
    if (spec.n > max_particles || (only != 0 && spec.n != only)) continue;
    spec.poured = bed_kind == "poured" || (bed_kind == "auto" && spec.n <= 20000);
    spec.label += spec.poured ? ", poured" : ", lattice";
    const Bed bed = spec.poured ? make_poured_bed(spec) : make_bed(spec);
    // Settling: restitution 0.1 (instead of 0.4) damps the bed faster; it runs until the
    // kinetic energy is below settle_ke N m g d (m, d of the mean sphere) after at least
    // settle_time, at most settle_max. The settled state is cached under cache_dir, keyed
    // by the bed and the settling parameters, and reused by later runs.
    char key[160];
    std::snprintf(key, sizeof key, "bed_%zu_%.5g_%.5g_%.3g_%.3g_%.3g_%s_v3.h5", spec.n, spec.rmin,
                  spec.rmax, settle_time, settle_max, settle_ke,
                  spec.poured ? "poured" : "lattice");
    const bool cache = !cache_dir.empty();
    if (cache) std::filesystem::create_directories(cache_dir);
    const auto state = cache ? std::filesystem::path(cache_dir) / key : dir / key;
    double settled_s = 0.0, ke_ratio = 0.0;
    std::string label = spec.label;
    {
      DemSystem sys(settings(settle_threads, settle_on, 0.1));
      for (const auto& w : bed.walls) sys.add_wall(w);
      sys.add_particles(bed.particles);
      const double rm = 0.5 * (spec.rmin + spec.rmax);
      // N m g d of the mean sphere (N: the spheres still in the box)
      const double unit1 = 2500.0 * 4.0 / 3.0 * 3.14159265358979 * rm * rm * rm * 9.81 * 2.0 * rm;
      auto unit = [&] { return static_cast<double>(sys.particle_count()) * unit1; };
      if (cache && std::filesystem::exists(state)) {
        demfem::io::H5File f(state, demfem::io::H5File::Mode::read);
        sys.restore(f, "/bed");
      } else {
        const std::int64_t chunk = 500;  // 5 ms
        while (sys.time() < settle_max - 1e-12) {
          sys.advance(chunk);
          // Spheres of the polydisperse lattice whose radius had to stay above rmin start
          // with an overlap and can be thrown over the (open-topped) walls; outside the box
          // they would fall forever and keep the bed from settling: drop them.
          const auto& st = sys.particles();
          std::vector<std::uint8_t> keep(st.size(), 1);
          bool lost = false;
          for (std::size_t i = 0; i < st.size(); ++i) {
            const double r = st.radius[i];
            if (st.px[i] < -r || st.px[i] > bed.lx + r || st.py[i] < -r || st.py[i] > bed.ly + r ||
                st.pz[i] < -r)
              keep[i] = 0, lost = true;
          }
          if (lost) sys.remove_particles(keep);
          if (sys.time() >= settle_time - 1e-12 && sys.kinetic_energy() < settle_ke * unit()) break;
        }
        demfem::io::H5File f(state, demfem::io::H5File::Mode::create);
        sys.save(f, "/bed");
      }
      settled_s = sys.time();
      ke_ratio = sys.kinetic_energy() / unit();
      if (sys.particle_count() < spec.n)
        label += " (" + std::to_string(spec.n - sys.particle_count()) + " thrown out)";
    }
    const std::int64_t steps = std::clamp<std::int64_t>(
        static_cast<std::int64_t>(work / static_cast<double>(spec.n)), 200, 20000);
    std::vector<std::pair<std::string, int>> runs;
    if (cpu_rows)
      for (int t : threads) runs.push_back({"cpu", t});
    if (have_gpu) runs.push_back({"cuda", 0});
    // Every configuration is measured `repeat` times in turns, so that a busy spell of a
    // shared machine falls on all of them alike. The row holds the fastest run (its rate per
    // CPU-second and its shares) and the median rate.
    std::vector<std::vector<Result>> done(runs.size());
    for (int rep_k = 0; rep_k < repeat; ++rep_k)
      for (std::size_t c = 0; c < runs.size(); ++c) {
        const auto& [backend, th] = runs[c];
        Result r = measure(bed, state, th, backend, backend == "cuda" ? 20 * steps : steps);
        if (!r.ok) {
          std::fprintf(stderr, "%zu particles, %s: %s\n", spec.n, backend.c_str(), r.note.c_str());
          continue;
        }
        done[c].push_back(std::move(r));
      }
    for (std::size_t c = 0; c < runs.size(); ++c) {
      auto& rs = done[c];
      if (rs.empty()) continue;
      const double median = demfem::bench::sort_fastest_first(rs);
      const Result& r = rs.front();
      rep.add_row({static_cast<long long>(spec.n), label, settled_s, ke_ratio, runs[c].first,
                   static_cast<long long>(runs[c].second), r.contacts, r.pairs, r.steps_per_build,
                   r.steps_per_refilter, r.rate, r.cpu_rate, static_cast<long long>(rs.size()),
                   median, r.det, r.force, r.integ});
    }
    if (!cache) std::filesystem::remove(state);
  }
  std::filesystem::remove_all(dir);
  rep.print();
  rep.write_json(json);
  return 0;
}
