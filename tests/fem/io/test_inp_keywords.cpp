// Issue 19, defect 14: the .inp keywords a user's deck commonly holds are read or refused,
// never skipped silently. *INCLUDE (relative, depth limit, cycles), parts and instances
// (translation then rotation, qualified set names), *BOUNDARY, *CLOAD, *DLOAD, *DSLOAD,
// *AMPLITUDE, *STEP with *STATIC / *DYNAMIC, the element formulations, and refusals of
// everything else by keyword and line. The loads of a deck give the same solution as the same
// loads written in the scene.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "demfem/fem/fem_scene.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/fem/inp_reader.hpp"
#include "demfem_test/error_of.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem;
using namespace demfem::fem;
using Catch::Contains;

namespace {

void write(const std::filesystem::path& p, const std::string& text) {
  std::filesystem::create_directories(p.parent_path());
  std::ofstream(p) << text;
}

std::string error_of(const std::string& text, const InpOptions& o = {}) {
  return demfem::test::error_of<InpError>([&] { parse_inp(text, "deck.inp", o); }, "no error");
}

bool has_note(const std::vector<std::string>& notes, const std::string& part) {
  for (const auto& n : notes)
    if (n.find(part) != std::string::npos) return true;
  return false;
}

// A 2 x 1 x 1 cantilever of two unit cubes along x (C3D8I), nodes 1..12, sets for the clamp
// (x = 0), the tip (x = 2) and the top face (z = 1).
const std::string kBar = R"(*NODE, NSET=ALLN
1, 0, 0, 0
2, 1, 0, 0
3, 2, 0, 0
4, 0, 1, 0
5, 1, 1, 0
6, 2, 1, 0
7, 0, 0, 1
8, 1, 0, 1
9, 2, 0, 1
10, 0, 1, 1
11, 1, 1, 1
12, 2, 1, 1
*ELEMENT, TYPE=C3D8I, ELSET=BAR
1, 1, 2, 5, 4, 7, 8, 11, 10
2, 2, 3, 6, 5, 8, 9, 12, 11
*NSET, NSET=FIX
1, 4, 7, 10
*NSET, NSET=TIP
3, 6, 9, 12
*SURFACE, NAME=TOPS
BAR, S2
*MATERIAL, NAME=STEEL
*ELASTIC
2.1e11, 0.3
*DENSITY
7850
*SOLID SECTION, ELSET=BAR, MATERIAL=STEEL
,
)";

FemScene scene_with_deck(const test::TempDir& dir, const std::string& deck,
                         const std::string& extra = "", const std::string& mesh_keys = "") {
  write(dir / "deck.inp", deck);
  const std::string text = "[fem]\nmesh = { file = \"deck.inp\"" + mesh_keys + " }\n" + extra;
  const auto doc = scene::Document::parse(text, (dir / "scene.toml").string());
  return read_fem_scene(doc.root().required_table("fem"));
}

std::string scene_error(const test::TempDir& dir, const std::string& deck,
                        const std::string& extra = "", const std::string& mesh_keys = "") {
  return test::error_of<scene::SceneError>([&] { scene_with_deck(dir, deck, extra, mesh_keys); },
                                           "no error");
}

std::vector<double> static_solution(const FemScene& s) {
  FemSolver solver(s.problem);
  solver.solve_static();
  return solver.displacements();
}

}  // namespace

