// Cost of particle shapes: building a library of K random rocks (hull, exact mass properties,
// sieve size) at the thesis's 10, 30 and 40 triangles on 1 and 2 threads; one rock core alone
// (hull + mass properties, no sieve size); drawing scaled particles from a library; and the
// accuracy of the sieve-size search against a much more thorough one on random hulls.
//
// Variants are interleaved over the repeats (a shared, noisy machine); the table gives the
// best and the median wall time.
//
// Large cores (--large, e.g. 1000,10000,100000 vertices on an ellipsoid 5 : 3.5 : 2 and on a
// sphere, all on the hull: a finely scanned rock, and the worst case of the search): the time
// of the hull, of the mass properties and of the sieve size, and the sieve size against the
// exhaustive reference (up to --large-reference vertices: it costs O(V^2 log V)).
//
//   build/bench/shape_library [--count 1000] [--repeats 3] [--hulls 200] [--json out.json]
//                             [--large 10000 --large-only]

#include <omp.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <functional>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "bench_report.hpp"
#include "demfem/dem/shapes/shapes.hpp"

using namespace demfem::dem;
using namespace demfem::dem::shapes;

namespace {

/// Wall and CPU seconds (all threads) of f.
struct Timing {
  double wall, cpu;
};
Timing seconds(const std::function<void()>& f) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::clock_t c0 = std::clock();
  f();
  return {std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
          double(std::clock() - c0) / CLOCKS_PER_SEC};
}

/// Best and median wall time, and the CPU time of the best run.
struct Summary {
  double best, median, cpu;
};
Summary summarise(const std::vector<Timing>& t) {
  std::vector<double> w;
  for (const Timing& x : t) w.push_back(x.wall);
  const auto it = std::min_element(
      t.begin(), t.end(), [](const Timing& a, const Timing& b) { return a.wall < b.wall; });
  std::sort(w.begin(), w.end());
  const std::size_t n = w.size();
  return {it->wall, n % 2 ? w[n / 2] : 0.5 * (w[n / 2 - 1] + w[n / 2]), it->cpu};
}

