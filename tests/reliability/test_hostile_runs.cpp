// Hostile use of a run as a whole (issue 19; docs/reports/reliability_history.md, "Hostile tests"): two runs
// in one folder, signals and a killed coupler inside a long coupling step, a solver that never
// attaches, impossible step counts, bad input found before any process starts, resumes that
// must be refused, the run record. Every run is a real demfem_run with real solver processes;
// each test takes a few seconds at most.
#include <catch2/catch.hpp>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "demfem/coupling/checkpoint.hpp"
#include "demfem/io/h5_file.hpp"
#include "hdf5_patch.hpp"
#include "demfem_test/box_scene.hpp"
#include "demfem_test/dem_material_text.hpp"
#include "hostile_run.hpp"

using namespace hostile;  // NOLINT: the shared helpers of hostile_run.hpp

TEST_CASE("two runs into one output folder: the second is refused naming the first's pid") {
  // Issue 19, defect 1: two runs into one folder gave missing CSV rows and zeroed HDF5 data
  // with both exiting 0.
  TempDir d;
  const fs::path shared_cp = d.path / "shared_checkpoints";
  const fs::path scene =
      variant(d.path, "long_step.toml",
              {{"dt = 2e-6                  # s; Rayleigh", "dt = 1e-10                 # s"},
               {"max_retries = 3", "max_retries = 3\ndirectory = \"" + shared_cp.string() + "\""}});
  const Launched first = start(d.path, {scene.string()});
  REQUIRE(eventually([&] { return fs::exists(shared_cp / "step-000000/manifest.json"); }, 30s));
  const std::string pid = std::to_string(first.pid);
  // Its solvers, read now: the runs below share the working folder, so its stdout.txt is
  // overwritten before it ends.
  const std::string first_out = read_text(d.path / "stdout.txt");
  REQUIRE(started_pids(first_out).size() == 2);
  {
    INFO("a second run into the same output folder");
    TempDir d2;
    const Ended second = run(d2.path, {scene.string(), "--output-dir", (d.path / kOut).string()});
    INFO(second.out << second.err);
    CHECK(second.status == 2);
    CHECK_THAT(second.err, Catch::Contains(kOut) && Catch::Contains("is in use by process " + pid));
    CHECK(started_pids(second.out).empty());
  }
  {
    INFO("the same with --in-process and with --resume");
    for (const char* how : {"--in-process", "--resume"}) {
      const Ended again = run(d.path, {scene.string(), how});
      INFO(how << "\n" << again.out << again.err);
      CHECK(again.status == 2);
      CHECK_THAT(again.err, Catch::Contains("is in use by process " + pid));
    }
  }
  {
    INFO("a solver run alone (no coupler) into the same folder");
    const Ended alone = demfem::test::wait_for(demfem::test::launch(
        d.path, {(kBin / "dem_server").string(), "--scene", scene.string(), "--output-dir",
                 (d.path / kOut).string(), "--quiet"}));
    INFO(alone.out << alone.err);
    CHECK(alone.status == 2);
    CHECK_THAT(alone.err, Catch::Contains("is in use by process " + pid));
  }
  {
    INFO("another output folder, but the same checkpoint.directory");
    const Ended other = run(d.path, {scene.string(), "--output-dir", "out/other"});
    INFO(other.out << other.err);
    CHECK(other.status == 2);
    CHECK_THAT(other.err, Catch::Contains("shared_checkpoints is in use by process " + pid));
  }
  // The first run is not disturbed: its files are its own. Killed, it leaves no stale lock.
  CHECK_FALSE(gone(first.pid));
  ::kill(first.pid, SIGKILL);
  const Ended killed = demfem::test::wait_for(first);
  CHECK(killed.status == 128 + SIGKILL);
  check_nothing_left(first_out);  // orphans still writing would mix into the next run's stderr
  CHECK(record_field(d.path / kOut, "status") == "running");  // it had no chance to say more
  const Ended after = run(d.path, {kCase.string()});
  INFO(after.out << after.err);
  CHECK(after.status == 0);
  CHECK_THAT(after.err, Catch::Contains("the previous run in " + std::string(kOut) + " (pid " +
                                        pid + ", started ") &&
                            Catch::Contains("ended without writing its end to run.json"));
  CHECK(record_field(d.path / kOut, "status") == "completed");
}