TEST_CASE("inp *INCLUDE: relative to the including file, errors name the included file", "[inp]") {
  test::TempDir dir;
  write(dir / "mesh/nodes.inp",
        "*NODE\n1, 0, 0, 0\n2, 1, 0, 0\n3, 0, 1, 0\n*INCLUDE, INPUT=more.inp\n");
  write(dir / "mesh/more.inp", "** the fourth node\n4, 0, 0, 1\n");
  write(dir / "main.inp",
        "*INCLUDE, INPUT=mesh/nodes.inp\n*ELEMENT, TYPE=C3D4, ELSET=T\n1, 1, 2, 3, 4\n");
  const InpModel m = read_inp_model(dir / "main.inp");
  REQUIRE(m.mesh.nodes.size() == 4);
  CHECK(m.mesh.nodes[3] == std::array<double, 3>{0, 0, 1});
  // The node of the included file keeps its file and line.
  CHECK(m.mesh.source_files[static_cast<std::size_t>(m.mesh.node_sources[3].file)] ==
        (dir.path / "mesh" / "more.inp").string());
  CHECK(m.mesh.node_sources[3].line == 2);
  CHECK_THAT(node_name(m.mesh, 3), Contains("more.inp:2"));
  // An error inside an included file names that file and line.
  write(dir / "mesh/more.inp", "4, 0, x, 1\n");
  CHECK_THROWS_WITH(read_inp_model(dir / "main.inp"),
                    Contains("more.inp:1: coordinate y of node 4 'x' is not a number"));
  // Missing, a directory, /dev/zero: named, with the *INCLUDE line.
  write(dir / "bad.inp", "*NODE\n1, 0, 0, 0\n*INCLUDE, INPUT=nowhere.inp\n");
  CHECK_THROWS_WITH(read_inp_model(dir / "bad.inp"),
                    Contains("bad.inp:3: *INCLUDE: ") && Contains("nowhere.inp: cannot open"));
  write(dir / "dir.inp", "*INCLUDE, INPUT=mesh\n");
  CHECK_THROWS_WITH(read_inp_model(dir / "dir.inp"),
                    Contains("dir.inp:1: *INCLUDE: ") && Contains("is a directory"));
  write(dir / "zero.inp", "*INCLUDE, INPUT=/dev/zero\n");
  CHECK_THROWS_WITH(read_inp_model(dir / "zero.inp"), Contains("character device"));
  // A cycle, and a chain deeper than the limit.
  write(dir / "a.inp", "*INCLUDE, INPUT=b.inp\n");
  write(dir / "b.inp", "*INCLUDE, INPUT=a.inp\n");
  CHECK_THROWS_WITH(read_inp_model(dir / "a.inp"),
                    Contains("b.inp:1: *INCLUDE of") && Contains("a cycle"));
  for (int i = 0; i <= kInpIncludeDepth + 1; ++i) {
    std::string next = "*INCLUDE, INPUT=c";  // built up (GCC 12 warns on a + chain here)
    next += std::to_string(i + 1);
    next += ".inp\n";
    std::string file = "c";
    file += std::to_string(i);
    file += ".inp";
    write(dir.path / file, next);
  }
  CHECK_THROWS_WITH(read_inp_model(dir / "c0.inp"), Contains("nested deeper than 10 files"));
  // Without file access (the fuzzer): refused, not read.
  InpOptions no_files;
  no_files.allow_include = false;
  CHECK_THAT(error_of("*INCLUDE, INPUT=x.inp\n", no_files),
             Contains("deck.inp:1: *INCLUDE is not available here"));
}

TEST_CASE("inp parts and instances: translation then rotation, qualified set names", "[inp]") {
  // Part BLOCK: a unit C3D8I cube with node set FIX (x = 0), surface TOP and a section. B1
  // is moved by (1, 0, 0) and turned 90 degrees about the z axis (Abaqus: translation
  // first), B2 moved by (0, 0, 5). An assembly-level set picks B2's node 2.
  const std::string deck = R"(*HEADING
two instances of one part
*PART, NAME=Block
*NODE
1, 0, 0, 0
2, 1, 0, 0
3, 1, 1, 0
4, 0, 1, 0
5, 0, 0, 1
6, 1, 0, 1
7, 1, 1, 1
8, 0, 1, 1
*ELEMENT, TYPE=C3D8I, ELSET=CUBE
1, 1, 2, 3, 4, 5, 6, 7, 8
*NSET, NSET=FIX
1, 4, 5, 8
*SURFACE, NAME=TOP
CUBE, S2
*SOLID SECTION, ELSET=CUBE, MATERIAL=STEEL
,
*END PART
*ASSEMBLY, NAME=Assembly
*INSTANCE, NAME=B1, PART=Block
1, 0, 0
0, 0, 0, 0, 0, 1, 90
*END INSTANCE
*INSTANCE, NAME=B2, PART=Block
0, 0, 5
*END INSTANCE
*NSET, NSET=PICK, INSTANCE=B2
2
*NSET, NSET=ONLYB1
B1.FIX
*END ASSEMBLY
*MATERIAL, NAME=STEEL
*ELASTIC
2e11, 0.3
)";
  const InpModel m = parse_inp(deck, "deck.inp");
  const Mesh& mesh = m.mesh;
  REQUIRE(mesh.nodes.size() == 16);
  REQUIRE(mesh.elements.size() == 2);
  // B1 node 2 at (1, 0, 0): translated to (2, 0, 0), then turned to (0, 2, 0). (Rotation
  // first would give (1, 1, 0).)
  CHECK(mesh.nodes[1][0] == Approx(0.0).margin(1e-15));
  CHECK(mesh.nodes[1][1] == Approx(2.0));
  CHECK(mesh.nodes[1][2] == Approx(0.0).margin(1e-15));
  // B2 node 7 at (1, 1, 1) + (0, 0, 5).
  CHECK(mesh.nodes[8 + 6] == std::array<double, 3>{1, 1, 6});
  // Labels repeat per instance; names say which.
  CHECK(mesh.node_labels[0] == 1);
  CHECK(mesh.node_labels[8] == 1);
  CHECK_THAT(node_name(mesh, 8), Contains("node B2.1 (deck.inp:5)"));
  CHECK_THAT(element_name(mesh, 0), Contains("element B1.1 (deck.inp:14)"));
  // Qualified names; FIX exists in both instances, so no plain alias; TOP neither.
  CHECK(mesh.node_sets.at("B1.FIX").size() == 4);
  CHECK(mesh.node_sets.at("B2.FIX") == std::vector<std::int32_t>{8, 11, 12, 15});
  CHECK_FALSE(mesh.node_sets.count("FIX"));
  CHECK(mesh.surfaces.at("B2.TOP").size() == 1);
  CHECK(mesh.node_sets.at("PICK") == std::vector<std::int32_t>{9});
  CHECK(mesh.node_sets.at("ONLYB1") == mesh.node_sets.at("B1.FIX"));
  // One section per instance.
  REQUIRE(m.sections.size() == 2);
  CHECK(m.sections[0].element_set == "B1.CUBE");
  CHECK(m.sections[1].element_set == "B2.CUBE");
  CHECK(has_note(m.notes, "2 part instance(s) flattened"));

  // A single instance gets plain aliases, and loads can name instance nodes as B1.n.
  const std::string one = R"(*PART, NAME=P
