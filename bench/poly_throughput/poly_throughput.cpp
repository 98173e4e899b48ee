// Polyhedron throughput: polyhedron-steps per second of settled ballast beds of dilated
// convex rocks (10, 30 or 40 triangles) from 10^3 to 10^5 rocks, on the CPU with 1 and 2
// threads and, where available, on the GPU; beside spheres of the same sizes in the same box
// (the cost ratio), and the bytes of state per particle.
//
// The bed: rocks of a shape library (50 random rocks, elongation 0.8, flatness 0.8, r_d 0.1
// of the sieve size) with sieve sizes from the thesis's ballast distribution (normal, mean
// 40 mm, sd 10 mm, in [20, 80] mm), packed by their bounding spheres (make_bed) in a box of
// triangle-mesh walls (floor + 4 sides, open top), fallen and settled under gravity
// (restitution 0.1, step --settle-dt) until the kinetic energy is below --settle-ke N m g d
// of the mean rock; saved (cached in --cache, by default beside the executable, so a build
// settles each bed once) and restored into one system per backend and thread count, which
// runs at the measured step of 10 us. Settling at 40 us (0.13 of the smallest rock's
// Rayleigh step at this stiffness; the time-step study, docs/polyhedra.md, found beds of
// 100 times stiffer rock stable to 0.32 of it) makes the 10^4 bed 4 times cheaper to settle. The
// sphere bed is made and settled the same way with spheres whose diameters are drawn from the same
// distribution. Material as the sphere benchmark (dem_throughput): E 100 MPa, nu 0.3, rho 2600, e
// 0.2, mu 0.6, dt 1e-5 s. --frozen F ... adds runs with the lowest fraction F of the particles
// (by centre height: the deep bed, far from a sleeper) frozen (DemSystem::freeze): the rate
// still counts every particle, as a user's run of the whole bed would.
//
// Beds of --tile-from rocks and more (default 50,000: the 10^5 bed) are not settled from their
// packing (about 6 core-hours at 10^5): they are --tile copies of the settled bed of 1/--tile as
// many rocks (cached as above), laid side by side in one box --tile times the footprint (the
// copies' side walls removed), and relaxed at --settle-dt for at least --tile-relax s and until
// the kinetic energy is below --settle-ke (the seams, where the removed walls stood, settle in a
// few hundredths of a second). Their "settled s" column is that relaxation.

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <map>
#include <tuple>

#include "ballast_bed.hpp"
#include "freeze_lowest.hpp"
#include "bench_report.hpp"
#include "median.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/omp_wait.hpp"
#include "demfem/dem/placement/insertion.hpp"
#include "demfem/dem/shapes/shape_library.hpp"
#include "demfem/io/h5_file.hpp"

using namespace demfem::dem;
using demfem::bench::Bed;
using demfem::bench::box_walls;
using demfem::bench::freeze_lowest;
using demfem::bench::make_bed;

