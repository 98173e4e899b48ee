// Abaqus .inp reader: each element type, sets (plain, GENERATE, nested), surfaces with the
// Abaqus face numbering, materials and sections, and a file:line message for every kind of
// malformed input.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <sstream>
#include <string>

#include "demfem/fem/inp_reader.hpp"
#include "demfem/fem/node_selector.hpp"
#include "demfem_test/error_of.hpp"

using namespace demfem::fem;

namespace {

std::filesystem::path mesh_file(const std::string& name) {
  return std::filesystem::path(DEMFEM_SOURCE_DIR) / "cases" / "meshes" / name;
}

std::set<std::int64_t> labels_of(const Mesh& m, const std::vector<std::int32_t>& nodes) {
  std::set<std::int64_t> out;
  for (auto n : nodes) out.insert(m.node_labels[static_cast<std::size_t>(n)]);
  return out;
}

// Outward normal of a face by Newell's formula on its ordered nodes.
std::array<double, 3> face_normal(const Mesh& m, const Face& f) {
  auto fn = face_nodes(m, f);
  std::array<double, 3> n{0, 0, 0};
  for (std::size_t i = 0; i < fn.size(); ++i) {
    const auto& a = m.nodes[static_cast<std::size_t>(fn[i])];
    const auto& b = m.nodes[static_cast<std::size_t>(fn[(i + 1) % fn.size()])];
    n[0] += (a[1] - b[1]) * (a[2] + b[2]);
    n[1] += (a[2] - b[2]) * (a[0] + b[0]);
    n[2] += (a[0] - b[0]) * (a[1] + b[1]);
  }
  return n;
}

std::string error_of(const std::string& text) {
  return demfem::test::error_of<InpError>([&] { parse_inp(text, "beam.inp"); }, "no error");
}

const std::string kNodes =
    "*NODE\n"        // line 1
    "1, 0, 0, 0\n"   // 2
    "2, 1, 0, 0\n"   // 3
    "3, 0, 1, 0\n"   // 4
    "4, 0, 0, 1\n";  // 5

}  // namespace

TEST_CASE("hex8 .inp: nodes, labels, sets, GENERATE, surfaces, material, section") {
  const InpModel m = read_inp_model(mesh_file("unit_hex.inp"));
  const Mesh& mesh = m.mesh;
  REQUIRE(mesh.nodes.size() == 8);
  REQUIRE(mesh.elements.size() == 1);
  CHECK(mesh.node_labels.front() == 101);
  CHECK(mesh.element_labels.front() == 7);
  CHECK(mesh.elements[0].type == ElementType::hex8);
  // The element joined over a continuation line, node labels mapped to indices 0..7.
  for (int k = 0; k < 8; ++k) CHECK(mesh.elements[0].nodes[static_cast<std::size_t>(k)] == k);
  CHECK(mesh.nodes[6] == std::array<double, 3>{1.0, 1.0, 1.0});

  CHECK(labels_of(mesh, mesh.node_sets.at("BOTTOM")) == std::set<std::int64_t>{101, 102, 103, 104});
  CHECK(labels_of(mesh, mesh.node_sets.at("ODD")) == std::set<std::int64_t>{101, 103, 105, 107});
  CHECK(labels_of(mesh, mesh.node_sets.at("BOTHSETS")) ==
        std::set<std::int64_t>{101, 102, 103, 104, 105, 107});
  CHECK(mesh.node_sets.at("ALLNODES").size() == 8);
  CHECK(mesh.element_sets.at("ALL_ELEMS") == std::vector<std::int32_t>{0});
  CHECK(mesh.element_sets.at("CUBE") == std::vector<std::int32_t>{0});

  // Abaqus C3D8 faces: S1 = 1-2-3-4 (z = 0), S2 = 5-6-7-8 (z = 1), S3 = 1-2-6-5 (y = 0),
  // S4 = 2-3-7-6 (x = 1), S5 = 3-4-8-7 (y = 1), S6 = 4-1-5-8 (x = 0) for the standard
  // node order of the unit cube; the outward normal of each follows.
  const std::array<std::set<std::int64_t>, 6> face_labels{{{101, 102, 103, 104},
                                                           {105, 106, 107, 108},
                                                           {101, 102, 106, 105},
                                                           {102, 103, 107, 106},
                                                           {103, 104, 108, 107},
                                                           {104, 101, 105, 108}}};
  const std::array<std::array<double, 3>, 6> normals{
      {{0, 0, -1}, {0, 0, 1}, {0, -1, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}}};
  for (int s = 0; s < 6; ++s) {
    const std::string name = std::string("S") + char('1' + s) + "SURF";
    const auto& surf = mesh.surfaces.at(name);
    REQUIRE(surf.size() == 1);
    CHECK(surf[0].face == s);
    CHECK(labels_of(mesh, face_nodes(mesh, surf[0])) == face_labels[static_cast<std::size_t>(s)]);
    const auto n = face_normal(mesh, surf[0]);
    for (int k = 0; k < 3; ++k) CHECK(n[k] == Approx(2.0 * normals[s][k]).margin(1e-12));
  }

  REQUIRE(m.materials.size() == 1);
  CHECK(m.materials[0].name == "STEEL");
  CHECK(m.materials[0].youngs_modulus == 2.1e11);
  CHECK(m.materials[0].poisson_ratio == 0.3);
  CHECK(m.materials[0].density == 7850.0);
  REQUIRE(m.sections.size() == 1);
  CHECK(m.sections[0].element_set == "CUBE");
  CHECK(m.sections[0].material == "STEEL");
  CHECK_FALSE(m.sections[0].shell);
}