*NODE
1, 0, 0, 0
2, 1, 0, 0
3, 0, 1, 0
4, 0, 0, 1
*ELEMENT, TYPE=C3D4, ELSET=T
1, 1, 2, 3, 4
*NSET, NSET=BASE
1, 2, 3
*END PART
*ASSEMBLY, NAME=A
*INSTANCE, NAME=P-1, PART=P
*END INSTANCE
*END ASSEMBLY
*STEP
*STATIC
*BOUNDARY
P-1.BASE, ENCASTRE
*CLOAD
P-1.4, 3, 10.0
*END STEP
)";
  const InpModel o = parse_inp(one, "one.inp");
  CHECK(o.mesh.node_sets.at("BASE") == o.mesh.node_sets.at("P-1.BASE"));
  REQUIRE(o.concentrated_loads.size() == 1);
  CHECK(o.concentrated_loads[0].nodes == std::vector<std::int32_t>{3});
  // Errors.
  CHECK_THAT(
      error_of("*ASSEMBLY, NAME=A\n*INSTANCE, NAME=I, PART=NOPE\n*END INSTANCE\n*END ASSEMBLY\n"),
      Contains("deck.inp:2: instance I refers to part NOPE, which is not defined"));
  CHECK_THAT(error_of("*PART, NAME=P\n*NODE\n1, 0, 0, 0\n"),
             Contains("deck.inp:1: *PART without *END PART"));
  CHECK_THAT(
      error_of("*ASSEMBLY, NAME=A\n*INSTANCE, NAME=I, PART=P\n1, 0, 0\n0, 0, 0, 0, 0, 0, 90\n"),
      Contains("deck.inp:4: *INSTANCE rotation: points a and b of the axis coincide"));
}

TEST_CASE("inp *BOUNDARY: DOF ranges, symbolic types, values, OP=NEW", "[inp]") {
  const InpModel m = parse_inp(kBar + R"(*BOUNDARY
FIX, 1, 3
1, 4, 6
TIP, XSYMM
*STEP
*STATIC
*BOUNDARY
9, 3, 3, -0.001
12, 2
*END STEP
)",
                               "deck.inp");
  REQUIRE(m.boundaries.size() == 5);
  CHECK(m.boundaries[0].fixed == std::array<bool, 6>{true, true, true, false, false, false});
  CHECK(m.boundaries[0].nodes.size() == 4);
  CHECK(m.boundaries[1].fixed == std::array<bool, 6>{false, false, false, true, true, true});
  CHECK(m.boundaries[2].fixed == std::array<bool, 6>{true, false, false, false, true, true});
  CHECK(m.boundaries[3].value[2] == -0.001);
  CHECK(m.boundaries[3].nodes == std::vector<std::int32_t>{8});
  CHECK(m.boundaries[4].fixed == std::array<bool, 6>{false, true, false, false, false, false});
  CHECK_THAT(m.boundaries[3].where, Contains("deck.inp:37"));
  // OP=NEW removes what was given before.
  const InpModel n = parse_inp(
      kBar +
          "*BOUNDARY\nFIX, ENCASTRE\n*STEP\n*STATIC\n*BOUNDARY, OP=NEW\nTIP, PINNED\n*END STEP\n",
      "deck.inp");
  REQUIRE(n.boundaries.size() == 1);
  CHECK(n.boundaries[0].nodes.size() == 4);
  CHECK(n.boundaries[0].fixed == std::array<bool, 6>{true, true, true, false, false, false});
  // Refused, by line.
  CHECK_THAT(error_of(kBar + "*BOUNDARY\nFIX, 11\n"),
             Contains("deck.inp:31: *BOUNDARY: DOF 11 is not a displacement"));
  CHECK_THAT(error_of(kBar + "*BOUNDARY, TYPE=VELOCITY\nFIX, 1\n"),
             Contains("deck.inp:30: *BOUNDARY, TYPE=VELOCITY is not supported"));
  CHECK_THAT(error_of(kBar + "*BOUNDARY\nFIX, CLAMPED\n"),
             Contains("deck.inp:31: *BOUNDARY: 'CLAMPED' is not a DOF number"));
  CHECK_THAT(error_of(kBar + "*BOUNDARY\nNOSET, 1\n"),
             Contains("deck.inp:31: node set NOSET is not defined"));
  CHECK_THAT(error_of(kBar + "*BOUNDARY, FIXED\nFIX, 1\n"),
             Contains("deck.inp:30: parameter FIXED of *BOUNDARY is not supported"));
}