namespace {

constexpr double kRho = 2600.0;

constexpr double kDt = 1e-5;  // the measured step

DemSettings settings(int threads, const std::string& backend, double restitution, double dt = kDt,
                     MaterialPair::PolyLaw law = MaterialPair::PolyLaw::pressure_centre) {
  DemSettings s;
  s.dt = dt;
  s.gravity = {0, 0, -9.81};
  s.materials = {{"rock", 1e8, 0.3, kRho}, {"wall", 1e8, 0.3, 0.0}};
  s.pairs.assign(4, MaterialPair{0.6, restitution, 0.0});
  for (auto& p : s.pairs) p.poly_law = law;
  s.threads = threads;
  s.backend = dem_backend_from_name(backend);
  return s;
}

struct Result {
  double rate = 0, cpu_rate = 0, det = 0, force = 0, integ = 0, contacts = 0, pairs = 0;
  double bytes = 0;
  std::uint64_t hash = 0;  ///< FNV-1a of the final positions, velocities, spins, orientations
  bool ok = false;
  std::string note;
};

// FNV-1a over the bits of the particles' kinematic state: two builds that give the same hash
// from the same bed and thread count computed the same bits (an A/B check of optimisations
// meant to change no result).
std::uint64_t state_hash(const ParticleState& p) {
  std::uint64_t h = 1469598103934665603ull;
  for (const auto* v : {&p.px, &p.py, &p.pz, &p.vx, &p.vy, &p.vz, &p.wx, &p.wy, &p.wz, &p.qw,
                        &p.qx, &p.qy, &p.qz, &p.fx, &p.fy, &p.fz}) {
    const auto* b = reinterpret_cast<const unsigned char*>(v->data());
    for (std::size_t k = 0; k < v->size() * sizeof(double); ++k) h = (h ^ b[k]) * 1099511628211ull;
  }
  return h;
}

DemSystem make_system(const Bed& bed, const shapes::ShapeLibrary* lib, int threads,
                      const std::string& backend, double restitution, double dt = kDt,
                      MaterialPair::PolyLaw law = MaterialPair::PolyLaw::pressure_centre) {
  DemSystem sys(settings(threads, backend, restitution, dt, law));
  if (lib) add_library_shapes(sys, *lib, "rock");
  for (const auto& w : bed.walls) sys.add_wall(w);
  sys.add_particles(bed.particles);
  return sys;
}

Result measure(const Bed& bed, const shapes::ShapeLibrary* lib, const std::filesystem::path& state,
               int threads, const std::string& backend, std::int64_t steps, double frozen,
               MaterialPair::PolyLaw law) {
  Result r;
  try {
    DemSystem sys = make_system(bed, lib, threads, backend, 0.2, kDt, law);
    {
      demfem::io::H5File f(state, demfem::io::H5File::Mode::read);
      sys.restore(f, "/bed");
    }
    freeze_lowest(sys, frozen);
    sys.advance(10);
    const auto t0 = sys.timings();
    const auto c0 = std::chrono::steady_clock::now();
    const std::clock_t k0 = std::clock();
    sys.advance(steps);
    const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - c0).count();
    const double cpu = static_cast<double>(std::clock() - k0) / CLOCKS_PER_SEC;
    const auto t1 = sys.timings();
    const double tot =
        (t1.detection - t0.detection) + (t1.forces - t0.forces) + (t1.integration - t0.integration);
    const double n = static_cast<double>(sys.particle_count());
    r.rate = n * static_cast<double>(steps) / el;
    r.cpu_rate = n * static_cast<double>(steps) / cpu;
    r.det = (t1.detection - t0.detection) / tot;
    r.force = (t1.forces - t0.forces) / tot;
    r.integ = (t1.integration - t0.integration) / tot;
    r.pairs = static_cast<double>(sys.neighbour_pairs()) / n;
    r.contacts = 2.0 * static_cast<double>(sys.contact_count()) / n;
    r.bytes = static_cast<double>(sys.state_bytes()) / n;
    r.hash = state_hash(sys.particles());
    r.ok = true;
  } catch (const std::exception& e) {
    r.note = e.what();
  }
  return r;
}

// Settles (or loads from the cache) and returns the settling time and KE / (N m g d).
std::pair<double, double> settle(const Bed& bed, const shapes::ShapeLibrary* lib,
                                 const std::filesystem::path& state, bool cached, int threads,
                                 double settle_min, double settle_max, double settle_ke,
                                 double settle_dt) {
  DemSystem sys = make_system(bed, lib, threads, "cpu", 0.1, settle_dt);
  const double m1 = kRho * 3.14159265358979 / 6.0 * 0.04 * 0.04 * 0.04;
  auto unit = [&] { return static_cast<double>(sys.particle_count()) * m1 * 9.81 * 0.04; };
  if (cached) {
    demfem::io::H5File f(state, demfem::io::H5File::Mode::read);
    sys.restore(f, "/bed");
  } else {
    const std::int64_t chunk = std::max<std::int64_t>(1, std::llround(0.01 / settle_dt));
    while (sys.time() < settle_max - 1e-12) {
      sys.advance(chunk);
      std::fprintf(stderr, "  settling %zu: t = %.3f s, KE/(N m g d) = %.3g\n",
                   sys.particle_count(), sys.time(), sys.kinetic_energy() / unit());
      if (sys.time() >= settle_min - 1e-12 && sys.kinetic_energy() < settle_ke * unit()) break;
    }
    demfem::io::H5File f(state, demfem::io::H5File::Mode::create);
    sys.save(f, "/bed");
  }
  return {sys.time(), sys.kinetic_energy() / unit()};
}