TEST_CASE("SIGTERM to the launcher inside a step of 10^6 substeps ends every process in seconds") {
  // Issue 19, defect 3: the signal used to wait for the end of the step (with dem.dt = 1e-20,
  // the launcher was alive 11 minutes after SIGTERM).
  TempDir d;
  const Launched l = start(d.path, {long_step_scene(d.path).string()});
  wait_inside_first_step(d.path / kOut);
  const auto t0 = std::chrono::steady_clock::now();
  ::kill(l.pid, SIGTERM);
  const Ended r = demfem::test::wait_for(l);
  const double secs = seconds_since(t0);
  INFO(r.out << r.err);
  CHECK(r.status == 128 + SIGTERM);
  CHECK(secs < 5.0);  // the step alone takes tens of seconds
  check_nothing_left(r.out, 1s);
  CHECK(record_field(d.path / kOut, "status") == "interrupted");
  CHECK(record_field(d.path / kOut, "signal") == "15");
  CHECK(record_field(d.path / kOut, "exit_code") == "143");
  // Nothing of the cut step was passed off as a result: coupling.csv has no row of step 0.
  CHECK(demfem::test::read_csv(d.path / kOut / "coupling.csv").size() == 1);
}

TEST_CASE("Ctrl-C of an --in-process run inside a long step ends it in seconds") {
  TempDir d;
  const Launched l = start(d.path, {long_step_scene(d.path).string(), "--in-process"}, true);
  wait_inside_first_step(d.path / kOut);
  const auto t0 = std::chrono::steady_clock::now();
  ::kill(-l.pid, SIGINT);  // the terminal's Ctrl-C: the whole process group
  const Ended r = demfem::test::wait_for(l);
  INFO(r.out << r.err);
  CHECK(r.status == 128 + SIGINT);
  CHECK(seconds_since(t0) < 5.0);
  CHECK(record_field(d.path / kOut, "status") == "interrupted");
}

TEST_CASE("kill -9 of the coupler inside a long step: the solvers notice and exit in seconds") {
  // Issue 19, defect 3: dem_server ran on at 100 % CPU as an orphan until its step ended.
  TempDir d;
  const Launched l = start(d.path, {long_step_scene(d.path).string()});
  wait_inside_first_step(d.path / kOut);
  const auto solvers = started_pids(read_text(d.path / "stdout.txt"));
  REQUIRE(solvers.size() == 2);
  const auto t0 = std::chrono::steady_clock::now();
  ::kill(l.pid, SIGKILL);
  const Ended r = demfem::test::wait_for(l);
  CHECK(r.status == 128 + SIGKILL);
  // peer_timeout is 2 s; a dead pid is seen within one check slice (100 ms).
  for (pid_t p : solvers) {
    INFO("solver " << p);
    CHECK(eventually([&] { return gone(p); }, 3s));
  }
  CHECK(seconds_since(t0) < 3.0);
  check_nothing_left(r.out, 1s);  // the solvers removed the dead coupler's segments
  CHECK_THAT(read_text(d.path / "stderr.txt"), Catch::Contains("the coupler died"));
}

TEST_CASE("a solver that starts but never attaches is killed after --hello-timeout (exit 1)") {
  // Issue 19, defect 11. The "solver" is a shell script that sleeps: it starts and never
  // attaches to the segment.
  TempDir d;
  const fs::path bin = d.path / "bin";
  fs::create_directories(bin);
  fs::create_symlink(kBin / "fem_server", bin / "fem_server");
  std::ofstream(bin / "dem_server") << "#!/bin/sh\nexec sleep 60\n";
  fs::permissions(bin / "dem_server", fs::perms::owner_all);
  const auto t0 = std::chrono::steady_clock::now();
  const Ended r = demfem::test::wait_for(
      demfem::test::launch(d.path, {(kBin / "demfem_run").string(), "--bin-dir", bin.string(),
                                    "--quiet", "--hello-timeout", "1", kCase.string()}));
  INFO(r.out << r.err);
  CHECK(r.status == 1);
  CHECK(seconds_since(t0) < 8.0);
  const auto pids = started_pids(r.out);
  REQUIRE(pids.size() == 2);
  CHECK_THAT(r.err, Catch::Contains("the DEM solver (dem_server, pid " + std::to_string(pids[1]) +
                                    ") did not attach within 1") &&
                        Catch::Contains("it was killed"));
  check_nothing_left(r.out, 3s);
  CHECK(record_field(d.path / kOut, "status") == "failed");
}

