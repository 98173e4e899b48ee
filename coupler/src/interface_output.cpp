#include "interface_output.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "demfem/io/atomic_file.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem/io/output_schedule.hpp"
#include "demfem/io/xdmf.hpp"

namespace demfem::coupling {

namespace {

/// The interface mesh and `state` into group "interface" of `h5` (nothing without nodes).
void write_interface(io::H5File& h5, const InterfaceState& st) {
  const std::size_t n = st.mesh ? st.mesh->node_count() : 0;
  if (n == 0) return;
  const std::size_t nt = st.mesh->triangle_count();
  const auto& ref = st.mesh->reference_positions;
  std::vector<double> displacement(3 * n);
  for (std::size_t k = 0; k < 3 * n; ++k) displacement[k] = st.positions[k] - ref[k];
  h5.create_group("interface");
  h5.write("interface/reference_positions", std::span<const double>(ref), {n, 3});
  std::vector<std::int64_t> tri(st.mesh->triangles.begin(), st.mesh->triangles.end());
  h5.write("interface/triangles", std::span<const std::int64_t>(tri), {nt, 3});
  h5.write("interface/positions", st.positions, {n, 3});
  h5.write("interface/displacements", std::span<const double>(displacement), {n, 3});
  h5.write("interface/velocities", st.velocities, {n, 3});
  h5.write("interface/forces", st.forces, {n, 3});
  h5.write("interface/dem_positions", st.dem_positions, {n, 3});
}

}  // namespace

void write_coupling_h5(const std::filesystem::path& dir, const InterfaceState& state,
                       const std::string& scheme, std::int64_t steps, double time) {
  const auto path = dir / "coupling.h5";
  {
    io::H5File h5(io::partial_path(path), io::H5File::Mode::create);
    h5.set_attribute("/", "scheme", scheme);
    h5.set_attribute("/", "steps", steps);
    h5.set_attribute("/", "time", time);
    write_interface(h5, state);
    h5.close();
  }
  io::commit_partial(path);
}

InterfaceSeries::InterfaceSeries(std::filesystem::path dir, const InterfaceMesh& mesh, bool resume)
    : dir_(std::move(dir)), nodes_(mesh.node_count()), triangles_(mesh.triangle_count()) {
  std::filesystem::create_directories(dir_);
  if (!resume) {
    // An earlier run's steps would be taken for this run's by a later resume.
    for (std::size_t k = 0; std::filesystem::exists(step_path(k)); ++k)
      std::filesystem::remove(step_path(k));
    std::filesystem::remove(io::partial_path(step_path(0)));
  } else {
    // Step files are committed in order: the series is 0, 1, ... up to the first gap.
    for (std::size_t k = 0;; ++k) {
      std::filesystem::remove(io::partial_path(step_path(k)));
      if (!std::filesystem::exists(step_path(k))) break;
      io::H5File h5(step_path(k), io::H5File::Mode::read);
      const auto dims = [&] {
        std::vector<std::size_t> d;
        h5.read_doubles("interface/reference_positions", &d);
        return d;
      }();
      if (dims.empty() || dims[0] != nodes_)
        throw std::runtime_error(step_path(k).string() + ": written for another interface (" +
                                 std::to_string(dims.empty() ? 0 : dims[0]) +
                                 " nodes, this run's " + std::to_string(nodes_) +
                                 "); cannot continue its series");
      times_.push_back(h5.attribute_double("/", "time"));
      state_times_.push_back(h5.attribute_double("/", "state_time"));
    }
  }
  write_xdmf();
}

std::filesystem::path InterfaceSeries::step_path(std::size_t k) const {
  return dir_ / io::series_file_name("coupling", k);
}

void InterfaceSeries::write(const InterfaceState& state, double time, double state_time) {
  const auto path = step_path(times_.size());
  {
    io::H5File h5(io::partial_path(path), io::H5File::Mode::create);
    h5.set_attribute("/", "time", time);
    h5.set_attribute("/", "state_time", state_time);
    write_interface(h5, state);
    h5.close();
  }
  io::commit_partial(path);
  times_.push_back(time);
  state_times_.push_back(state_time);
  write_xdmf();
}

void InterfaceSeries::rollback(double time) {
  std::size_t keep = 0;
  while (keep < state_times_.size() &&
         state_times_[keep] <= time + 1e-12 * std::max(1.0, std::abs(time)))
    ++keep;
  if (keep == times_.size()) return;
  const std::size_t had = times_.size();
  times_.resize(keep);
  state_times_.resize(keep);
  write_xdmf();  // first, so that it never names a file being deleted
  for (std::size_t k = keep; k < had; ++k) std::filesystem::remove(step_path(k));
}

void InterfaceSeries::write_xdmf() const {
  // References are relative to the XDMF's folder, so the output folder can be moved.
  const std::string nodes = std::to_string(nodes_) + " 3";
  const std::string nt = std::to_string(triangles_);
  std::ostringstream x;
  x << "<?xml version=\"1.0\" ?>\n"
    << "<Xdmf Version=\"3.0\" xmlns:xi=\"http://www.w3.org/2001/XInclude\">\n"
    << " <Domain>\n"
    << "  <Grid Name=\"interface\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  const std::pair<const char*, const char*> arrays[] = {{"force", "forces"},
                                                        {"displacement", "displacements"},
                                                        {"position", "positions"},
                                                        {"velocity", "velocities"},
                                                        {"dem_position", "dem_positions"}};
  for (std::size_t k = 0; k < times_.size(); ++k) {
    const std::string file = step_path(k).filename().string() + ":/interface/";
    x << "   <Grid Name=\"step_" << k << "\" GridType=\"Uniform\">\n"
      << "    <Time Value=\"" << io::format_time(times_[k]) << "\"/>\n"
      << "    <Topology TopologyType=\"Triangle\" NumberOfElements=\"" << nt
      << "\" NodesPerElement=\"3\">\n"
      << "     " << io::xdmf_hdf_item(nt + " 3", "Int", file + "triangles") << "\n"
      << "    </Topology>\n"
      << "    <Geometry GeometryType=\"XYZ\">\n"
      << "     " << io::xdmf_hdf_item(nodes, "Float", file + "reference_positions") << "\n"
      << "    </Geometry>\n";
    for (const auto& [name, dataset] : arrays) {
      x << "    <Attribute Name=\"" << name << "\" AttributeType=\"Vector\" Center=\"Node\">\n"
        << "     " << io::xdmf_hdf_item(nodes, "Float", file + dataset) << "\n"
        << "    </Attribute>\n";
    }
    x << "   </Grid>\n";
  }
  x << "  </Grid>\n"
    << " </Domain>\n"
    << "</Xdmf>\n";
  io::write_file_atomic(dir_ / "coupling.xdmf", x.str());
}

}  // namespace demfem::coupling
