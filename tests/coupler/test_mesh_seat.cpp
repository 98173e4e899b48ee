// fem.mesh.seat (coupler/src/launch/mesh_seat.hpp): the FEM mesh placed `gap` above the
// highest particle top of a prepared bed under its footprint, and fem.mesh.translate, which
// carries the result to the FEM reader. A bed of spheres with known tops (z + r): one under
// the footprint, a higher one whose centre lies just outside it but whose body reaches under
// it, and a still higher one far away that must not count. The expected tops are written
// out from the CSV's numbers, independently of the packing measurement.

#include <catch2/catch.hpp>

#include <algorithm>
#include <fstream>
#include <string>

#include "demfem/fem/fem_scene.hpp"
#include "demfem/scene/scene_reader.hpp"
#include "demfem_test/box_scene.hpp"
#include "demfem_test/error_of.hpp"
#include "demfem_test/temp_dir.hpp"
#include "launch/mesh_seat.hpp"

using namespace demfem;
using namespace demfem::coupling::launch;
using demfem::scene::Document;
using demfem::scene::Override;
using demfem::scene::SceneError;
using demfem::test::TempDir;

namespace {

// Spheres of r = 0.01 m: under the footprint (x, y in [0.2, 0.4]) tops 0.11 and 0.16 m; at
// x = 0.195 (5 mm outside it, reaching 5 mm under it) top 0.21 m; far away top 0.51 m.
const char* kBed =
    "x,y,z,r\n"
    "0.30,0.30,0.10,0.01\n"
    "0.25,0.35,0.15,0.01\n"
    "0.195,0.30,0.20,0.01\n"
    "0.55,0.55,0.50,0.01\n";

std::string scene_text(const std::string& seat, const std::string& mesh_lo = "[0.2, 0.2, 1.0]",
                       const std::string& mesh_hi = "[0.4, 0.4, 1.1]",
                       const std::string& load = "[dem.load]\nfile = \"bed.csv\"\nmaterial = "
                                                 "\"rock\"\n") {
  std::string t = test::rock_box("[0.6, 0.6, 2.0]").text();
  t += load;
  t += "\n[fem]\nanalysis = \"static\"\n\n[fem.mesh]\nbox = { lo = " + mesh_lo + ", hi = " +
       mesh_hi + ", cells = [2, 2, 1] }\n" + seat;
  t += "\n[[fem.materials]]\nname = \"timber\"\nyoungs_modulus = 9e9\npoisson_ratio = 0.35\n"
       "density = 800.0\n";
  // a selector written for the file's coordinates: the bottom nodes (z = 1.0 there)
  t += "\n[[fem.clamps]]\nnodes = \"z <= 1.0001\"\ndofs = [\"x\", \"y\", \"z\"]\n";
  return t;
}

Document write_scene(const TempDir& dir, const std::string& text,
                     const std::vector<Override>& overrides = {}) {
  std::ofstream(dir / "bed.csv") << kBed;
  std::ofstream(dir / "scene.toml") << text;
  return Document::load(dir / "scene.toml", overrides);
}

std::string seat_error(const TempDir& dir, const std::string& text) {
  return test::error_of<SceneError>([&] { resolve_mesh_seat(write_scene(dir, text), 1); },
                                    "(no error)");
}

}  // namespace

TEST_CASE("mesh seat: the mesh's bottom lands gap above the highest top under it", "[launch]") {
  TempDir dir("mesh_seat");
  const std::string seat = "\n[fem.mesh.seat]\ngap = 0.004\n";
  const Document doc = write_scene(dir, scene_text(seat));
  const auto s = resolve_mesh_seat(doc, 1);
  REQUIRE(s);
  REQUIRE(s->computed);
  // Default margin: the largest particle's radius, so the sphere reaching in from x = 0.195
  // counts (3 of the 4; the far one does not)
  CHECK(s->margin == 0.01);
  CHECK(s->particles == 3);
  CHECK(s->bed_top == 0.20 + 0.01);
  CHECK(s->mesh_bottom == 1.0);
  CHECK(s->dz == Approx(0.214 - 1.0).margin(1e-15));

  // The FEM reader with the launcher's override: the whole mesh moved by dz, the selector
  // written for the file still choosing the bottom nodes (3 x 3 of the 2 x 2 x 1 box)
  std::vector<Override> with = {Override::parse(s->override_text())};
  const Document moved = write_scene(dir, scene_text(seat), with);
  const fem::FemScene fs = fem::read_fem_scene(*moved.root().table("fem"));
  double lo = 1e9, hi = -1e9;
  for (const auto& x : fs.problem.mesh.nodes) {
    lo = std::min(lo, x[2]);
    hi = std::max(hi, x[2]);
  }
  CHECK(lo == Approx(0.214).margin(1e-12));
  CHECK(hi == Approx(0.314).margin(1e-12));
  REQUIRE(fs.problem.constraints.size() == 1);
  CHECK(fs.problem.constraints[0].nodes.size() == 9);
  for (auto n : fs.problem.constraints[0].nodes)
    CHECK(fs.problem.mesh.nodes[static_cast<std::size_t>(n)][2] == Approx(0.214).margin(1e-12));
}

