// dem_server as users run it: --help, a bad scene (exit 2, message naming file, line and
// key on stderr), and a small standalone run that writes particles and sensor series.

#include <catch2/catch.hpp>

#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "demfem_test/dem_material_text.hpp"
#include "demfem_test/temp_dir.hpp"

using demfem::test::TempDir;

namespace {

const std::filesystem::path kServer = std::filesystem::path(DEMFEM_BINARY_DIR) / "bin/dem_server";

struct Result {
  int code = -1;
  std::string out, err;
};

Result run(const std::string& args, const TempDir& dir) {
  const auto out = dir / "stdout.txt", err = dir / "stderr.txt";
  // Appended piecewise: GCC 12 warns falsely (-Wrestrict) on "'" + std::string&&.
  std::string cmd = "'";
  cmd += kServer.string();
  cmd += "' " + args + " >'";
  cmd += out.string();
  cmd += "' 2>'";
  cmd += err.string();
  cmd += "'";
  const int status = std::system(cmd.c_str());
  Result r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  auto slurp = [](const std::filesystem::path& p) {
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  };
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

const std::string kScene = std::string(R"([run]
end_time = 0.01
output_interval = 0.005

[dem]
dt = 1e-5
threads = 1

)") +
    demfem::test::dem_material("grain", "1e7", "1000.0") +
    demfem::test::dem_pair("grain", "grain", "0.5", "0.5") +
    R"(
[[dem.walls]]
name = "floor"
material = "grain"
plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0], size = 0.2 }

[[dem.insert]]
material = "grain"
lo = [-0.02, -0.02, 0.0]
hi = [0.02, 0.02, 0.03]
count = 50
distribution = { kind = "constant", diameter = 0.004 }

[[dem.sensors]]
name = "ke"
kind = "kinetic_energy"
interval = 0.001
)";

}  // namespace

TEST_CASE("dem_server: help, bad scene, standalone run", "[server]") {
  if (!std::filesystem::exists(kServer)) {
    WARN("dem_server is not built (" << kServer << "); build the dem_server target");
    return;
  }
  TempDir dir;
  const Result help = run("--help", dir);
  CHECK(help.code == 0);
  CHECK_THAT(help.out, Catch::Contains("--scene") && Catch::Contains("--segment") &&
                           Catch::Contains("--output-dir"));

  std::string bad = kScene;
  bad.replace(bad.find("restitution = 0.5"), 17, "restitution = 0.5\nrolling_fricton = 0.1");
  const auto line_no =
      1 + std::count(bad.begin(), bad.begin() + long(bad.find("rolling_fricton")), '\n');
  std::ofstream(dir / "bad.toml") << bad;
  const Result b = run("--scene '" + (dir / "bad.toml").string() + "'", dir);
  CHECK(b.code == 2);
  CHECK_THAT(b.err, Catch::Contains("bad.toml:" + std::to_string(line_no) + ":") &&
                        Catch::Contains("key 'dem.pairs[0].rolling_fricton': is not a known key"));

  // An impossible size is bad input found before anything is allocated: exit 2 at once,
  // naming the key (it used to start and die of bad_alloc with no key named).
  std::string huge = kScene;
  huge.replace(huge.find("count = 50"), 10, "count = 5000000000000");
  std::ofstream(dir / "huge.toml") << huge;
  const Result h = run("--scene '" + (dir / "huge.toml").string() + "'", dir);
  CHECK(h.code == 2);
  CHECK_THAT(h.err, Catch::Contains("key 'dem.insert[0].count'") &&
                        Catch::Contains("about 5e+12 particles"));

  std::ofstream(dir / "good.toml") << kScene;
  const Result g = run("--scene '" + (dir / "good.toml").string() + "' --output-dir '" +
                           (dir / "out").string() + "'",
                       dir);
  CHECK(g.code == 0);
  CHECK_THAT(g.out, Catch::Contains("Rayleigh time step") && Catch::Contains("dem: done"));
  // Snapshots at 0, 0.005, 0.01 s; kinetic energy every 1 ms from 0 to 0.01 s.
  CHECK(std::filesystem::exists(dir / "out" / "particles_000002.h5"));
  CHECK_FALSE(std::filesystem::exists(dir / "out" / "particles_000003.h5"));
  std::ifstream csv(dir / "out" / "sensor_ke.csv");
  std::string line;
  int rows = -1;
  while (std::getline(csv, line)) ++rows;
  CHECK(rows == 11);
}