TEST_CASE("bad input is refused with exit 2 before any process starts and names the key") {
  // Issue 19, defects 5, 8 and 13: these were found after the solvers had started (exit 1),
  // or not at all.
  TempDir d;
  struct Case {
    const char* what;
    std::vector<std::pair<std::string, std::string>> subs;
    const char* expect;
  };
  const Case cases[] = {
      {"end_time = 1e300",
       {{"end_time = 0.005 ", "end_time = 1e300 "}},
       "key 'run.end_time' = 1e+300 s"},
      {"dem.dt = 1e-20", {{"dt = 2e-6  ", "dt = 1e-20  "}}, "DEM substeps per coupling step"},
      {"dt above the Rayleigh time step",
       {{"dt = 2e-6  ", "dt = 1e-4  "}},
       "key 'dem.dt': dt = 0.0001 s exceeds the Rayleigh time step"},
      {"a missing STL file",
       {{"[[dem.sensors]]",
         "[[dem.walls]]\nstl = \"missing.stl\"\nmaterial = \"steel\"\n\n"
         "[[dem.sensors]]"}},
       "missing.stl"},
      {"run.name = ../../x",
       {{"name = \"beam_checkpoint_ci\"", "name = \"../../x\""}},
       "key 'run.name': '../../x' starts with '.'"},
  };
  for (const auto& c : cases) {
    INFO(c.what);
    const fs::path scene = variant(d.path, "bad.toml", c.subs);
    const Ended r = run(d.path, {scene.string()});
    INFO(r.out << r.err);
    CHECK(r.status == 2);
    CHECK_THAT(r.err, Catch::Contains("bad.toml:") && Catch::Contains(c.expect));
    CHECK(started_pids(r.out).empty());
  }
  CHECK_FALSE(fs::exists(d.path / "x"));
  // An output folder that cannot be created: its parent is a file.
  std::ofstream(d.path / "a_file") << "x";
  const Ended r = run(d.path, {kCase.string(), "--output-dir", (d.path / "a_file/out").string()});
  INFO(r.out << r.err);
  CHECK(r.status == 2);
  CHECK_THAT(r.err, Catch::Contains("a_file/out") && Catch::Contains("Not a directory") &&
                        Catch::Contains("choose a writable folder"));
  CHECK(started_pids(r.out).empty());
}

TEST_CASE("an unstable DEM exits with status 3 as a blow-up") {
  // Issue 19, defect 8: DEM instability exited 1. 32 spheres hit a plane at 300 m/s with
  // dem.dt at 0.8 of the Rayleigh time step: they sink through each other and the wall.
  TempDir d;
  std::ofstream(d.path / "unstable.toml") << std::string(R"([run]
end_time = 0.002
[dem]
dt = 2.4e-5
)") +
    demfem::test::dem_material("sphere", "210e9", "44037.0") +
    demfem::test::dem_pair("sphere", "sphere", "0.0", "0.1") +
    R"([[dem.walls]]
plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0], size = 1.0 }
material = "sphere"
[[dem.lattice]]
material = "sphere"
lo = [0.0, 0.0, 0.0001]
hi = [0.1, 0.1, 0.05]
diameter = 0.024
spacing = 0.025
velocity = [0.0, 0.0, -300.0]
)";
  for (const bool in_process : {false, true}) {
    INFO((in_process ? "in process" : "three processes"));
    std::vector<std::string> args = {(d.path / "unstable.toml").string()};
    if (in_process) args.push_back("--in-process");
    const Ended r = run(d.path, args);
    INFO(r.out << r.err);
    CHECK(r.status == 3);
    CHECK_THAT(r.err, Catch::Contains("blow-up: the DEM solver failed in coupling step 0") &&
                          Catch::Contains("the DEM blew up: DEM run unstable") &&
                          Catch::Contains("unstable.toml:4:6: key 'dem.dt'"));
    CHECK(record_field(d.path / "out/unstable", "status") == "failed");
    CHECK(record_field(d.path / "out/unstable", "exit_code") == "3");
    check_nothing_left(r.out);
  }
}

TEST_CASE("resume messages name a missing folder and a scene without a checkpoint section") {
  // Issue 19, defect 9.
  TempDir d;
  Ended r = run(d.path, {kCase.string(), "--resume", "/nonexistent/step-000010"});
  CHECK(r.status == 2);
  CHECK_THAT(r.err, Catch::Contains("--resume /nonexistent/step-000010: no such folder"));
  std::string text = read_text(kCase);
  text.erase(text.find("[checkpoint]"), text.find("[coupling]") - text.find("[checkpoint]"));
  std::ofstream(d.path / "plain.toml") << text;
  r = run(d.path, {(d.path / "plain.toml").string(), "--resume"});
  CHECK(r.status == 2);
  CHECK_THAT(r.err, Catch::Contains("plain.toml has no [checkpoint] section"));
  CHECK(started_pids(r.out).empty());
}

