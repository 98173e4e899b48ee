// FemOutput: HDF5 step files re-read exactly, every dataset the XDMF names exists with the
// stated dimensions, the CSV series, and no partial file left behind.
#include <catch2/catch.hpp>

#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

#include "demfem/fem/fem_output.hpp"
#include "demfem/fem/inp_reader.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem;
using namespace demfem::fem;

namespace {

using demfem::test::read_text;
using demfem::test::TempDir;

/// A mixed mesh: the unit hex (nodes 0..7) plus a shell quad on its top face and a tet.
Mesh mixed_mesh() {
  Mesh m = read_inp(std::filesystem::path(DEMFEM_SOURCE_DIR) / "cases/meshes/unit_hex.inp");
  m.nodes.push_back({0.5, 0.5, 2.0});
  Element quad;
  quad.type = ElementType::quad4;
  quad.nodes = {4, 5, 6, 7, 0, 0, 0, 0};
  m.elements.push_back(quad);
  Element tet;
  tet.type = ElementType::tet4;
  tet.nodes = {4, 5, 6, 8, 0, 0, 0, 0};
  m.elements.push_back(tet);
  m.node_labels.push_back(200);
  m.element_labels.push_back(8);
  m.element_labels.push_back(9);
  return m;
}

FemFields fields_at(double t, std::size_t nodes, std::size_t elements) {
  FemFields f;
  f.time = t;
  for (std::size_t i = 0; i < 3 * nodes; ++i) {
    f.displacement.push_back(t * 1e-3 * static_cast<double>(i));
    f.velocity.push_back(t + static_cast<double>(i));
    f.acceleration.push_back(-t * static_cast<double>(i));
    f.reaction_force.push_back(i % 3 == 2 ? 10.0 * t : 0.0);
  }
  for (std::size_t e = 0; e < elements; ++e) {
    f.elements.von_mises.push_back(1e6 * t + static_cast<double>(e));
    f.elements.max_principal_strain.push_back(1e-4 * t * static_cast<double>(e + 1));
    for (int k = 0; k < 6; ++k) f.elements.strain.push_back(1e-5 * static_cast<double>(10 * e + k));
  }
  return f;
}

}  // namespace

