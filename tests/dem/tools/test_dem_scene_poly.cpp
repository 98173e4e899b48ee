// [[dem.shapes]] in a scene: rock libraries, STL hulls and simple solids, inserted by count
// and by mass with random orientations and on a lattice; bad shape input is an error naming
// file, line and key.

#include <catch2/catch.hpp>
#include <cmath>
#include <fstream>
#include <random>
#include <sstream>

#include "demfem/dem/run/dem_output.hpp"
#include "demfem/dem/run/dem_run.hpp"
#include "demfem/dem/shapes/convex_polyhedron.hpp"
#include "demfem/dem/shapes/geometry/stl_reader.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem_test/box_scene.hpp"
#include "demfem_test/cube_shape.hpp"
#include "demfem_test/dem_scene_text.hpp"
#include "demfem_test/error_of.hpp"
#include "demfem_test/rock_fill.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem::dem;
using demfem::scene::Document;
using demfem::scene::SceneError;
using demfem::test::TempDir;

namespace {

// Six random rocks (sieve-sized, dilated by 10 % of their size), 60 of them inserted.
const std::string kRocks = demfem::test::rock_box("[0.3, 0.3, 1.0]").text() +
                           demfem::test::sieved_rocks("0.7").text() +
                           demfem::test::RockFill("[0.3, 0.3, 1.0]", "60", "3").text();

std::string replace(const std::string& s, const std::string& from, const std::string& to) {
  return demfem::test::replace_first(s, from, to);
}

using demfem::test::line_of;

DemScene parse(const std::string& text) { return demfem::test::parse_dem_scene(text, "rocks.toml"); }

// The message of building the scene (reading, then DemRun), or "(no error)".
std::string error_of(const std::string& text) {
  return demfem::test::error_of<SceneError>(
      [&] {
        const DemScene s = parse(text);
        DemRun run(s, "", 1, 0.0, nullptr);
      },
      "(no error)");
}

}  // namespace

TEST_CASE("[[dem.shapes]]: random rocks inserted by count and by mass", "[scene][poly]") {
  const DemScene s = parse(kRocks);
  REQUIRE(s.shapes.size() == 1);
  CHECK(s.shapes[0].triangles == 10);
  CHECK(s.inserts[0].shape == 0);
  std::ostringstream log;
  DemRun run(s, "", 1, 0.0, &log);
  const auto& st = run.system().particles();
  REQUIRE(st.size() == 60);
  CHECK(run.system().shape_count() == 6);
  double mass = 0.0;
  for (std::size_t i = 0; i < st.size(); ++i) {
    CHECK(st.shape[i] == static_cast<std::uint8_t>(ParticleShape::polyhedron));
    CHECK(st.shape_id[i] >= 0);
    CHECK(st.shape_id[i] < 6);
    CHECK(st.scale[i] >= 0.02);  // the unit shape has size 1 m: scale = sieve size
    CHECK(st.scale[i] <= 0.06);
    mass += st.mass[i];
  }
  // orientations differ (random)
  CHECK(st.qw[0] != st.qw[1]);
  CHECK_THAT(log.str(), Catch::Contains("Rayleigh time step"));
  run.run_to(0.002);
  CHECK(run.system().time() == Approx(0.002));
  SECTION("sized by their bounding diameter") {
    // size = "bounding": each rock's bounding sphere (the broad phase's radius) has the drawn
    // diameter, its scale; sieve-sized, the same rocks reach further than half their size.
    for (std::size_t i = 0; i < st.size(); ++i) CHECK(2 * st.radius[i] > 1.1 * st.scale[i]);
    const DemScene b = parse(replace(kRocks, "size = \"sieve\"", "size = \"bounding\""));
    DemRun rb(b, "", 1, 0.0, nullptr);
    const auto& pb = rb.system().particles();
    REQUIRE(pb.size() == 60);
    for (std::size_t i = 0; i < pb.size(); ++i)
      CHECK(2 * pb.radius[i] == Approx(pb.scale[i]).epsilon(1e-12));
  }
  SECTION("by mass") {
    const DemScene m = parse(replace(kRocks, "count = 60", "mass = 5.0"));
    DemRun r2(m, "", 1, 0.0, nullptr);
    double total = 0.0;
    for (double x : r2.system().particles().mass) total += x;
    CHECK(total >= 5.0);
    CHECK(total < 5.0 + 2600.0 * 0.06 * 0.06 * 0.06);  // less than one more rock
  }
  SECTION("a lattice of rocks and simple solids") {
    std::string t = replace(kRocks, "[[dem.insert]]", R"([[dem.shapes]]
name = "cubes"
kind = "cube"
dilation = 0.2

[[dem.lattice]]
material = "rock"
shape = "cubes"
lo = [0.0, 0.0, 0.0]
hi = [0.3, 0.3, 0.2]
diameter = 0.03
spacing = 0.06
seed = 4

[[dem.insert]])");
    t = replace(t, "count = 60", "count = 5");
    const DemScene l = parse(t);
    DemRun r3(l, "", 1, 0.0, nullptr);
    const auto& p = r3.system().particles();
    std::size_t cubes = 0;
    for (std::size_t i = 0; i < p.size(); ++i)
      cubes += p.shape_id[i] == 6 ? 1 : 0;  // after 6 rocks
    CHECK(cubes == 5 * 5 * 3);              // spacing 0.06 m in a 0.3 x 0.3 x 0.2 box
    CHECK(p.size() == cubes + 5);
  }
}

