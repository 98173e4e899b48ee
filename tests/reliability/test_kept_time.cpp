// [dem.load] keep_time under demfem run (docs/scene_dem.md, [dem.load]): a DEM-only scene that
// continues a saved state at the state's time runs from that time to run.end_time, an
// absolute time. Before, the run's clock started at 0 and took end_time's worth of coupling
// steps: the DEM went on past run.end_time, and coupling.csv's times differed from the DEM's
// sensors and state by the state's time. A chain of two small scenes (216 spheres settling in
// a box, then continued with the clock kept) run as a user runs them: real demfem_run
// processes in a folder of their own, and dem_server alone, which ends the same.
#include <catch2/catch.hpp>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "demfem/io/h5_file.hpp"
#include "demfem_test/box_scene.hpp"
#include "demfem_test/demfem_run.hpp"
#include "demfem_test/run_output.hpp"
#include "demfem_test/temp_dir.hpp"

namespace fs = std::filesystem;
using demfem::io::H5File;
using demfem::test::csv_column;
using demfem::test::Ended;
using demfem::test::read_csv;
using demfem::test::started_pids;
using demfem::test::TempDir;

namespace {

constexpr double kStateTime = 0.02;  // s: where the first scene ends and saves its state
constexpr double kEndTime = 0.0505;  // s: not a whole number of 1 ms slices after it

// The box of both scenes with 216 spheres of 6 mm (the first scene's lattice; the second
// loads them), and [run] with `run_keys`.
std::string box_scene(const std::string& run_keys, const std::string& particles) {
  demfem::test::BoxScene b;
  b.end_time = "";  // the [run] table below
  return "[run]\n" + run_keys + "\n" + b.text() + particles + "\n[dem.output]\nstate = true\n";
}

fs::path write(const fs::path& file, const std::string& text) {
  std::ofstream(file) << text;
  return file;
}

// prep.toml (settles to kStateTime) and load.toml (continues it, its clock kept, with a
// sensor and checkpoints) in `dir`; `load_extra` is appended to load.toml's [run].
fs::path write_chain(const fs::path& dir, const std::string& load_extra = "",
                     const std::string& load_tail = "") {
  write(dir / "prep.toml",
        box_scene("end_time = 0.02\noutput_dir = \"out/prep\"\n",
                  "\n[[dem.lattice]]\nmaterial = \"wheat\"\nlo = [0.0, 0.0, 0.0]\n"
                  "hi = [0.04, 0.04, 0.0361]\ndiameter = 0.006\nspacing = 0.006\n"));
  return write(dir / "load.toml",
               box_scene("end_time = 0.0505\noutput_dir = \"out/load\"\n" + load_extra +
                             "\n[checkpoint]\nevery_steps = 10\nkeep = 10\n",
                         "\n[dem.load]\nscene = \"prep.toml\"\nkeep_time = true\n"
                         "\n[[dem.sensors]]\nname = \"ke\"\nkind = \"kinetic_energy\"\n"
                         "interval = 0.005\n" +
                             load_tail));
}

Ended run(const fs::path& dir, std::vector<std::string> args) {
  args.push_back("--quiet");
  return demfem::test::run_demfem(dir, args);
}

// The DEM's end state of a run: its clock, and every particle array of DemSystem::save.
struct DemEnd {
  double time = 0.0;
  std::vector<std::vector<double>> arrays;
};

DemEnd dem_end(const fs::path& out) {
  const H5File h5(out / "dem_state.h5", H5File::Mode::read);
  DemEnd e;
  e.time = h5.attribute_double("/", "time");
  for (const char* a : {"px", "py", "pz", "vx", "vy", "vz", "wx", "wy", "wz"})
    e.arrays.push_back(h5.read_doubles(std::string("dem/") + a));
  return e;
}

// The simulated time a checkpoint's manifest records.
double manifest_time(const fs::path& checkpoint) {
  const std::string text = demfem::test::read_text(checkpoint / "manifest.json");
  const auto at = text.find("\"time\": ");
  return at == std::string::npos ? -1.0 : std::stod(text.substr(at + 8));
}

// coupling.csv and the sensor's series of two runs, cell for cell (wall-clock columns out).
void check_same_series(const fs::path& a, const fs::path& b) {
  for (const char* name : {"coupling.csv", "sensor_ke.csv"}) {
    INFO(name);
    CHECK(demfem::test::first_difference_but_wall_times(read_csv(a / name), read_csv(b / name)) ==
          "");
  }
}

}  // namespace

