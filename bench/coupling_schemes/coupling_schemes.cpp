// bench/coupling_schemes: the evidence for choosing a coupling scheme (issue 13,
// docs/coupling.md "Choosing a scheme"). Real three-process runs (demfem_run with dem_server
// and fem_server) of the reference problems, for every scheme and coupling step dt_F:
//
//  * work-precision: wall time (the coupler's, timing.csv) and CPU time (of the run's processes)
//    against the error of a quantity of interest (problem a: the mid-span deflection of the
//    beam under the dropped slab; problem b: the centre deflection of the plate under the bed)
//    relative to a converged reference,
//    the same problem with implicit coupling at dt_F = dt_D (problem b: shown converged by the
//    run at 2 dt_D; problem a: at three dt_F = dt_D below the case's, halving, combined by
//    Richardson extrapolation, with the observed order and the extrapolation's own error
//    printed); plus the interface energy error, the iterations, stable or not;
//  * stability map (problem b): the largest stable dt_F of each scheme against the plate's
//    density (the structure-to-particle mass ratio);
//  * concurrency: the concurrent scheme's wall time per step against max(DEM, FEM) and the
//    sequential sum, on problem a with a finer FEM mesh so that both cost about the same;
//  * problem (c), the sheet CI case (cases/sheet_ci.toml, shortened by --sheet-end): every
//    scheme at the dt_F of --sheet-dts, the error of the mean deflection at the measurement
//    position against implicit IQN-ILS at dt_F = dt_D.
//
// Unstable (a measurable criterion): the run stops with a blow-up (exit status 3: a
// non-finite state, an overlap beyond the case's bound, a DEM step past half a radius of
// overlap), or the largest displacement of any interface node over the run exceeds twice the
// reference's (spurious energy makes the response grow), or the interface energy error
// |W_DEM - W_FEM| exceeds the largest interface work of the reference (the scheme creates
// more energy than the physics moves).
//
// Output: a table on stdout, JSON (--json FILE, one row per run) and, with --plots, the PNG
// figures drawn by tools/plot_coupling_schemes.py. Options: --parts LIST (work,stability,
// concurrency,sheet; default all), --repeat N (timed repetitions of each work-precision run,
// interleaved; default 3), --quick (fewer dt_F and densities), --work DIR (run folders),
// --schemes LIST and --dts LIST (of the work-precision part: scheme labels, dt_F; default all),
// --beam-dem-dts LIST (dt_D of problem a's grid, default 1e-6), --sheet-end S (s of flow
// of problem c, default 0.6), --sheet-dts LIST, --sheet-schemes LIST.
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
//
// Files: study.hpp (what the parts share), scene_variant.cpp (a run's scene), case_run.cpp (one
// run and what is read from it), judging.cpp (errors, stability, report rows), references.cpp,
// options.cpp, and one file per part: work_precision.cpp, stability_map.cpp, concurrency.cpp,
// sheet_study.cpp.
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "study.hpp"

namespace demfem::bench::coupling_study {

Problems study_problems(bool quick) {
  // Problem (a): the beam under the dropped slab; mid-span deflection every 1 ms.
  Problem beam{
      "beam_drop",
      kSource / "cases" / "beam_drop.toml",
      {0.5, 0.05, 0.0},
      1e-6,
      0.01,
      1e-4,
      quick ? std::vector<double>{1e-5, 1e-4, 1e-3}
            : std::vector<double>{1e-6, 2e-6, 5e-6, 1e-5, 2e-5, 5e-5, 1e-4, 2e-4, 5e-4, 1e-3},
      {},
      // dt_F = dt_D = 5e-7, 2.5e-7, 1.25e-7 s (docs/coupling.md, "Work-precision": the
      // deflection converges at order 1 to 2 in dt, the extrapolation to about 2e-5).
      {5e-7, 2.5e-7, 1.25e-7}};
  // Problem (a'): the same with elastic contacts (restitution 1, no dashpot). The dashpot of
  // the damped contacts makes the deflection converge irregularly, at orders 0.4 to 1.2 in
  // dt_F and dt_D (its force grows as overlap^(1/4) from the contact's start and takes the
  // mesh velocity of the step's mean), so no extrapolation pins it below about 3e-5; the
  // elastic slab converges at order 2 (docs/coupling.md, "Work-precision"), which resolves
  // the 1e-4 target. Its DEM error at dt_D = 1e-6 s is about 1e-5.
  Problem elastic = beam;
  elastic.name = "beam_drop_elastic";
  elastic.sets = {"dem.pairs[0].restitution=1.0", "dem.pairs[1].restitution=1.0"};
  elastic.reference_dts = {1e-6, 5e-7, 2.5e-7};
  // Problem (b): the plate under the bed; centre deflection every 1 ms.
  Problem plate{"plate_bed",
                kSource / "cases" / "plate_bed.toml",
                {0.1, 0.1, 0.0},
                5e-6,
                0.03,
                1e-4,
                quick ? std::vector<double>{1e-5, 1e-4, 1e-3}
                      : std::vector<double>{5e-6, 1e-5, 2e-5, 5e-5, 1e-4, 2e-4, 5e-4, 1e-3},
                {},
                {}};

  return {beam, elastic, plate};
}

}  // namespace demfem::bench::coupling_study

int main(int argc, char** argv) try {
  using namespace demfem::bench::coupling_study;
  const Options opt = parse(argc, argv);
  if (opt.help) {
    std::fputs(kUsage, stdout);
    return 0;
  }
  Report rep("coupling_schemes", kColumns);
  rep.set_info("repeat", static_cast<long long>(opt.repeat));
  rep.set_info("quick", static_cast<long long>(opt.quick ? 1 : 0));
  rep.set_info("criterion",
               std::string("unstable: exit 3 (blow-up), or max interface displacement > 2 x "
                           "reference, or max |W_DEM - W_FEM| > max |W_FEM| of the reference"));
  fs::create_directories(opt.work);
  const Problems problems = study_problems(opt.quick);
  if (opt.parts.count("work")) work_precision_part(opt, rep, problems);
  if (opt.parts.count("stability")) stability_part(opt, rep, problems);
  if (opt.parts.count("concurrency")) concurrency_part(opt, rep, problems);
  if (opt.parts.count("sheet")) sheet_part(opt, rep);
  rep.print();
  rep.write_json(opt.json);
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "coupling_schemes: %s\n", e.what());
  return 1;
}