TEST_CASE("[[dem.shapes]]: an STL scan becomes its hull; bad input names file, line and key",
          "[scene][poly]") {
  TempDir dir;
  // a closed tetrahedron (an STL "scan"), an open mesh, a flat one
  TriangleMesh tet;
  tet.vertices = {0, 0, 0, 0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.01};
  tet.triangles = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  write_stl_binary(dir / "rock.stl", tet);
  TriangleMesh open = tet;
  open.triangles.resize(9);
  write_stl_binary(dir / "open.stl", open);
  const std::string stl_entry = R"(kind = "stl"
stl = "rock.stl")";
  std::string text = replace(kRocks, R"(kind = "random_rock"
count = 6
triangles = 10
elongation = 0.8
flatness = 0.7
seed = 5)",
                             stl_entry);
  {
    std::ofstream(dir / "scene.toml") << text;
    Document d = Document::load(dir / "scene.toml");
    const DemScene s = read_dem_scene(d.root().required_table("dem"));
    DemRun run(s, "", 1, 0.0, nullptr);
    CHECK(run.system().shape_count() == 1);
    CHECK(run.system().shape(0).triangles.size() == 12);
  }
  auto load_error = [&](const std::string& t) {
    std::ofstream(dir / "scene.toml") << t;
    return demfem::test::error_of<SceneError>([&] {
      Document d = Document::load(dir / "scene.toml");
      const DemScene s = read_dem_scene(d.root().required_table("dem"));
      DemRun run(s, "", 1, 0.0, nullptr);
    });
  };
  const std::string e1 = load_error(replace(text, "rock.stl", "open.stl"));
  CHECK_THAT(
      e1, Catch::Contains("scene.toml:" + std::to_string(line_of(text, "kind = \"stl\"")) + ":") &&
              Catch::Contains("dem.shapes[0].kind") && Catch::Contains("open.stl"));
  // keys checked when read
  CHECK_THAT(
      error_of(replace(kRocks, "dilation = 0.1", "dilation = 0.5")),
      Catch::Contains("rocks.toml:" + std::to_string(line_of(kRocks, "dilation = 0.1")) + ":") &&
          Catch::Contains("dem.shapes[0].dilation") && Catch::Contains("[0.01, 0.5)"));
  // issue 34: a dilation that thin was accepted and blew up at the first contact
  CHECK_THAT(error_of(replace(kRocks, "dilation = 0.1", "dilation = 1e-300")),
             Catch::Contains("dem.shapes[0].dilation") && Catch::Contains("[0.01, 0.5)"));
  // and a box of [1e300, 1, 1] was refused as "collinear (nan, nan, nan)"
  const std::string box_shape = replace(
      kRocks,
      "kind = \"random_rock\"\ncount = 6\ntriangles = 10\nelongation = 0.8\nflatness = 0.7\n"
      "seed = 5",
      "kind = \"box\"\naspect = [1e300, 1.0, 1.0]");
  CHECK_THAT(error_of(box_shape), Catch::Contains("dem.shapes[0].aspect") &&
                                      Catch::Contains("at most 1000"));
  CHECK_THAT(error_of(replace(box_shape, "aspect = [1e300, 1.0, 1.0]", "aspect = [1.0, 1e-5, 2.0]")),
             Catch::Contains("dem.shapes[0].aspect"));
  CHECK_THAT(error_of(replace(box_shape, "aspect = [1e300, 1.0, 1.0]", "aspect = [1.0, 0.5, 2.0]")),
             !Catch::Contains("aspect"));
  CHECK_THAT(error_of(replace(kRocks, "triangles = 10", "triangles = 11")),
             Catch::Contains("dem.shapes[0].triangles") && Catch::Contains("even"));
  CHECK_THAT(error_of(replace(kRocks, "elongation = 0.8", "elongation = 0.0")),
             Catch::Contains("dem.shapes[0].elongation"));
  CHECK_THAT(error_of(replace(kRocks, "shape = \"ballast\"", "shape = \"gravel\"")),
             Catch::Contains("dem.insert[0].shape") && Catch::Contains("\"ballast\""));
  CHECK_THAT(error_of(replace(kRocks, "size = \"sieve\"", "size = \"mesh\"")),
             Catch::Contains("dem.shapes[0].size"));
  CHECK_THAT(error_of(replace(kRocks, "kind = \"random_rock\"", "kind = \"blob\"")),
             Catch::Contains("dem.shapes[0].kind"));
  CHECK_THAT(error_of(replace(kRocks, "seed = 5", "seed = 5\ncolour = 3")),
             Catch::Contains("dem.shapes[0].colour"));
  // a gradation that does not sum to 1
  CHECK_THAT(
      error_of(replace(kRocks,
                       "distribution = { kind = \"normal\", mean = 0.04, stddev = 0.01, d_min = "
                       "0.02, d_max = 0.06 }",
                       "distribution = { kind = \"gradation\", sieves = [0.02, 0.04, 0.06], "
                       "mass_fractions = [0.5, 0.4] }")),
      Catch::Contains("dem.insert[0].distribution") && Catch::Contains("sum"));
}

