// The [fem] scene section: a complete scene read into a FemProblem, and errors that name the
// file, line and key.
#include <catch2/catch.hpp>

#include <filesystem>
#include <string>

#include "demfem/fem/fem_scene.hpp"
#include "demfem_test/error_of.hpp"

using namespace demfem;
using namespace demfem::fem;

namespace {

// Scenes are parsed as if they lived in cases/meshes/, so mesh files resolve there.
const std::string kSceneName =
    (std::filesystem::path(DEMFEM_SOURCE_DIR) / "cases/meshes/test_scene.toml").string();

FemScene read(const std::string& text) {
  const auto doc = scene::Document::parse(text, kSceneName);
  return read_fem_scene(doc.root().required_table("fem"));
}

std::string error_of(const std::string& text) {
  return demfem::test::error_of<scene::SceneError>([&] { read(text); }, "no error");
}

const std::string kBox = R"([fem]
mesh = { box = { lo = [0, 0, 0], hi = [2, 0.2, 0.2], cells = [10, 1, 1] } }
materials = [{ name = "steel", youngs_modulus = 2.1e11, poisson_ratio = 0.3, density = 7850 }]
)";

}  // namespace

TEST_CASE("fem scene: box mesh, clamps, loads, amplitudes, dynamics settings") {
  const FemScene s = read(kBox + R"(
analysis = "dynamic"
dt = 1e-4
gravity = [0, 0, -9.81]
mass = "lumped"
interface_surface = "z >= 0.2"
[[fem.clamps]]
nodes = "x <= 0"
[[fem.clamps]]
nodes = "x >= 2"
dofs = ["z"]
[[fem.pressures]]
surface = "zmax"
total_force = 1.0
amplitude = { type = "sleeper", time_scale = 10 }
[[fem.pressures]]
surface = "z >= 0.2 and x <= 1"
magnitude = 5e3
amplitude = { type = "table", points = [[0, 0], [1, 2]] }
[[fem.nodal_loads]]
nodes = "x >= 2 and y >= 0.2 and z >= 0.2"
force = [0, 0, -10]
amplitude = { type = "sine", amplitude = 1, frequency = 5 }
[fem.bossak]
alpha = -0.2
[fem.damping]
mass_factor = 0.5
stiffness_factor = 1e-5
[fem.output]
interval = 0.01
fields = ["displacement", "von_mises"]
)");
  const FemProblem& p = s.problem;
  CHECK(s.analysis == Analysis::dynamic);
  CHECK(s.dt == 1e-4);
  CHECK(p.mesh.elements.size() == 10);
  REQUIRE(p.sections.size() == 1);
  CHECK(p.materials[0].youngs_modulus == 2.1e11);
  REQUIRE(p.constraints.size() == 2);
  CHECK(p.constraints[0].nodes.size() == 4);
  CHECK(p.constraints[0].fixed == std::array<bool, 6>{true, true, true, true, true, true});
  CHECK(p.constraints[1].fixed == std::array<bool, 6>{false, false, true, false, false, false});
  REQUIRE(p.pressures.size() == 2);
  CHECK(p.pressures[0].faces.size() == 10);
  // total_force 1 N over the 2 x 0.2 m top: 2.5 Pa per newton of the amplitude.
  CHECK(p.pressures[0].magnitude == Approx(2.5));
  CHECK(p.pressures[0].amplitude(0.15) == Approx(110e3));  // sleeper ramp, time scale 10
  CHECK(p.pressures[1].faces.size() == 5);
  CHECK(p.pressures[1].amplitude(0.5) == Approx(1.0));
  REQUIRE(p.nodal_loads.size() == 1);
  CHECK(p.nodal_loads[0].nodes.size() == 1);
  CHECK(p.nodal_loads[0].amplitude(0.05) == Approx(1.0));  // sin(pi/2)
  CHECK(p.gravity[2] == -9.81);
  CHECK(p.mass == MassLumping::lumped);
  CHECK(p.bossak.alpha == -0.2);
  CHECK(p.bossak.gamma == Approx(0.7));
  CHECK(p.bossak.beta == Approx(0.36));
  CHECK(p.damping.mass_factor == 0.5);
  CHECK(p.interface_surface == "interface_surface");
  CHECK(p.mesh.surfaces.at("interface_surface").size() == 10);
  CHECK(s.output.interval == 0.01);
  CHECK(s.output.fields == std::vector<std::string>{"displacement", "von_mises"});
}

TEST_CASE("fem scene: .inp mesh with its own materials and sections") {
  const FemScene s = read(R"([fem]
analysis = "static"
mesh = { file = "plate_s4r.inp" }
[[fem.clamps]]
nodes = "EDGE"
)");
  CHECK(s.analysis == Analysis::static_analysis);
  CHECK(s.problem.mesh.elements.size() == 2);
  REQUIRE(s.problem.sections.size() == 1);
  CHECK(s.problem.sections[0].thickness == 0.002);
  CHECK(s.problem.materials[s.problem.sections[0].material].density == 7800.0);
  CHECK(s.problem.interface_surface.empty());
  CHECK(s.output.fields.size() == 7);  // all by default
}

