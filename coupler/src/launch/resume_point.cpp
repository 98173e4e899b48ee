#include "launch/resume_point.hpp"

#include <cstdio>
#include <cstdlib>

#include "demfem/coupling/checkpoint.hpp"
#include "demfem/coupling/coupling_run.hpp"
#include "demfem/interface/exit_status.hpp"
#include "demfem/io/h5_file.hpp"
#include "launch/resume_check.hpp"

namespace fs = std::filesystem;

namespace demfem::coupling::launch {
namespace {

// --resume DIR: a folder that exists and holds a committed checkpoint of this run's parts.
std::optional<int> check_named_checkpoint(const fs::path& from,
                                          const std::vector<std::string>& parts) {
  std::error_code ec;
  if (!fs::exists(from, ec)) {
    std::fprintf(stderr,
                 "demfem run: --resume %s: no such folder; give a checkpoint folder "
                 "(<checkpoint directory>/step-NNNNNN), or --resume alone for the latest\n",
                 from.c_str());
    return kExitBadInput;
  }
  if (!fs::is_directory(from, ec)) {
    std::fprintf(stderr,
                 "demfem run: --resume %s: is a file, not a checkpoint folder "
                 "(<checkpoint directory>/step-NNNNNN with manifest.json)\n",
                 from.c_str());
    return kExitBadInput;
  }
  try {
    (void)verify_checkpoint(from, parts);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "demfem run: --resume %s: not a valid checkpoint: %s\n", from.c_str(),
                 e.what());
    return kExitBadInput;
  }
  return std::nullopt;
}

// --resume alone: the latest valid checkpoint of the run's checkpoint folder.
std::optional<int> find_latest_checkpoint(const fs::path& cp_dir, const fs::path& out_dir,
                                          const std::vector<std::string>& parts,
                                          const std::function<void(const std::string&)>& report,
                                          fs::path& found) {
  if (!fs::exists(cp_dir)) {
    std::fprintf(stderr,
                 "demfem run: --resume: the checkpoint folder %s does not exist (no run of "
                 "this scene has written to %s yet?)\n",
                 cp_dir.c_str(), out_dir.c_str());
    return kExitBadInput;
  }
  const auto latest = latest_valid_checkpoint(cp_dir, parts, report);
  if (!latest) {
    std::fprintf(stderr, "demfem run: --resume: no valid checkpoint in %s\n", cp_dir.c_str());
    return kExitBadInput;
  }
  found = *latest;
  return std::nullopt;
}

}  // namespace

std::optional<int> find_resume_point(const LaunchOptions& opt, const CheckedRun& run,
                                     RunFolder& folder,
                                     const std::function<void(const std::string&)>& report,
                                     std::optional<ResumePoint>& point) {
  const auto parts = checkpoint_parts(run.settings);
  ResumePoint p;
  if (!opt.resume_from.empty()) {
    p.checkpoint = opt.resume_from;
    if (const auto code = check_named_checkpoint(p.checkpoint, parts)) return code;
  } else if (const auto code = find_latest_checkpoint(folder.checkpoint_dir(), folder.output_dir(),
                                                      parts, report, p.checkpoint)) {
    return code;
  }
  RunRecord& record = folder.record();
  if (const auto code =
          prepare_resume(p.checkpoint, run.settings, run.sections, folder.output_dir(), record)) {
    return *code;
  }
  try {
    const io::H5File cp(p.checkpoint / "coupler.h5", io::H5File::Mode::read);
    if (run.settings.has_fem) p.fem_interface_nodes = cp.attribute_int64("/", "node_count");
  } catch (const std::exception&) {
    // unreadable coupler.h5: the restore names the file and the reason
  }
  // demfem's own backends: the scene's interface must be the checkpoint's, checked before
  // any process starts (an external code's is checked when it says Hello).
  if (p.fem_interface_nodes && run.sections.fem_interface_nodes > 0 && !run.external_fem &&
      static_cast<std::size_t>(*p.fem_interface_nodes) != run.sections.fem_interface_nodes) {
    std::fprintf(stderr,
                 "demfem run: --resume: checkpoint %s cannot be resumed: the checkpoint's "
                 "interface has %lld nodes, this scene's %zu (the FEM mesh or "
                 "fem.interface_surface changed): its state cannot be continued with this "
                 "scene\n",
                 p.checkpoint.c_str(), static_cast<long long>(*p.fem_interface_nodes),
                 run.sections.fem_interface_nodes);
    return kExitBadInput;
  }
  record.resumed_from = fs::absolute(p.checkpoint).string();
  const std::string name = p.checkpoint.filename().string();
  if (name.rfind("step-", 0) == 0) record.resumed_step = std::atoll(name.c_str() + 5);
  point = std::move(p);
  return std::nullopt;
}

}  // namespace demfem::coupling::launch
