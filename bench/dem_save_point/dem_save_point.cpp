// The DEM's in-memory save point of implicit coupling (DemSystem::save_state / restore_state,
// docs/dem.md): its cost against a DEM step, from 10^3 to 10^5 spheres (--max N). A bed of
// spheres (radius 2.24-2.26 mm, friction and rolling resistance, so that the pair and wall
// springs are state) on a cubic lattice of 4.52 mm in a box, touching or nearly, advanced
// 400 steps under gravity so that it is in contact (about 3 contacts per sphere); then,
// measured --repeat times (default 9; median and best):
//   save       save_state() into a copy object kept from the previous save (no allocation)
//   restore    restore_state() from it
//   step       one advance(1) of the system as it runs (the neighbour list reused)
//   step after restore   the first advance(1) after a restore: it rebuilds the neighbour list
// and the bytes a copy holds per particle. An implicit coupling step of k iterations costs one
// save, k - 1 restores and k - 1 rebuilds on top of its k x n_D steps.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "bench_report.hpp"
#include "demfem/dem/dem_system.hpp"

using namespace demfem::dem;
using Clock = std::chrono::steady_clock;

namespace {

WallMesh quad(std::array<double, 3> a, std::array<double, 3> b, std::array<double, 3> c,
              std::array<double, 3> d) {
  WallMesh w;
  w.material = 1;
  for (const auto& p : {a, b, c, d}) w.vertices.insert(w.vertices.end(), p.begin(), p.end());
  w.triangles = {0, 1, 2, 0, 2, 3};
  return w;
}

DemSystem make_bed(std::size_t n, int threads) {
  DemSettings s;
  s.dt = 1e-5;
  s.gravity = {0, 0, -9.81};
  s.materials = {{"grain", 1e8, 0.3, 2500.0}, {"wall", 1e8, 0.3, 0.0}};
  s.pairs.assign(4, MaterialPair{0.5, 0.4, 0.1});
  s.threads = threads;
  DemSystem sys(s);
  const double a = 0.00452;  // lattice spacing: the spheres (4.48-4.52 mm) touch or nearly
  const auto side = static_cast<std::size_t>(std::ceil(std::cbrt(static_cast<double>(n) / 2)));
  const double lx = a * static_cast<double>(side), h = 2 * lx + 0.01;
  sys.add_wall(quad({0, 0, 0}, {lx, 0, 0}, {lx, lx, 0}, {0, lx, 0}));
  sys.add_wall(quad({0, 0, 0}, {0, lx, 0}, {0, lx, h}, {0, 0, h}));
  sys.add_wall(quad({lx, 0, 0}, {lx, 0, h}, {lx, lx, h}, {lx, lx, 0}));
  sys.add_wall(quad({0, 0, 0}, {0, 0, h}, {lx, 0, h}, {lx, 0, 0}));
  sys.add_wall(quad({0, lx, 0}, {lx, lx, 0}, {lx, lx, h}, {0, lx, h}));
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<ParticleInit> p;
  for (std::size_t k = 0; p.size() < n; ++k)
    for (std::size_t j = 0; j < side && p.size() < n; ++j)
      for (std::size_t i = 0; i < side && p.size() < n; ++i) {
        ParticleInit q;
        q.position = {a * (static_cast<double>(i) + 0.5), a * (static_cast<double>(j) + 0.5),
                      a * (static_cast<double>(k) + 0.5)};
        q.velocity = {0.01 * u(rng), 0.01 * u(rng), 0.0};
        q.radius = 0.00225 + 0.00001 * u(rng);
        p.push_back(q);
      }
  sys.add_particles(p);
  return sys;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) try {
  std::size_t max_n = 100000;
  int repeat = 9, threads = 1;
  std::string json;
  CLI::App app{"Cost of the DEM's in-memory save point (save_state, restore_state) against a "
               "DEM step, beds of 10^3 spheres up to --max"};
  app.add_option("--max", max_n, "largest bed, spheres (10^3, 10^4, ... up to it)")
      ->check(CLI::Range(std::size_t{1000}, std::size_t{100000000}));
  app.add_option("--repeat", repeat, "measurements of each (median and best)")
      ->check(CLI::Range(1, 100000));
  app.add_option("--threads", threads, "CPU threads")->check(CLI::Range(1, 4096));
  app.add_option("--json", json, "write the results as JSON");
  CLI11_PARSE(app, argc, argv);
  demfem::bench::Report rep(
      "dem_save_point",
      {"particles", "pairs", "copy_bytes_per_particle", "save_ms_median", "save_ms_best",
       "restore_ms_median", "restore_ms_best", "step_ms_median", "step_ms_best",
       "step_after_restore_ms_median", "step_after_restore_ms_best"});
  rep.set_info("threads", static_cast<long long>(threads));
  rep.set_info("repeat", static_cast<long long>(repeat));
  for (std::size_t n = 1000; n <= max_n; n *= 10) {
    DemSystem sys = make_bed(n, threads);
    sys.advance(400);
    DemStateCopy copy;
    sys.save_state(copy);  // sizes the copy's arrays once
    std::size_t bytes =
        copy.row.size() * 8 + copy.wkey.size() * 8 + copy.nbr.size() * 4 + copy.wcount.size();
    for (const auto& a : copy.arrays) bytes += a.size() * sizeof(double);
    std::vector<double> save, restore, step, step_after;
    auto ms = [](Clock::time_point a) {
      return std::chrono::duration<double, std::milli>(Clock::now() - a).count();
    };
    for (int r = 0; r < repeat; ++r) {
      auto t = Clock::now();
      sys.save_state(copy);
      save.push_back(ms(t));
      t = Clock::now();
      sys.advance(1);
      step.push_back(ms(t));
      t = Clock::now();
      sys.restore_state(copy);
      restore.push_back(ms(t));
      t = Clock::now();
      sys.advance(1);
      step_after.push_back(ms(t));
    }
    rep.add_row({static_cast<long long>(sys.particle_count()),
                 static_cast<long long>(sys.neighbour_pairs()),
                 static_cast<double>(bytes) / static_cast<double>(sys.particle_count()),
                 median(save), *std::min_element(save.begin(), save.end()), median(restore),
                 *std::min_element(restore.begin(), restore.end()), median(step),
                 *std::min_element(step.begin(), step.end()), median(step_after),
                 *std::min_element(step_after.begin(), step_after.end())});
  }
  rep.print();
  rep.write_json(json);
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "dem_save_point: %s\n", e.what());
  return 1;
}