TEST_CASE("inp loads give the same solution as the same loads in the scene", "[inp]") {
  test::TempDir dir;
  // Deck: clamp FIX by *BOUNDARY, a tip force by *CLOAD, the top face by *DSLOAD, face S4
  // (x = 2) of element 2 by *DLOAD P4, gravity by *DLOAD GRAV over the whole model.
  const FemScene deck = scene_with_deck(dir, kBar + R"(*STEP, NAME=Load
*STATIC
*BOUNDARY
FIX, ENCASTRE
*CLOAD
TIP, 3, -250.
*DSLOAD
TOPS, P, 1.0e4
*DLOAD
2, P4, 5.0e3
ALL, GRAV, 9.81, 0, 0, -2
*END STEP
*ELSET, ELSET=ALL
BAR
)",
                                        "analysis = \"static\"\n");
  CHECK(deck.problem.gravity == std::array<double, 3>{0, 0, -9.81});  // direction normalised
  CHECK(has_note(deck.notes,
                 "taken from the deck: 1 boundary condition(s), 1 concentrated "
                 "load(s), 2 pressure load(s), gravity"));
  const FemScene scene = scene_with_deck(dir, kBar, R"(analysis = "static"
gravity = [0, 0, -9.81]
[[fem.clamps]]
nodes = "FIX"
[[fem.nodal_loads]]
nodes = "TIP"
force = [0, 0, -250]
[[fem.pressures]]
surface = "z >= 1"
magnitude = 1e4
[[fem.pressures]]
surface = "x >= 2"
magnitude = 5e3
)");
  const auto a = static_solution(deck), b = static_solution(scene);
  REQUIRE(a.size() == b.size());
  double scale = 0, diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    scale = std::max(scale, std::abs(b[i]));
    diff = std::max(diff, std::abs(a[i] - b[i]));
  }
  CHECK(scale > 1e-9);
  CHECK(diff <= 1e-12 * scale);  // same system up to round-off of the load summation order
  // Refusals.
  CHECK_THAT(error_of(kBar + "*STEP\n*STATIC\n*CLOAD\nTIP, 5, 1.0\n*END STEP\n"),
             Contains("deck.inp:33: *CLOAD on DOF 5: only forces"));
  CHECK_THAT(error_of(kBar + "*STEP\n*STATIC\n*DLOAD\nBAR, BX, 1.0\n*END STEP\n"),
             Contains("deck.inp:33: *DLOAD load type BX is not supported"));
  CHECK_THAT(error_of(kBar + "*STEP\n*STATIC\n*DLOAD\nBAR, P, 1.0\n*END STEP\n"),
             Contains("deck.inp:33: *DLOAD P does not fit element 1"));
  CHECK_THAT(error_of(kBar + "*STEP\n*STATIC\n*DSLOAD\nTOPS, TRVEC, 1.0, 0, 0, 1\n*END STEP\n"),
             Contains("deck.inp:33: *DSLOAD load type TRVEC is not supported"));
  CHECK_THAT(error_of(kBar + "*CLOAD\nTIP, 3, 1.0\n"),
             Contains("deck.inp:30: *CLOAD outside a *STEP"));
  CHECK_THAT(scene_error(dir, kBar + "*STEP\n*STATIC\n*DLOAD\n1, GRAV, 9.81, 0, 0, -1\n*END STEP\n",
                         "analysis = \"static\"\n"),
             Contains("'fem.mesh.file'") && Contains("deck.inp:33: *DLOAD GRAV acts on part of "
                                                     "the model only"));
}