/// Setup cost of cores of many vertices (hull, mass properties, sieve size) and the sieve size
/// against the every-vertex reference.
void large_cores(const std::vector<std::size_t>& counts, std::size_t reference_up_to) {
  std::printf("%10s %10s %10s %10s %10s %12s %12s %22s %22s\n", "shape", "points", "vertices",
              "hull s", "mass s", "sieve s", "ref sieve s", "sieve size", "reference");
  for (const bool sphere : {false, true})
    for (const std::size_t n : counts) {
      std::mt19937_64 gen(n);
      std::normal_distribution<double> g;
      std::vector<Vec3> p(n);
      for (Vec3& x : p) {
        const Vec3 y{g(gen), g(gen), g(gen)};
        const double l = norm(y);
        x = sphere ? Vec3{0.04 * y[0] / l, 0.04 * y[1] / l, 0.04 * y[2] / l}
                   : Vec3{0.05 * y[0] / l, 0.035 * y[1] / l, 0.02 * y[2] / l};
      }
      std::optional<ConvexPolyhedron> k;
      const Timing th = seconds([&] { k.emplace(ConvexPolyhedron::hull(p, "ellipsoid points")); });
      const Timing tm = seconds([&] {
        if (!(core_mass_properties(*k).volume > 0)) std::abort();
      });
      SieveFit fit, ref;
      const Timing ts = seconds([&] { fit = sieve_size(*k); });
      Timing tr{NAN, NAN};
      if (n <= reference_up_to) {
        SieveSearch every;
        every.band_from_vertices = INT_MAX;
        every.skip_hopeless_normals = false;
        tr = seconds([&] { ref = sieve_size(*k, every); });
      }
      std::printf("%10s %10zu %10zu %10.3f %10.3f %12.3f %12.3f %22.17g %22.17g\n",
                  sphere ? "sphere" : "ellipsoid", n, k->vertices().size(), th.wall, tm.wall,
                  ts.wall, tr.wall, fit.size, n <= reference_up_to ? ref.size : NAN);
      std::fflush(stdout);
    }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Particle shapes: library build time, per-rock cost, sieve-size accuracy"};
  std::size_t count = 1000;
  int repeats = 3;
  int hulls = 200;
  std::size_t cores = 10000, samples = 100000;
  std::string json;
  app.add_option("--count", count, "rocks per library");
  app.add_option("--repeats", repeats, "repeats of each timing (interleaved)");
  app.add_option("--cores", cores, "rock cores for the per-core cost");
  app.add_option("--samples", samples, "scaled particles drawn from a library");
  app.add_option("--hulls", hulls, "random hulls for the sieve-size accuracy study");
  app.add_option("--json", json, "write the results as JSON");
  std::vector<std::size_t> large;
  std::size_t large_reference = 20000;
  bool large_only = false;
  app.add_option("--large", large, "vertex counts of large cores (ellipsoid points)")
      ->delimiter(',');
  app.add_option("--large-reference", large_reference,
                 "largest core also sized by projecting every vertex");
  app.add_flag("--large-only", large_only, "only the large cores");
  CLI11_PARSE(app, argc, argv);
  if (!large.empty()) large_cores(large, large_reference);
  if (large_only) return 0;

  demfem::bench::Report report("shape_library", {"task", "triangles", "threads", "items", "best s",
                                                 "median s", "CPU s of best", "best ms/item"});
  report.set_info("machine", demfem::bench::machine_description());
  report.set_info("commit", demfem::bench::git_commit());
  report.set_info("rock", std::string("elongation 0.8, flatness 0.7, r_d = 0.1 x sieve size"));

  const RockParams base{30, 0.8, 0.7};
  const std::vector<int> triangle_counts{10, 30, 40};
  const std::vector<int> thread_counts{1, 2};

  // Library builds, interleaved: (triangles, threads) per repeat.
  std::map<std::pair<int, int>, std::vector<Timing>> build;
  std::map<int, std::vector<Timing>> core_only;
  for (int r = 0; r < repeats; ++r) {
    for (int tri : triangle_counts) {
      RockParams p = base;
      p.triangles = tri;
      for (int th : thread_counts) {
        omp_set_num_threads(th);
        build[{tri, th}].push_back(seconds([&] {
          const auto lib =
              ShapeLibrary::random_rocks(p, count, 1 + std::uint64_t(r), SizeKind::sieve, 0.1);
          if (lib.size() != count) std::abort();
        }));
      }
      core_only[tri].push_back(seconds([&] {
        double v = 0;
        for (std::size_t k = 0; k < cores; ++k)
          v += core_mass_properties(random_rock(p, derived_seed(7 + std::uint64_t(r), k))).volume;
        if (!(v > 0)) std::abort();
      }));
    }
  }
  for (int tri : triangle_counts) {
    for (int th : thread_counts) {
      const Summary t = summarise(build[{tri, th}]);
      report.add_row({std::string("library build (hull, mass, sieve)"), (long long)tri,
                      (long long)th, (long long)count, t.best, t.median, t.cpu,
                      1e3 * t.best / double(count)});
    }
    const Summary t = summarise(core_only[tri]);
    report.add_row({std::string("rock core + mass properties"), (long long)tri, 1LL,
                    (long long)cores, t.best, t.median, t.cpu, 1e3 * t.best / double(cores)});
  }

  // Drawing scaled particles (the per-particle cost of a bed): shape index + size + scaling.
  {
    omp_set_num_threads(2);
    const auto lib = ShapeLibrary::random_rocks(base, 200, 3, SizeKind::sieve, 0.1);
    const auto dist = SizeDistribution::normal(0.04, 0.01, 0.02, 0.08);
    std::vector<Timing> t;
    for (int r = 0; r < repeats; ++r) {
      Rng rng(5 + std::uint64_t(r));
      double mass = 0;
      t.push_back(seconds([&] {
        for (std::size_t i = 0; i < samples; ++i) mass += lib.sample(rng, dist).volume;
      }));
      if (!(mass > 0)) std::abort();
    }
    const Summary s = summarise(t);
    report.add_row({std::string("scaled particle from a library"), 30LL, 1LL, (long long)samples,
                    s.best, s.median, s.cpu, 1e3 * s.best / double(samples)});
  }
  report.print();

  // Sieve-size search against a thorough one (16x directions, 8x starts, last step 1e-11).
  {
    std::mt19937_64 gen(1);
    std::normal_distribution<double> g;
    double worst = 0;
    int above = 0;
    for (int trial = 0; trial < hulls; ++trial) {
      std::vector<Vec3> p(std::size_t(4 + trial % 30));
      for (Vec3& x : p) {
        const Vec3 y{g(gen), g(gen), g(gen)};
        const double l = norm(y);
        x = {y[0] / l, 0.7 * y[1] / l, 0.4 * y[2] / l};
      }
      const auto k = ConvexPolyhedron::hull(p, "random hull");
      const double a = sieve_size(k).size;
      const double b = sieve_size(k, {8192, 64, 8, 1e-11, 64, true, {}}).size;
      const double rel = (a - b) / b;
      worst = std::max(worst, rel);
      above += rel > 1e-6;
    }
    std::printf(
        "\nsieve size: default search vs thorough search on %d random hulls (4-33 points "
        "on an ellipsoid 1 : 0.7 : 0.4): worst relative excess %.3g, %d above 1e-6\n",
        hulls, worst, above);
    report.set_info("sieve_hulls", (long long)hulls);
    report.set_info("sieve_worst_relative_excess", worst);
    report.set_info("sieve_above_1e-6", (long long)above);
  }
  report.write_json(json);
  return 0;
}
