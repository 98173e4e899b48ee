// Frozen particles (DemSystem::freeze): held bitwise where they are, felt by the others, their
// holding force the weight of what rests on them, and a saved and restored state continues
// bitwise.

#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem_test/cube_shape.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;

namespace {

constexpr double kG = 9.81;

// Cubes of half extent 5 mm (the test cube core 0.3 + dilation 0.2, at scale 0.01): A and B
// side by side, touching (0.1 mm overlap), C just above A. A and B are frozen from the
// start, so C settles on A, and the A-B pair (both frozen) is never computed.
DemSystem cube_stack() {
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.3, 0.5, 2e-6);
  s.gravity = {0, 0, -kG};
  DemSystem sys(s);
  const auto id = sys.add_shape(demfem::test::cube_shape());
  std::vector<ParticleInit> p(3);
  for (auto& q : p) {
    q.shape = ParticleShape::polyhedron;
    q.shape_id = id;
    q.scale = 0.01;
    q.material = 0;
  }
  p[0].position = {0.0, 0.0, 0.0};
  p[1].position = {0.0099, 0.0, 0.0};
  p[2].position = {0.0, 0.0, 0.0101};
  sys.add_particles(p);
  const std::vector<std::uint8_t> mask{1, 1, 0};
  sys.freeze(mask);
  return sys;
}

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

}  // namespace

TEST_CASE("Frozen particles are held, carry what rests on them, and restore bitwise",
          "[dem][frozen]") {
  DemSystem sys = cube_stack();
  const ParticleState start = sys.particles();
  REQUIRE(sys.frozen_count() == 2);
  sys.advance(50000);  // 0.1 s: C falls 0.1 mm onto A and comes to rest (e = 0.3)
  const ParticleState& p = sys.particles();
  // A and B: not moved by a bit, at rest (C presses on A, A and B overlap)
  for (std::size_t i : {0u, 1u}) {
    CHECK(p.px[i] == start.px[i]);
    CHECK(p.py[i] == start.py[i]);
    CHECK(p.pz[i] == start.pz[i]);
    CHECK(p.qw[i] == start.qw[i]);
    CHECK(p.qx[i] == start.qx[i]);
    CHECK(p.vz[i] == 0.0);
    CHECK(p.wx[i] == 0.0);
  }
  // C rests on A: its top face 10 mm above A's (less the contact's overlap)
  CHECK(p.pz[2] == Approx(0.01).margin(1e-4));
  CHECK(std::abs(p.vz[2]) < 1e-4);
  // Reference: statics. The holding force carries A, B and C: (m_A + m_B + m_C) g upwards,
  // within 1e-6 relative (C at rest; A-B is a pair of frozen particles, not computed: its
  // forces would cancel in the sum anyway).
  const double weight = (p.mass[0] + p.mass[1] + p.mass[2]) * kG;
  const auto support = sys.frozen_support();
  CHECK(support[2] == Approx(weight).epsilon(1e-6));
  CHECK(std::abs(support[0]) < 1e-6 * weight);
  CHECK(std::abs(support[1]) < 1e-6 * weight);

  SECTION("save and restore continue bitwise") {
    const auto dir = std::filesystem::temp_directory_path() / "demfem_test_frozen";
    std::filesystem::create_directories(dir);
    DemSystem ref = cube_stack();
    ref.advance(3000);  // mid-fall
    {
      demfem::io::H5File h5(dir / "s.h5", demfem::io::H5File::Mode::create);
      ref.save(h5, "/dem");
    }
    DemSystem other = cube_stack();
    other.freeze(std::vector<std::uint8_t>{0, 0, 1});  // differs: replaced by the saved mask
    {
      demfem::io::H5File h5(dir / "s.h5", demfem::io::H5File::Mode::read);
      other.restore(h5, "/dem");
    }
    REQUIRE(other.frozen_count() == 2);
    ref.advance(2000);
    other.advance(2000);
    CHECK(same_bits(ref.particles().pz, other.particles().pz));
    CHECK(same_bits(ref.particles().vz, other.particles().vz));
    CHECK(same_bits(ref.particles().qx, other.particles().qx));
    CHECK(ref.frozen_support() == other.frozen_support());
    // in memory (a coupling step's save point) too
    DemStateCopy copy;
    ref.save_state(copy);
    const auto z = ref.particles().pz;
    ref.advance(100);
    ref.restore_state(copy);
    ref.advance(100);
    other.advance(100);
    CHECK(same_bits(ref.particles().pz, other.particles().pz));
    std::filesystem::remove_all(dir);
  }
  SECTION("a removed particle's mask entry goes with it; a mask of another size is refused") {
    sys.remove_particles(std::vector<std::uint8_t>{1, 0, 1});
    REQUIRE(sys.particle_count() == 2);
    CHECK(sys.frozen_count() == 1);
    CHECK(sys.frozen()[0] == 1);
    CHECK(sys.frozen()[1] == 0);
    CHECK_THROWS_WITH(sys.freeze(std::vector<std::uint8_t>{1, 1, 1}),
                      Catch::Contains("mask has 3 entries, need 2"));
  }
}

TEST_CASE("Frozen spheres carry the sphere that rests in their pocket", "[dem][frozen]") {
  // Three frozen spheres of 2 mm in a touching triangle, a fourth dropped into the pocket
  // above them (a stable rest: the tetrahedron's apex).
  auto s = two_material_settings(1e7, 0.3, 2500.0, 0.3, 0.5, 1e-5);
  s.gravity = {0, 0, -kG};
  DemSystem sys(s);
  const double r = 0.002, h = 2.0 * r * std::sqrt(2.0 / 3.0);
  sys.add_particles(std::vector<ParticleInit>{sphere({0, 0, 0}, r), sphere({2 * r, 0, 0}, r),
                                              sphere({r, std::sqrt(3.0) * r, 0}, r),
                                              sphere({r, r / std::sqrt(3.0), h + 1e-5}, r)});
  sys.freeze(std::vector<std::uint8_t>{1, 1, 1, 0});
  sys.advance(100000);  // 1 s
  const auto& p = sys.particles();
  CHECK(p.pz[0] == 0.0);
  CHECK(p.px[1] == 2 * r);
  CHECK(std::abs(p.vz[3]) < 1e-6);
  CHECK(p.pz[3] < h);  // it rests on the three, pressed into them
  // Reference: statics, the four weights, within 1e-6 relative.
  double weight = 0.0;
  for (double m : p.mass) weight += m * kG;
  CHECK(sys.frozen_support()[2] == Approx(weight).epsilon(1e-6));
}
