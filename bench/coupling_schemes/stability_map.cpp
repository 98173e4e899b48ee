// Part "stability": the largest stable dt_F of each scheme against the plate's density.
#include "study.hpp"

#include <algorithm>
#include <cstdio>

namespace demfem::bench::coupling_study {

void stability_part(const Options& opt, Report& rep, const Problems& problems) {
  const Problem& plate = problems.plate;
  const std::vector<double> factors =
      opt.quick ? std::vector<double>{1, 10} : std::vector<double>{1, 3, 10, 30, 100};
  for (double f : factors) {
    const double density = 2700.0 * f;
    const std::vector<std::string> sets = {"fem.materials[0].density=" + fmt(density)};
    RunResult ref;
    try {
      ref = reference(opt, rep, plate, "rho" + fmt(density), sets, false);
    } catch (const std::exception& e) {
      // Recorded, not fatal: the other densities are still measured.
      std::printf("# stability at plate density %g: %s; density skipped\n", density, e.what());
      rep.set_info("stability_failed_reference_" + fmt(density), std::string(e.what()));
      continue;
    }
    for (const Scheme& sc : kSchemes) {
      // From the largest dt_F down to the first stable one: the largest stable dt_F (smaller
      // ones are not run; the work-precision part has them at the case's density).
      std::vector<double> dts = plate.dts;
      std::reverse(dts.begin(), dts.end());
      for (double dt : dts) {
        const fs::path dir =
            opt.work / (plate.name + "_stab_" + fmt(density) + "_" + sc.label + "_" + fmt(dt));
        const fs::path scene = scene_variant(plate, sc, dir, 1.0);
        const RunResult res = run(plate, scene, dir, sets, dt, false, sc.scheme == "concurrent");
        fs::remove(scene);
        const Stability st = judge(res, ref);
        add_row(rep, "stability", plate, sc.label, dt, density, {res.wall},
                errors_of(res, ref, plate), res, st);
        if (st.stable) break;
      }
    }
    rep.write_json(opt.json);  // the rows so far
  }
}

}  // namespace demfem::bench::coupling_study