TEST_CASE("inp steps and amplitudes: static end values, dynamic time functions", "[inp]") {
  test::TempDir dir;
  const std::string amp = R"(*AMPLITUDE, NAME=RISE
0, 0, 2, 1
*AMPLITUDE, NAME=EQ, DEFINITION=EQUALLY SPACED, FIXED INTERVAL=0.5, SCALEY=2
0, 1, 3
)";
  // Static step of period 2: the load's amplitude at the end (RISE(2) = 1, EQ(2) = 2 * 3 = 6).
  const FemScene st = scene_with_deck(dir, kBar + amp + R"(*STEP
*STATIC
0.1, 2.0
*BOUNDARY
FIX, ENCASTRE
*CLOAD, AMPLITUDE=EQ
TIP, 1, 10.0
*END STEP
)",
                                      "analysis = \"static\"\n");
  REQUIRE(st.problem.nodal_loads.size() == 1);
  CHECK(st.problem.nodal_loads[0].force[0] == Approx(60.0));
  CHECK_FALSE(st.problem.nodal_loads[0].amplitude);
  // Dynamic: tabular amplitudes become time functions; loads without one are applied at once
  // (Abaqus' default for *DYNAMIC) unless the step ramps them.
  const FemScene dy = scene_with_deck(dir, kBar + amp + R"(*STEP, AMPLITUDE=RAMP
*DYNAMIC, ALPHA=-0.05
0.001, 0.5
*BOUNDARY
FIX, ENCASTRE
*CLOAD, AMPLITUDE=RISE
TIP, 3, 10.0
*DSLOAD
TOPS, P, 100
*END STEP
)",
                                      "dt = 1e-3\n");
  CHECK(dy.analysis == Analysis::dynamic);
  CHECK(has_note(dy.notes, "*DYNAMIC: demfem integrates with Bossak-Newmark"));
  CHECK(has_note(dy.notes, "ignored: ALPHA=-0.05"));
  REQUIRE(dy.problem.nodal_loads.size() == 1);
  const auto& f = dy.problem.nodal_loads[0].amplitude;
  REQUIRE(f);
  CHECK(f(1.0) == Approx(0.5));
  CHECK(f(5.0) == Approx(1.0));
  const auto& ramp = dy.problem.pressures[0].amplitude;
  REQUIRE(ramp);
  CHECK(ramp(0.25) == Approx(0.5));  // over the step's period 0.5
  // The scene's analysis wins, with a note.
  const FemScene over =
      scene_with_deck(dir, kBar + "*STEP\n*STATIC\n*BOUNDARY\nFIX, ENCASTRE\n*END STEP\n",
                      "analysis = \"dynamic\"\ndt = 1e-3\n");
  CHECK(over.analysis == Analysis::dynamic);
  CHECK(has_note(over.notes, "overrides the deck's *STATIC"));
  // Without fem.analysis, a *STATIC deck is refused: the coupler reads the scene's value.
  CHECK_THAT(scene_error(dir, kBar + "*STEP\n*STATIC\n*BOUNDARY\nFIX, ENCASTRE\n*END STEP\n"),
             Contains("deck.inp:31: the deck's step is *STATIC but fem.analysis is not given"));
  // Prescribed non-zero values are static only.
  CHECK_THAT(
      scene_error(dir, kBar + "*STEP\n*DYNAMIC\n0.001, 1\n*BOUNDARY\nFIX, 1, 1, 0.01\n*END STEP\n",
                  "dt = 1e-3\n"),
      Contains("non-zero value: prescribed displacements are supported in a static "
               "analysis only"));
  // The scene's clamps add to the deck's; deck_loads = false takes the mesh only.
  const std::string clamped = kBar + "*STEP\n*STATIC\n*BOUNDARY\nFIX, ENCASTRE\n*END STEP\n";
  const std::string scene_clamp = "analysis = \"static\"\n[[fem.clamps]]\nnodes = \"TIP\"\n";
  CHECK(scene_with_deck(dir, clamped, scene_clamp).problem.constraints.size() == 2);
  const FemScene mesh_only = scene_with_deck(dir, clamped, scene_clamp, ", deck_loads = false");
  CHECK(mesh_only.problem.constraints.size() == 1);
  CHECK(has_note(mesh_only.notes, "are not used (fem.mesh.deck_loads = false)"));
  // Refusals.
  CHECK_THAT(error_of(kBar + "*STEP\n*STATIC\n*END STEP\n*STEP\n*STATIC\n*END STEP\n"),
             Contains("deck.inp:33: a second *STEP (the first is at deck.inp:30)"));
  CHECK_THAT(error_of(kBar + "*STEP, NLGEOM=YES\n*STATIC\n*END STEP\n"),
             Contains("deck.inp:30: *STEP, NLGEOM=YES asks for geometric nonlinearity"));
  CHECK_THAT(error_of(kBar + "*STEP\n*BUCKLE\n10\n*END STEP\n"),
             Contains("deck.inp:31: procedure *BUCKLE is not supported"));
  CHECK_THAT(error_of(kBar + "*STEP\n*BOUNDARY\nFIX, 1\n*END STEP\n"),
             Contains("deck.inp:33: the *STEP has no procedure"));
  CHECK_THAT(error_of(kBar + "*STEP\n*STATIC\n"), Contains("deck.inp:30: *STEP without *END STEP"));
  CHECK_THAT(error_of(kBar + "*STEP\n*STATIC, STABILIZE\n*END STEP\n"),
             Contains("deck.inp:31: parameter STABILIZE of *STATIC is not supported"));
  CHECK_THAT(error_of(kBar + "*AMPLITUDE, NAME=W, DEFINITION=PERIODIC\n1, 1, 0, 0\n0, 1\n"),
             Contains("deck.inp:30: *AMPLITUDE, DEFINITION=PERIODIC is not supported"));
  CHECK_THAT(error_of(kBar + "*AMPLITUDE, NAME=W\n0, 0, 0, 1\n"),
             Contains("deck.inp:30: *AMPLITUDE W: times must increase strictly"));
  CHECK_THAT(error_of(kBar + "*STEP\n*STATIC\n*CLOAD, AMPLITUDE=NOPE\nTIP, 1, 1\n*END STEP\n"),
             Contains("deck.inp:33: amplitude NOPE is not defined"));
}

