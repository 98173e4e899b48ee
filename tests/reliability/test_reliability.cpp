// Reliability tests with real processes (docs/reliability.md): a run killed at a random
// coupling step (SIGKILL of dem_server, of fem_server, or of the coupler, through the
// launcher's testing option --debug-kill ROLE:STEP) recovers or is resumed and ends with
// results equal to the uninterrupted run: every CSV series equal cell for cell (wall-time
// columns excepted, they measure this machine), every dataset of every HDF5 output file equal
// bit for bit (the files themselves differ in HDF5's object time stamps even between two
// uninterrupted runs), and no process or /dev/shm segment left behind. Corrupt checkpoints
// (truncated part, missing part, bad checksum, no manifest) are skipped with a message naming
// the file, and the previous checkpoint is used.
#include <catch2/catch.hpp>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "demfem/io/h5_file.hpp"
#include "demfem_test/demfem_run.hpp"
#include "demfem_test/launch.hpp"
#include "demfem_test/run_output.hpp"
#include "demfem_test/scene_variant.hpp"
#include "demfem_test/temp_dir.hpp"

namespace fs = std::filesystem;

namespace {

using demfem::test::read_csv;
using demfem::test::read_text;
using demfem::test::segments_of;
using demfem::test::started_pids;
using demfem::test::TempDir;

using demfem::test::kBin;
const fs::path kScene = fs::path(DEMFEM_SOURCE_DIR) / "cases" / "beam_checkpoint_ci.toml";
constexpr const char* kOut = "out/beam_checkpoint_ci";
constexpr int kSteps = 50;  // coupling steps of the case

using Result = demfem::test::Ended;

// demfem_run in `dir` (relative output paths land there), stdout/stderr to files there.
Result run(const fs::path& dir, std::vector<std::string> args, const fs::path& scene = kScene) {
  args.insert(args.begin(), {scene.string(), "--quiet"});
  return demfem::test::run_demfem(dir, args);
}

// Every solver process of these outputs has ended (a solver whose coupler died leaves within
// its peer timeout; a dead coupler's pid within 0.1 s) and none of the runs' segments is left in /dev/shm.
void check_nothing_left(const std::vector<std::string>& outs) {
  for (const auto& out : outs) {
    for (pid_t p : started_pids(out)) {
      const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(10);
      while (::kill(p, 0) == 0 && std::chrono::steady_clock::now() < end) {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
      INFO("solver pid " << p);
      CHECK((::kill(p, 0) != 0 && errno == ESRCH));
    }
    for (const auto& seg : segments_of(out)) {
      INFO("segment " << seg);
      CHECK_FALSE(fs::exists("/dev/shm/" + seg));
      CHECK_FALSE(fs::exists("/dev/shm/" + seg + "-bulk"));
    }
  }
}

// "file.h5:/path" references of an XDMF file with their number type.
std::vector<std::pair<std::string, bool>> xdmf_datasets(const fs::path& xdmf) {
  std::vector<std::pair<std::string, bool>> refs;
  const std::string text = read_text(xdmf);
  std::regex re("NumberType=\"(Float|Int)\"[^>]*Format=\"HDF\">([^<]+)<");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator();
       ++it)
    refs.emplace_back((*it)[2], (*it)[1] == "Float");
  return refs;
}

// The output folder of run `b` equals that of run `a` (see the file comment).
void check_same_results(const fs::path& a, const fs::path& b, std::int64_t steps = kSteps) {
  auto listing = [](const fs::path& d) {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(d)) {
      const std::string n = e.path().filename().string();
      if (n != "checkpoints" && n != "timing.csv") names.insert(n);
    }
    return names;
  };
  REQUIRE(listing(a) == listing(b));
  for (const auto& name : listing(a)) {
    const fs::path fa = a / name, fb = b / name;
    INFO(fb.string());
    if (fa.extension() == ".csv") {
      REQUIRE(demfem::test::first_difference_but_wall_times(read_csv(fa), read_csv(fb)) == "");
    } else if (fa.extension() == ".xdmf") {
      REQUIRE(read_text(fa) == read_text(fb));
      for (const auto& [ref, is_float] : xdmf_datasets(fa)) {
        const auto colon = ref.find(':');
        const std::string file = ref.substr(0, colon), set = ref.substr(colon + 1);
        INFO(ref);
        demfem::io::H5File ha(a / file, demfem::io::H5File::Mode::read);
        demfem::io::H5File hb(b / file, demfem::io::H5File::Mode::read);
        if (is_float) {
          REQUIRE(ha.read_doubles(set) == hb.read_doubles(set));
        } else {
          REQUIRE(ha.read_int64(set) == hb.read_int64(set));
        }
      }
    }
  }
  demfem::io::H5File ha(a / "coupling.h5", demfem::io::H5File::Mode::read);
  demfem::io::H5File hb(b / "coupling.h5", demfem::io::H5File::Mode::read);
  REQUIRE(hb.attribute_int64("/", "steps") == steps);
  REQUIRE(ha.attribute_double("/", "time") == hb.attribute_double("/", "time"));
  for (const char* set : {"interface/positions", "interface/forces", "interface/dem_positions"}) {
    INFO(set);
    REQUIRE(ha.read_doubles(set) == hb.read_doubles(set));
  }
}