TEST_CASE("fem scene: errors name file, line and key") {
  // Unknown key.
  CHECK_THAT(error_of(kBox + "damping_ratio = 0.1\n"),
             Catch::Contains("test_scene.toml:4:17: key 'fem.damping_ratio'") &&
                 Catch::Contains("not a known key"));
  // Value out of range.
  CHECK_THAT(error_of(R"([fem]
mesh = { box = { lo = [0, 0, 0], hi = [1, 1, 1], cells = [1, 1, 1] } }
[[fem.materials]]
name = "m"
youngs_modulus = 1e9
poisson_ratio = 0.6
density = 1000
)"),
             Catch::Contains("test_scene.toml:6:17: key 'fem.materials[0].poisson_ratio'") &&
                 Catch::Contains("outside the accepted range (-1, 0.5)"));
  // NaN.
  CHECK_THAT(error_of(kBox + "gravity = [0, 0, nan]\n"), Catch::Contains("test_scene.toml:4:") &&
                                                             Catch::Contains("'fem.gravity'") &&
                                                             Catch::Contains("must be finite"));
  // Negative time step.
  CHECK_THAT(error_of(kBox + "dt = -1e-3\n"),
             Catch::Contains("test_scene.toml:4:6: key 'fem.dt'") && Catch::Contains("(0, 1e+06]"));
  // Missing mesh file: the scene key and the file.
  CHECK_THAT(error_of("[fem]\nmesh = { file = \"no_such_beam.inp\" }\n"),
             Catch::Contains("test_scene.toml:2:") && Catch::Contains("'fem.mesh.file'") &&
                 Catch::Contains("no_such_beam.inp: cannot open: no such file"));
  // Issue 19: a directory said "has no elements", /dev/zero grew to 4 GB.
  CHECK_THAT(error_of("[fem]\nmesh = { file = \".\" }\n"),
             Catch::Contains("'fem.mesh.file'") &&
                 Catch::Contains("is a directory, not a regular file; expected an Abaqus input "
                                 "file (.inp)"));
  CHECK_THAT(error_of("[fem]\nmesh = { file = \"/dev/zero\" }\n"),
             Catch::Contains("/dev/zero: is a character device, not a regular file"));
  // A malformed mesh file: both the scene key and the .inp line.
  CHECK_THAT(error_of("[fem]\nmesh = { file = \"malformed_missing_node.inp\" }\n"),
             Catch::Contains("test_scene.toml:2:") && Catch::Contains("'fem.mesh.file'") &&
                 Catch::Contains("malformed_missing_node.inp:7: element 12 references node 99, "
                                 "which is not defined"));
  // A selector that selects nothing.
  CHECK_THAT(
      error_of("[fem]\nmesh = { file = \"plate_s4r.inp\" }\n[[fem.clamps]]\nnodes = \"x <= -5\"\n"),
      Catch::Contains("test_scene.toml:4:9: key 'fem.clamps[0].nodes'") &&
          Catch::Contains("selects no node"));
  CHECK_THAT(error_of(kBox + "[[fem.clamps]]\nnodes = \"x <= 0\"\ndofs = [\"x\", \"q\"]\n"),
             Catch::Contains("'fem.clamps[0].dofs'") && Catch::Contains("\"q\" is not a DOF"));
  CHECK_THAT(error_of(kBox + "[[fem.sections]]\nmaterial = \"wood\"\n"),
             Catch::Contains("test_scene.toml:5:12: key 'fem.sections[0].material'"));
  CHECK_THAT(error_of(kBox + "[[fem.pressures]]\nsurface = \"zmax\"\nmagnitude = 1\n"
                             "amplitude = { type = \"table\", points = [[0, 0], [0, 1]] }\n"),
             Catch::Contains("'fem.pressures[0].amplitude.points'") &&
                 Catch::Contains("increase strictly"));
  CHECK_THAT(error_of(R"([fem]
mesh = { box = { lo = [0, 0, 0], hi = [1, 1, 1], cells = [0, 1, 1] } }
)"),
             Catch::Contains("'fem.mesh.box.cells'") && Catch::Contains("[1, 1e+06]"));
  CHECK_THAT(error_of(R"([fem]
mesh = { box = { lo = [0, 0, 0], hi = [1, 1, 1], cells = [1000, 1000, 1000] } }
)"),
             Catch::Contains("'fem.mesh.box.cells'") && Catch::Contains("at most 2e7"));
  CHECK_THAT(error_of(kBox + "[fem.output]\nfields = [\"stress\"]\n"),
             Catch::Contains("'fem.output.fields'") && Catch::Contains("not an output field"));
}