TEST_CASE(
    "keep_time under demfem run: the run's clock starts at the state's time and ends at "
    "run.end_time in every output, and --resume continues it bit for bit") {
  TempDir d;
  const fs::path scene = write_chain(d.path);
  const Ended r = run(d.path, {scene.string()});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  // 30 slices of 1 ms from 0.02 s, and the last cut to 0.5 ms.
  CHECK_THAT(r.out, Catch::Contains("31 coupling steps from t = 0.02 s (the DEM state's time) to "
                                    "t = 0.0505 s"));
  const fs::path out = d.path / "out/load";
  const auto t = csv_column(read_csv(out / "coupling.csv"), "time");
  REQUIRE(t.size() == 31);
  CHECK(t.front() == Approx(kStateTime + 0.001).margin(1e-12));
  CHECK(t.back() == Approx(kEndTime).margin(1e-12));
  {
    const H5File h5(out / "coupling.h5", H5File::Mode::read);
    CHECK(h5.attribute_int64("/", "steps") == 31);
    CHECK(h5.attribute_double("/", "time") == Approx(kEndTime).margin(1e-12));
  }
  // The DEM's own clock: its end state and its sensor, sampled from the state's time on.
  const DemEnd end = dem_end(out);
  CHECK(end.time == Approx(kEndTime).margin(1e-12));
  CHECK(end.time == Approx(t.back()).margin(1e-12));
  const auto ke = csv_column(read_csv(out / "sensor_ke.csv"), "time");
  REQUIRE(!ke.empty());
  CHECK(ke.front() >= kStateTime - 1e-9);
  CHECK(ke.front() < kStateTime + 0.005);
  CHECK(ke.back() <= kEndTime + 1e-12);
  CHECK(ke.back() > kEndTime - 0.005);
  // The checkpoints carry the run's times too: step 10 is t = 0.03 s.
  CHECK(manifest_time(out / "checkpoints/step-000010") == Approx(0.03).margin(1e-12));
  {
    INFO("dem_server alone runs the scene to the same end state, bit for bit");
    const Ended alone = demfem::test::wait_for(
        demfem::test::launch(d.path, {(demfem::test::kBin / "dem_server").string(), "--scene",
                                      scene.string(), "--output-dir", "out/alone"}));
    INFO(alone.out << alone.err);
    REQUIRE(alone.status == 0);
    const DemEnd by_itself = dem_end(d.path / "out/alone");
    CHECK(by_itself.time == end.time);
    CHECK(by_itself.arrays == end.arrays);
  }

  {
    INFO("SIGUSR2 half-way and --resume: the same bits as the run straight through");
    const std::vector<std::string> args = {scene.string(), "--output-dir", "out/cut"};
    std::vector<std::string> cut_args = args;
    cut_args.insert(cut_args.end(), {"--debug-kill", "job:14:usr2"});
    const Ended cut = run(d.path, cut_args);
    INFO(cut.out << cut.err);
    REQUIRE(cut.status == 128 + SIGUSR2);
    CHECK_THAT(cut.err, Catch::Contains("checkpoint of step 15 (t = 0.035 s) written on request"));
    std::vector<std::string> resume_args = args;
    resume_args.push_back("--resume");
    const Ended resumed = run(d.path, resume_args);
    INFO(resumed.out << resumed.err);
    REQUIRE(resumed.status == 0);
    CHECK_THAT(resumed.err, Catch::Contains("step-000015 (step 15, t = 0.035 s)"));
    const DemEnd again = dem_end(d.path / "out/cut");
    CHECK(again.time == end.time);
    CHECK(again.arrays == end.arrays);
    check_same_series(out, d.path / "out/cut");
  }
  {
    INFO("a checkpoint is not continued by a run whose clock starts elsewhere");
    const Ended e = run(d.path, {scene.string(), "--resume", "--set", "dem.load.keep_time=false"});
    INFO(e.out << e.err);
    CHECK(e.status == 2);
    CHECK_THAT(e.err, Catch::Contains("clock started at t = 0.02 s, this run's at t = 0 s"));
    CHECK(started_pids(e.out).empty());
  }
  {
    INFO("run.end_time before the state's time is refused naming it");
    const Ended e = run(d.path, {scene.string(), "--set", "run.end_time=0.015"});
    INFO(e.out << e.err);
    CHECK(e.status == 2);
    CHECK_THAT(e.err, Catch::Contains("key 'run.end_time'") &&
                          Catch::Contains("is not after t = 0.02 s") &&
                          Catch::Contains("key 'dem.load.keep_time'") &&
                          Catch::Contains("an absolute time"));
    CHECK(started_pids(e.out).empty());
  }
}

TEST_CASE(
    "keep_time is refused where the run's clock cannot follow the DEM's: with a [fem], "
    "with dem.settle_time") {
  // Refused from the keys, before the prepare scene runs (its state is never made here) and
  // before any process starts; --check says the same.
  TempDir d;
  const fs::path coupled =
      write_chain(d.path, "", "\n[fem]\ndt = 1e-4\n\n[coupling]\nscheme = \"just_in_time\"\n");
  for (const bool check : {false, true}) {
    INFO((check ? "--check" : "a run"));
    std::vector<std::string> args = {coupled.string()};
    if (check) args.push_back("--check");
    const Ended e = run(d.path, args);
    INFO(e.out << e.err);
    CHECK(e.status == 2);
    CHECK_THAT(e.err, Catch::Contains("load.toml:") &&
                          Catch::Contains("key 'dem.load.keep_time'") &&
                          Catch::Contains("[fem] starts at t = 0") &&
                          Catch::Contains("keep_time = false"));
    CHECK(started_pids(e.out).empty());
  }
  const fs::path settled = write_chain(d.path, "", "\n");
  const Ended e = run(d.path, {settled.string(), "--set", "dem.settle_time=0.01"});
  INFO(e.out << e.err);
  CHECK(e.status == 2);
  CHECK_THAT(e.err, Catch::Contains("key 'dem.load.keep_time'") &&
                        Catch::Contains("key 'dem.settle_time'") &&
                        Catch::Contains("0.01 s the DEM's clock runs on"));
  CHECK(started_pids(e.out).empty());
  CHECK_FALSE(fs::exists(d.path / "out/prep"));
  CHECK_FALSE(fs::exists(d.path / "out/load"));
}