TEST_CASE("a finely scanned STL rock is set up in seconds, with progress lines", "[scene][poly]") {
  // Issue 34, item 7: a rock STL of 10^4 vertices took 78 s to set up with no output. A scan
  // of 3000 vertices (all on its hull, an ellipsoid 50 x 35 x 20 mm) reports its hull and the
  // sieve-size search's stages on the run's log.
  TempDir dir;
  std::mt19937_64 gen(11);
  std::normal_distribution<double> g;
  std::vector<demfem::dem::shapes::Vec3> p(3000);
  for (auto& x : p) {
    const double a = g(gen), b = g(gen), c = g(gen), l = std::sqrt(a * a + b * b + c * c);
    x = {0.025 * a / l, 0.0175 * b / l, 0.01 * c / l};
  }
  const auto hull = demfem::dem::shapes::ConvexPolyhedron::hull(p, "scan");
  TriangleMesh scan;
  for (const auto& v : hull.vertices())
    scan.vertices.insert(scan.vertices.end(), v.begin(), v.end());
  for (const auto& t : hull.triangles())
    scan.triangles.insert(scan.triangles.end(), t.begin(), t.end());
  write_stl_binary(dir / "scan.stl", scan);
  const std::string text = replace(kRocks, R"(kind = "random_rock"
count = 6
triangles = 10
elongation = 0.8
flatness = 0.7
seed = 5)",
                                   "kind = \"stl\"\nstl = \"scan.stl\"");
  std::ofstream(dir / "scene.toml") << text;
  Document d = Document::load(dir / "scene.toml");
  const DemScene s = read_dem_scene(d.root().required_table("dem"));
  std::ostringstream log;
  DemRun run(s, "", 1, 0.0, &log);
  CHECK(run.system().shape_count() == 1);
  CHECK(run.system().shape(0).vertices.size() == 3 * 3000);
  INFO(log.str());
  CHECK_THAT(log.str(), Catch::Contains("shape 'ballast': " + (dir / "scan.stl").string() +
                                        ": convex hull of 3000 vertices"));
  CHECK_THAT(log.str(), Catch::Contains("shape 'ballast': sieve size: candidates 5996 of 5996"));
  CHECK_THAT(log.str(), Catch::Contains("shape 'ballast': sieve size: local searches 10 of 10"));
}

