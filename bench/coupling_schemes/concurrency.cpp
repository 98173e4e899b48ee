// Part "concurrency": the concurrent scheme's step time against the sequential one's.
#include "study.hpp"

#include <algorithm>
#include <cstdio>
#include <map>
#include <utility>

namespace demfem::bench::coupling_study {

void concurrency_part(const Options& opt, Report& rep, const Problems& problems) {
  const Problem& beam = problems.beam;
  Problem balanced = beam;
  balanced.name = "beam_drop_balanced";
  // 60 x 6 x 6 hex8 (2160 elements): a FEM step of about the DEM's 300 substeps of 160
  // spheres at dt_F = 3e-4 s, about 10 ms each here (the table shows both, measured).
  balanced.sets.push_back("fem.mesh.box.cells=[60,6,6]");
  const double dt = 3e-4;
  // The reference of this finer mesh at dt_F = 1e-5 s: the errors compared here
  // (3e-4 s) are of order 0.1, the reference's at 1e-5 s below 1e-2 (the work-precision
  // part).
  balanced.dem_dt = 1e-5;
  balanced.reference_dts.clear();
  const RunResult ref = reference(opt, rep, balanced, "balanced", {}, false);
  // Each scheme as demfem_run starts the solvers by default (in its own session) and with
  // --solver-sessions (each in a session of its own: a CPU share each under autogroup).
  struct Variant {
    std::string label;
    const Scheme* scheme;
    bool sessions;
  };
  const std::vector<Variant> variants = {{"sequential", &kSchemes[0], false},
                                         {"concurrent", &kSchemes[4], false},
                                         {"sequential, solver sessions", &kSchemes[0], true},
                                         {"concurrent, solver sessions", &kSchemes[4], true}};
  // The first run of each has field output (for the error); the timed ones after it not.
  std::map<std::string, std::vector<RunResult>> runs;
  std::map<std::string, RunResult> accuracy;
  const int repeats = std::max(opt.repeat, 7);
  for (int r = -1; r < repeats; ++r) {  // interleaved
    for (const auto& v : variants) {
      if (r < 0 && v.sessions) continue;  // the same numbers as without
      const fs::path dir = opt.work / ("balanced_" + std::to_string(&v - &variants[0]) + "_" +
                                       std::to_string(r + 1));
      const fs::path scene = scene_variant(balanced, *v.scheme, dir, 1.0);
      RunResult res =
          run(balanced, scene, dir, {}, dt, r < 0, v.scheme->scheme == "concurrent", v.sessions);
      fs::remove(scene);
      if (r < 0) {
        accuracy[v.label] = std::move(res);
      } else {
        runs[v.label].push_back(std::move(res));
      }
    }
  }
  // Per run: the median over its steps of the step's wall time and of each solver's own
  // compute time (StepDone); over the runs: their median and their best.
  auto stat = [&](const std::string& label, double RunResult::*field) {
    std::vector<double> v;
    for (const auto& x : runs[label])
      if (x.exit == 0) v.push_back(x.*field);
    return std::make_pair(median(v), v.empty() ? NAN : *std::min_element(v.begin(), v.end()));
  };
  for (const std::string suffix : {"", ", solver sessions"}) {
    const auto seq_step = stat("sequential" + suffix, &RunResult::step_wall);
    const auto seq_dem = stat("sequential" + suffix, &RunResult::dem_compute);
    const auto seq_fem = stat("sequential" + suffix, &RunResult::fem_compute);
    const auto con_step = stat("concurrent" + suffix, &RunResult::step_wall);
    const auto con_ratio = stat("concurrent" + suffix, &RunResult::step_ratio);
    const double max_med = std::max(seq_dem.first, seq_fem.first);
    const double max_best = std::max(seq_dem.second, seq_fem.second);
    std::printf(
        "# concurrency%s (beam_drop, FEM 60 x 6 x 6 hex8, dt_F = %g s, %d runs of each, "
        "interleaved): per step, median (best) over the runs of their medians:\n"
        "#   sequential (just-in-time): step %.3g ms (%.3g), DEM %.3g ms (%.3g), FEM "
        "%.3g ms (%.3g)\n"
        "#   concurrent: step %.3g ms (%.3g) = %.3f (%.3f) x max(DEM, FEM) of the sequential "
        "runs, %.3f (%.3f) x their step; in the same run, step / max(DEM, FEM): %.3f "
        "(%.3f)\n",
        suffix.c_str(), dt, repeats, 1e3 * seq_step.first, 1e3 * seq_step.second,
        1e3 * seq_dem.first, 1e3 * seq_dem.second, 1e3 * seq_fem.first, 1e3 * seq_fem.second,
        1e3 * con_step.first, 1e3 * con_step.second, con_step.first / max_med,
        con_step.second / max_best, con_step.first / seq_step.first,
        con_step.second / seq_step.second, con_ratio.first, con_ratio.second);
    const std::string key = suffix.empty() ? "" : "_sessions";
    rep.set_info("concurrency" + key + "_step_over_max_median", con_step.first / max_med);
    rep.set_info("concurrency" + key + "_step_over_max_best", con_step.second / max_best);
    rep.set_info("concurrency" + key + "_step_over_sequential_median",
                 con_step.first / seq_step.first);
    rep.set_info("concurrency" + key + "_same_run_ratio_median", con_ratio.first);
  }
  for (const auto& v : variants) {
    const auto& rs = runs[v.label];
    std::vector<double> walls;
    for (const auto& x : rs) walls.push_back(x.wall);
    const RunResult& acc = accuracy[v.scheme->scheme == "concurrent" ? "concurrent" : "sequential"];
    RunResult shown = rs.front();  // the timed run's compute times, the accuracy run's rest
    shown.max_energy_error = acc.max_energy_error;
    shown.max_displacement = acc.max_displacement;
    add_row(rep, "concurrency", balanced, v.label, dt, NAN, walls, errors_of(acc, ref, balanced),
            shown, judge(acc, ref));
  }
}

}  // namespace demfem::bench::coupling_study