// The factor pair tx x ty = n closest to a square (tx >= ty).
std::pair<int, int> tile_grid(int n) {
  int ty = static_cast<int>(std::floor(std::sqrt(static_cast<double>(n))));
  while (ty > 1 && n % ty != 0) --ty;
  return {n / ty, ty};
}

// `tiles` copies of the settled bed `base` (its state in `base_state`) side by side, tx x ty, in
// one box whose footprint is tx x ty times the base's (its walls' height); velocities and spins
// as settled, contact history dropped (the relaxation rebuilds it).
Bed tiled_bed(const Bed& base, const shapes::ShapeLibrary* lib,
              const std::filesystem::path& base_state, int tiles) {
  DemSystem sys = make_system(base, lib, 1, "cpu", 0.1);
  {
    demfem::io::H5File f(base_state, demfem::io::H5File::Mode::read);
    sys.restore(f, "/bed");
  }
  const ParticleState& p = sys.particles();
  const auto [tx, ty] = tile_grid(tiles);
  double height = 0.0;
  for (const auto& w : base.walls)
    for (std::size_t k = 2; k < w.vertices.size(); k += 3) height = std::max(height, w.vertices[k]);
  Bed bed;
  bed.lx = tx * base.lx;
  bed.ly = ty * base.ly;
  bed.walls = box_walls(bed.lx, bed.ly, height);
  bed.particles.reserve(static_cast<std::size_t>(tiles) * p.size());
  for (int j = 0; j < ty; ++j)
    for (int i = 0; i < tx; ++i)
      for (std::size_t k = 0; k < p.size(); ++k) {
        ParticleInit q;
        q.position = {p.px[k] + i * base.lx, p.py[k] + j * base.ly, p.pz[k]};
        q.velocity = {p.vx[k], p.vy[k], p.vz[k]};
        q.angular_velocity = {p.wx[k], p.wy[k], p.wz[k]};
        q.radius = p.radius[k];
        q.material = p.material[k];
        q.shape = static_cast<ParticleShape>(p.shape[k]);
        q.shape_id = p.shape_id[k];
        q.scale = p.scale[k];
        const double qn = std::sqrt(p.qw[k] * p.qw[k] + p.qx[k] * p.qx[k] + p.qy[k] * p.qy[k] +
                                    p.qz[k] * p.qz[k]);
        q.orientation = {p.qw[k] / qn, p.qx[k] / qn, p.qy[k] / qn, p.qz[k] / qn};
        bed.particles.push_back(q);
      }
  return bed;
}

}  // namespace