TEST_CASE("polyhedra are written as triangle surfaces beside the particles' points",
          "[scene][poly][output]") {
  // Reference: the pose. A cube (r_d 0.2 of the size) at a known position and orientation:
  // its 12 surface triangles; each surface point at distance |R (v + r_d n_v)| s from the
  // centre, where n_v is the vertex's mean normal (a cube corner: (1, 1, 1)/sqrt(3)); the
  // index is a spatial collection of the points grid and a Triangle grid. Tolerance 1e-12.
  TempDir dir;
  DemSystem sys = demfem::test::cube_and_sphere({"rock", 1e8, 0.3, 2600.0}, {0, 0, 0});
  ParticleOutput out(dir.path);
  out.set_shapes({sys.shape(0)});
  const std::vector<std::int64_t> ids{7, 8};
  out.write(sys.particles(), ids, 0.0);
  demfem::io::H5File f(out.snapshot_path(0), demfem::io::H5File::Mode::read);
  const auto pts = f.read_doubles("surface_points");
  REQUIRE(pts.size() == 8 * 3);
  CHECK(f.read_int64("surface_triangles").size() == 12 * 3);
  CHECK(f.read_int64("surface_id") == std::vector<std::int64_t>(12, 7));
  const double expect = 0.05 * (0.3 * std::sqrt(3.0) + 0.2);
  for (int k = 0; k < 8; ++k) {
    const double d = std::sqrt((pts[3 * k] - 1.0) * (pts[3 * k] - 1.0) +
                               (pts[3 * k + 1] - 2.0) * (pts[3 * k + 1] - 2.0) +
                               (pts[3 * k + 2] - 3.0) * (pts[3 * k + 2] - 3.0));
    CHECK(d == Approx(expect).epsilon(1e-12));
  }
  std::ifstream in(out.index_path());
  std::stringstream text;
  text << in.rdbuf();
  CHECK_THAT(text.str(), Catch::Contains("CollectionType=\"Spatial\"") &&
                             Catch::Contains("TopologyType=\"Triangle\" NumberOfElements=\"12\"") &&
                             Catch::Contains("TopologyType=\"Polyvertex\" NumberOfElements=\"2\""));
}

TEST_CASE("remove_by = \"top\" removes the rocks that reach above remove_above", "[scene][poly]") {
  // The highest point of each kept rock, from its core vertices rotated by the quaternion's
  // z row written out here (not the engine's rotation), plus the scaled dilation.
  auto top_of = [](const DemSystem& sys, std::size_t i) {
    const auto& p = sys.particles();
    const PolyhedronShape& sh = sys.shape(p.shape_id[i]);
    const double w = p.qw[i], x = p.qx[i], y = p.qy[i], z = p.qz[i];
    const double r0 = 2.0 * (x * z - w * y), r1 = 2.0 * (y * z + w * x),
                 r2 = 1.0 - 2.0 * (x * x + y * y);
    double up = -1e300;
    for (std::size_t v = 0; v + 2 < sh.vertices.size(); v += 3)
      up = std::max(up, r0 * sh.vertices[v] + r1 * sh.vertices[v + 1] + r2 * sh.vertices[v + 2]);
    return p.pz[i] + p.scale[i] * (up + sh.dilation);
  };
  const std::string base = replace(kRocks, "threads = 1\n", "threads = 1\nremove_above = 0.5\n");
  DemRun all(parse(kRocks), "", 1, 0.0, nullptr);
  DemRun by_centre(parse(base), "", 1, 0.0, nullptr);
  DemRun by_top(
      parse(replace(base, "remove_above = 0.5", "remove_above = 0.5\nremove_by = \"top\"")), "", 1,
      0.0, nullptr);
  std::size_t reaching = 0, centre_below = 0;
  for (std::size_t i = 0; i < all.system().particles().size(); ++i) {
    const double top = top_of(all.system(), i);
    reaching += top > 0.5 ? 1 : 0;
    centre_below += all.system().particles().pz[i] <= 0.5 ? 1 : 0;
  }
  REQUIRE(all.system().particles().size() == 60);
  CHECK(by_centre.system().particles().size() == centre_below);
  CHECK(by_top.system().particles().size() == 60 - reaching);
  CHECK(by_top.system().particles().size() < by_centre.system().particles().size());
  for (std::size_t i = 0; i < by_top.system().particles().size(); ++i)
    CHECK(top_of(by_top.system(), i) <= 0.5);
  CHECK_THAT(error_of(replace(kRocks, "threads = 1\n", "threads = 1\nremove_by = \"top\"\n")),
             Catch::Contains("remove_by") && Catch::Contains("needs remove_above"));
  CHECK_THAT(
      error_of(replace(base, "remove_above = 0.5", "remove_above = 0.5\nremove_by = \"any\"")),
      Catch::Contains("remove_by") && Catch::Contains("top"));
}

