// Part "work": work-precision of every scheme and dt_F on problems (a), (a'), (b).
#include "study.hpp"

#include <map>
#include <utility>

namespace demfem::bench::coupling_study {

void work_precision_part(const Options& opt, Report& rep, const Problems& problems) {
  const Problem& beam = problems.beam;
  const Problem& elastic = problems.elastic;
  const Problem& plate = problems.plate;
  // Problem (a) at each dt_D of --beam-dem-dts (the case's with its whole dt_F grid, a finer
  // one from dt_F = dt_D to 20 dt_D), then problem (b).
  std::vector<Problem> grid;
  for (double d : opt.beam_dem_dts) {
    Problem level = beam;
    if (d != beam.dem_dt) {
      level.dem_dt = d;
      level.sets.push_back("dem.dt=" + fmt(d));
      level.dts = {d, 2 * d, 4 * d, 8 * d, 20 * d};
    }
    grid.push_back(level);
  }
  grid.push_back(elastic);
  grid.push_back(plate);
  for (auto& pb : grid) {
    if (opt.dts.empty()) continue;
    std::vector<double> kept;
    for (double dt : pb.dts)
      for (double want : opt.dts)
        if (std::abs(dt - want) <= 1e-9 * want) kept.push_back(dt);
    pb.dts = kept;
  }
  std::map<std::string, RunResult> extrapolated;  // by problem
  for (const Problem* pb = grid.data(); pb != grid.data() + grid.size(); ++pb) {
    if (!opt.problems.count(pb->name)) continue;
    if (!pb->reference_dts.empty() && !extrapolated.count(pb->name))
      extrapolated[pb->name] = extrapolated_reference(opt, rep, *pb);
    const RunResult ref =
        pb->reference_dts.empty() ? reference(opt, rep, *pb, "work", {}) : extrapolated[pb->name];
    // Run folders of a dt_D other than the case's are named by it.
    const std::string tag =
        pb->name +
        (pb->dem_dt != beam.dem_dt && pb->name == beam.name ? "_D" + fmt(pb->dem_dt) : "");
    struct Cell {
      RunResult first;
      std::vector<double> walls, cpus;
    };
    std::map<std::pair<std::size_t, std::size_t>, Cell> cells;
    // Interleaved: every (scheme, dt) once, then again, so that the load of the machine
    // (shared with other jobs) falls on all variants alike.
    auto chosen = [&](std::size_t s) {
      return opt.schemes.empty() || opt.schemes.count(kSchemes[s].label);
    };
    for (int r = 0; r < opt.repeat; ++r) {
      for (std::size_t s = 0; s < kSchemes.size(); ++s) {
        if (!chosen(s)) continue;
        for (std::size_t k = 0; k < pb->dts.size(); ++k) {
          auto& cell = cells[{s, k}];
          const double dt = pb->dts[k];
          const fs::path dir = opt.work / (tag + "_" + kSchemes[s].label + "_" + fmt(dt));
          const fs::path scene = scene_variant(*pb, kSchemes[s], dir, 1.0);
          // First the accuracy run (field output for the probe), then timed runs without
          // field output; an unstable variant is not timed.
          const bool conc = kSchemes[s].scheme == "concurrent";
          if (r == 0) cell.first = run(*pb, scene, dir.string() + "_fields", {}, dt, true, conc);
          if (cell.first.exit == 0) {
            const RunResult timed = run(*pb, scene, dir, {}, dt, false, conc);
            cell.walls.push_back(timed.wall);
            cell.cpus.push_back(timed.cpu);
          }
          fs::remove(scene);
        }
      }
    }
    for (std::size_t s = 0; s < kSchemes.size(); ++s) {
      if (!chosen(s)) continue;
      for (std::size_t k = 0; k < pb->dts.size(); ++k) {
        const auto& cell = cells[{s, k}];
        const Stability st = judge(cell.first, ref);
        add_row(rep, "work", *pb, kSchemes[s].label, pb->dts[k], NAN, cell.walls,
                errors_of(cell.first, ref, *pb), cell.first, st, cell.cpus);
      }
    }
    rep.write_json(opt.json);  // the rows so far: a later part that fails keeps them
  }
}

}  // namespace demfem::bench::coupling_study