TEST_CASE("tet4 .inp: Abaqus C3D4 faces and exterior faces") {
  const Mesh mesh = read_inp(mesh_file("two_tets.inp"));
  REQUIRE(mesh.elements.size() == 2);
  CHECK(mesh.elements[1].type == ElementType::tet4);
  // C3D4: S1 = 1-2-3 (opposite node 4), S3 = 2-4-3 (opposite node 1).
  const auto& base = mesh.surfaces.at("BASE");
  REQUIRE(base.size() == 1);
  CHECK(labels_of(mesh, face_nodes(mesh, base[0])) == std::set<std::int64_t>{1, 2, 3});
  const auto nb = face_normal(mesh, base[0]);
  CHECK(nb[2] < 0.0);  // z = 0 face of the first tet points down, out of it
  const auto& opp = mesh.surfaces.at("OPPOSITE1");
  CHECK(labels_of(mesh, face_nodes(mesh, opp[0])) == std::set<std::int64_t>{2, 3, 4});
  const auto no = face_normal(mesh, opp[0]);
  CHECK(no[0] > 0.0);  // points away from node 1 at the origin
  CHECK(no[1] > 0.0);
  CHECK(no[2] > 0.0);
  // Every outward normal of an element points away from its centroid.
  for (std::int32_t e = 0; e < 2; ++e) {
    std::array<double, 3> c{0, 0, 0};
    for (int k = 0; k < 4; ++k) {
      for (int d = 0; d < 3; ++d) {
        c[d] += 0.25 * mesh.nodes[static_cast<std::size_t>(mesh.elements[e].nodes[k])][d];
      }
    }
    for (int f = 0; f < 4; ++f) {
      const auto fn = face_nodes(mesh, {e, f});
      const auto n = face_normal(mesh, {e, f});
      const auto& p = mesh.nodes[static_cast<std::size_t>(fn[0])];
      CHECK(n[0] * (p[0] - c[0]) + n[1] * (p[1] - c[1]) + n[2] * (p[2] - c[2]) > 0.0);
    }
  }
  // The shared face 2-3-4 is interior: 8 faces, 6 exterior.
  CHECK(exterior_faces(mesh).size() == 6);
}

TEST_CASE("quad4 .inp: S4R shells, SPOS/SNEG surfaces and shell section") {
  const InpModel m = read_inp_model(mesh_file("plate_s4r.inp"));
  REQUIRE(m.mesh.elements.size() == 2);
  CHECK(m.mesh.elements[0].type == ElementType::quad4);
  CHECK(m.mesh.surfaces.at("TOP")[0].face == 1);
  CHECK(m.mesh.surfaces.at("BOTTOM")[0].face == 0);
  CHECK(face_normal(m.mesh, m.mesh.surfaces.at("TOP")[0])[2] > 0.0);
  CHECK(face_normal(m.mesh, m.mesh.surfaces.at("BOTTOM")[0])[2] < 0.0);
  REQUIRE(m.sections.size() == 1);
  CHECK(m.sections[0].shell);
  CHECK(m.sections[0].thickness == 0.002);
  CHECK(face_area(m.mesh, {0, 1}) == Approx(0.5));
}