TEST_CASE("[dem.freeze]: the particles outside the active box are held from its time on",
          "[scene][poly][frozen]") {
  const std::string frozen = replace(kRocks, "threads = 1\n", R"(threads = 1

[dem.freeze]
time = 0.001
active = { lo = [0.0, 0.0, 0.5], hi = [0.3, 0.3, 1.0] }
max_speed = 1e9

[[dem.sensors]]
name = "held"
kind = "frozen"
interval = 0.001
)");
  const DemScene s = parse(frozen);
  REQUIRE(s.freeze);
  CHECK(s.freeze->time == 0.001);
  DemRun run(s, "", 1, 0.0, nullptr);
  std::size_t below = 0;
  for (double z : run.system().particles().pz) below += z < 0.5 ? 1 : 0;
  REQUIRE(below > 0);
  REQUIRE(below < 60);
  CHECK(run.system().frozen_count() == 0);
  run.run_to(0.001);
  CHECK(run.system().frozen_count() == below);  // at 0.001 s, all outside the box (centre z < 0.5)
  const auto z1 = run.system().particles().pz;
  run.run_to(0.003);
  const auto& p = run.system().particles();
  std::size_t held = 0, fell = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (run.system().frozen()[i] != 0)
      held += p.pz[i] == z1[i] ? 1 : 0;
    else
      fell += p.pz[i] < z1[i] ? 1 : 0;
  }
  CHECK(held == below);
  CHECK(fell == 60 - below);
  // disabled, it does nothing; bad boxes are refused, naming the key; both backends hold
  DemRun off(parse(replace(frozen, "time = 0.001", "enabled = false\ntime = 0.001")), "", 1, 0.0,
             nullptr);
  off.run_to(0.002);
  CHECK(off.system().frozen_count() == 0);
  CHECK_THAT(error_of(replace(frozen, "hi = [0.3, 0.3, 1.0]", "hi = [0.3, 0.3, 0.4]")),
             Catch::Contains("dem.freeze.active") && Catch::Contains("hi > lo"));
  CHECK(parse(replace(frozen, "threads = 1\n", "threads = 1\nbackend = \"cuda\"\n")).freeze.has_value());
}

TEST_CASE("a bed that blows up while it settles stops there, naming the time", "[scene][poly]") {
  // Rocks thrown onto the floor at 40 m/s press into it by more than half their dilation in
  // the first hundredth of a second: the settling (0.5 s asked) stops within it.
  const std::string t =
      replace(replace(kRocks, "threads = 1\n", "threads = 1\nsettle_time = 0.5\n"), "count = 60\n",
              "count = 60\nvelocity = [0.0, 0.0, -40.0]\n");
  const std::string message =
      demfem::test::error_of<Unstable>([&] { DemRun run(parse(t), "", 1, 0.0, nullptr); }, "");
  CHECK_THAT(message, Catch::Contains("unstable in the steps up to t = 0.0"));
  CHECK_THAT(message, Catch::Contains("of the smaller contact radius"));
}