TEST_CASE("run.json tells how a run ended and a fresh start clears only demfem's files") {
  // Issue 19, defect 10.
  TempDir d;
  const fs::path out = d.path / kOut;
  fs::create_directories(out);
  // An earlier run with other output settings, and a file of the user's.
  for (const char* stale :
       {"particles_000099.h5", "sensor_old.csv", "fem_000123.h5", "coupling.h5.part"}) {
    std::ofstream(out / stale) << "old";
  }
  std::ofstream(out / "notes.txt") << "mine";
  const Ended r = run(d.path, {kCase.string()});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  CHECK_THAT(r.err, Catch::Contains("removed 4 files of an earlier run"));
  for (const char* stale :
       {"particles_000099.h5", "sensor_old.csv", "fem_000123.h5", "coupling.h5.part"}) {
    INFO(stale);
    CHECK_FALSE(fs::exists(out / stale));
  }
  CHECK(read_text(out / "notes.txt") == "mine");
  CHECK(record_field(out, "format") == "demfem-run-1");
  CHECK(record_field(out, "status") == "completed");
  CHECK(record_field(out, "exit_code") == "0");
  CHECK(record_field(out, "reason") == "null");
  CHECK(record_field(out, "scene") == kCase.string());
  CHECK(record_field(out, "scene_hash") == [] {
    char h[17];
    std::snprintf(h, sizeof h, "%016llx",
                  static_cast<unsigned long long>(demfem::coupling::fnv1a64_file(kCase)));
    return std::string(h);
  }());
  CHECK(record_field(out, "steps_done") == "50");
  CHECK(record_field(out, "step_count") == "50");
  CHECK(std::regex_match(record_field(out, "git_commit"), std::regex("[0-9a-f]{40}|unknown")));
  CHECK(record_field(out, "demfem_version") == "0.1.0");
  CHECK(record_field(out, "dem_threads") != "null");
  CHECK(std::regex_match(record_field(out, "start_time"),
                         std::regex("\\d{4}-\\d\\d-\\d\\dT\\d\\d:\\d\\d:\\d\\dZ")));
  CHECK(std::regex_match(record_field(out, "end_time"),
                         std::regex("\\d{4}-\\d\\d-\\d\\dT\\d\\d:\\d\\d:\\d\\dZ")));
  CHECK(record_field(out, "mode") == "three processes");
  CHECK_THAT(read_text(out / "run.json"), Catch::Contains("\"sensor_old.csv\""));
}

