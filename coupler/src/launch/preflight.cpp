#include "launch/preflight.hpp"
#include "launch/mesh_seat.hpp"

#include <unistd.h>

#include <cstdio>
#include <string>
#include <utility>

#include "demfem/interface/exit_status.hpp"

namespace fs = std::filesystem;

namespace demfem::coupling::launch {
namespace {

fs::path self_dir() {
  std::error_code ec;
  const auto exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::current_path() : exe.parent_path();
}

void print_seat(const MeshSeat& seat) {
  if (!seat.computed) {
    std::printf("demfem run: fem.mesh.seat: the bed's state is not made yet, so the seat is not "
                "computed by this check (a run computes it)\n");
    return;
  }
  std::printf("demfem run: fem.mesh.seat: the highest of the %lld particles under the mesh "
              "(its footprint widened by %.4g m) reaches z = %.6f m; the mesh moves by %+.6f m "
              "(its bottom from %.6f to %.6f m, %.4g m above the bed)\n",
              static_cast<long long>(seat.particles), seat.margin, seat.bed_top, seat.dz,
              seat.mesh_bottom, seat.mesh_bottom + seat.dz, seat.gap);
}

// The scene with its overrides, the settings, the [[post]] steps and the solver sections.
std::optional<int> read_scene(const LaunchOptions& opt, CheckedRun& run) {
  try {
    std::vector<scene::Override> overrides;
    for (const auto& s : opt.sets) overrides.push_back(scene::Override::parse(s));
    for (const auto& [section, kind] :
         {std::pair{"fem", &opt.fem_backend}, std::pair{"dem", &opt.dem_backend}}) {
      if (kind->empty()) continue;
      if (!scene::Document::load(opt.scene, overrides).root().table(section)) {
        std::fprintf(stderr, "demfem run: --%s-backend %s: %s has no [%s] section\n", section,
                     kind->c_str(), opt.scene.c_str(), section);
        return kExitBadInput;
      }
      overrides.push_back(
          scene::Override::parse(std::string(section) + ".backend=\"" + *kind + "\""));
    }
    run.doc = scene::Document::load(opt.scene, overrides);
    run.settings = read_coupling_settings(*run.doc);
    run.post_steps = read_post_steps(*run.doc, run.bin);
    // A [dem.load] scene = ... whose state is missing or stale: that scene runs first, so
    // that the check of the solver sections (which builds the particles) finds the state.
    // With --check a missing state is not made: the prepare scene is checked instead (and
    // this scene's particles are set up without it).
    if (const int c = run_prepare_scenes(*run.doc, run.bin, opt.quiet, opt.in_process, opt.check))
      return c;
    if (const auto seat = resolve_mesh_seat(*run.doc, run.settings.run.seed)) {
      // Every process reads the seat as fem.mesh.translate (the FEM cannot read the bed).
      const std::string set = seat->override_text();
      overrides.push_back(scene::Override::parse(set));
      run.computed_sets.push_back(set);
      run.doc = scene::Document::load(opt.scene, overrides);
      print_seat(*seat);  // as the prepare steps' lines: also with --quiet
    }
    run.sections = check_solver_sections(*run.doc, run.settings.run.seed);
    // A DEM that continues its loaded state's clock ([dem.load] keep_time, DEM alone): the
    // run's clock starts there too, so that coupling.csv, the progress and the step count
    // agree with the DEM's sensors and snapshots, and run.end_time is where both end.
    if (!run.sections.dem_start_where.empty())
      start_clock_at(run.settings, run.sections.dem_start_time, run.sections.dem_start_where);
  } catch (const scene::SceneError& e) {
    std::fprintf(stderr, "demfem run: scene error: %s\n", e.what());
    return kExitBadInput;
  }
  return std::nullopt;
}

// External backends (fem.command, dem.command): resolved before anything starts.
std::optional<int> resolve_external_programs(const LaunchOptions& opt, CheckedRun& run) {
  for (const auto& [role, ext] : {std::pair{protocol::Role::fem, &run.external_fem},
                                  std::pair{protocol::Role::dem, &run.external_dem}}) {
    const bool dem = role == protocol::Role::dem;
    if (!(dem ? run.settings.dem_external() : run.settings.fem_external())) continue;
    if (opt.in_process) {
      std::fprintf(stderr,
                   "demfem run: --in-process runs demfem's own %s backends only; %s.backend = "
                   "\"external\" starts the program of %s.command in its own process\n",
                   dem ? "DEM" : "FEM", dem ? "dem" : "fem", dem ? "dem" : "fem");
      return kExitBadInput;
    }
    try {
      *ext = resolve_external_command(run.settings, role);
    } catch (const scene::SceneError& e) {
      std::fprintf(stderr, "demfem run: scene error: %s\n", e.what());
      return kExitBadInput;
    }
  }
  if (!run.sections.dem_unapplied_keys.empty()) {
    std::string keys;
    for (const auto& k : run.sections.dem_unapplied_keys) keys += (keys.empty() ? "" : ", ") + k;
    std::fprintf(stderr,
                 "demfem run: note: dem.backend = \"external\": demfem reads only dem.backend, "
                 "command, dt and settle_time; [dem] %s are the external program's to read or "
                 "ignore (dem_server's particles, output and sensors do not run)\n",
                 keys.c_str());
  }
  return std::nullopt;
}

std::optional<int> check_debug_kill(const LaunchOptions& opt, CheckedRun& run) {
  try {
    run.debug_kill = parse_debug_kill(opt.debug_kill);
  } catch (const std::exception&) {
    std::fprintf(stderr,
                 "demfem run: --debug-kill '%s': expected ROLE:STEP[:always|:stop] with ROLE dem, "
                 "fem or coupler, or job:STEP:usr1|usr2, and STEP >= 0\n",
                 opt.debug_kill.c_str());
    return kExitBadInput;
  }
  if (!run.remote && run.debug_kill && run.debug_kill->role != "coupler" &&
      run.debug_kill->role != "job") {
    std::fprintf(stderr,
                 "demfem run: --debug-kill %s needs solver processes (not with --in-process)\n",
                 opt.debug_kill.c_str());
    return kExitBadInput;
  }
  return std::nullopt;
}

// The solver executables, before the output folder is touched: one that cannot be started
// is reported now, not after the other solver has started and set up.
std::optional<int> check_solver_executables(const CheckedRun& run) {
  if (!run.remote) return std::nullopt;
  for (const auto& [needed, name] :
       {std::pair{run.settings.has_fem && !run.external_fem, "fem_server"},
        std::pair{run.settings.has_dem && !run.external_dem, "dem_server"}}) {
    const fs::path exe = run.bin / name;
    std::error_code ec;
    if (needed && (!fs::is_regular_file(exe, ec) || ::access(exe.c_str(), X_OK) != 0)) {
      std::fprintf(stderr,
                   "demfem run: cannot start the solver %s: it is missing or not executable "
                   "(build it, or give the folder that holds it with --bin-dir; --in-process "
                   "needs no solver executables)\n",
                   exe.c_str());
      return kExitBadInput;
    }
  }
  return std::nullopt;
}

}  // namespace

std::optional<int> check_before_start(const LaunchOptions& opt, CheckedRun& run) {
  run.bin = opt.bin_dir.empty() ? self_dir() : fs::path(opt.bin_dir);
  if (const auto code = read_scene(opt, run)) return code;
  if (const auto code = resolve_external_programs(opt, run)) return code;
  if (opt.check) {
    std::printf("demfem run: %s: the scene is valid\n", opt.scene.c_str());
    return 0;
  }
  if (run.settings.fem_modal && opt.resume) {
    std::fprintf(stderr,
                 "demfem run: --resume: fem.analysis = \"modal\" takes no time steps and no "
                 "checkpoints; run it afresh\n");
    return kExitBadInput;
  }
  run.out_dir = opt.output_dir.empty() ? run.settings.run.output_dir : fs::path(opt.output_dir);
  run.remote = !opt.in_process;
  if (const auto code = check_debug_kill(opt, run)) return code;
  if (const auto code = check_solver_executables(run)) return code;
  // --resume without a [checkpoint] section: nothing was ever checkpointed.
  if (opt.resume && opt.resume_from.empty() && !run.settings.checkpoint.enabled) {
    std::fprintf(stderr,
                 "demfem run: --resume: %s has no [checkpoint] section, so its runs take no "
                 "checkpoints to resume from; add one (docs/scenes.md, [checkpoint]) and run "
                 "afresh, or name a checkpoint folder: --resume DIR\n",
                 opt.scene.c_str());
    return kExitBadInput;
  }
  return std::nullopt;
}

}  // namespace demfem::coupling::launch
