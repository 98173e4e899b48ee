#include "launch/modal_analysis.hpp"

#include <cstdio>
#include <iostream>
#include <stdexcept>

#include "demfem/fem/fem_backend.hpp"
#include "demfem/fem/fem_scene.hpp"
#include "demfem/fem/modal_run.hpp"
#include "demfem/interface/exit_status.hpp"

namespace demfem::coupling::launch {

int run_modal_analysis(const LaunchOptions& opt, const CheckedRun& run, RunFolder& folder) {
  RunRecord& record = folder.record();
  int code = 0;
  try {
    const fem::FemScene fs = fem::read_fem_scene(*run.doc->root().table("fem"));
    for (const auto& note : fs.notes) std::fprintf(stderr, "fem: note: %s\n", note.c_str());
    (void)fem::run_modal_analysis(fs, run.out_dir, opt.quiet ? nullptr : &std::cout);
    record.status = "completed";
  } catch (const std::exception& e) {
    std::fprintf(stderr, "demfem run: modal analysis: %s\n", e.what());
    code = dynamic_cast<const fem::FemModelError*>(&e) ||
                   dynamic_cast<const std::invalid_argument*>(&e)
               ? kExitBadInput
               : kExitFailed;
    record.status = "failed";
    record.reason = e.what();
  }
  record.exit_code = code;
  record.end_time = utc_now();
  record.steps_done = 0;
  record.time_reached = 0.0;
  write_run_record(run.out_dir, record);
  return code;
}

}  // namespace demfem::coupling::launch