// The uninterrupted run, once per test process.
const fs::path& reference() {
  static TempDir dir;
  static bool done = false;
  if (!done) {
    const Result r = run(dir.path, {});
    INFO(r.out << r.err);
    REQUIRE(r.status == 0);
    // Not a comparison of two empty runs: the beam moved and the spheres loaded it.
    const auto rows = read_csv(dir.path / kOut / "coupling.csv");
    REQUIRE(rows.size() == kSteps + 1);
    REQUIRE(std::stod(rows.back()[9]) > 1e-7);   // fem_max_displacement, m
    REQUIRE(std::stod(rows.back()[10]) < -400);  // force_sum_z, N
    done = true;
  }
  static const fs::path out = dir.path / kOut;
  return out;
}

// Steps 1..49 drawn per seed (step 0 would kill before the first checkpoint's successor).
std::int64_t kill_step(int seed, int salt) {
  std::mt19937 gen(static_cast<unsigned>(seed * 1000 + salt));
  return std::uniform_int_distribution<int>(1, kSteps - 1)(gen);
}

}  // namespace

TEST_CASE("checkpoints: committed every 10 steps and at the end with a manifest, the last 2 kept") {
  const fs::path cp = reference() / "checkpoints";
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(cp)) names.insert(e.path().filename().string());
  // Step 50 is the end of the run: a finished run can be continued from it.
  CHECK(names == std::set<std::string>{"step-000040", "step-000050"});
  const std::string manifest = read_text(cp / "step-000040" / "manifest.json");
  for (const char* part : {"dem.h5", "fem.h5", "coupler.h5"}) {
    INFO(part);
    CHECK(manifest.find(std::string("\"name\": \"") + part + "\"") != std::string::npos);
    CHECK(fs::file_size(cp / "step-000040" / part) > 0);
  }
  CHECK(manifest.find("\"step\": 40,") != std::string::npos);
}

TEST_CASE("a run with checkpoints equals the same run without them") {
  TempDir d;
  // The same scene with the [checkpoint] section renamed away (an unknown key would be refused,
  // so the section's keys go with it).
  std::string text = read_text(kScene);
  const auto at = text.find("[checkpoint]");
  const auto end = text.find("[coupling]");
  REQUIRE((at != std::string::npos && end != std::string::npos));
  text.erase(at, end - at);
  const fs::path scene = d.path / "plain.toml";
  std::ofstream(scene) << text;
  std::vector<std::string> argv_s = {(kBin / "demfem_run").string(),
                                     "--bin-dir",
                                     kBin.string(),
                                     scene.string(),
                                     "--quiet",
                                     "--output-dir",
                                     (d.path / kOut).string()};
  std::string cmd;
  for (auto& a : argv_s) cmd += "'" + a + "' ";
  REQUIRE(std::system((cmd + "> " + (d.path / "log.txt").string() + " 2>&1").c_str()) == 0);
  CHECK_FALSE(fs::exists(d.path / kOut / "checkpoints"));
  check_same_results(reference(), d.path / kOut);
}

TEST_CASE("SIGKILL of dem_server at a random step: restarted, rolled back, same results") {
  for (int seed = 1; seed <= 5; ++seed) {
    const std::int64_t step = kill_step(seed, 1);
    INFO("seed " << seed << ": kill at step " << step);
    TempDir d;
    const Result r = run(d.path, {"--debug-kill", "dem:" + std::to_string(step)});
    INFO(r.out << r.err);
    REQUIRE(r.status == 0);
    CHECK(r.err.find("SIGKILL to the DEM solver in step " + std::to_string(step)) !=
          std::string::npos);
    CHECK(r.err.find("recovered: every process is back at step " +
                     std::to_string(step / 10 * 10)) != std::string::npos);
    CHECK(started_pids(r.out).size() == 3);  // fem, dem, dem again
    check_same_results(reference(), d.path / kOut);
    check_nothing_left({r.out});
  }
}

