#include "demfem/fem/fem_output.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "demfem/io/atomic_file.hpp"
#include "demfem/io/csv_writer.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem/io/output_schedule.hpp"
#include "demfem/io/xdmf.hpp"

namespace demfem::fem {

namespace {

const char* type_key(ElementType t) {
  switch (t) {
    case ElementType::hex8:
      return "hex8";
    case ElementType::tet4:
      return "tet4";
    case ElementType::quad4:
      return "quad4";
  }
  return "?";
}

const char* xdmf_topology(ElementType t) {
  switch (t) {
    case ElementType::hex8:
      return "Hexahedron";
    case ElementType::tet4:
      return "Tetrahedron";
    case ElementType::quad4:
      return "Quadrilateral";
  }
  return "?";
}

}  // namespace

namespace {

std::vector<double> strain_tensors(const std::vector<double>& engineering) {
  // (exx, eyy, ezz, gxy, gyz, gzx) per element -> the symmetric tensor, row by row
  const std::size_t k = engineering.size() / 6;
  std::vector<double> out(9 * k);
  for (std::size_t e = 0; e < k; ++e) {
    const double* v = engineering.data() + 6 * e;
    const double xy = 0.5 * v[3], yz = 0.5 * v[4], zx = 0.5 * v[5];
    const double t[9] = {v[0], xy, zx, xy, v[1], yz, zx, yz, v[2]};
    std::copy(t, t + 9, out.begin() + static_cast<std::ptrdiff_t>(9 * e));
  }
  return out;
}

}  // namespace

FemScalars summarize(const FemFields& f) {
  FemScalars s;
  s.time = f.time;
  for (std::size_t i = 0; i + 2 < f.displacement.size(); i += 3) {
    const double u = std::sqrt(f.displacement[i] * f.displacement[i] +
                               f.displacement[i + 1] * f.displacement[i + 1] +
                               f.displacement[i + 2] * f.displacement[i + 2]);
    s.max_displacement = std::max(s.max_displacement, u);
  }
  for (double v : f.elements.von_mises) s.max_von_mises = std::max(s.max_von_mises, v);
  if (!f.elements.max_principal_strain.empty()) {
    s.max_principal_strain = *std::max_element(f.elements.max_principal_strain.begin(),
                                               f.elements.max_principal_strain.end());
  }
  for (std::size_t i = 0; i + 2 < f.reaction_force.size(); i += 3) {
    for (std::size_t k = 0; k < 3; ++k) s.reaction[k] += f.reaction_force[i + k];
  }
  return s;
}

FemOutput::FemOutput(std::filesystem::path dir, std::string name, const Mesh& mesh,
                     FemOutputSettings settings, OutputMode mode)
    : dir_(std::move(dir)), name_(std::move(name)), settings_(std::move(settings)) {
  if (settings_.fields.empty()) {
    for (const char* k : kFemOutputFields) settings_.fields.emplace_back(k);
  }
  std::filesystem::create_directories(dir_);
  node_count_ = mesh.nodes.size();
  for (ElementType t : {ElementType::hex8, ElementType::tet4, ElementType::quad4}) {
    TypeGroup g{t, {}};
    for (std::size_t e = 0; e < mesh.elements.size(); ++e) {
      if (mesh.elements[e].type == t) g.elements.push_back(static_cast<std::int64_t>(e));
    }
    if (!g.elements.empty()) groups_.push_back(std::move(g));
  }
  const std::vector<std::string> columns{
      "time",       "max_displacement", "max_von_mises", "max_principal_strain",
      "reaction_x", "reaction_y",       "reaction_z"};
  if (mode == OutputMode::resume && std::filesystem::exists(mesh_path())) {
    std::vector<std::size_t> dims;
    io::H5File(mesh_path(), io::H5File::Mode::read).read_doubles("nodes", &dims);
    if (dims.empty() || dims[0] != node_count_) {
      throw std::runtime_error(mesh_path().string() + ": written for another mesh (" +
                               std::to_string(dims.empty() ? 0 : dims[0]) + " nodes, this one " +
                               std::to_string(node_count_) + "); cannot resume its output");
    }
    scan_existing();
    if (settings_.csv) {
      if (std::filesystem::exists(csv_path())) {
        csv_ = std::make_unique<io::CsvWriter>(io::CsvWriter::resume(csv_path(), times_.size()));
        csv_->flush();
      } else {
        csv_ = std::make_unique<io::CsvWriter>(csv_path(), columns);
      }
    }
  } else {
    // Step files of an earlier run in this folder go: a later resume (a restarted solver)
    // scans the folder and would take them for this run's.
    // (From 1 too: series written before the numbering started at 0 begin there.)
    for (std::size_t k = 0; k < 2 || std::filesystem::exists(step_path(k)); ++k) {
      std::filesystem::remove(step_path(k));
    }
    write_mesh(mesh);
    if (settings_.csv) csv_ = std::make_unique<io::CsvWriter>(csv_path(), columns);
  }
  write_xdmf();
}

void FemOutput::write_mesh(const Mesh& mesh) const {
  {
    io::H5File h5(io::partial_path(mesh_path()), io::H5File::Mode::create);
    std::vector<double> xyz;
    xyz.reserve(3 * node_count_);
    for (const auto& n : mesh.nodes) xyz.insert(xyz.end(), n.begin(), n.end());
    h5.write("nodes", xyz, {node_count_, 3});
    h5.create_group("topology");
    h5.create_group("elements");
    for (const auto& g : groups_) {
      const std::size_t npe = static_cast<std::size_t>(nodes_per_element(g.type));
      std::vector<std::int64_t> conn;
      conn.reserve(g.elements.size() * npe);
      for (auto e : g.elements) {
        const Element& el = mesh.elements[static_cast<std::size_t>(e)];
        for (std::size_t k = 0; k < npe; ++k) conn.push_back(el.nodes[k]);
      }
      h5.write(std::string("topology/") + type_key(g.type), conn, {g.elements.size(), npe});
      h5.write(std::string("elements/") + type_key(g.type), g.elements);
    }
    if (!mesh.node_labels.empty()) h5.write("node_labels", mesh.node_labels);
    if (!mesh.element_labels.empty()) h5.write("element_labels", mesh.element_labels);
    h5.close();
  }
  io::commit_partial(mesh_path());
}

void FemOutput::scan_existing() {
  // Step files are committed in order, so the series is 0, 1, ... up to the first gap; a
  // ".part" left by a crash is incomplete and removed.
  times_.clear();
  state_times_.clear();
  written_.clear();
  for (std::size_t k = 0;; ++k) {
    std::filesystem::remove(io::partial_path(step_path(k)));
    if (!std::filesystem::exists(step_path(k))) break;
    io::H5File h5(step_path(k), io::H5File::Mode::read);
    times_.push_back(h5.attribute_double("/", "time"));
    state_times_.push_back(times_.back());
    try {
      state_times_.back() = h5.attribute_double("/", "state_time");
    } catch (const std::exception&) {
      // written before the attribute existed: the label is the state's time
    }
    std::vector<std::string> present;
    for (const char* f : kFemOutputFields) {
      const std::string field = f;
      const bool node_field = field == "displacement" || field == "velocity" ||
                              field == "acceleration" || field == "reaction_force";
      const std::string where = node_field || groups_.empty()
                                    ? field
                                    : std::string(type_key(groups_[0].type)) + "/" + field;
      if (h5.exists(where)) present.push_back(field);
    }
    written_.push_back(std::move(present));
  }
}

void FemOutput::rollback(double time) {
  std::size_t keep = 0;
  while (keep < state_times_.size() &&
         state_times_[keep] <= time + 1e-12 * std::max(1.0, std::abs(time))) {
    ++keep;
  }
  if (keep == times_.size()) return;
  // Index first, so that it never names a file that is being deleted.
  const std::size_t had = times_.size();
  times_.resize(keep);
  state_times_.resize(keep);
  written_.resize(keep);
  write_xdmf();
  for (std::size_t k = keep; k < had; ++k) std::filesystem::remove(step_path(k));
  if (csv_) {
    csv_.reset();
    csv_ = std::make_unique<io::CsvWriter>(io::CsvWriter::resume(csv_path(), keep));
    csv_->flush();
  }
}

FemOutput::~FemOutput() = default;

std::filesystem::path FemOutput::xdmf_path() const {
  return dir_ / (name_ + ".xdmf");
}
std::filesystem::path FemOutput::csv_path() const {
  return dir_ / (name_ + "_series.csv");
}
std::filesystem::path FemOutput::mesh_path() const {
  return dir_ / (name_ + "_mesh.h5");
}
std::filesystem::path FemOutput::step_path(std::size_t step) const {
  return dir_ / io::series_file_name(name_, step);
}

bool FemOutput::wants(const std::string& field) const {
  return std::find(settings_.fields.begin(), settings_.fields.end(), field) !=
         settings_.fields.end();
}

void FemOutput::write(const FemFields& f) {
  auto check_nodes = [&](const std::vector<double>& v, const char* what) {
    if (!v.empty() && v.size() != 3 * node_count_) {
      throw std::invalid_argument(std::string("FemOutput: ") + what + " has " +
                                  std::to_string(v.size()) + " values, expected 3 per node (" +
                                  std::to_string(3 * node_count_) + ")");
    }
  };
  check_nodes(f.displacement, "displacement");
  check_nodes(f.velocity, "velocity");
  check_nodes(f.acceleration, "acceleration");
  check_nodes(f.reaction_force, "reaction_force");
  for (const auto& [name, v] : f.node_vectors) check_nodes(v, name.c_str());
  std::size_t element_count = 0;
  for (const auto& g : groups_) element_count += g.elements.size();
  if (!f.elements.von_mises.empty() && f.elements.von_mises.size() != element_count) {
    throw std::invalid_argument("FemOutput: von_mises needs one value per element");
  }
  if (!f.elements.strain.empty() && f.elements.strain.size() != 6 * element_count) {
    throw std::invalid_argument("FemOutput: strain needs 6 values per element");
  }
  if (!f.elements.max_principal_strain.empty() &&
      f.elements.max_principal_strain.size() != element_count) {
    throw std::invalid_argument("FemOutput: max_principal_strain needs one value per element");
  }

  const std::size_t step = times_.size();
  const auto path = step_path(step);
  const double state_time = std::isnan(f.state_time) ? f.time : f.state_time;
  // The series row first, the step file's commit (its rename) last: a process killed in
  // between leaves one row too many, which a resume cuts back to the step files; the other
  // order left a step file without its row, and every later resume refused the folder.
  if (csv_) {
    const FemScalars s = summarize(f);
    csv_->row({s.time, s.max_displacement, s.max_von_mises, s.max_principal_strain, s.reaction[0],
               s.reaction[1], s.reaction[2]});
    csv_->flush();
  }
  {
    io::H5File h5(io::partial_path(path), io::H5File::Mode::create);
    h5.set_attribute("/", "time", f.time);
    h5.set_attribute("/", "state_time", state_time);
    const std::pair<const char*, const std::vector<double>*> node_fields[] = {
        {"displacement", &f.displacement},
        {"velocity", &f.velocity},
        {"acceleration", &f.acceleration},
        {"reaction_force", &f.reaction_force}};
    for (const auto& [name, data] : node_fields) {
      if (wants(name) && !data->empty()) h5.write(name, *data, {node_count_, 3});
    }
    for (const auto& [name, data] : f.node_vectors) h5.write(name, data, {node_count_, 3});
    for (const auto& g : groups_) {
      const std::string grp = type_key(g.type);
      h5.create_group(grp);
      const std::size_t k = g.elements.size();
      auto gather = [&](const std::vector<double>& all, std::size_t per) {
        std::vector<double> out;
        out.reserve(k * per);
        for (auto e : g.elements) {
          const auto base = static_cast<std::size_t>(e) * per;
          out.insert(out.end(), all.begin() + static_cast<std::ptrdiff_t>(base),
                     all.begin() + static_cast<std::ptrdiff_t>(base + per));
        }
        return out;
      };
      if (wants("von_mises") && !f.elements.von_mises.empty()) {
        h5.write(grp + "/von_mises", gather(f.elements.von_mises, 1));
      }
      if (wants("strain") && !f.elements.strain.empty()) {
        h5.write(grp + "/strain", strain_tensors(gather(f.elements.strain, 6)), {k, 9});
      }
      if (wants("max_principal_strain") && !f.elements.max_principal_strain.empty()) {
        h5.write(grp + "/max_principal_strain", gather(f.elements.max_principal_strain, 1));
      }
    }
    h5.close();
  }
  io::commit_partial(path);
  times_.push_back(f.time);
  state_times_.push_back(state_time);
  written_.push_back(present_fields(f));
  write_xdmf();
}

std::vector<std::string> FemOutput::present_fields(const FemFields& f) const {
  std::vector<std::string> out;
  auto add = [&](const char* name, bool present) {
    if (present && wants(name)) out.emplace_back(name);
  };
  add("displacement", !f.displacement.empty());
  add("velocity", !f.velocity.empty());
  add("acceleration", !f.acceleration.empty());
  add("reaction_force", !f.reaction_force.empty());
  add("von_mises", !f.elements.von_mises.empty());
  add("strain", !f.elements.strain.empty());
  add("max_principal_strain", !f.elements.max_principal_strain.empty());
  for (const auto& [name, v] : f.node_vectors) out.push_back(name);
  return out;
}

void FemOutput::write_xdmf() const {
  // References are relative to the XDMF's folder, so the output folder can be moved.
  const std::string mesh_file = mesh_path().filename().string();
  const std::string n = std::to_string(node_count_);
  std::ostringstream x;
  x << "<?xml version=\"1.0\" ?>\n"
    << "<Xdmf Version=\"3.0\" xmlns:xi=\"http://www.w3.org/2001/XInclude\">\n"
    << " <Domain>\n"
    << "  <Grid Name=\"" << name_ << "\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  const bool mixed = groups_.size() > 1;
  for (std::size_t s = 0; s < times_.size(); ++s) {
    const std::string step_file = step_path(s).filename().string();
    const auto& fields = written_[s];
    auto has = [&](const char* name) {
      return std::find(fields.begin(), fields.end(), name) != fields.end();
    };
    std::string indent = "   ";
    if (mixed) {
      x << indent << "<Grid Name=\"step_" << s
        << "\" GridType=\"Collection\" CollectionType=\"Spatial\">\n"
        << indent << " <Time Value=\"" << io::format_time(times_[s]) << "\"/>\n";
      indent += " ";
    }
    for (const auto& g : groups_) {
      const std::string k = std::to_string(g.elements.size());
      const std::string npe = std::to_string(nodes_per_element(g.type));
      const std::string t = type_key(g.type);
      x << indent << "<Grid Name=\"" << (mixed ? t : "step_" + std::to_string(s))
        << "\" GridType=\"Uniform\">\n";
      if (!mixed) x << indent << " <Time Value=\"" << io::format_time(times_[s]) << "\"/>\n";
      x << indent << " <Topology TopologyType=\"" << xdmf_topology(g.type)
        << "\" NumberOfElements=\"" << k << "\" NodesPerElement=\"" << npe << "\">\n"
        << indent << "  " << io::xdmf_hdf_item(k + " " + npe, "Int", mesh_file + ":/topology/" + t)
        << "\n"
        << indent << " </Topology>\n"
        << indent << " <Geometry GeometryType=\"XYZ\">\n"
        << indent << "  " << io::xdmf_hdf_item(n + " 3", "Float", mesh_file + ":/nodes") << "\n"
        << indent << " </Geometry>\n";
      std::vector<std::string> vectors = {"displacement", "velocity", "acceleration",
                                          "reaction_force"};
      for (const auto& f : fields) {
        const bool standard = std::find(std::begin(kFemOutputFields), std::end(kFemOutputFields),
                                        f) != std::end(kFemOutputFields);
        if (!standard) vectors.push_back(f);  // FemFields::node_vectors
      }
      for (const auto& f : vectors) {
        if (!has(f.c_str())) continue;
        x << indent << " <Attribute Name=\"" << f
          << "\" AttributeType=\"Vector\" Center=\"Node\">\n"
          << indent << "  " << io::xdmf_hdf_item(n + " 3", "Float", step_file + ":/" + f) << "\n"
          << indent << " </Attribute>\n";
      }
      if (has("von_mises")) {
        x << indent << " <Attribute Name=\"von_mises\" AttributeType=\"Scalar\" Center=\"Cell\">\n"
          << indent << "  " << io::xdmf_hdf_item(k, "Float", step_file + ":/" + t + "/von_mises")
          << "\n"
          << indent << " </Attribute>\n";
      }
      if (has("strain")) {
        // The full tensor (9 components, row by row): with 6, ParaView assumes a symmetric
        // tensor in the order XX, YY, ZZ, XY, YZ, XZ while XDMF's Tensor6 is XX, XY, XZ, YY,
        // YZ, ZZ; 9 components mean the same to every reader.
        x << indent << " <Attribute Name=\"strain\" AttributeType=\"Tensor\" Center=\"Cell\">\n"
          << indent << "  "
          << io::xdmf_hdf_item(k + " 9", "Float", step_file + ":/" + t + "/strain") << "\n"
          << indent << " </Attribute>\n";
      }
      if (has("max_principal_strain")) {
        x << indent
          << " <Attribute Name=\"max_principal_strain\" AttributeType=\"Scalar\" "
             "Center=\"Cell\">\n"
          << indent << "  "
          << io::xdmf_hdf_item(k, "Float", step_file + ":/" + t + "/max_principal_strain") << "\n"
          << indent << " </Attribute>\n";
      }
      x << indent << "</Grid>\n";
    }
    if (mixed) x << "   </Grid>\n";
  }
  x << "  </Grid>\n"
    << " </Domain>\n"
    << "</Xdmf>\n";
  io::write_file_atomic(xdmf_path(), x.str());
}

}  // namespace demfem::fem