TEST_CASE("fem scene: values the solver cannot use are refused upfront, naming the key") {
  // Issue 19: density 0 passed and crashed fem_server (SIGSEGV in the factorisation).
  const std::string massless = R"([fem]
mesh = { box = { lo = [0, 0, 0], hi = [2, 0.2, 0.2], cells = [10, 1, 1] } }
materials = [{ name = "foam", youngs_modulus = 1e6, poisson_ratio = 0.3, density = 0 }]
)";
  const std::string clamp = "[[fem.clamps]]\nnodes = \"x <= 0\"\n";
  CHECK_THAT(error_of(massless + "analysis = \"dynamic\"\n" + clamp),
             Catch::Contains("test_scene.toml:3:") &&
                 Catch::Contains("'fem.materials[0].density'") &&
                 Catch::Contains("fem.analysis = \"dynamic\" needs mass"));
  // Static analysis needs no mass ...
  CHECK_NOTHROW(read(massless + "analysis = \"static\"\n" + clamp));
  // ... unless gravity asks for the weight.
  CHECK_THAT(
      error_of(massless + "analysis = \"static\"\ngravity = [0, 0, -9.81]\n" + clamp),
      Catch::Contains("'fem.materials[0].density'") && Catch::Contains("fem.gravity is set"));
  // Typo guards on the material.
  CHECK_THAT(
      error_of(R"([fem]
mesh = { box = { lo = [0, 0, 0], hi = [2, 0.2, 0.2], cells = [10, 1, 1] } }
materials = [{ name = "s", youngs_modulus = 2.1e20, poisson_ratio = 0.3, density = 7850 }]
)"),
      Catch::Contains("'fem.materials[0].youngs_modulus'") && Catch::Contains("[0.001, 1e+14]"));
  CHECK_THAT(error_of(R"([fem]
mesh = { box = { lo = [0, 0, 0], hi = [2, 0.2, 0.2], cells = [10, 1, 1] } }
materials = [{ name = "s", youngs_modulus = 2.1e11, poisson_ratio = 0.5, density = 7850 }]
)"),
             Catch::Contains("'fem.materials[0].poisson_ratio'") && Catch::Contains("(-1, 0.5)"));
  // Bossak parameters: alpha outside [-1/3, 0], and gamma/beta that make the step unstable
  // (beta < gamma / 2: amplifies high frequencies), found by the spectral radius.
  CHECK_THAT(error_of(kBox + "[fem.bossak]\nalpha = -0.5\n"),
             Catch::Contains("'fem.bossak.alpha'") && Catch::Contains("[-0.333333, 0]"));
  CHECK_THAT(error_of(kBox + "[fem.bossak]\nalpha = 0\ngamma = 0.6\nbeta = 0.2\n"),
             Catch::Contains("'fem.bossak.beta'") && Catch::Contains("unstable") &&
                 Catch::Contains("spectral radius"));
  CHECK_NOTHROW(read(kBox + "[fem.bossak]\nalpha = 0\ngamma = 0.5\nbeta = 0.25\n"));
  // Damping and time step bounds.
  CHECK_THAT(error_of(kBox + "[fem.damping]\nstiffness_factor = 10\n"),
             Catch::Contains("'fem.damping.stiffness_factor'") && Catch::Contains("[0, 1]"));
  CHECK_THAT(error_of(kBox + "dt = 0\n"), Catch::Contains("'fem.dt'"));
  // Box cells too flat, or too small for their coordinates.
  CHECK_THAT(error_of(R"([fem]
mesh = { box = { lo = [0, 0, 0], hi = [1, 1e-5, 1], cells = [1, 1, 1] } }
materials = [{ name = "s", youngs_modulus = 2.1e11, poisson_ratio = 0.3, density = 7850 }]
)"),
             Catch::Contains("'fem.mesh.box.cells'") && Catch::Contains("aspect ratio"));
  CHECK_THAT(error_of(R"([fem]
mesh = { box = { lo = [1e6, 0, 0], hi = [1000000.0000001, 1, 1], cells = [1, 1, 1] } }
materials = [{ name = "s", youngs_modulus = 2.1e11, poisson_ratio = 0.3, density = 7850 }]
)"),
             Catch::Contains("'fem.mesh.box.cells'") &&
                 Catch::Contains("cannot be told apart in double precision"));
  // Shell thickness against the element size (bending lost to round-off below 1e-5).
  CHECK_THAT(error_of(R"([fem]
analysis = "static"
mesh = { plate = { size = [1, 1], cells = [2, 2] } }
materials = [{ name = "s", youngs_modulus = 2.1e11, poisson_ratio = 0.3, density = 7850 }]
[[fem.sections]]
material = "s"
thickness = 1e-7
)"),
             Catch::Contains("'fem.mesh'") && Catch::Contains("below 1e-5 of its longest edge"));
}