TEST_CASE("inp *FREQUENCY: a modal analysis, the deck's mode count unless the scene's wins",
          "[inp]") {
  // Issue 34, item 14: *FREQUENCY was refused even under fem.analysis = "modal". The clamp
  // holds nodes 1, 4, 7, 10 of the bar's 12: 24 free DOFs.
  test::TempDir dir;
  const std::string clamped = kBar + "*BOUNDARY\nFIX, ENCASTRE\n";
  const std::string five = clamped + "*STEP\n*FREQUENCY\n5, 0., 1000.\n*END STEP\n";
  const FemScene deck = scene_with_deck(dir, five, "analysis = \"modal\"\n");
  CHECK(deck.analysis == Analysis::modal);
  CHECK(deck.modal.modes == 5);
  CHECK(has_note(deck.notes, "deck.inp:33: 5 modes, as the deck's *FREQUENCY asks"));
  CHECK(has_note(deck.notes, "the data line's other fields (frequency range, shift) are ignored"));
  const FemScene scene =
      scene_with_deck(dir, five, "analysis = \"modal\"\n[fem.modal]\nmodes = 3\n");
  CHECK(scene.modal.modes == 3);
  CHECK(has_note(scene.notes,
                 "fem.modal.modes = 3 wins over the deck's *FREQUENCY (5 "
                 "eigenvalues, "));
  CHECK(has_note(scene.notes, "deck.inp:33)"));
  // Another analysis: refused, naming the deck's line and the key to set.
  CHECK_THAT(scene_error(dir, five),
             Contains("deck.inp:33: the deck's step is *FREQUENCY (natural frequencies), but "
                      "fem.analysis is not given (default \"dynamic\"): set fem.analysis = "
                      "\"modal\""));
  CHECK_THAT(scene_error(dir, five, "analysis = \"static\"\n"),
             Contains("but fem.analysis = \"static\""));
  // More modes than free DOFs: refused when the scene is read (so demfem run --check finds
  // it), naming where the count comes from and the accepted range.
  CHECK_THAT(
      scene_error(dir, clamped + "*STEP\n*FREQUENCY\n30\n*END STEP\n", "analysis = \"modal\"\n"),
      Contains("deck.inp:33: *FREQUENCY: 30 modes asked for, but the model has 24 free "
               "DOFs (the clamped ones eliminated); accepted: 1 to 24"));
  CHECK_THAT(scene_error(dir, five, "analysis = \"modal\"\n[fem.modal]\nmodes = 25\n"),
             Contains("key 'fem.modal.modes': 25 modes asked for, but the model has 24 free DOFs"));
  // Both ends clamped: 12 free DOFs, fewer than the default 20 modes.
  CHECK_THAT(scene_error(dir, clamped + "TIP, ENCASTRE\n", "analysis = \"modal\"\n"),
             Contains("key 'fem.modal': fem.modal.modes is not given, and its default 20 modes "
                      "asked for, but the model has 12 free DOFs"));
  CHECK(scene_error(dir, clamped, "analysis = \"modal\"\n[fem.modal]\nmodes = 24\n") == "no error");
  CHECK_THAT(error_of(kBar + "*STEP\n*FREQUENCY\n0\n*END STEP\n"),
             Contains("deck.inp:32: number of eigenvalues 0 is outside [1, 100000]"));
  CHECK_THAT(error_of(kBar + "*STEP\n*FREQUENCY, STABILIZE\n5\n*END STEP\n"),
             Contains("deck.inp:31: parameter STABILIZE of *FREQUENCY is not supported"));
}