int main(int argc, char** argv) {
  demfem::dem::ensure_omp_wait_policy(argv);  // first: it may re-execute the program
  CLI::App app{"Polyhedron throughput (polyhedron-steps per second) of settled ballast beds"};
  std::vector<std::size_t> counts = {1000, 10000, 100000};
  std::vector<int> triangles = {10, 30, 40};
  std::vector<int> threads = {1, 2};
  double settle_min = 0.1, settle_max = 1.0, settle_ke = 1e-3, settle_dt = 4e-5, work = 4e6;
  int settle_threads = 2, repeat = 1, tiles = 10;
  std::size_t tile_from = 50000;
  double tile_relax = 0.02;
  bool gpu = true, spheres = true, hashes = false;
  std::string json;
  std::error_code ec;
  const auto exe = std::filesystem::canonical("/proc/self/exe", ec);
  std::string cache_dir =
      ((ec ? std::filesystem::temp_directory_path() : exe.parent_path()) / "poly_throughput_cache")
          .string();
  app.add_option("--counts", counts, "rocks per bed (default 1000 10000 100000)");
  app.add_option("--triangles", triangles, "triangles per rock (default 10 30 40)");
  app.add_option("--threads", threads, "CPU thread counts (default 1 2)");
  app.add_option("--settle-time", settle_min, "least settling time, s");
  app.add_option("--settle-max", settle_max, "longest settling time, s");
  app.add_option("--settle-ke", settle_ke, "settled below this KE / (N m g d)");
  app.add_option("--settle-threads", settle_threads, "threads for settling");
  app.add_option("--settle-dt", settle_dt, "time step while settling, s")
      ->check(CLI::Range(1e-7, 1e-4));
  app.add_option("--tile-from", tile_from,
                 "beds of this many rocks and more are tiled from settled smaller beds "
                 "(default 50000)");
  app.add_option("--tile", tiles, "copies of the smaller bed in a tiled bed (default 10)")
      ->check(CLI::Range(2, 1000));
  app.add_option("--tile-relax", tile_relax, "least relaxation of a tiled bed, s (default 0.02)")
      ->check(CLI::Range(0.0, 10.0));
  app.add_option("--work", work, "particle-steps per measurement (steps: 100 to 20000)");
  app.add_option("--repeat", repeat, "measurements per configuration, in turns (best and median)")
      ->check(CLI::Range(1, 1000));
  app.add_option("--cache", cache_dir,
                 "folder for settled beds (default: poly_throughput_cache beside the executable; "
                 "empty: no cache)");
  app.add_option("--json", json, "write the results as JSON");
  std::vector<double> frozen_fracs{0.0};
  app.add_option("--frozen", frozen_fracs,
                 "fractions of the particles frozen, the lowest first (default 0; CPU runs)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_flag("!--no-gpu", gpu, "skip the GPU even when one is present");
  app.add_flag("!--no-spheres", spheres, "skip the sphere beds");
  std::vector<std::string> laws = {"pressure_centre"};
  app.add_option("--law", laws,
                 "contact laws of the rocks, measured in turns on the same settled bed "
                 "(pressure_centre, smooth; default pressure_centre; beds settle under "
                 "pressure_centre)")
      ->check(CLI::IsMember({"pressure_centre", "smooth"}));
  app.add_flag("--state-hash", hashes,
               "print a hash of each run's final particle state (bitwise A/B of two builds)");
  CLI11_PARSE(app, argc, argv);

  demfem::bench::Report rep(
      "poly_throughput",
      {"particles", "shape", "law", "settled s", "KE/(N m g d)", "backend", "threads", "frozen",
       "contacts/particle", "list pairs/particle", "particle-steps/s", "per cpu-s", "runs",
       "median", "ratio to spheres", "bytes/particle", "detection", "forces", "integration"});
  rep.set_info("dt", kDt);
  rep.set_info("settle dt", settle_dt);
  rep.set_info("model",
               std::string("dilated polyhedra, E 100 MPa, nu 0.3, rho 2600, e 0.2, mu 0.6; "
                           "sizes normal(40, 10) mm in [20, 80] (sieve), r_d 0.1"));
  rep.set_info("machine", demfem::bench::machine_description());
  const bool have_gpu = gpu && cuda_available();
  const bool cache = !cache_dir.empty();
  if (cache) std::filesystem::create_directories(cache_dir);
  const auto tmp = std::filesystem::temp_directory_path() /
                   ("demfem_poly_throughput_" + std::to_string(::getpid()));
  std::filesystem::create_directories(tmp);
  for (std::size_t n_asked : counts) {
    // spheres of the same sizes first: the reference rate of the ratio column
    std::map<std::pair<std::string, int>, double> sphere_rate;  // by backend and threads
    std::vector<std::string> kinds;
    if (spheres) kinds.push_back("spheres");
    for (int t : triangles) kinds.push_back(std::to_string(t) + " triangles");
    for (const auto& kind : kinds) {
      const bool rock = kind != "spheres";
      std::unique_ptr<shapes::ShapeLibrary> lib;
      if (rock) {
        shapes::RockParams p;
        p.triangles = std::stoi(kind);
        p.elongation = 0.8;
        p.flatness = 0.8;
        lib = std::make_unique<shapes::ShapeLibrary>(
            shapes::ShapeLibrary::random_rocks(p, 50, 2024, shapes::SizeKind::sieve, 0.1));
      }
      const bool tiled = n_asked >= tile_from;
      const std::size_t n_bed =
          tiled ? n_asked / static_cast<std::size_t>(tiles) : n_asked;
      auto state_file = [&](std::size_t count, const char* suffix) {
        char key[200];
        std::snprintf(key, sizeof key, "poly_bed_%zu_%s_%.3g_%.3g_%.3g_%.3g%s_v3.h5", count,
                      rock ? std::to_string(std::stoi(kind)).c_str() : "spheres", settle_min,
                      settle_max, settle_ke, settle_dt, suffix);
        return cache ? std::filesystem::path(cache_dir) / key : tmp / key;
      };
      Bed bed = make_bed(n_bed, lib.get(), 0);
      auto state = state_file(n_bed, "");
      auto [settled, ke] =
          settle(bed, lib.get(), state, cache && std::filesystem::exists(state), settle_threads,
                 settle_min, settle_max, settle_ke, settle_dt);
      if (tiled) {
        bed = tiled_bed(bed, lib.get(), state, tiles);
        char suffix[64];
        std::snprintf(suffix, sizeof suffix, "_tile%d_%.3g", tiles, tile_relax);
        state = state_file(n_bed, suffix);
        std::tie(settled, ke) =
            settle(bed, lib.get(), state, cache && std::filesystem::exists(state), settle_threads,
                   tile_relax, settle_max, settle_ke, settle_dt);
      }
      const std::size_t n = bed.particles.size();
      const std::int64_t steps = std::clamp<std::int64_t>(
          static_cast<std::int64_t>(work / static_cast<double>(n)), 100, 20000);
      struct Run {
        std::string first;
        int second;
        double frozen;
        std::string law;
      };
      std::vector<Run> runs;
      // spheres do not depend on the polyhedron law: measured once
      const std::vector<std::string> kind_laws = rock ? laws : std::vector<std::string>{"-"};
      for (const auto& law : kind_laws) {
        for (double f : frozen_fracs)
          for (int t : threads) runs.push_back({"cpu", t, f, law});
        if (have_gpu) runs.push_back({"cuda", 0, 0.0, law});
      }
      std::vector<std::vector<Result>> done(runs.size());
      for (int k = 0; k < repeat; ++k)
        for (std::size_t c = 0; c < runs.size(); ++c) {
          Result r = measure(
              bed, lib.get(), state, runs[c].second, runs[c].first,
              runs[c].first == "cuda" ? 20 * steps : steps, runs[c].frozen,
              rock ? poly_law_from_name(runs[c].law) : MaterialPair::PolyLaw::pressure_centre);
          if (!r.ok) {
            std::fprintf(stderr, "%zu %s, %s: %s\n", n, kind.c_str(), runs[c].first.c_str(),
                         r.note.c_str());
            continue;
          }
          if (hashes)
            std::printf("state hash: %zu %s %s, %s %d threads, %lld steps: %016llx\n", n,
                        kind.c_str(), runs[c].law.c_str(), runs[c].first.c_str(), runs[c].second,
                        static_cast<long long>(runs[c].first == "cuda" ? 20 * steps : steps),
                        static_cast<unsigned long long>(r.hash));
          done[c].push_back(std::move(r));
        }
      for (std::size_t c = 0; c < runs.size(); ++c) {
        auto& rs = done[c];
        if (rs.empty()) continue;
        const double median = demfem::bench::sort_fastest_first(rs);
        const Result& r = rs.front();
        const auto key = std::make_pair(runs[c].first, runs[c].second);
        if (!rock && runs[c].frozen == 0.0) sphere_rate[key] = r.rate;
        const double ratio = rock && sphere_rate.count(key) && runs[c].frozen == 0.0
                                 ? sphere_rate[key] / r.rate
                                 : 1.0;
        rep.add_row({static_cast<long long>(n), kind, runs[c].law, settled, ke, runs[c].first,
                     static_cast<long long>(runs[c].second), runs[c].frozen, r.contacts, r.pairs,
                     r.rate, r.cpu_rate, static_cast<long long>(rs.size()), median, ratio, r.bytes,
                     r.det, r.force, r.integ});
      }
      if (!cache) std::filesystem::remove(state);
    }
  }
  std::filesystem::remove_all(tmp);
  rep.print();
  rep.write_json(json);
  return 0;
}