TEST_CASE("FemOutput: HDF5 + XDMF of a mixed mesh re-read, references valid, CSV series") {
  TempDir tmp;
  const Mesh mesh = mixed_mesh();
  const std::size_t n = mesh.nodes.size();
  const std::size_t ne = mesh.elements.size();
  FemOutput out(tmp.path, "run", mesh);
  CHECK(std::filesystem::exists(out.mesh_path()));
  CHECK(read_text(out.xdmf_path()).find("CollectionType=\"Temporal\"") != std::string::npos);
  for (int s = 0; s < 3; ++s) out.write(fields_at(0.1 * (s + 1), n, ne));
  REQUIRE(out.steps() == 3);

  // Re-read the second output (file 1: the series is numbered from 0) and compare exactly
  // with what was written.
  const FemFields f2 = fields_at(0.2, n, ne);
  io::H5File h5(out.step_path(1), io::H5File::Mode::read);
  CHECK(out.step_path(1).filename() == "run_000001.h5");
  CHECK(h5.attribute_double("/", "time") == 0.2);
  CHECK(h5.attribute_double("/", "state_time") == 0.2);
  std::vector<std::size_t> dims;
  CHECK(h5.read_doubles("displacement", &dims) == f2.displacement);
  CHECK(dims == std::vector<std::size_t>{n, 3});
  CHECK(h5.read_doubles("reaction_force") == f2.reaction_force);
  // Cell data is split by element type: the hex is element 0, the quad 1, the tet 2.
  CHECK(h5.read_doubles("hex8/von_mises") == std::vector<double>{f2.elements.von_mises[0]});
  CHECK(h5.read_doubles("quad4/von_mises") == std::vector<double>{f2.elements.von_mises[1]});
  CHECK(h5.read_doubles("tet4/von_mises") == std::vector<double>{f2.elements.von_mises[2]});
  // The strain tensor, row by row: shear components are half the engineering shear.
  {
    const auto e =
        std::vector<double>(f2.elements.strain.begin() + 12, f2.elements.strain.begin() + 18);
    std::vector<std::size_t> sdims;
    CHECK(h5.read_doubles("tet4/strain", &sdims) == std::vector<double>{e[0], e[3] / 2, e[5] / 2,
                                                                        e[3] / 2, e[1], e[4] / 2,
                                                                        e[5] / 2, e[4] / 2, e[2]});
    CHECK(sdims == std::vector<std::size_t>{1, 9});
  }
  io::H5File mh5(out.mesh_path(), io::H5File::Mode::read);
  CHECK(mh5.read_int64("topology/tet4") == std::vector<std::int64_t>{4, 5, 6, 8});
  CHECK(mh5.read_int64("elements/quad4") == std::vector<std::int64_t>{1});
  CHECK(mh5.read_int64("node_labels").back() == 200);

  // Every "file.h5:/dataset" in the XDMF exists, with the dimensions the XDMF states.
  const std::string xdmf = read_text(out.xdmf_path());
  CHECK(xdmf.find("<Xdmf Version=\"3.0\"") != std::string::npos);
  for (const char* topo : {"Hexahedron", "Tetrahedron", "Quadrilateral"}) {
    CHECK(xdmf.find(std::string("TopologyType=\"") + topo + "\"") != std::string::npos);
  }
  const std::regex item(R"re(<DataItem Dimensions="([0-9 ]+)"[^>]*>([^:<]+):([^<]+)</DataItem>)re");
  int references = 0;
  for (auto it = std::sregex_iterator(xdmf.begin(), xdmf.end(), item); it != std::sregex_iterator();
       ++it) {
    const std::string file = (*it)[2];
    const std::string dataset = (*it)[3];
    std::vector<std::size_t> want;
    std::istringstream ds((*it)[1].str());
    for (std::size_t d; ds >> d;) want.push_back(d);
    INFO(file << ":" << dataset);
    REQUIRE(std::filesystem::exists(tmp.path / file));
    io::H5File f(tmp.path / file, io::H5File::Mode::read);
    REQUIRE(f.exists(dataset));
    std::vector<std::size_t> got;
    if (dataset.find("topology") != std::string::npos) {
      f.read_int64(dataset, &got);
    } else {
      f.read_doubles(dataset, &got);
    }
    CHECK(got == want);
    ++references;
  }
  // 3 steps x 3 element types x (topology + geometry + 4 node + 3 cell fields).
  CHECK(references == 3 * 3 * 9);
  // Times as the shortest decimal that reads back exactly, and the tensor as a 9-component
  // "Tensor" (a 6-component one is ordered differently by XDMF and by ParaView).
  CHECK(xdmf.find("<Time Value=\"0.2\"/>") != std::string::npos);
  CHECK(xdmf.find("<Attribute Name=\"strain\" AttributeType=\"Tensor\" Center=\"Cell\">") !=
        std::string::npos);

  // No temporary file remains.
  for (const auto& e : std::filesystem::directory_iterator(tmp.path)) {
    CHECK(e.path().extension() != ".part");
  }

  // CSV: header + one row per step; row 3 holds max |u|, max von Mises, max strain and the
  // summed reaction (10 t per node in z).
  const std::string csv = read_text(out.csv_path());
  CHECK(csv.rfind("time,max_displacement,max_von_mises,max_principal_strain,reaction_x,", 0) == 0);
  CHECK(std::count(csv.begin(), csv.end(), '\n') == 4);
  const FemScalars s3 = summarize(fields_at(0.3, n, ne));
  const double i = static_cast<double>(3 * n - 3);
  const double umax = 0.3e-3 * std::sqrt(i * i + (i + 1) * (i + 1) + (i + 2) * (i + 2));
  CHECK(s3.max_displacement == Approx(umax).epsilon(1e-14));
  CHECK(s3.max_von_mises == Approx(0.3e6 + 2.0));
  CHECK(s3.max_principal_strain == Approx(0.3e-4 * 3.0));
  CHECK(s3.reaction[2] == Approx(3.0 * static_cast<double>(n)));
}