TEST_CASE("resume refuses a checkpoint whose state or scene cannot be continued (exit 2)") {
  // Issue 19, defect 7: a changed particle count was accepted, and a checkpoint with NaN
  // positions (its manifest matching) resumed to exit 0. Defect 8: a changed mesh exited 1.
  TempDir d;
  const fs::path out = d.path / kOut;
  REQUIRE(run(d.path, {kCase.string()}).status == 0);
  const fs::path cp40 = out / "checkpoints" / "step-000040";
  const std::vector<std::string> parts = {"dem.h5", "fem.h5", "coupler.h5"};
  auto damaged = [&](const std::string& name) {
    const fs::path cp = d.path / name;
    fs::remove_all(cp);
    fs::copy(cp40, cp);
    return cp;
  };
  {
    INFO("NaN positions in dem.h5, manifest rewritten to match");
    const fs::path cp = damaged("nan_dem");
    demfem::test::overwrite_doubles(cp / "dem.h5", "dem/pz", 7, std::nan(""));
    demfem::coupling::commit_checkpoint(cp, 40, 0.004, "just_in_time", parts);
    const Ended r = run(d.path, {kCase.string(), "--resume", cp.string()});
    INFO(r.out << r.err);
    CHECK(r.status == 2);
    CHECK_THAT(r.err, Catch::Contains("nan_dem/dem.h5") &&
                          Catch::Contains("particle 7: position z is nan"));
    check_nothing_left(r.out);
    CHECK(record_field(out, "status") == "failed");
    CHECK(record_field(out, "exit_code") == "2");
  }
  {
    INFO("an infinite velocity in fem.h5");
    const fs::path cp = damaged("inf_fem");
    demfem::test::overwrite_doubles(cp / "fem.h5", "fem/v", 30, INFINITY);
    demfem::coupling::commit_checkpoint(cp, 40, 0.004, "just_in_time", parts);
    const Ended r = run(d.path, {kCase.string(), "--resume", cp.string()});
    INFO(r.out << r.err);
    CHECK(r.status == 2);
    CHECK_THAT(r.err,
               Catch::Contains("inf_fem/fem.h5") && Catch::Contains("fem/v[30] is not finite"));
  }
  {
    INFO("a changed particle count: refused before any process starts");
    const fs::path scene =
        variant(d.path, "fewer.toml", {{"hi = [1.0, 0.1, 0.1245]", "hi = [0.5, 0.1, 0.1245]"}});
    const Ended r = run(d.path, {scene.string(), "--resume", cp40.string(), "--output-dir",
                                 (d.path / kOut).string()});
    INFO(r.out << r.err);
    CHECK(r.status == 2);
    CHECK_THAT(r.err, Catch::Contains("made 160 particles at set-up") &&
                          Catch::Contains("fewer.toml makes 80"));
    CHECK(started_pids(r.out).empty());
  }
  {
    INFO("a changed mesh");
    const fs::path scene =
        variant(d.path, "coarser.toml", {{"cells = [20, 2, 2]", "cells = [10, 2, 2]"}});
    const Ended r = run(d.path, {scene.string(), "--resume", cp40.string(), "--output-dir",
                                 (d.path / kOut).string()});
    INFO(r.out << r.err);
    CHECK(r.status == 2);
    CHECK_THAT(r.err, Catch::Contains("the checkpoint's FEM mesh has 189 nodes and 80 elements") &&
                          Catch::Contains("coarser.toml has 99 and 40"));
    CHECK(started_pids(r.out).empty());
  }
  {
    INFO("another interface surface (same mesh): refused by the coupler's own check");
    const fs::path scene =
        variant(d.path, "surface.toml",
                {{"interface_surface = \"z >= 0.1\"", "interface_surface = \"z >= 0.05\""}});
    const Ended r = run(d.path, {scene.string(), "--resume", cp40.string(), "--output-dir",
                                 (d.path / kOut).string()});
    INFO(r.out << r.err);
    CHECK(r.status == 2);
    CHECK_THAT(r.err, Catch::Contains("cannot be resumed") &&
                          Catch::Contains("the checkpoint's interface has 63 nodes") &&
                          Catch::Contains("the FEM mesh or fem.interface_surface changed"));
    CHECK_THAT(r.err, Catch::Contains("the scene differs from the one checkpoint"));
    check_nothing_left(r.out);
  }
}

TEST_CASE("SIGTERM to the launcher while a prepare scene runs ends that run too") {
  // 2026-12-02: a stop signal during a [dem.load] preparation ended the launcher only; the
  // prepare run went on with its dem_server and segment to the end of its scene.
  TempDir d;
  demfem::test::BoxScene box;
  box.end_time = "0.02";
  const std::string lattice = R"(
[[dem.lattice]]
material = "wheat"
lo = [0.005, 0.005, 0.005]
hi = [0.035, 0.035, 0.03]
diameter = 0.004
spacing = 0.005
)";
  {
    std::ofstream prep(d.path / "prep.toml");  // settles for ever (10^8 steps)
    std::string t = box.text();
    t.replace(t.find("threads = 1\n"), 12, "threads = 1\nsettle_time = 1000.0\n");
    prep << t << lattice << "\n[dem.output]\nstate = true\n";
  }
  {
    std::ofstream top(d.path / "top.toml");
    top << box.text() << "\n[dem.load]\nscene = \"prep.toml\"\n";
  }
  const Launched l = start(d.path, {(d.path / "top.toml").string()});
  REQUIRE(eventually(
      [&] { return !started_pids(read_text(d.path / "stdout.txt")).empty(); }, 30s));
  std::this_thread::sleep_for(500ms);  // the prepare run's dem_server is settling
  const std::string before = read_text(d.path / "stdout.txt");
  const auto t0 = std::chrono::steady_clock::now();
  ::kill(l.pid, SIGTERM);
  const Ended r = demfem::test::wait_for(l);
  INFO(r.out << r.err);
  CHECK(r.status == 128 + SIGTERM);
  CHECK(seconds_since(t0) < 5.0);
  check_nothing_left(before + r.out);  // the prepare run's dem_server and its segments
  // and no process of the prepare scene is left (its own demfem_run included)
  CHECK(eventually(
      [&] {
        for (const auto& e : fs::directory_iterator("/proc")) {
          const std::string name = e.path().filename().string();
          if (name.find_first_not_of("0123456789") != std::string::npos) continue;
          std::ifstream in(e.path() / "cmdline");
          const std::string cmd((std::istreambuf_iterator<char>(in)), {});
          if (cmd.find((d.path / "prep.toml").string()) != std::string::npos) return false;
        }
        return true;
      },
      5s));
}