TEST_CASE("fem scene: [fem.rigid] names each held DOF once (issue 34, item 15)") {
  // fixed = ["x", "x", "x"] was accepted as if it held one DOF.
  const std::string rigid = kBox + "backend = \"rigid\"\n[fem.rigid]\n";
  CHECK_THAT(error_of(rigid + "fixed = [\"x\", \"x\", \"x\"]\n"),
             Catch::Contains("test_scene.toml:6:") && Catch::Contains("'fem.rigid.fixed'") &&
                 Catch::Contains("names \"x\" twice") &&
                 Catch::Contains("each at most once, not all six"));
  CHECK_THAT(error_of(rigid + "fixed = [\"y\", \"RZ\", \"rz\"]\n"),
             Catch::Contains("names \"rz\" twice"));
  CHECK(read(rigid + "fixed = [\"x\", \"y\", \"rz\"]\n").rigid.fixed ==
        std::array<bool, 6>{true, true, false, false, false, true});
}

TEST_CASE("fem scene: the sleeper pattern by cycle count, per rail seat or in total") {
  // 4 cycles at 2 Hz after a 0.5 s ramp: the cyclic stage ends at 0.5 + 2 s, the second ramp
  // reaches the peak at 3 s (as cycle_duration = 2 would)
  const std::string base = kBox + "[[fem.pressures]]\nsurface = \"zmax\"\ntotal_force = 1.0\n";
  const FemScene a = read(base +
                          "amplitude = { type = \"sleeper\", cycles = 4, cycle_frequency = "
                          "2, ramp_duration = 0.5 }\n");
  const FemScene b = read(base +
                          "amplitude = { type = \"sleeper\", cycle_duration = 2, "
                          "cycle_frequency = 2, ramp_duration = 0.5 }\n");
  for (double t : {0.2, 0.75, 1.6, 2.4, 2.75, 3.0, 4.0})
    CHECK(a.problem.pressures[0].amplitude(t) == b.problem.pressures[0].amplitude(t));
  CHECK(a.problem.pressures[0].amplitude(3.0) == Approx(220e3));  // the peak, in N
  // in total over two seats: each seat gets half
  const FemScene c = read(base +
                          "amplitude = { type = \"sleeper\", cycles = 4, cycle_frequency = "
                          "2, ramp_duration = 0.5, force_is = \"total\" }\n");
  for (double t : {0.2, 0.75, 1.6, 3.0})
    CHECK(c.problem.pressures[0].amplitude(t) == Approx(0.5 * a.problem.pressures[0].amplitude(t)));
  const FemScene d = read(base +
                          "amplitude = { type = \"sleeper\", cycles = 4, cycle_frequency = "
                          "2, ramp_duration = 0.5, start_time = 0.25 }\n");
  CHECK(d.problem.pressures[0].amplitude(0.2) == 0.0);
  for (double t : {0.2, 0.75, 1.6, 3.0})
    CHECK(d.problem.pressures[0].amplitude(t + 0.25) == a.problem.pressures[0].amplitude(t));
  CHECK_THAT(
      error_of(base + "amplitude = { type = \"sleeper\", cycles = 4, cycle_duration = 1 }\n"),
      Catch::Contains("'fem.pressures[0].amplitude.cycles'") && Catch::Contains("not both"));
  CHECK_THAT(error_of(base + "amplitude = { type = \"sleeper\", cycles = 0 }\n"),
             Catch::Contains("'fem.pressures[0].amplitude.cycles'"));
  CHECK_THAT(error_of(base + "amplitude = { type = \"sleeper\", seats = 3 }\n"),
             Catch::Contains("'fem.pressures[0].amplitude.seats'") && Catch::Contains("force_is"));
  // a finite unloading from the peak: the cycles (and all after them) start 0.25 s later
  const FemScene u = read(base +
                          "amplitude = { type = \"sleeper\", cycles = 4, cycle_frequency = "
                          "2, ramp_duration = 0.5, unload_duration = 0.25 }\n");
  CHECK(u.problem.pressures[0].amplitude(0.625) == Approx(0.5 * (220e3 + 4.4e3)));
  for (double t : {0.75, 1.6, 2.4, 2.75, 3.0, 4.0})
    CHECK(u.problem.pressures[0].amplitude(t + 0.25) == a.problem.pressures[0].amplitude(t));
  CHECK_THAT(
      error_of(base + "amplitude = { type = \"sleeper\", unload_duration = -0.1 }\n"),
      Catch::Contains("'fem.pressures[0].amplitude.unload_duration'") && Catch::Contains(">= 0"));
}