TEST_CASE("malformed .inp input names the file and line") {
  // Unknown element type.
  CHECK_THAT(error_of(kNodes + "*ELEMENT, TYPE=C3D20\n1, 1, 2, 3, 4\n"),
             Catch::Contains("beam.inp:6: element type C3D20 is not supported"));
  // Element references a node that is not defined.
  CHECK_THAT(error_of(kNodes + "*ELEMENT, TYPE=C3D4\n12, 1, 2, 3, 99\n"),
             Catch::Contains("beam.inp:7: element 12 references node 99, which is not defined"));
  // Truncated node line.
  CHECK_THAT(error_of(kNodes + "5, 1.0, 2.0\n"),
             Catch::Contains("beam.inp:6: node 5 has 2 coordinates, needs 3"));
  // NaN and non-numbers.
  CHECK_THAT(error_of(kNodes + "5, 1.0, nan, 0\n"),
             Catch::Contains("beam.inp:6: coordinate y of node 5 is nan, not a finite number"));
  CHECK_THAT(error_of(kNodes + "5, 1.0, 2.x, 0\n"),
             Catch::Contains("beam.inp:6: coordinate y of node 5 '2.x' is not a number"));
  CHECK_THAT(error_of(kNodes + "*ELEMENT, TYPE=C3D4\n1, 1, 2, three, 4\n"),
             Catch::Contains("beam.inp:7: node of element 1 'three' is not an integer label"));
  // Duplicate labels.
  CHECK_THAT(error_of(kNodes + "3, 5, 5, 5\n"),
             Catch::Contains("beam.inp:6: node 3 is defined twice (first on line 4)"));
  CHECK_THAT(error_of(kNodes + "*ELEMENT, TYPE=C3D4\n1, 1, 2, 3, 4\n1, 1, 2, 3, 4\n"),
             Catch::Contains("beam.inp:8: element 1 is defined twice (first on line 7)"));
  // Wrong node count (truncated element line).
  CHECK_THAT(error_of(kNodes + "*ELEMENT, TYPE=C3D8\n1, 1, 2, 3, 4\n"),
             Catch::Contains("beam.inp:7: element 1 has 4 nodes, C3D8 needs 8"));
  CHECK_THAT(error_of(kNodes + "*ELEMENT, TYPE=S4R\n1, 1, 2, 3\n"),
             Catch::Contains("beam.inp:7: element 1 has 3 nodes, S4R needs 4"));
  // Sets and surfaces that refer to what does not exist.
  CHECK_THAT(error_of(kNodes + "*NSET, NSET=A\n1, 2, 77\n"),
             Catch::Contains("beam.inp:7: node set A references node 77, which is not defined"));
  CHECK_THAT(error_of(kNodes + "*NSET, NSET=A\nNOPE\n"),
             Catch::Contains("beam.inp:7: node set NOPE is not defined"));
  CHECK_THAT(error_of(kNodes + "*ELEMENT, TYPE=C3D4\n1, 1, 2, 3, 4\n*SURFACE, NAME=S\n1, S5\n"),
             Catch::Contains("beam.inp:9: surface S: face S5 is not one of S1..S4"));
  CHECK_THAT(error_of(kNodes + "*NSET, NSET=A, GENERATE\n1, 4, 0\n"),
             Catch::Contains("beam.inp:7: GENERATE value 0 must be a positive label"));
  // Data before any keyword, material data out of range, section with a missing material.
  CHECK_THAT(error_of("1, 0, 0, 0\n"), Catch::Contains("beam.inp:1: data line outside"));
  CHECK_THAT(error_of("*MATERIAL, NAME=M\n*ELASTIC\n1e9, 0.7\n"),
             Catch::Contains("beam.inp:3: Poisson's ratio must be in (-1, 0.5)"));
  CHECK_THAT(error_of(kNodes + "*ELEMENT, TYPE=C3D4, ELSET=E\n1, 1, 2, 3, 4\n"
                               "*SOLID SECTION, ELSET=E, MATERIAL=WOOD\n"),
             Catch::Contains("beam.inp:8: section refers to material WOOD, which is not defined"));
  // A missing file names the file.
  CHECK_THROWS_WITH(read_inp("/nonexistent/beam.inp"),
                    Catch::Contains("/nonexistent/beam.inp: cannot open: no such file; expected an Abaqus input file"));
}

TEST_CASE("mutated .inp files parse or fail with a file:line message, never otherwise") {
  // 600 deterministic mutations of a valid file (delete, duplicate or replace a character,
  // drop a line); each must either parse or throw InpError naming "beam.inp:<line>:".
  std::ifstream in(mesh_file("beam_hex.inp"));
  std::stringstream buf;
  buf << in.rdbuf();
  const std::string original = buf.str();
  std::mt19937_64 rng(12345);
  const std::string alphabet = "0123456789,.-eE*xn \n";
  int failures = 0;
  int parsed = 0;
  for (int trial = 0; trial < 600; ++trial) {
    std::string text = original;
    const int edits = 1 + static_cast<int>(rng() % 3);
    for (int e = 0; e < edits; ++e) {
      const std::size_t pos = rng() % text.size();
      switch (rng() % 4) {
        case 0:
          text.erase(pos, 1);
          break;
        case 1:
          text.insert(pos, 1, text[pos]);
          break;
        case 2:
          text[pos] = alphabet[rng() % alphabet.size()];
          break;
        case 3: {
          const auto a = text.rfind('\n', pos);
          const auto b = text.find('\n', pos);
          if (a != std::string::npos && b != std::string::npos) text.erase(a, b - a);
          break;
        }
      }
    }
    try {
      parse_inp(text, "beam.inp");
      ++parsed;
    } catch (const InpError& err) {
      const std::string what = err.what();
      const bool located = what.rfind("beam.inp:", 0) == 0 && what.size() > 9 &&
                           std::isdigit(static_cast<unsigned char>(what[9]));
      if (!located) {
        ++failures;
        UNSCOPED_INFO("unlocated message: " << what);
      }
    } catch (const std::exception& err) {
      ++failures;
      UNSCOPED_INFO("other exception: " << err.what());
    }
  }
  CHECK(failures == 0);
  CHECK(parsed > 0);  // some mutations (in coordinates) leave a valid file
  CHECK(parsed < 600);
}
