// System tests: the run launcher with real solver processes and real shared memory.
// Each run happens in its own temporary folder (the scene's run.output_dir is relative to
// the current directory), with the executables of this build (DEMFEM_BINARY_DIR/bin).
#include <catch2/catch.hpp>

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "demfem/io/h5_file.hpp"
#include "demfem_test/demfem_run.hpp"
#include "demfem_test/launch.hpp"
#include "demfem_test/run_output.hpp"
#include "demfem_test/temp_dir.hpp"

namespace fs = std::filesystem;

namespace {

using demfem::test::read_csv;
using demfem::test::read_text;
using demfem::test::segments_of;
using demfem::test::started_pids;
using demfem::test::TempDir;

using demfem::test::kBin;
using demfem::test::kCases;
using Result = demfem::test::Ended;

// Starts demfem_run in `dir` (own process group when `group`), stdout/stderr to files.
pid_t spawn_run(const fs::path& dir, const std::vector<std::string>& args, bool group) {
  std::vector<std::string> argv = {(kBin / "demfem_run").string(), "--bin-dir", kBin.string()};
  argv.insert(argv.end(), args.begin(), args.end());
  return demfem::test::launch(dir, argv, group).pid;
}

Result wait_run(const fs::path& dir, pid_t pid) {
  int st = 0;
  REQUIRE(waitpid(pid, &st, 0) == pid);
  Result r;
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
  r.out = read_text(dir / "stdout.txt");
  r.err = read_text(dir / "stderr.txt");
  return r;
}

Result run(const fs::path& dir, const std::vector<std::string>& args) {
  return wait_run(dir, spawn_run(dir, args, false));
}

bool pid_gone(pid_t pid) {
  return kill(pid, 0) != 0 && errno == ESRCH;
}

std::string segment_of(const std::string& out) {
  const auto segs = segments_of(out);
  return segs.empty() ? std::string() : segs.front();
}

// Waits until the run has written `rows` CSV data rows (it is in its loop).
void wait_for_rows(const fs::path& csv, std::size_t rows) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < end) {
    if (fs::exists(csv) && read_csv(csv).size() > rows) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  FAIL("the run wrote no coupling rows within 60 s");
}

// A copy of a case with some `key = value` lines replaced (first match of each key).
fs::path variant(const fs::path& dir, const std::string& name, const std::string& case_file,
                 const std::vector<std::pair<std::string, std::string>>& lines) {
  std::string text = read_text(kCases / case_file);
  for (const auto& [from, to] : lines) {
    const auto at = text.find(from);
    REQUIRE(at != std::string::npos);
    text.replace(at, from.size(), to);
  }
  const fs::path p = dir / name;
  std::ofstream(p) << text;
  return p;
}

}  // namespace

TEST_CASE("CI beam: three processes equal the in-process run bitwise") {
  TempDir a, b;
  std::string scene = (kCases / "beam_dynamic_ci.toml").string();
  SECTION("just-in-time") {}
  SECTION("predictive with force averaging") {
    scene = variant(a.path, "predictive.toml", "beam_dynamic_ci.toml",
                    {{"scheme = \"just_in_time\"", "scheme = \"predictive\""},
                     {"force_averaging = false", "force_averaging = true"}})
                .string();
  }
  // Issue 13: the in-process link runs the concurrent scheme's two solvers on two threads,
  // the three-process run in two processes; the implicit scheme iterates with save points.
  SECTION("concurrent") {
    scene = variant(a.path, "concurrent.toml", "beam_dynamic_ci.toml",
                    {{"scheme = \"just_in_time\"", "scheme = \"concurrent\""}})
                .string();
  }
  SECTION("implicit IQN-ILS") {
    scene =
        variant(
            a.path, "implicit.toml", "beam_dynamic_ci.toml",
            {{"scheme = \"just_in_time\"", "scheme = \"implicit\"\ndisplacement_tolerance = 1e-7"}})
            .string();
  }
  const Result remote = run(a.path, {scene, "--quiet"});
  INFO(remote.out << remote.err);
  REQUIRE(remote.status == 0);
  const Result local = run(b.path, {scene, "--quiet", "--in-process"});
  INFO(local.out << local.err);
  REQUIRE(local.status == 0);
  const auto ra = read_csv(a.path / "out/beam_dynamic_ci/coupling.csv");
  const auto rb = read_csv(b.path / "out/beam_dynamic_ci/coupling.csv");
  REQUIRE(ra.size() == 51);  // header + 50 coupling steps
  // Every column but the wall times, as written (17 significant digits).
  CHECK(demfem::test::first_difference_but_wall_times(ra, rb) == "");
  // The final interface state, bit for bit.
  demfem::io::H5File ha(a.path / "out/beam_dynamic_ci/coupling.h5", demfem::io::H5File::Mode::read);
  demfem::io::H5File hb(b.path / "out/beam_dynamic_ci/coupling.h5", demfem::io::H5File::Mode::read);
  for (const char* name : {"interface/positions", "interface/forces", "interface/dem_positions"}) {
    INFO(name);
    CHECK(ha.read_doubles(name) == hb.read_doubles(name));
  }
  // The beam moved and the load arrived: the comparison is not of two empty runs.
  CHECK(std::stod(ra.back()[9]) > 1e-7);   // fem_max_displacement, m
  CHECK(std::stod(ra.back()[10]) < -400);  // force_sum_z, N (51 kg: -500 N at rest)
}

