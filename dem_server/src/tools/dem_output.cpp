#include "demfem/dem/dem_output.hpp"

#include <cmath>
#include <cstdio>
#include <numeric>
#include <sstream>

#include "demfem/io/atomic_file.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem/io/output_schedule.hpp"

namespace demfem::dem {

ParticleOutput::ParticleOutput(std::filesystem::path dir, std::string stem)
    : dir_(std::move(dir)), stem_(std::move(stem)) {
  std::filesystem::create_directories(dir_);
}

std::filesystem::path ParticleOutput::index_path() const {
  return dir_ / (stem_ + ".xdmf");
}

std::filesystem::path ParticleOutput::snapshot_path(std::size_t k) const {
  char buf[32];
  std::snprintf(buf, sizeof buf, "_%06zu.h5", k);
  return dir_ / (stem_ + buf);
}

void ParticleOutput::write(const ParticleState& p, std::span<const std::int64_t> ids, double time,
                           double state_time) {
  const std::size_t n = p.size();
  if (ids.size() != n) throw std::logic_error("particle output: ids and particles differ");
  const auto final_path = snapshot_path(entries_.size());
  {
    io::H5File f(io::partial_path(final_path), io::H5File::Mode::create);
    auto xyz = [&](const std::vector<double>& x, const std::vector<double>& y,
                   const std::vector<double>& z) {
      std::vector<double> a(3 * n);
      for (std::size_t i = 0; i < n; ++i) {
        a[3 * i] = x[i];
        a[3 * i + 1] = y[i];
        a[3 * i + 2] = z[i];
      }
      return a;
    };
    f.write("position", xyz(p.px, p.py, p.pz), {n, 3});
    f.write("velocity", xyz(p.vx, p.vy, p.vz), {n, 3});
    f.write("angular_velocity", xyz(p.wx, p.wy, p.wz), {n, 3});
    f.write("radius", std::span<const double>(p.radius), {n});
    f.write("mass", std::span<const double>(p.mass), {n});
    std::vector<std::int64_t> mat(p.material.begin(), p.material.end());
    f.write("material", std::span<const std::int64_t>(mat), {n});
    f.write("id", ids, {n});
    std::vector<std::int64_t> vertex(n);
    std::iota(vertex.begin(), vertex.end(), std::int64_t{0});
    f.write("vertex", std::span<const std::int64_t>(vertex), {n});
    f.set_attribute("/", "time", time);
    f.set_attribute("/", "state_time", std::isnan(state_time) ? time : state_time);
    f.set_attribute("/", "count", static_cast<std::int64_t>(n));
    f.close();
  }
  io::commit_partial(final_path);
  entries_.push_back({time, n});
  write_index();
}

void ParticleOutput::resume(std::size_t keep) {
  entries_.clear();
  for (std::size_t k = 0; k < keep; ++k) {
    io::H5File f(snapshot_path(k), io::H5File::Mode::read);
    entries_.push_back({f.attribute_double("/", "time"),
                        static_cast<std::size_t>(f.attribute_int64("/", "count"))});
  }
  write_index();
}

void ParticleOutput::write_sphere_grid(std::ostream& x, std::size_t k,
                                       const std::string& indent) const {
  const auto& e = entries_[k];
  const std::string h5 = snapshot_path(k).filename().string();
  auto item = [&](const std::string& ds, const std::string& dims, const char* type) {
    std::ostringstream s;
    s << "<DataItem Dimensions=\"" << dims << "\" NumberType=\"" << type
      << "\" Precision=\"8\" Format=\"HDF\">" << h5 << ":/" << ds << "</DataItem>";
    return s.str();
  };
  const std::string n = std::to_string(e.count);
  x << indent << "<Grid Name=\"step_" << k << "\" GridType=\"Uniform\">\n"
    << indent << "  <Time Value=\"" << io::format_time(e.time) << "\"/>\n"
    << indent << "  <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << n
    << "\" NodesPerElement=\"1\">" << item("vertex", n + " 1", "Int") << "</Topology>\n"
    << indent << "  <Geometry GeometryType=\"XYZ\">" << item("position", n + " 3", "Float")
    << "</Geometry>\n";
  const char* vectors[] = {"velocity", "angular_velocity"};
  for (const char* v : vectors) {
    x << indent << "  <Attribute Name=\"" << v << "\" AttributeType=\"Vector\" Center=\"Node\">"
      << item(v, n + " 3", "Float") << "</Attribute>\n";
  }
  const std::pair<const char*, const char*> scalars[] = {
      {"radius", "Float"}, {"mass", "Float"}, {"material", "Int"}, {"id", "Int"}};
  for (const auto& [name, type] : scalars) {
    x << indent << "  <Attribute Name=\"" << name << "\" AttributeType=\"Scalar\" Center=\"Node\">"
      << item(name, n, type) << "</Attribute>\n";
  }
  x << indent << "</Grid>\n";
}

void ParticleOutput::write_index() const {
  std::ostringstream x;
  x << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n  <Domain>\n"
    << "    <Grid Name=\"" << stem_ << "\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (std::size_t k = 0; k < entries_.size(); ++k) {
    if (entries_[k].count == 0) continue;  // an empty grid is not valid XDMF
    write_sphere_grid(x, k, "      ");
  }
  x << "    </Grid>\n  </Domain>\n</Xdmf>\n";
  io::write_file_atomic(index_path(), x.str());
}

}  // namespace demfem::dem
