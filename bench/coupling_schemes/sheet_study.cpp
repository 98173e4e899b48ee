// Part "sheet": problem (c), every scheme on the sheet CI case.
#include "study.hpp"

#include <algorithm>
#include <cstdio>
#include <stdexcept>

namespace demfem::bench::coupling_study {

// cases/sheet_ci.toml as it is (its geometry and fill are named by paths relative to it, so
// the scheme goes in by --set, not by a rewritten copy), cut to opt.sheet_end s of flow. The
// quantity of interest is the deflection of the measurement position (probe "lmp" of
// fem_monitor.csv, every FEM step): its mean over the last 0.1 s (the grains reach the
// sheet at about 0.26 s; a granular flow's details are chaotic, its mean load less so) and
// its largest |value|, against implicit IQN-ILS at dt_F = dt_D = 2e-5 s.
void sheet_part(const Options& opt, Report& rep) {
  Problem sheet{
      "sheet_ci",
      kSource / "cases" / "sheet_ci.toml",
      {0.28, 0.05, 0.0},
      2e-5,
      opt.sheet_end,
      1e-4,
      opt.sheet_dts,
      {"run.end_time=" + fmt(opt.sheet_end),
       "fem.monitor.mean_window=[" + fmt(opt.sheet_end - 0.1) + "," + fmt(opt.sheet_end) + "]"},
      {}};
  auto scheme_sets = [](const Scheme& sc) {
    std::vector<std::string> v = {
        "coupling.scheme=\"" + sc.scheme + "\"",
        std::string("coupling.force_averaging=") + (sc.force_averaging ? "true" : "false")};
    if (sc.scheme == "implicit") {
      // The tolerances of problem (b) (plate_bed.toml); before the grains arrive the sheet
      // carries no force.
      for (const std::string& s : {"coupling.acceleration=\"" + sc.acceleration + "\"",
                                   std::string("coupling.displacement_tolerance=1e-3"),
                                   std::string("coupling.force_tolerance=1e-2"),
                                   std::string("coupling.force_abs_tolerance=1e-6"),
                                   std::string("coupling.displacement_abs_tolerance=1e-12"),
                                   std::string("coupling.max_iterations=50")})
        v.push_back(s);
    }
    return v;
  };
  struct SheetResult {
    RunResult run;
    double mean = NAN, peak = 0.0;  // lmp u_z: mean over the last 0.1 s, largest |u_z|
  };
  auto sheet_run = [&](const Scheme& sc, double dt, const std::string& tag) {
    const fs::path dir = opt.work / ("sheet_ci_" + sc.label + "_" + fmt(dt) + tag);
    auto sets = scheme_sets(sc);
    sets.push_back("coupling.diagnostics_interval=1");  // every step's iterations counted
    SheetResult r;
    r.run = run(sheet, sheet.scene, dir, sets, dt, false, sc.scheme == "concurrent");
    const auto rows = read_csv(dir / "fem_monitor.csv");
    if (rows.size() > 1) {
      std::size_t col = 0;
      for (std::size_t k = 0; k < rows[0].size(); ++k)
        if (rows[0][k] == "lmp_uz") col = k;
      double sum = 0.0;
      std::size_t n = 0;
      for (std::size_t i = 1; i < rows.size(); ++i) {
        if (col == 0 || rows[i].size() <= col) continue;
        const double t = std::stod(rows[i][0]), w = std::stod(rows[i][col]);
        r.peak = std::max(r.peak, std::abs(w));
        if (t >= opt.sheet_end - 0.1 - 1e-9) sum += w, ++n;
      }
      if (n > 0) r.mean = sum / static_cast<double>(n);
    }
    return r;
  };
  const SheetResult ref = sheet_run(kSchemes.back(), sheet.dem_dt, "_reference");
  if (ref.run.exit != 0)
    throw std::runtime_error("sheet_ci reference failed: " + ref.run.error_text);
  std::printf(
      "# sheet_ci reference: implicit-iqn, dt_F = %g s, %.3g s of flow, %lld steps, %.3g "
      "iterations per step, wall %.1f s; lmp deflection: mean over the last 0.1 s %.4g m, "
      "largest %.4g m\n",
      sheet.dem_dt, opt.sheet_end, static_cast<long long>(ref.run.steps),
      static_cast<double>(ref.run.iterations) / static_cast<double>(ref.run.steps), ref.run.wall,
      ref.mean, ref.peak);
  std::fflush(stdout);
  add_row(rep, "reference", sheet, "implicit-iqn (sheet)", sheet.dem_dt, NAN, {ref.run.wall},
          {0.0, 0.0}, ref.run, {true, ""});
  for (double dt : sheet.dts) {  // interleaved over the schemes
    for (const Scheme& sc : kSchemes) {
      if (!opt.sheet_schemes.empty() && !opt.sheet_schemes.count(sc.label)) continue;
      const SheetResult r = sheet_run(sc, dt, "");
      const Stability st = judge(r.run, ref.run);
      Errors e;
      if (r.run.exit == 0 && std::isfinite(r.mean) && ref.mean != 0.0)
        e = {std::abs(r.mean - ref.mean) / std::abs(ref.mean),
             std::abs(r.peak - ref.peak) / ref.peak};
      add_row(rep, "sheet", sheet, sc.label, dt, NAN, {r.run.wall}, e, r.run, st);
      rep.write_json(opt.json);  // the rows so far: a long study cut short keeps them
      std::printf(
          "# sheet_ci %-18s dt_F %-7g exit %d %s wall %.1f s, mean-deflection error "
          "%.3g, peak error %.3g, iterations/step %.3g\n",
          sc.label.c_str(), dt, r.run.exit, st.stable ? "stable" : st.why.c_str(), r.run.wall,
          e.series, e.peak,
          r.run.steps ? static_cast<double>(r.run.iterations) / static_cast<double>(r.run.steps)
                      : NAN);
      std::fflush(stdout);
    }
  }
}

}  // namespace demfem::bench::coupling_study