TEST_CASE("CI beam, one-way static: coupled deflection within 0.1 % of the pure-FEM pressure run") {
  TempDir d;
  const Result r = run(d.path, {(kCases / "beam_fixed_ci.toml").string(), "--quiet"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  CHECK_THAT(r.out, Catch::Contains("beam check"));
  const auto rows = read_csv(d.path / "out/beam_fixed_ci/beam_check.csv");
  REQUIRE(rows.size() == 2);
  const double coupled = std::stod(rows[1][1]), fem = std::stod(rows[1][2]);
  const double load = std::stod(rows[1][4]), mg = std::stod(rows[1][5]);
  // The acceptance bound of the issue (the thesis reached 0.38 %, table 4.2).
  CHECK(std::abs(coupled - fem) / std::abs(fem) < 1e-3);
  // All the spheres' weight reaches the beam once they rest (same bound).
  CHECK(std::abs(load - mg) / mg < 1e-3);
  CHECK(coupled < 0.0);
}

TEST_CASE("a scene with only a DEM starts only dem_server") {
  TempDir d;
  // The beam case's particles on a rigid floor, without [fem] and [coupling].
  std::string text = read_text(kCases / "beam_fixed_ci.toml");
  const auto c0 = text.find("[coupling]"), c1 = text.find("[dem]");
  text.erase(c0, c1 - c0);
  text.replace(text.find("interface_material = \"steel\""), 28,
               "[[dem.walls]]\nname = \"floor\"\nmaterial = \"steel\"\n"
               "plane = { point = [0.5, 0.05, 0.1], normal = [0.0, 0.0, 1.0], size = 2.0 }\n");
  // [[dem.walls]] must come after the [dem] keys: move it to the end.
  const auto w0 = text.find("[[dem.walls]]");
  const auto w1 = text.find("[[dem.materials]]");
  const std::string walls = text.substr(w0, w1 - w0);
  text.erase(w0, w1 - w0);
  text += "\n" + walls;
  std::ofstream(d.path / "dem_only.toml") << text;
  const Result r = run(d.path, {(d.path / "dem_only.toml").string(), "--quiet"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  CHECK_THAT(r.out, Catch::Contains("started dem_server"));
  CHECK_THAT(r.out, !Catch::Contains("fem_server"));
  CHECK(started_pids(r.out).size() == 1);
  CHECK(fs::exists(d.path / "out/beam_fixed_ci/coupling.csv"));
}

TEST_CASE("a scene with only a FEM starts only fem_server") {
  TempDir d;
  // The beam with the spheres' weight as a pressure, without [dem] and [coupling].
  std::string text = read_text(kCases / "beam_fixed_ci.toml");
  text.erase(text.find("[coupling]"), text.find("[fem]") - text.find("[coupling]"));
  text.erase(text.find("[dem]"));
  text += "[[fem.pressures]]\nsurface = \"z >= 0.1\"\ntotal_force = 500.31\n";
  std::ofstream(d.path / "fem_only.toml") << text;
  const Result r = run(d.path, {(d.path / "fem_only.toml").string(), "--quiet"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  CHECK_THAT(r.out, Catch::Contains("started fem_server"));
  CHECK_THAT(r.out, !Catch::Contains("dem_server"));
  CHECK(started_pids(r.out).size() == 1);
  // One static solve: the beam deflected.
  const auto rows = read_csv(d.path / "out/beam_fixed_ci/coupling.csv");
  REQUIRE(rows.size() == 2);
  CHECK(std::stod(rows[1][9]) > 5e-7);
}

TEST_CASE("a bad scene gives exit status 2 and names file, line and key") {
  TempDir d;
  const auto bad = variant(
      d.path, "bad.toml", "beam_fixed_ci.toml",
      {{"scheme = \"one_way_static\"", "scheme = \"one_way_static\"\nforce_averagin = true"}});
  Result r = run(d.path, {bad.string()});
  CHECK(r.status == 2);
  CHECK_THAT(r.err, Catch::Contains("bad.toml:11") && Catch::Contains("coupling.force_averagin"));
  CHECK(started_pids(r.out).empty());
  // A bad key in a solver's section is found before any process starts as well.
  const auto bad_dem = variant(d.path, "bad_dem.toml", "beam_fixed_ci.toml",
                               {{"restitution = 0.1 ", "restitution = 1.5 "}});
  r = run(d.path, {bad_dem.string()});
  CHECK(r.status == 2);
  CHECK_THAT(r.err, Catch::Contains("bad_dem.toml:") && Catch::Contains("restitution"));
  CHECK(started_pids(r.out).empty());
  // Inconsistent time steps: n_D = 1e-4 / 3e-6 is not an integer.
  const auto bad_dt =
      variant(d.path, "bad_dt.toml", "beam_dynamic_ci.toml", {{"dt = 2e-6 ", "dt = 3e-6 "}});
  r = run(d.path, {bad_dt.string()});
  CHECK(r.status == 2);
  CHECK_THAT(r.err, Catch::Contains("fem.dt") && Catch::Contains("dem.dt"));
  // A coupled scene whose DEM does not say which material the structure's surface is.
  const auto no_material = variant(d.path, "no_material.toml", "beam_fixed_ci.toml",
                                   {{"interface_material = \"steel\"", ""}});
  r = run(d.path, {no_material.string()});
  CHECK(r.status == 2);
  CHECK_THAT(r.err,
             Catch::Contains("no_material.toml:") && Catch::Contains("dem.interface_material"));
  CHECK(started_pids(r.out).empty());
  // A missing file.
  r = run(d.path, {(d.path / "missing.toml").string()});
  CHECK(r.status == 2);
  CHECK_THAT(r.err, Catch::Contains("missing.toml"));
}

TEST_CASE("an overlap beyond the bound stops the run with status 3 and keeps the output") {
  TempDir d;
  const auto scene = variant(d.path, "blowup.toml", "beam_dynamic_ci.toml",
                             {{"max_overlap = 1.2e-3", "max_overlap = 1e-7"}});
  const Result r = run(d.path, {scene.string(), "--quiet"});
  CHECK(r.status == 3);
  CHECK_THAT(r.err, Catch::Contains("blow-up at coupling step") &&
                        Catch::Contains("coupling.blowup.max_overlap"));
  const auto rows = read_csv(d.path / "out/beam_dynamic_ci/coupling.csv");
  CHECK(rows.size() >= 2);
  CHECK(fs::exists(d.path / "out/beam_dynamic_ci/coupling.h5"));
  for (pid_t p : started_pids(r.out)) CHECK(pid_gone(p));
}

TEST_CASE("SIGTERM or SIGINT stops all three processes and leaves no shared memory") {
  for (const bool group_sigint : {false, true}) {
    DYNAMIC_SECTION(
        (group_sigint ? "SIGINT to the process group (Ctrl-C)" : "SIGTERM to the launcher")) {
      TempDir d;
      const auto scene = variant(d.path, "long.toml", "beam_dynamic_ci.toml",
                                 {{"end_time = 0.005 ", "end_time = 100.0 "}});
      const pid_t pid = spawn_run(d.path, {scene.string(), "--quiet"}, true);
      wait_for_rows(d.path / "out/beam_dynamic_ci/coupling.csv", 2);
      const std::string out_before = read_text(d.path / "stdout.txt");
      const auto pids = started_pids(out_before);
      const std::string segment = segment_of(out_before);
      REQUIRE(pids.size() == 2);
      REQUIRE(!segment.empty());
      REQUIRE(fs::exists(fs::path("/dev/shm") / segment));
      if (group_sigint) {
        kill(-pid, SIGINT);
      } else {
        kill(pid, SIGTERM);
      }
      const Result r = wait_run(d.path, pid);
      INFO(r.out << r.err);
      CHECK(r.status == (group_sigint ? 128 + SIGINT : 128 + SIGTERM));
      for (pid_t p : pids) CHECK(pid_gone(p));
      CHECK(!fs::exists(fs::path("/dev/shm") / segment));
      CHECK(!fs::exists(fs::path("/dev/shm") / (segment + "-bulk")));
      // The series written so far stays readable.
      CHECK(read_csv(d.path / "out/beam_dynamic_ci/coupling.csv").size() >= 3);
    }
  }
}

TEST_CASE("a closed output pipe (demfem run | head) stops all three cleanly") {
  TempDir d;
  // Long enough that a progress line (every 10 %) is written after the pipe is closed.
  const auto scene = variant(d.path, "long.toml", "beam_dynamic_ci.toml",
                             {{"end_time = 0.005 ", "end_time = 1.0 "}});
  int fds[2];
  REQUIRE(pipe(fds) == 0);
  std::vector<std::string> argv_s = {(kBin / "demfem_run").string(), "--bin-dir", kBin.string(),
                                     scene.string()};
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, fds[1], 1);
  posix_spawn_file_actions_addclose(&fa, fds[0]);
  const std::string err = (d.path / "stderr.txt").string();
  posix_spawn_file_actions_addopen(&fa, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  const fs::path old = fs::current_path();
  fs::current_path(d.path);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, argv[0], &fa, nullptr, argv.data(), environ);
  fs::current_path(old);
  posix_spawn_file_actions_destroy(&fa);
  close(fds[1]);
  REQUIRE(rc == 0);
  // Read like `head` until both solvers have started, then close the pipe.
  std::string out;
  char buf[512];
  while (started_pids(out).size() < 2) {
    const ssize_t n = read(fds[0], buf, sizeof buf);
    REQUIRE(n > 0);
    out.append(buf, static_cast<std::size_t>(n));
  }
  close(fds[0]);
  const auto pids = started_pids(out);
  const std::string segment = segment_of(out);
  REQUIRE(!segment.empty());
  int st = 0;
  REQUIRE(waitpid(pid, &st, 0) == pid);
  INFO(read_text(d.path / "stderr.txt"));
  CHECK(WIFEXITED(st));
  CHECK(WEXITSTATUS(st) == 128 + SIGPIPE);
  for (pid_t p : pids) CHECK(pid_gone(p));
  CHECK(!fs::exists(fs::path("/dev/shm") / segment));
  CHECK(!fs::exists(fs::path("/dev/shm") / (segment + "-bulk")));
}

TEST_CASE("two-way dynamic beam settles to the static deflection within 0.5 %") {
  for (const char* name : {"beam_dynamic_jit", "beam_dynamic_predictive", "beam_dynamic_concurrent",
                           "beam_dynamic_implicit"}) {
    DYNAMIC_SECTION(name) {
      TempDir d;
      // The schemes of issue 13 on the case of the just-in-time one.
      const std::string file = std::string(name) + ".toml";
      const fs::path scene =
          std::string(name) == "beam_dynamic_concurrent"
              ? variant(d.path, file, "beam_dynamic_jit.toml",
                        {{"scheme = \"just_in_time\"", "scheme = \"concurrent\""},
                         {"name = \"beam_dynamic_jit\"", "name = \"beam_dynamic_concurrent\""}})
          : std::string(name) == "beam_dynamic_implicit"
              ? variant(d.path, file, "beam_dynamic_jit.toml",
                        {{"scheme = \"just_in_time\"", "scheme = \"implicit\""},
                         {"name = \"beam_dynamic_jit\"", "name = \"beam_dynamic_implicit\""}})
              : kCases / file;
      const Result r = run(d.path, {scene.string()});
      INFO(r.out << r.err);
      REQUIRE(r.status == 0);
      // Not on a terminal: plain progress lines.
      CHECK_THAT(r.out, Catch::Contains("progress: t = 0.04 s / 0.04 s (100.0 %)"));
      const auto rows = read_csv(d.path / "out" / name / "beam_check.csv");
      REQUIRE(rows.size() == 2);
      const double coupled = std::stod(rows[1][1]), fem = std::stod(rows[1][2]);
      // The acceptance bound of the issue: the static pure-FEM deflection within 0.5 %.
      CHECK(std::abs(coupled - fem) / std::abs(fem) < 5e-3);
      const auto timing = read_csv(d.path / "out" / name / "timing.csv");
      REQUIRE(timing.size() == 2);
      CHECK(std::stod(timing[1][6]) < 0.5);  // coupling share recorded (a fraction)
    }
  }
}

TEST_CASE("solver sessions (demfem_run --solver-sessions): Ctrl-C still stops all three") {
  TempDir d;
  const auto scene = variant(d.path, "long.toml", "beam_dynamic_ci.toml",
                             {{"end_time = 0.005 ", "end_time = 100.0 "},
                              {"scheme = \"just_in_time\"", "scheme = \"concurrent\""}});
  const pid_t pid = spawn_run(d.path, {scene.string(), "--quiet", "--solver-sessions"}, true);
  wait_for_rows(d.path / "out/beam_dynamic_ci/coupling.csv", 2);
  const std::string out = read_text(d.path / "stdout.txt");
  const auto pids = started_pids(out);
  REQUIRE(pids.size() == 2);
  for (pid_t p : pids) {
    CHECK(getsid(p) == p);  // a session leader: its own autogroup under Linux
    CHECK(getsid(p) != getsid(pid));
  }
  kill(-pid, SIGINT);  // the terminal's Ctrl-C reaches the launcher only; it forwards SIGTERM
  const Result r = wait_run(d.path, pid);
  INFO(r.out << r.err);
  CHECK(r.status == 128 + SIGINT);
  for (pid_t p : pids) CHECK(pid_gone(p));
  const std::string segment = segment_of(out);
  CHECK(!fs::exists(fs::path("/dev/shm") / segment));
  CHECK(!fs::exists(fs::path("/dev/shm") / (segment + "-bulk")));
}

TEST_CASE("concurrent scheme: the same bits on every three-process run") {
  // The DEM and the FEM step at the same time in two processes, writing different buffers:
  // the order in which they finish must not change any number.
  TempDir dir;
  const fs::path scene = variant(dir.path, "concurrent.toml", "beam_dynamic_ci.toml",
                                 {{"scheme = \"just_in_time\"", "scheme = \"concurrent\""}});
  std::vector<std::vector<std::vector<std::string>>> series;
  for (int k = 0; k < 3; ++k) {
    TempDir d;
    const Result r = run(d.path, {scene.string(), "--quiet"});
    INFO(r.out << r.err);
    REQUIRE(r.status == 0);
    auto rows = read_csv(d.path / "out/beam_dynamic_ci/coupling.csv");
    REQUIRE(rows.size() == 51);
    const auto header = rows[0];
    for (auto& row : rows)
      for (std::size_t c = 0; c < row.size(); ++c)
        if (header[c].rfind("wall_", 0) == 0) row[c].clear();  // wall-clock times
    series.push_back(std::move(rows));
  }
  CHECK(series[1] == series[0]);
  CHECK(series[2] == series[0]);
  CHECK(std::stod(series[0].back()[10]) < -400);  // the load arrived: not two empty runs
}

TEST_CASE("implicit: a step that does not converge is reported over real processes") {
  // Two iterations and a displacement tolerance no iteration meets: "stop" ends the run with
  // status 3 naming the step and both residuals; "accept" goes on, warns, marks the steps
  // converged = 0 in coupling.csv and counts them in the summary.
  const std::vector<std::string> sets = {(kCases / "beam_dynamic_ci.toml").string(),
                                         "--quiet",
                                         "--set",
                                         "coupling.scheme=\"implicit\"",
                                         "--set",
                                         "coupling.max_iterations=2",
                                         "--set",
                                         "coupling.displacement_tolerance=1e-300"};
  SECTION("stop") {
    TempDir d;
    const Result r = run(d.path, sets);
    INFO(r.out << r.err);
    CHECK(r.status == 3);
    CHECK_THAT(r.err, Catch::Contains("did not converge in 2 iterations") &&
                          Catch::Contains("coupling.displacement_tolerance") &&
                          Catch::Contains("coupling.on_nonconvergence"));
    const auto rows = read_csv(d.path / "out/beam_dynamic_ci/coupling.csv");
    REQUIRE(rows.size() >= 2);
    std::size_t col = 0;
    for (std::size_t k = 0; k < rows[0].size(); ++k)
      if (rows[0][k] == "converged") col = k;
    REQUIRE(col > 0);
    CHECK(rows.back()[col] == "0");
    for (pid_t p : started_pids(r.out)) CHECK(pid_gone(p));
  }
  SECTION("accept") {
    TempDir d;
    auto args = sets;
    args.insert(args.end(), {"--set", "coupling.on_nonconvergence=\"accept\""});
    const Result r = run(d.path, args);
    INFO(r.out << r.err);
    REQUIRE(r.status == 0);
    CHECK_THAT(r.out + r.err, Catch::Contains("accepted (coupling.on_nonconvergence"));
    const auto rows = read_csv(d.path / "out/beam_dynamic_ci/coupling.csv");
    REQUIRE(rows.size() == 51);
    std::size_t col = 0, unconverged = 0;
    for (std::size_t k = 0; k < rows[0].size(); ++k)
      if (rows[0][k] == "converged") col = k;
    REQUIRE(col > 0);
    for (std::size_t i = 1; i < rows.size(); ++i) unconverged += rows[i][col] == "0";
    CHECK(unconverged == 50);
    CHECK_THAT(r.out + r.err, Catch::Contains("50 steps accepted without convergence"));
  }
}

TEST_CASE("scene overrides (--set) reach every process and change the run's result") {
  TempDir base, half, bad;
  const std::string scene = (kCases / "beam_fixed_ci.toml").string();
  Result r = run(base.path, {scene, "--quiet"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  // Half the sphere density (read by dem_server) and half the check's load mass (read by the
  // coupler): the weight on the beam and its deflection halve. The base run is not changed.
  r = run(half.path, {scene, "--quiet", "--set", "dem.materials[0].density=22018.50612436703",
                      "--set", "coupling.beam_check.load_mass=25.5"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  const auto b = read_csv(base.path / "out/beam_fixed_ci/beam_check.csv");
  const auto h = read_csv(half.path / "out/beam_fixed_ci/beam_check.csv");
  REQUIRE(b.size() == 2);
  REQUIRE(h.size() == 2);
  CHECK(std::stod(b[1][0]) == 51.0);
  CHECK(std::stod(h[1][0]) == 25.5);
  // coupled_load (column 4), N: the spheres' weight as the DEM delivered it to the beam, at
  // rest within the 1e-3 of the static case's bound; and the coupled deflection (column 1).
  const double load_b = std::stod(b[1][4]), load_h = std::stod(h[1][4]);
  CHECK(std::abs(load_b - 51.0 * 9.81) / (51.0 * 9.81) < 1e-3);
  CHECK(std::abs(load_h - 25.5 * 9.81) / (25.5 * 9.81) < 1e-3);
  CHECK(std::abs(std::stod(h[1][1]) / std::stod(b[1][1]) - 0.5) < 1e-3);
  // A bad override: exit 2 before any process starts, the message names the override.
  r = run(bad.path, {scene, "--quiet", "--set", "dem.pairs[0].restitution=1.5"});
  CHECK(r.status == 2);
  CHECK_THAT(r.err, Catch::Contains("key 'dem.pairs[0].restitution' (from --set "
                                    "dem.pairs[0].restitution=1.5)"));
  CHECK(started_pids(r.out).empty());
  r = run(bad.path, {scene, "--quiet", "--set", "dem.pairs[7].friction=0.1"});
  CHECK(r.status == 2);
  CHECK_THAT(r.err, Catch::Contains("--set dem.pairs[7].friction=0.1: the scene has no "
                                    "'dem.pairs[7]'"));
  r = run(bad.path, {scene, "--quiet", "--set", "dem.backend=cuda"});
  CHECK(r.status == 2);
  CHECK_THAT(r.err, Catch::Contains("VALUE is not a TOML value"));
  CHECK(started_pids(r.out).empty());
}
