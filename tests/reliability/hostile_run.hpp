#pragma once
// What the hostile-run tests share (test_hostile_runs.cpp, test_hostile_runs_qa.cpp): real
// demfem_run processes of the CI case or a variant of it, started in a folder of their own, and
// checks that nothing of them is left. Test double: lives in tests/ only.

#include <catch2/catch.hpp>

#include <chrono>
#include <filesystem>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "demfem_test/launch.hpp"
#include "demfem_test/run_output.hpp"
#include "demfem_test/scene_variant.hpp"
#include "demfem_test/temp_dir.hpp"

namespace fs = std::filesystem;
using namespace std::chrono_literals;

namespace hostile {

using demfem::test::Ended;
using demfem::test::eventually;
using demfem::test::gone;
using demfem::test::Launched;
using demfem::test::read_text;
using demfem::test::segments_of;
using demfem::test::started_pids;
using demfem::test::TempDir;

inline const fs::path kBin = fs::path(DEMFEM_BINARY_DIR) / "bin";
inline const fs::path kCase = fs::path(DEMFEM_SOURCE_DIR) / "cases" / "beam_checkpoint_ci.toml";
inline constexpr const char* kOut = "out/beam_checkpoint_ci";

// The CI case with some `key = value` texts replaced (each must occur).
inline fs::path variant(const fs::path& dir, const std::string& name,
                        const std::vector<std::pair<std::string, std::string>>& subs) {
  return demfem::test::write_variant(kCase, dir / name, subs);
}

// One coupling step of 10^6 DEM substeps (dem.dt = 1e-10 s): tens of seconds here, so that a
// signal or a killed coupler arrives in the middle of a step.
inline fs::path long_step_scene(const fs::path& dir) {
  return variant(dir, "long_step.toml",
                 {{"dt = 2e-6                  # s; Rayleigh", "dt = 1e-10                 # s"}});
}

inline Launched start(const fs::path& dir, const std::vector<std::string>& args,
                      bool group = false) {
  std::vector<std::string> argv = {(kBin / "demfem_run").string(), "--bin-dir", kBin.string(),
                                   "--quiet"};
  argv.insert(argv.end(), args.begin(), args.end());
  return demfem::test::launch(dir, argv, group);
}

inline Ended run(const fs::path& dir, const std::vector<std::string>& args) {
  return demfem::test::wait_for(start(dir, args));
}

inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Waits until the run is inside coupling step 0: its step-0 checkpoint is committed right
// before the step is sent.
inline void wait_inside_first_step(const fs::path& out) {
  REQUIRE(
      eventually([&] { return fs::exists(out / "checkpoints/step-000000/manifest.json"); }, 30s));
  std::this_thread::sleep_for(300ms);
}

// Every solver process of the run has ended within `limit`, and its segments are gone.
inline void check_nothing_left(const std::string& out, std::chrono::milliseconds limit = 5s) {
  for (pid_t p : started_pids(out)) {
    INFO("solver pid " << p);
    CHECK(eventually([&] { return gone(p); }, limit));
  }
  for (const auto& seg : segments_of(out)) {
    INFO("segment " << seg);
    CHECK(eventually([&] { return !fs::exists("/dev/shm/" + seg); }, limit));
    CHECK_FALSE(fs::exists("/dev/shm/" + seg + "-bulk"));
  }
}

// `"key": value` of run.json, as text (strings without their quotes).
inline std::string record_field(const fs::path& out, const std::string& key) {
  const std::string text = read_text(out / "run.json");
  std::smatch m;
  if (std::regex_search(text, m, std::regex("\"" + key + "\": (\"([^\"]*)\"|([^,\\n]*))"))) {
    return m[2].matched ? m[2].str() : m[3].str();
  }
  return "<absent>";
}

}  // namespace hostile
