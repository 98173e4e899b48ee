#include "coupling_series.hpp"

#include <sstream>

#include "demfem/io/h5_file.hpp"
#include "demfem/io/output_schedule.hpp"
#include "demfem/io/xdmf.hpp"

namespace demfem::coupling {

const std::vector<std::string>& coupling_columns() {
  static const std::vector<std::string> columns = {"step",
                                                   "time",
                                                   "drift",
                                                   "work_dem",
                                                   "work_fem",
                                                   "energy_error",
                                                   "max_overlap",
                                                   "dem_max_overlap",
                                                   "kinetic_energy",
                                                   "fem_max_displacement",
                                                   "force_sum_z",
                                                   "wall_dem",
                                                   "wall_fem",
                                                   "wall_coupling",
                                                   "iterations",
                                                   "residual_displacement",
                                                   "residual_force",
                                                   "converged",
                                                   "wall_dem_compute",
                                                   "wall_fem_compute"};
  return columns;
}

std::vector<double> row_of(const StepDiagnostics& d) {
  return {static_cast<double>(d.step),
          d.time,
          d.drift,
          d.work_dem,
          d.work_fem,
          d.energy_error,
          d.max_overlap,
          d.dem_max_overlap,
          d.kinetic_energy,
          d.fem_max_displacement,
          d.force_sum_z,
          d.wall_dem,
          d.wall_fem,
          d.wall_coupling,
          static_cast<double>(d.iterations),
          d.residual_displacement,
          d.residual_force,
          d.converged ? 1.0 : 0.0,
          d.wall_dem_compute,
          d.wall_fem_compute};
}

StepDiagnostics diagnostics_of(std::span<const double> r) {
  StepDiagnostics d;
  d.step = static_cast<std::int64_t>(r[0]);
  d.time = r[1];
  d.drift = r[2];
  d.work_dem = r[3];
  d.work_fem = r[4];
  d.energy_error = r[5];
  d.max_overlap = r[6];
  d.dem_max_overlap = r[7];
  d.kinetic_energy = r[8];
  d.fem_max_displacement = r[9];
  d.force_sum_z = r[10];
  d.wall_dem = r[11];
  d.wall_fem = r[12];
  d.wall_coupling = r[13];
  d.iterations = static_cast<std::int64_t>(r[14]);
  d.residual_displacement = r[15];
  d.residual_force = r[16];
  d.converged = r[17] != 0.0;
  d.wall_dem_compute = r[18];
  d.wall_fem_compute = r[19];
  return d;
}

void write_interface_output(const std::filesystem::path& dir, const InterfaceState& st) {
  const auto h5_path = dir / "coupling.h5";
  const std::size_t n = st.mesh ? st.mesh->node_count() : 0;
  const std::size_t nt = st.mesh ? st.mesh->triangle_count() : 0;
  {
    io::H5File h5(io::partial_path(h5_path), io::H5File::Mode::create);
    h5.set_attribute("/", "scheme", st.scheme);
    h5.set_attribute("/", "steps", st.steps);
    h5.set_attribute("/", "time", st.time);
    // The time series stay in coupling.csv only: holding them in memory for the HDF5 file
    // would grow without bound over a long run.
    if (n > 0) {
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
    h5.close();
  }
  io::commit_partial(h5_path);

  // The index, written after the data it points to (none for a run without an interface:
  // DEM or FEM alone).
  if (n == 0) return;
  std::ostringstream x;
  x << "<?xml version=\"1.0\" ?>\n"
    << "<Xdmf Version=\"3.0\" xmlns:xi=\"http://www.w3.org/2001/XInclude\">\n"
    << " <Domain>\n"
    << "  <Grid Name=\"interface\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  {
    const std::string nodes = std::to_string(n) + " 3";
    const std::string file = "coupling.h5:/interface/";
    x << "   <Grid Name=\"interface\" GridType=\"Uniform\">\n"
      << "    <Time Value=\"" << io::format_time(st.time) << "\"/>\n"
      << "    <Topology TopologyType=\"Triangle\" NumberOfElements=\"" << nt
      << "\" NodesPerElement=\"3\">\n"
      << "     " << io::xdmf_hdf_item(std::to_string(nt) + " 3", "Int", file + "triangles") << "\n"
      << "    </Topology>\n"
      << "    <Geometry GeometryType=\"XYZ\">\n"
      << "     " << io::xdmf_hdf_item(nodes, "Float", file + "reference_positions") << "\n"
      << "    </Geometry>\n";
    const std::pair<const char*, const char*> arrays[] = {{"force", "forces"},
                                                          {"displacement", "displacements"},
                                                          {"position", "positions"},
                                                          {"velocity", "velocities"},
                                                          {"dem_position", "dem_positions"}};
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
  io::write_file_atomic(dir / "coupling.xdmf", x.str());
}

}  // namespace demfem::coupling