TEST_CASE("mesh seat: margin, and a literal that would start in a rock", "[launch]") {
  TempDir dir("mesh_seat_margin");
  // margin 0: only the centres under the footprint count; the sphere reaching in from
  // outside is left out and the mesh lands in it (its top 0.21 m above the bottom 0.164 m):
  // the default margin is the one that keeps every particle out of the mesh
  const auto s0 = resolve_mesh_seat(
      write_scene(dir, scene_text("\n[fem.mesh.seat]\ngap = 0.004\nmargin = 0.0\n")), 1);
  REQUIRE(s0);
  CHECK(s0->particles == 2);
  CHECK(s0->bed_top == 0.15 + 0.01);
  // A mesh whose file puts its bottom at 0.18 m, inside the highest sphere under it (top
  // 0.21 m), is lifted out of it; one at 0.5 m, far above the bed, is lowered onto it
  for (const char* z : {"0.18", "0.5"}) {
    INFO(z);
    const std::string lo = std::string("[0.2, 0.2, ") + z + "]";
    const std::string hi = std::string("[0.4, 0.4, ") + z + "1]";
    const auto s = resolve_mesh_seat(
        write_scene(dir, scene_text("\n[fem.mesh.seat]\ngap = 0.002\n", lo, hi)), 1);
    REQUIRE(s);
    CHECK(s->mesh_bottom + s->dz == Approx(0.212).margin(1e-12));
  }
  // No seat: nothing to resolve
  CHECK_FALSE(resolve_mesh_seat(write_scene(dir, scene_text("")), 1).has_value());
}

TEST_CASE("mesh seat: bad input names the key", "[launch]") {
  TempDir dir("mesh_seat_bad");
  using Catch::Contains;
  CHECK_THAT(seat_error(dir, scene_text("translate = [0, 0, 0.1]\n[fem.mesh.seat]\ngap = 0.004\n")),
             Contains("fem.mesh.translate") && Contains("give one of them"));
  CHECK_THAT(seat_error(dir, scene_text("\n[fem.mesh.seat]\ngap = -0.001\n")),
             Contains("fem.mesh.seat.gap"));
  CHECK_THAT(seat_error(dir, scene_text("\n[fem.mesh.seat]\ngap = 0.004\nmargin = 11\n")),
             Contains("fem.mesh.seat.margin"));
  CHECK_THAT(seat_error(dir, scene_text("\n[fem.mesh.seat]\ngap = 0.004\ngapp = 1\n")),
             Contains("gapp"));
  CHECK_THAT(seat_error(dir, scene_text("\n[fem.mesh.seat]\ngap = 0.004\n", "[1.0, 1.0, 1.0]",
                                        "[1.2, 1.2, 1.1]")),
             Contains("not over the bed"));
  CHECK_THAT(seat_error(dir, scene_text("\n[fem.mesh.seat]\ngap = 0.004\n", "[0.2, 0.2, 1.0]",
                                        "[0.4, 0.4, 1.1]", "")),
             Contains("[dem.load]"));
  // fem_server started by hand on a scene with a seat: the launcher's translate is missing
  const std::string alone = test::error_of<SceneError>(
      [&] {
        const Document d = write_scene(dir, scene_text("\n[fem.mesh.seat]\ngap = 0.004\n"));
        fem::read_fem_scene(*d.root().table("fem"));
      },
      "(no error)");
  CHECK_THAT(alone, Contains("fem.mesh.seat") && Contains("demfem run"));
}
