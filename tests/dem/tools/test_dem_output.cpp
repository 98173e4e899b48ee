// Particle output: HDF5 snapshots re-read, the XDMF index lists every snapshot, stays valid
// after each write, and resume() trims it.

#include <catch2/catch.hpp>

#include <fstream>
#include <sstream>

#include "demfem/dem/dem_output.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem::dem;
using demfem::io::H5File;
using demfem::test::TempDir;

namespace {

ParticleState make_state(std::size_t n, double shift) {
  ParticleState s;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = double(i) + shift;
    s.px.push_back(x);
    s.py.push_back(2 * x);
    s.pz.push_back(3 * x);
    s.vx.push_back(-x);
    s.vy.push_back(0.5);
    s.vz.push_back(0.25);
    s.wx.push_back(1);
    s.wy.push_back(2);
    s.wz.push_back(3);
    s.radius.push_back(0.001 * double(i + 1));
    s.mass.push_back(0.01);
    s.material.push_back(std::int32_t(i % 2));
  }
  return s;
}

std::string read_text(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::size_t occurrences(const std::string& s, const std::string& what) {
  std::size_t n = 0;
  for (auto p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

}  // namespace

TEST_CASE("particle snapshots re-read from HDF5 and indexed in XDMF", "[output]") {
  TempDir dir;
  ParticleOutput out(dir.path);
  const auto a = make_state(4, 0.0);
  const std::vector<std::int64_t> ids_a{10, 11, 12, 13};
  out.write(a, ids_a, 0.0);
  const auto b = make_state(3, 0.5);
  const std::vector<std::int64_t> ids_b{10, 12, 13};
  out.write(b, ids_b, 0.125);
  CHECK(out.count() == 2);

  H5File f(out.snapshot_path(1), H5File::Mode::read);
  std::vector<std::size_t> dims;
  const auto pos = f.read_doubles("position", &dims);
  REQUIRE(dims == std::vector<std::size_t>{3, 3});
  CHECK(pos[3] == 1.5);  // particle 1: x
  CHECK(pos[5] == 4.5);  // particle 1: z = 3 x
  const auto vel = f.read_doubles("velocity");
  CHECK(vel[3] == -1.5);
  CHECK(f.read_doubles("radius") == b.radius);
  CHECK(f.read_int64("id") == ids_b);
  CHECK(f.read_int64("material") == std::vector<std::int64_t>{0, 1, 0});
  CHECK(f.attribute_double("/", "time") == 0.125);
  CHECK(f.attribute_int64("/", "count") == 3);
  f.close();

  const std::string x = read_text(out.index_path());
  CHECK_THAT(x, Catch::Contains("<Xdmf Version=\"3.0\">"));
  CHECK_THAT(x, Catch::Contains("CollectionType=\"Temporal\""));
  CHECK(occurrences(x, "TopologyType=\"Polyvertex\"") == 2);
  CHECK_THAT(x, Catch::Contains("<Time Value=\"0.125\"/>"));
  CHECK_THAT(
      x, Catch::Contains("Dimensions=\"3 3\"") && Catch::Contains("particles_000001.h5:/position"));
  CHECK_THAT(x, Catch::Contains("</Xdmf>"));
  // No partial files left behind.
  for (const auto& e : std::filesystem::directory_iterator(dir.path))
    CHECK(e.path().extension() != ".part");

  // Resume after a restore to one snapshot: the index lists only the first.
  ParticleOutput again(dir.path);
  again.resume(1);
  CHECK(again.count() == 1);
  CHECK(occurrences(read_text(again.index_path()), "<Grid Name=\"step_") == 1);
  again.write(b, ids_b, 0.25);
  CHECK(occurrences(read_text(again.index_path()), "<Time Value=\"0.25\"/>") == 1);
  CHECK(again.count() == 2);
}