TEST_CASE("inp element types map to named formulations; C3D8R needs the scene's consent", "[inp]") {
  test::TempDir dir;
  std::string c3d8 = kBar;
  c3d8.replace(c3d8.find("C3D8I"), 5, "C3D8");
  const InpModel m = parse_inp(c3d8, "deck.inp");
  CHECK(m.mesh.elements[0].formulation == SolidFormulation::selective_reduced);
  CHECK(has_note(m.notes,
                 "2 C3D8 element(s) -> hex8, full 2x2x2 integration with the "
                 "mean-dilatation B-bar"));
  const InpModel mi = parse_inp(kBar, "deck.inp");
  CHECK(mi.mesh.elements[0].formulation == SolidFormulation::incompatible_modes);
  CHECK(has_note(mi.notes, "2 C3D8I element(s) -> hex8 with incompatible modes"));
  std::string c3d8r = kBar;
  c3d8r.replace(c3d8r.find("C3D8I"), 5, "C3D8R");
  // Issue 19: C3D8R was solved as incompatible modes without a word.
  CHECK_THAT(error_of(c3d8r),
             Contains("deck.inp:14: element type C3D8R") && Contains("fem.mesh.c3d8r_as"));
  CHECK_THAT(scene_error(dir, c3d8r), Contains("'fem.mesh.file'") && Contains("C3D8R"));
  const FemScene mapped = scene_with_deck(dir, c3d8r, "materials = []\n", ", c3d8r_as = \"C3D8I\"");
  CHECK(mapped.problem.mesh.elements[0].formulation == SolidFormulation::incompatible_modes);
  CHECK(has_note(mapped.notes,
                 "2 C3D8R element(s) -> hex8 with incompatible modes (C3D8I), as "
                 "fem.mesh.c3d8r_as asks"));
  CHECK_THAT(scene_error(dir, c3d8r, "", ", c3d8r_as = \"C3D8R\""),
             Contains("'fem.mesh.c3d8r_as'"));
  CHECK_THAT(error_of(kBar + "*ELEMENT, TYPE=C3D20\n9, 1\n"),
             Contains("deck.inp:30: element type C3D20 is not supported (supported: C3D8, C3D8I"));
}

TEST_CASE("inp: every other keyword is refused by name and line, harmless ones accepted", "[inp]") {
  // Unknown and model-changing keywords: refused, with the reason where there is one.
  CHECK_THAT(error_of(kBar + "*FROBNICATE, X=1\n1, 2\n"),
             Contains("deck.inp:30: *FROBNICATE is not supported by demfem's .inp reader") &&
                 Contains("docs/scene_fem.md"));
  CHECK_THAT(
      error_of(kBar + "*EQUATION\n2\n3, 1, 1.0, 6, 1, -1.0\n"),
      Contains("deck.inp:30: *EQUATION is not supported") && Contains("multi-point constraints"));
  CHECK_THAT(error_of(kBar + "*MATERIAL, NAME=W\n*DAMPING, ALPHA=0.1\n"),
             Contains("deck.inp:31: *DAMPING is not supported") && Contains("[fem.damping]"));
  CHECK_THAT(error_of(kBar + "*MATERIAL, NAME=P\n*ELASTIC\n1e9, 0.3\n*PLASTIC\n1e6, 0\n"),
             Contains("deck.inp:33: *PLASTIC is not supported") && Contains("linear elastic"));
  CHECK_THAT(error_of(kBar + "*INITIAL CONDITIONS, TYPE=VELOCITY\nALLN, 1, 1.0\n"),
             Contains("deck.inp:30: *INITIAL CONDITIONS is not supported"));
  CHECK_THAT(error_of(kBar + "*TRANSFORM, NSET=TIP\n1, 0, 0, 0, 1, 0\n"),
             Contains("deck.inp:30: *TRANSFORM is not supported"));
  // A material option that does not follow its *MATERIAL.
  CHECK_THAT(error_of(kBar + "*ELASTIC\n1e9, 0.3\n"),
             Contains("deck.inp:30: *ELASTIC outside of a *MATERIAL"));
  // Shell offsets: refused unless zero.
  const std::string plate = R"(*NODE
1, 0, 0, 0
2, 1, 0, 0
3, 1, 1, 0
4, 0, 1, 0
*ELEMENT, TYPE=S4, ELSET=P
1, 1, 2, 3, 4
*MATERIAL, NAME=AL
*ELASTIC
7e10, 0.33
)";
  CHECK_THAT(error_of(plate + "*SHELL SECTION, ELSET=P, MATERIAL=AL, OFFSET=SPOS\n0.002, 5\n"),
             Contains("deck.inp:11: *SHELL SECTION, OFFSET=SPOS moves the reference surface"));
  CHECK(error_of(plate + "*SHELL SECTION, ELSET=P, MATERIAL=AL, OFFSET=0.0\n0.002, 5\n") ==
        "no error");
  CHECK(error_of(plate + "*SHELL SECTION, ELSET=P, MATERIAL=AL, OFFSET=MIDSURFACE\n0.002\n") ==
        "no error");
  // Harmless: accepted; output requests and *ORIENTATION with a note.
  const InpModel m =
      parse_inp("*HEADING\nmy model\n*PREPRINT, ECHO=NO\n" + plate + R"(*ORIENTATION, NAME=ORI
1, 0, 0, 0, 1, 0
3, 0
*SHELL SECTION, ELSET=P, MATERIAL=AL, ORIENTATION=ORI
0.002, 5
*STEP
*STATIC
*OUTPUT, FIELD
*NODE OUTPUT
U, RF
*ELEMENT OUTPUT
S
*RESTART, WRITE, FREQUENCY=0
*END STEP
)",
                "deck.inp");
  CHECK(has_note(m.notes, "*ORIENTATION accepted: for isotropic materials"));
  CHECK(has_note(m.notes, "ORIENTATION=ORI changes only the frame"));
  CHECK(has_note(m.notes, "output requests and solution controls ignored"));
  CHECK(has_note(m.notes, "*ELEMENT OUTPUT (line 24)"));
  CHECK(has_note(m.notes, "*RESTART"));
  CHECK(has_note(m.notes, "1 S4 element(s) -> quad4 MITC4 shell"));
}