TEST_CASE("SIGKILL of fem_server at a random step: restarted, rolled back, same results") {
  for (int seed = 1; seed <= 5; ++seed) {
    const std::int64_t step = kill_step(seed, 2);
    INFO("seed " << seed << ": kill at step " << step);
    TempDir d;
    const Result r = run(d.path, {"--debug-kill", "fem:" + std::to_string(step)});
    INFO(r.out << r.err);
    REQUIRE(r.status == 0);
    CHECK(r.err.find("SIGKILL to the FEM solver in step " + std::to_string(step)) !=
          std::string::npos);
    CHECK(r.err.find("recovered: every process is back at step " +
                     std::to_string(step / 10 * 10)) != std::string::npos);
    check_same_results(reference(), d.path / kOut);
    check_nothing_left({r.out});
  }
}

TEST_CASE("SIGKILL of the coupler at a random step: the solvers leave, --resume finishes the run") {
  for (int seed = 1; seed <= 5; ++seed) {
    const std::int64_t step = kill_step(seed, 3);
    INFO("seed " << seed << ": kill at step " << step);
    TempDir d;
    const Result killed = run(d.path, {"--debug-kill", "coupler:" + std::to_string(step)});
    INFO(killed.out << killed.err);
    REQUIRE(killed.status == 128 + SIGKILL);
    // The orphaned solvers notice the dead coupler and exit by themselves.
    for (pid_t p : started_pids(killed.out)) {
      const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(10);
      while (::kill(p, 0) == 0 && std::chrono::steady_clock::now() < end) {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
      CHECK((::kill(p, 0) != 0 && errno == ESRCH));
    }
    // ... and, the coupler's pid being gone, remove its segments themselves.
    for (const auto& seg : segments_of(killed.out)) {
      INFO("segment " << seg << " after the coupler died");
      CHECK_FALSE(fs::exists("/dev/shm/" + seg));
      CHECK_FALSE(fs::exists("/dev/shm/" + seg + "-bulk"));
    }
    const Result resumed = run(d.path, {"--resume"});
    INFO(resumed.out << resumed.err);
    REQUIRE(resumed.status == 0);
    CHECK(resumed.err.find("resumed from checkpoint") != std::string::npos);
    CHECK(resumed.err.find("step-" + std::string(6 - std::to_string(step / 10 * 10).size(), '0') +
                           std::to_string(step / 10 * 10)) != std::string::npos);
    check_same_results(reference(), d.path / kOut);
    check_nothing_left({killed.out, resumed.out});
  }
}

TEST_CASE("in process: a killed run resumed with --in-process equals the three-process run") {
  TempDir d;
  const Result killed = run(d.path, {"--in-process", "--debug-kill", "coupler:33"});
  INFO(killed.out << killed.err);
  REQUIRE(killed.status == 128 + SIGKILL);
  const Result resumed = run(d.path, {"--in-process", "--resume"});
  INFO(resumed.out << resumed.err);
  REQUIRE(resumed.status == 0);
  CHECK(resumed.err.find("step-000030") != std::string::npos);
  check_same_results(reference(), d.path / kOut);
}

TEST_CASE("a solver that keeps dying at the same step stops the run after max_retries (exit 4)") {
  TempDir d;
  const Result r = run(d.path, {"--debug-kill", "dem:25:always"});
  INFO(r.out << r.err);
  CHECK(r.status == 4);
  CHECK(r.err.find("restart 3 of 3") != std::string::npos);
  CHECK(r.err.find("kept failing: 3 restarts from checkpoint") != std::string::npos);
  CHECK(r.err.find("step-000020") != std::string::npos);
  CHECK(started_pids(r.out).size() == 5);  // fem, dem, and 3 restarts of dem
  check_nothing_left({r.out});
}

TEST_CASE("a corrupt or incomplete checkpoint is skipped with a message, the previous is used") {
  struct Damage {
    const char* what;
    const char* part;
    const char* expect;  // in the message
  };
  const Damage cases[] = {
      {"truncated", "dem.h5", "dem.h5: size"},
      {"missing", "fem.h5", "fem.h5: part missing"},
      {"bad checksum", "coupler.h5", "coupler.h5: checksum"},
      {"no manifest", "manifest.json", "manifest.json: missing (the checkpoint was not committed)"},
      {"truncated manifest", "manifest.json", "manifest.json:"},
  };
  for (const auto& c : cases) {
    INFO(c.what);
    TempDir d;
    fs::create_directories(d.path / "out");
    fs::copy(reference(), d.path / kOut, fs::copy_options::recursive);
    const fs::path target = d.path / kOut / "checkpoints" / "step-000050" / c.part;
    const std::string what = c.what;
    if (what == "truncated") {
      fs::resize_file(target, fs::file_size(target) / 2);
    } else if (what == "missing" || what == "no manifest") {
      fs::remove(target);
    } else if (what == "bad checksum") {
      std::fstream f(target, std::ios::in | std::ios::out | std::ios::binary);
      f.seekg(static_cast<std::streamoff>(fs::file_size(target) - 9));
      char byte = 0;
      f.read(&byte, 1);
      byte = static_cast<char>(byte ^ 0x5a);
      f.seekp(static_cast<std::streamoff>(fs::file_size(target) - 9));
      f.write(&byte, 1);
    } else {
      fs::resize_file(target, fs::file_size(target) - 20);
    }
    const Result r = run(d.path, {"--resume"});
    INFO(r.out << r.err);
    REQUIRE(r.status == 0);
    CHECK(r.err.find("skipping checkpoint") != std::string::npos);
    CHECK(r.err.find(c.expect) != std::string::npos);
    CHECK(r.err.find("resumed from checkpoint " + std::string(kOut) + "/checkpoints/step-000040") !=
          std::string::npos);
    check_same_results(reference(), d.path / kOut);
    // Given explicitly, a damaged checkpoint is refused (exit 2), naming the file.
    if (what != "no manifest") {
      fs::copy(reference() / "checkpoints" / "step-000040", d.path / "cp40",
               fs::copy_options::recursive);
      fs::copy_file(d.path / "cp40" / "coupler.h5", d.path / "cp40" / "dem.h5",
                    fs::copy_options::overwrite_existing);
      const Result e = run(d.path, {"--resume", (d.path / "cp40").string()});
      CHECK(e.status == 2);
      CHECK(e.err.find("cp40/dem.h5: size") != std::string::npos);
    }
  }
}

TEST_CASE("a bad [checkpoint] key is refused before any process starts, naming file, line, key") {
  TempDir d;
  std::string text = read_text(kScene);
  const std::string from = "keep = 2 ";
  const auto at = text.find(from);
  REQUIRE(at != std::string::npos);
  text.replace(at, from.size(), "keep = 0 ");
  const fs::path scene = d.path / "bad.toml";
  std::ofstream(scene) << text;
  // Appended piecewise: GCC 12 warns falsely (-Wrestrict) on "'" + std::string&&.
  std::string cmd = "'";
  cmd += (kBin / "demfem_run").string();
  cmd += "' '" + scene.string() + "' --quiet > '";
  cmd += (d.path / "log.txt").string();
  cmd += "' 2>&1";
  const int st = std::system(cmd.c_str());
  REQUIRE(WIFEXITED(st));
  CHECK(WEXITSTATUS(st) == 2);
  const std::string log = read_text(d.path / "log.txt");
  INFO(log);
  CHECK(log.find("bad.toml:13") != std::string::npos);
  CHECK(log.find("keep") != std::string::npos);
  CHECK(log.find("started") == std::string::npos);
}

TEST_CASE("a hung (SIGSTOP) dem_server is found by its stale heartbeat, killed and replaced") {
  TempDir d;
  // run.peer_timeout = 1 s (default 10 s): the hang is found within a second.
  const Result r = run(d.path, {"--debug-kill", "dem:31:stop", "--set", "run.peer_timeout=1"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  CHECK(r.err.find("SIGSTOP to the DEM solver in step 31") != std::string::npos);
  CHECK(r.err.find("heartbeat stale") != std::string::npos);
  CHECK(r.err.find("recovered: every process is back at step 30") != std::string::npos);
  check_same_results(reference(), d.path / kOut);
  check_nothing_left({r.out});
}

// The case with some `key = value` texts replaced (each must occur).
fs::path variant(const fs::path& dir,
                 const std::vector<std::pair<std::string, std::string>>& subs) {
  return demfem::test::write_variant(kScene, dir / "variant.toml", subs);
}

TEST_CASE("a solver that hangs inside a step (heartbeat alive) is killed after reply_timeout") {
  // The DEM time step 2000 times smaller makes one coupling step take 100,000 substeps
  // (about two seconds here) while the heartbeat goes on; checkpoint.reply_timeout = 0.5 s
  // gives up on it, kills and restarts it, rolls back to the step-0 checkpoint, and after
  // max_retries = 1 stops with exit 4, naming the timeout. The run must end within seconds
  // (not hang) and leave no process or segment behind. (With 0.1 s, the step-0 checkpoint
  // itself, which starts the DEM's output, sometimes took longer on the loaded 2-core machine:
  // the run then stopped with exit 1 before it had a checkpoint to recover to.)
  TempDir d;
  const fs::path scene = variant(
      d.path,
      {{"max_retries = 3", "max_retries = 1\nreply_timeout = 0.5"},
       {"dt = 2e-6                  # s; Rayleigh", "dt = 1e-9                  # s; Rayleigh"}});
  const auto t0 = std::chrono::steady_clock::now();
  const Result r = run(d.path, {}, scene);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  INFO(r.out << r.err);
  CHECK(r.status == 4);
  CHECK(r.err.find("no reply within reply_timeout (500 ms)") != std::string::npos);
  CHECK(r.err.find("kept failing: 1 restarts from checkpoint") != std::string::npos);
  CHECK(secs < 30.0);
  check_nothing_left({r.out});
}

// The schemes of issue 13 keep more history than predictive: concurrent the FEM's second
// buffer and the DEM's last forces, implicit the accelerator (IQN-ILS's columns of the last
// steps, Aitken's factor) and the iteration counters. A run killed anywhere (a solver, in the
// middle of a step's iterations; or the coupler) must end with the uninterrupted run's bits.
namespace {
void check_scheme_faults(const std::vector<std::pair<std::string, std::string>>& subs, int dem_kill,
                         int fem_kill, int coupler_kill) {
  TempDir ref, a, b, c;
  const fs::path scene = variant(ref.path, subs);
  const Result r0 = run(ref.path, {}, scene);
  INFO(r0.out << r0.err);
  REQUIRE(r0.status == 0);
  const Result r1 = run(a.path, {"--debug-kill", "dem:" + std::to_string(dem_kill)}, scene);
  INFO(r1.out << r1.err);
  REQUIRE(r1.status == 0);
  CHECK(r1.err.find("back at step " + std::to_string(dem_kill / 10 * 10)) != std::string::npos);
  check_same_results(ref.path / kOut, a.path / kOut);
  const Result r2 = run(b.path, {"--debug-kill", "fem:" + std::to_string(fem_kill)}, scene);
  INFO(r2.out << r2.err);
  REQUIRE(r2.status == 0);
  CHECK(r2.err.find("back at step " + std::to_string(fem_kill / 10 * 10)) != std::string::npos);
  check_same_results(ref.path / kOut, b.path / kOut);
  const Result killed =
      run(c.path, {"--debug-kill", "coupler:" + std::to_string(coupler_kill)}, scene);
  REQUIRE(killed.status == 128 + SIGKILL);
  const Result resumed = run(c.path, {"--resume"}, scene);
  INFO(resumed.out << resumed.err);
  REQUIRE(resumed.status == 0);
  check_same_results(ref.path / kOut, c.path / kOut);
  check_nothing_left({r1.out, r2.out, killed.out, resumed.out});
}
}  // namespace

TEST_CASE(
    "predictive with force averaging: killed solvers and a killed coupler end with the same bits") {
  // The predictive scheme keeps the previous DEM forces between steps: the coupler's part of
  // the checkpoint must carry them.
  check_scheme_faults({{"scheme = \"just_in_time\"", "scheme = \"predictive\""},
                       {"force_averaging = false", "force_averaging = true"}},
                      23, 37, 44);
}

TEST_CASE("concurrent scheme: killed solvers and a killed coupler end with the same bits") {
  check_scheme_faults({{"scheme = \"just_in_time\"", "scheme = \"concurrent\""}}, 23, 37, 44);
}

TEST_CASE("implicit IQN-ILS: killed solvers and a killed coupler end with the same bits") {
  // Tight tolerances, so that every step iterates several times and the columns of the last
  // steps matter: a restored run without them would iterate differently.
  check_scheme_faults({{"scheme = \"just_in_time\"",
                        "scheme = \"implicit\"\nacceleration = \"iqn-ils\"\n"
                        "displacement_tolerance = 1e-7\nforce_tolerance = 1e-5\n"
                        "reuse_steps = 4"}},
                      26, 15, 32);
}

TEST_CASE("implicit Aitken: killed solvers and a killed coupler end with the same bits") {
  // Aitken's factor of the last step starts the next step's relaxation, as min(omega_0, |omega|):
  // part of the checkpoint. omega_0 = 1, so that the restored factor is the one used (with the
  // default 0.5 the last factors here were larger, and a restore that dropped them still
  // passed).
  check_scheme_faults({{"scheme = \"just_in_time\"",
                        "scheme = \"implicit\"\nacceleration = \"aitken\"\n"
                        "displacement_tolerance = 1e-7\ninitial_relaxation = 1.0"}},
                      28, 34, 41);
}

TEST_CASE("every_sim_time: checkpoints where the simulated time passes a multiple") {
  TempDir d;
  // 1.5 ms = 15 coupling steps: checkpoints at steps 0, 15, 30, 45 (all kept).
  const fs::path scene = variant(
      d.path, {{"every_steps = 10 ", "every_sim_time = 1.5e-3 "}, {"keep = 2 ", "keep = 9 "}});
  const Result r = run(d.path, {"--debug-kill", "fem:40"}, scene);
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  CHECK(r.err.find("back at step 30") != std::string::npos);
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(d.path / kOut / "checkpoints"))
    names.insert(e.path().filename().string());
  CHECK(names == std::set<std::string>{"step-000000", "step-000015", "step-000030", "step-000045",
                                       "step-000050"});
  check_same_results(reference(), d.path / kOut);
}

TEST_CASE(
    "old checkpoints do not outlive their run: a fresh run and an older resume discard them") {
  TempDir d;
  REQUIRE(run(d.path, {}).status == 0);  // leaves step-40 and step-50
  const fs::path cp = d.path / kOut / "checkpoints";
  // A fresh run in the same folder, killed and recovered: it must roll back to its own
  // checkpoint, not find an older run's step-40 newer than its own.
  const Result r = run(d.path, {"--debug-kill", "fem:15"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  CHECK(r.err.find("back at step 10") != std::string::npos);
  check_same_results(reference(), d.path / kOut);
  // Resuming explicitly from an older checkpoint drops the newer ones, then writes its own.
  const Result e =
      run(d.path, {"--resume", (cp / "step-000040").string(), "--debug-kill", "dem:45"});
  INFO(e.out << e.err);
  REQUIRE(e.status == 0);
  CHECK(e.err.find("back at step 40") != std::string::npos);
  check_same_results(reference(), d.path / kOut);
}

TEST_CASE("every_wall_time: a checkpoint whenever the wall-time interval has passed") {
  TempDir d;
  // 1 ns: due at every step boundary (the results may not depend on where they fall).
  const fs::path scene = variant(d.path, {{"every_steps = 10 ", "every_wall_time = 1e-9 "}});
  const Result r = run(d.path, {"--debug-kill", "dem:37"}, scene);
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  CHECK(r.err.find("back at step 37") != std::string::npos);
  CHECK(r.out.find("51 checkpoints") != std::string::npos);  // steps 0..49 and the end, 50
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(d.path / kOut / "checkpoints"))
    names.insert(e.path().filename().string());
  CHECK(names == std::set<std::string>{"step-000049", "step-000050"});
  check_same_results(reference(), d.path / kOut);
}

TEST_CASE("one-way static: a FEM killed in its static solve recovers to the same deflection") {
  // cases/beam_fixed_ci.toml (the DEM settles for 8 steps, then one static FEM solve) with a
  // checkpoint every 5 steps; fem_server is killed in step 7, the settle step.
  TempDir ref, d;
  std::string text = read_text(fs::path(DEMFEM_SOURCE_DIR) / "cases" / "beam_fixed_ci.toml");
  const auto at = text.find("[coupling]\n");
  REQUIRE(at != std::string::npos);
  text.insert(at, "[checkpoint]\nevery_steps = 5\n\n");
  const fs::path scene = ref.path / "fixed.toml";
  std::ofstream(scene) << text;
  const Result r0 = run(ref.path, {}, scene);
  INFO(r0.out << r0.err);
  REQUIRE(r0.status == 0);
  const Result r1 = run(d.path, {"--debug-kill", "fem:7"}, scene);
  INFO(r1.out << r1.err);
  REQUIRE(r1.status == 0);
  CHECK(r1.err.find("SIGKILL to the FEM solver in step 7") != std::string::npos);
  CHECK(r1.err.find("back at step 5") != std::string::npos);
  check_same_results(ref.path / "out/beam_fixed_ci", d.path / "out/beam_fixed_ci", 8);
  check_nothing_left({r1.out});
}

TEST_CASE("a finished run is continued to a later end_time and equals the run straight to it") {
  // Issue 19, defect 17: no checkpoint was taken at the end, so a run that ended could not be
  // continued. The run to 4 ms ends with a checkpoint of its end state (step 40); --resume
  // with the scene's end_time of 5 ms continues it, equal to the uninterrupted run to 5 ms
  // (4 ms is a multiple of the output interval, so the first run wrote no extra output).
  TempDir d;
  const fs::path t1 = variant(d.path, {{"end_time = 0.005 ", "end_time = 0.004 "}});
  const Result first = run(d.path, {}, t1);
  INFO(first.out << first.err);
  REQUIRE(first.status == 0);
  REQUIRE(fs::exists(d.path / kOut / "checkpoints" / "step-000040" / "manifest.json"));
  const Result second = run(d.path, {"--resume"});
  INFO(second.out << second.err);
  REQUIRE(second.status == 0);
  CHECK(second.err.find("resumed from checkpoint " + std::string(kOut) +
                        "/checkpoints/step-000040 (step 40") != std::string::npos);
  CHECK(second.err.find("the scene differs from the one checkpoint") != std::string::npos);
  check_same_results(reference(), d.path / kOut);
  // Resumed at its end, a finished run has nothing left to do and stays as it is.
  const Result again = run(d.path, {"--resume"});
  INFO(again.out << again.err);
  REQUIRE(again.status == 0);
  CHECK(again.err.find("step-000050 (step 50") != std::string::npos);
  check_same_results(reference(), d.path / kOut);
}

TEST_CASE("resume into a new output folder continues the series of the checkpoint's run") {
  // Issue 19, defect 17: "coupling.csv: cannot read the series to continue" until the old
  // coupling.csv was copied by hand. The checkpoint records its run's output folder; the
  // new folder takes over that run's series and continues them.
  TempDir d;
  const fs::path cp40 = reference() / "checkpoints" / "step-000040";
  const fs::path fresh = d.path / "continued";
  const Result r = run(d.path, {"--resume", cp40.string(), "--output-dir", fresh.string()});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  CHECK(r.err.find("took over the series of " + fs::absolute(reference()).string()) !=
        std::string::npos);
  check_same_results(reference(), fresh);
  // The folder the series came from is gone: refused with what to do (exit 2).
  TempDir gone_run;
  REQUIRE(run(gone_run.path, {}).status == 0);
  const fs::path kept = d.path / "kept-step-000040";
  fs::copy(gone_run.path / kOut / "checkpoints" / "step-000040", kept);
  fs::remove_all(gone_run.path / kOut);
  const Result e =
      run(d.path, {"--resume", kept.string(), "--output-dir", (d.path / "x").string()});
  INFO(e.out << e.err);
  CHECK(e.status == 2);
  CHECK(e.err.find("whose series (coupling.csv) are not there any more") != std::string::npos);
  CHECK(started_pids(e.out).empty());
}

TEST_CASE("after a resume the wall-time shares are of the same wall time") {
  // Issue 19, defect 12: the restored DEM total was divided by this session's wall time
  // ("DEM 716 %").
  // Resumed at the end of a finished run, this session computes nothing, so the old sum was
  // the whole run's DEM time over a few milliseconds.
  TempDir d;
  REQUIRE(run(d.path, {}).status == 0);
  const Result r = run(d.path, {"--resume"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  REQUIRE(r.err.find("step-000050 (step 50") != std::string::npos);
  auto shares = [&](const std::string& label) {
    const std::regex re(label +
                        ": total ([0-9.]+) s; DEM [0-9.]+ s \\(([0-9.]+) %\\), FEM [0-9.]+ "
                        "s \\(([0-9.]+) %\\), coupling [0-9.]+ s \\(([0-9.]+) %\\)");
    std::smatch m;
    REQUIRE(std::regex_search(r.out, m, re));
    return std::stod(m[2]) + std::stod(m[3]) + std::stod(m[4]);
  };
  CHECK(shares("wall time of this session") <= 100.5);
  CHECK(shares("wall time of the whole run \\(earlier sessions up to the checkpoint, and this "
               "one\\)") <= 100.5);
}

TEST_CASE(
    "SIGUSR2 to every process: a checkpoint at the next step, exit 140, --resume to the same "
    "bits") {
  // A Slurm job near its time limit (`--signal=USR2@120`, which reaches the solvers too) or a
  // user who needs the machine: nothing since the last periodic checkpoint is lost.
  for (const bool in_process : {false, true}) {
    INFO((in_process ? "--in-process" : "three processes"));
    TempDir d;
    std::vector<std::string> args = {"--debug-kill", "job:23:usr2"};
    if (in_process) args.push_back("--in-process");
    const Result r = run(d.path, args);
    INFO(r.out << r.err);
    REQUIRE(r.status == 128 + SIGUSR2);
    CHECK(r.err.find("checkpoint of step 24 (t = 0.0024 s) written on request") !=
          std::string::npos);
    // The solvers ignored the signal (they would have died of it): nothing was restarted.
    CHECK(r.err.find("restarting") == std::string::npos);
    CHECK(fs::exists(d.path / kOut / "checkpoints" / "step-000024" / "manifest.json"));
    CHECK(read_csv(d.path / kOut / "coupling.csv").size() == 25);  // header + steps 0..23
    CHECK(read_text(d.path / kOut / "run.json").find("\"status\": \"interrupted\"") !=
          std::string::npos);
    check_nothing_left({r.out});
    const Result resumed = run(d.path, {"--resume"});
    INFO(resumed.out << resumed.err);
    REQUIRE(resumed.status == 0);
    CHECK(resumed.err.find("step-000024 (step 24") != std::string::npos);
    check_same_results(reference(), d.path / kOut);
    check_nothing_left({resumed.out});
  }
}

TEST_CASE(
    "SIGUSR1 to every process: a checkpoint at the next step, the run goes on to the same bits") {
  TempDir d;
  const Result r = run(d.path, {"--debug-kill", "job:23:usr1"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  CHECK(r.err.find("checkpoint of step 24 (t = 0.0024 s) written on request") != std::string::npos);
  CHECK(r.err.find("restarting") == std::string::npos);
  // Steps 0, 10, 20, 24 (asked for), 30, 40 and the end, 50.
  CHECK(r.out.find("7 checkpoints") != std::string::npos);
  check_same_results(reference(), d.path / kOut);
  check_nothing_left({r.out});

  // Without [checkpoint] the request is answered with a message, and the run goes on.
  TempDir e;
  const fs::path scene = variant(e.path, {{"[checkpoint]\n", "\n"},
                                          {"every_steps = 10 ", "# every_steps = 10 "},
                                          {"keep = 2 ", "# keep = 2 "},
                                          {"max_retries = 3 ", "# max_retries = 3 "}});
  const Result n = run(e.path, {"--debug-kill", "job:23:usr1"}, scene);
  INFO(n.out << n.err);
  REQUIRE(n.status == 0);
  CHECK(n.err.find("the scene has no [checkpoint]: none written") != std::string::npos);
  check_same_results(reference(), e.path / kOut);
}

TEST_CASE("Ctrl-C as the run ends: a finished run stays finished, any other resumes to the same bits") {
  // CI, 2026-12-05 (the sweep's resume test, 1 in ~30 under load): a Ctrl-C that reached the
  // coupler after its last step went on to the solvers as SIGTERM while they wrote their end
  // state. fem_server died between its last step file and that step's row of
  // fem_series.csv; the run that had finished exited 1, and every --resume after it was
  // refused ("has 1 rows, the checkpoint expects at least 2"): the member was lost for good.
  // Now the coupler passes no stop on once it said Shutdown, a solver holds stop signals
  // while it writes its end state, and the FEM writes a row before its step file's commit.
  // The signal goes to the whole process group, as a terminal's Ctrl-C does, at moments
  // around the final checkpoint's commit (which comes just before Shutdown).
  const fs::path last_manifest = fs::path("checkpoints") / "step-000050" / "manifest.json";
  for (const int delay_us : {0, 200, 500, 1000, 2000, 3000, 5000, 8000}) {
    TempDir d;
    const fs::path out = d.path / kOut;
    const auto l = demfem::test::launch(
        d.path, {(kBin / "demfem_run").string(), kScene.string(), "--quiet"}, /*group=*/true);
    const bool seen = demfem::test::eventually(
        [&] { return fs::exists(out / last_manifest) || demfem::test::gone(l.pid); },
        std::chrono::seconds(120));
    std::this_thread::sleep_for(std::chrono::microseconds(delay_us));
    ::kill(-l.pid, SIGINT);
    const Result r = demfem::test::wait_for(l);
    INFO("SIGINT " << delay_us << " us after the last checkpoint\n" << r.out << r.err);
    REQUIRE(seen);
    // Done (0), or stopped cleanly (130) with a run.json that says so; never failed.
    REQUIRE((r.status == 0 || r.status == 128 + SIGINT));
    const std::string record = read_text(out / "run.json");
    CHECK(record.find(r.status == 0 ? "\"completed\"" : "\"interrupted\"") != std::string::npos);
    check_nothing_left({r.out});
    if (r.status != 0) {
      const Result again = run(d.path, {"--resume"});
      INFO(again.out << again.err);
      REQUIRE(again.status == 0);
    }
    check_same_results(reference(), out);
  }
}