TEST_CASE("FemOutput: selected fields only, and wrong sizes are refused") {
  TempDir tmp;
  const Mesh mesh =
      read_inp(std::filesystem::path(DEMFEM_SOURCE_DIR) / "cases/meshes/unit_hex.inp");
  FemOutputSettings settings;
  settings.fields = {"displacement"};
  settings.csv = false;
  FemOutput out(tmp.path, "only_u", mesh, settings);
  out.write(fields_at(1.0, 8, 1));
  io::H5File h5(out.step_path(0), io::H5File::Mode::read);
  CHECK(h5.exists("displacement"));
  CHECK_FALSE(h5.exists("velocity"));
  CHECK_FALSE(h5.exists("hex8/von_mises"));
  const std::string xdmf = read_text(out.xdmf_path());
  CHECK(xdmf.find("Name=\"velocity\"") == std::string::npos);
  CHECK(xdmf.find("Name=\"displacement\"") != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(out.csv_path()));
  FemFields bad = fields_at(2.0, 7, 1);
  CHECK_THROWS_WITH(out.write(bad), Catch::Contains("expected 3 per node"));
  CHECK(out.steps() == 1);
}

TEST_CASE("FemOutput: rollback drops later steps, resume continues an existing series") {
  TempDir tmp;
  const Mesh mesh =
      read_inp(std::filesystem::path(DEMFEM_SOURCE_DIR) / "cases/meshes/unit_hex.inp");
  {
    FemOutput out(tmp.path, "fem", mesh);
    for (int s = 1; s <= 3; ++s) out.write(fields_at(0.1 * s, 8, 1));
    out.rollback(0.2);  // a restore to t = 0.2: the third output (file 2) goes
    CHECK(out.steps() == 2);
    CHECK_FALSE(std::filesystem::exists(out.step_path(2)));
    CHECK(read_text(out.xdmf_path()).find("fem_000002.h5") == std::string::npos);
    const std::string csv = read_text(out.csv_path());
    CHECK(std::count(csv.begin(), csv.end(), '\n') == 3);  // header + 2 rows
    out.write(fields_at(0.3, 8, 1));                       // the continuation
    CHECK(out.steps() == 3);
  }
  // A crash left a partial fourth output; a restarted writer resumes after the third.
  std::ofstream(tmp.path / "fem_000003.h5.part") << "half";
  FemOutput again(tmp.path, "fem", mesh, {}, OutputMode::resume);
  CHECK(again.steps() == 3);
  CHECK(again.last_time() == Approx(0.3));
  CHECK_FALSE(std::filesystem::exists(tmp.path / "fem_000003.h5.part"));
  again.write(fields_at(0.4, 8, 1));
  CHECK(std::filesystem::exists(again.step_path(3)));
  const std::string xdmf = read_text(again.xdmf_path());
  CHECK(xdmf.find("fem_000000.h5:/displacement") != std::string::npos);
  CHECK(xdmf.find("fem_000003.h5:/hex8/strain") != std::string::npos);
  const std::string csv = read_text(again.csv_path());
  CHECK(std::count(csv.begin(), csv.end(), '\n') == 5);  // header + 4 rows
  // Resuming with another mesh is refused.
  Mesh other = mesh;
  other.nodes.push_back({2.0, 2.0, 2.0});
  CHECK_THROWS_WITH(FemOutput(tmp.path, "fem", other, {}, OutputMode::resume),
                    Catch::Contains("written for another mesh"));
}