TEST_CASE("inp decks: orphan nodes and element errors reach the scene with file and line",
          "[inp]") {
  test::TempDir dir;
  // An extra node no element uses (Gmsh and CAE exports keep such points).
  const std::string orphan =
      kBar + "*NODE\n99, 5, 5, 5\n" +
      "*STEP\n*STATIC\n*BOUNDARY\nFIX, ENCASTRE\n*CLOAD\nTIP, 3, -1\n*END STEP\n";
  const FemScene s = scene_with_deck(dir, orphan, "analysis = \"static\"\n");
  CHECK(has_note(s.notes,
                 "1 node(s) belong to no element and are left out of the model (node 99 "
                 "(" +
                     (dir.path / "deck.inp").string() + ":31))"));
  CHECK(static_solution(s)[3 * 12 + 2] == 0.0);  // the orphan does not move
  // An inverted element: the message names the deck and its line.
  std::string inverted = kBar;
  inverted.replace(inverted.find("2, 2, 3, 6, 5, 8, 9, 12, 11"), 27, "2, 8, 9, 12, 11, 2, 3, 6, 5");
  CHECK_THAT(scene_error(dir, inverted),
             Contains("'fem.mesh'") && Contains("element 2 (" + (dir.path / "deck.inp").string() +
                                                ":16): non-positive Jacobian"));
  // A material without density in a dynamic analysis: the deck's *MATERIAL line.
  std::string no_density = kBar;
  no_density.replace(no_density.find("*DENSITY\n7850\n"), 14, "");
  CHECK_THAT(scene_error(dir, no_density, "analysis = \"dynamic\"\n"),
             Contains("deck.inp:23: material STEEL: density is 0 (or not given)"));
}

TEST_CASE(
    "inp: a CAE-style deck (part, instance, includes, step) moved and turned solves the "
    "same, turned",
    "[inp]") {
  // tests/fem/io/decks: cantilever_plain.inp and cantilever_moved.inp include the same part
  // and step (*Dsload on the part's surface, *Boundary ENCASTRE on an assembly set); the
  // second moves the instance by (5, 0, 0), then turns it 90 degrees about the x axis. The
  // pressure follows the surface, so u_moved = R u_plain with R: (x, y, z) -> (x, -z, y).
  const auto dir = std::filesystem::path(DEMFEM_SOURCE_DIR) / "tests/fem/io/decks";
  auto solve = [&](const char* deck) {
    const std::string text =
        std::string("[fem]\nanalysis = \"static\"\nmesh = { file = \"") + deck + "\" }\n";
    const auto doc = scene::Document::parse(text, (dir / "scene.toml").string());
    return read_fem_scene(doc.root().required_table("fem"));
  };
  const FemScene plain = solve("cantilever_plain.inp"), moved = solve("cantilever_moved.inp");
  REQUIRE(plain.problem.mesh.nodes.size() == 20);
  CHECK(has_note(moved.notes,
                 "taken from the deck: 1 boundary condition(s), 0 concentrated "
                 "load(s), 1 pressure load(s)"));
  const auto up = static_solution(plain), um = static_solution(moved);
  double scale = 0, err = 0, xerr = 0;
  for (std::size_t n = 0; n < 20; ++n) {
    const auto& a = plain.problem.mesh.nodes[n];
    const auto& b = moved.problem.mesh.nodes[n];
    xerr =
        std::max({xerr, std::abs(b[0] - (a[0] + 5)), std::abs(b[1] + a[2]), std::abs(b[2] - a[1])});
    const double r[3] = {up[3 * n], -up[3 * n + 2], up[3 * n + 1]};
    for (int c = 0; c < 3; ++c) {
      scale = std::max(scale, std::abs(r[c]));
      err = std::max(err, std::abs(um[3 * n + static_cast<std::size_t>(c)] - r[c]));
    }
  }
  CHECK(xerr < 1e-12);
  CHECK(scale > 1e-6);  // 20 kPa on a 2 m steel cantilever bends it visibly
  CHECK(err < 1e-9 * scale);
  // The tip deflects down (-z) in the plain deck: the pressure pushes on the top face.
  CHECK(up[3 * 4 + 2] < 0.0);
}
