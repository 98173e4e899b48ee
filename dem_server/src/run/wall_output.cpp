#include "demfem/dem/run/wall_output.hpp"

#include <cctype>
#include <cmath>
#include <set>
#include <sstream>
#include <stdexcept>

#include "demfem/io/atomic_file.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem/io/output_schedule.hpp"
#include "demfem/io/xdmf.hpp"

namespace demfem::dem {

WallOutput::WallOutput(std::filesystem::path dir, std::vector<Wall> walls, std::string stem)
    : dir_(std::move(dir)), stem_(std::move(stem)), walls_(std::move(walls)) {
  std::filesystem::create_directories(dir_);
  std::set<std::string> taken;
  for (std::size_t w = 0; w < walls_.size(); ++w) {
    std::string safe = walls_[w].name.empty() ? "wall" : walls_[w].name;
    for (char& c : safe)
      if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.'))
        c = '_';
    std::string file = stem_ + "_" + safe + ".xdmf";
    if (!taken.insert(file).second) {
      file = stem_ + "_" + safe + "_" + std::to_string(w) + ".xdmf";
      taken.insert(file);
    }
    file_names_.push_back(file);
  }
}

std::filesystem::path WallOutput::wall_index_path(std::size_t w) const {
  return dir_ / file_names_.at(w);
}

std::filesystem::path WallOutput::index_path() const {
  return dir_ / (stem_ + ".xdmf");
}

std::filesystem::path WallOutput::snapshot_path(std::size_t k) const {
  return dir_ / io::series_file_name(stem_, k);
}

void WallOutput::write(std::span<const Pose> poses, double time, double state_time) {
  if (poses.size() != walls_.size())
    throw std::logic_error("wall output: one pose per wall expected");
  const auto final_path = snapshot_path(entries_.size());
  Entry entry{time, {}};
  {
    io::H5File f(io::partial_path(final_path), io::H5File::Mode::create);
    for (std::size_t w = 0; w < walls_.size(); ++w) {
      const std::string g = "wall_" + std::to_string(w);
      const std::size_t n = poses[w].vertices.size() / 3, t = walls_[w].triangles.size() / 3;
      for (std::int32_t v : walls_[w].triangles)
        if (v < 0 || std::size_t(v) >= n)
          throw std::logic_error("wall output: a triangle of wall '" + walls_[w].name +
                                 "' names a vertex it does not have");
      f.create_group(g);
      f.set_attribute(g, "name", walls_[w].name);
      f.write(g + "/points", poses[w].vertices, {n, 3});
      const std::vector<std::int64_t> tris(walls_[w].triangles.begin(), walls_[w].triangles.end());
      f.write(g + "/triangles", std::span<const std::int64_t>(tris), {t, 3});
      std::vector<double> force(3 * t);
      for (std::size_t k = 0; k < force.size(); ++k) force[k] = poses[w].force[k % 3];
      f.write(g + "/force", std::span<const double>(force), {t, 3});
      for (std::size_t k = 0; k < force.size(); ++k) force[k] = poses[w].sensor_force[k % 3];
      f.write(g + "/sensor_force", std::span<const double>(force), {t, 3});
      const std::vector<std::int64_t> index(t, static_cast<std::int64_t>(w));
      f.write(g + "/wall", std::span<const std::int64_t>(index), {t});
      entry.points.push_back(n);
    }
    f.set_attribute("/", "time", time);
    f.set_attribute("/", "state_time", std::isnan(state_time) ? time : state_time);
    f.set_attribute("/", "walls", static_cast<std::int64_t>(walls_.size()));
    f.close();
  }
  io::commit_partial(final_path);
  entries_.push_back(std::move(entry));
  write_index();
}

void WallOutput::resume(std::size_t keep) {
  entries_.clear();
  for (std::size_t k = 0; k < keep; ++k) {
    io::H5File f(snapshot_path(k), io::H5File::Mode::read);
    Entry e{f.attribute_double("/", "time"), {}, walls_.empty() || f.exists("wall_0/wall")};
    for (std::size_t w = 0; w < walls_.size(); ++w) {
      std::vector<std::size_t> dims;
      f.read_doubles("wall_" + std::to_string(w) + "/points", &dims);
      e.points.push_back(dims.empty() ? 0 : dims[0]);
    }
    entries_.push_back(std::move(e));
  }
  write_index();
}

std::string WallOutput::wall_grid(std::size_t k, std::size_t w, const std::string& indent) const {
  if (entries_[k].points[w] == 0 || walls_[w].triangles.empty()) return {};
  const std::string h5 = snapshot_path(k).filename().string();
  const std::string time = io::format_time(entries_[k].time);
  const std::string g = h5 + ":/wall_" + std::to_string(w);
  const std::string n = std::to_string(entries_[k].points[w]);
  const std::string t = std::to_string(walls_[w].triangles.size() / 3);
  std::ostringstream x;
  x << indent << "<Grid Name=\"" << io::xml_escape(walls_[w].name) << "\" GridType=\"Uniform\">\n"
    << indent << "  <Time Value=\"" << time << "\"/>\n"
    << indent << "  <Topology TopologyType=\"Triangle\" NumberOfElements=\"" << t << "\">"
    << io::xdmf_hdf_item(t + " 3", "Int", g + "/triangles") << "</Topology>\n"
    << indent << "  <Geometry GeometryType=\"XYZ\">"
    << io::xdmf_hdf_item(n + " 3", "Float", g + "/points") << "</Geometry>\n"
    << indent << "  <Attribute Name=\"force\" AttributeType=\"Vector\" Center=\"Cell\">"
    << io::xdmf_hdf_item(t + " 3", "Float", g + "/force") << "</Attribute>\n";
  if (entries_[k].wall_field) {
    x << indent << "  <Attribute Name=\"sensor_force\" AttributeType=\"Vector\" Center=\"Cell\">"
      << io::xdmf_hdf_item(t + " 3", "Float", g + "/sensor_force") << "</Attribute>\n";
    x << indent << "  <Attribute Name=\"wall\" AttributeType=\"Scalar\" Center=\"Cell\">"
      << io::xdmf_hdf_item(t, "Int", g + "/wall") << "</Attribute>\n";
  }
  x << indent << "</Grid>\n";
  return x.str();
}

void WallOutput::write_index() const {
  const char* head = "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n  <Domain>\n";
  const char* tail = "    </Grid>\n  </Domain>\n</Xdmf>\n";
  std::ostringstream x;
  x << head << "    <Grid Name=\"" << stem_
    << "\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (std::size_t k = 0; k < entries_.size(); ++k) {
    x << "      <Grid Name=\"walls_" << k << "\" GridType=\"Collection\" "
      << "CollectionType=\"Spatial\">\n"
      << "        <Time Value=\"" << io::format_time(entries_[k].time) << "\"/>\n";
    for (std::size_t w = 0; w < walls_.size(); ++w) x << wall_grid(k, w, "        ");
    x << "      </Grid>\n";
  }
  x << tail;
  // Each wall's own index first: walls.xdmf, rewritten last, lists only snapshots whose
  // per-wall indexes exist too.
  for (std::size_t w = 0; w < walls_.size(); ++w) {
    if (walls_[w].triangles.empty()) continue;  // nothing to show (an empty grid is not valid)
    std::ostringstream y;
    y << head << "    <Grid Name=\"" << io::xml_escape(walls_[w].name)
      << "\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    for (std::size_t k = 0; k < entries_.size(); ++k) y << wall_grid(k, w, "      ");
    y << tail;
    io::write_file_atomic(wall_index_path(w), y.str());
  }
  io::write_file_atomic(index_path(), x.str());
}

}  // namespace demfem::dem
