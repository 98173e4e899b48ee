#include "demfem/dem/run/dem_output.hpp"

#include <array>
#include <cmath>
#include <numeric>
#include <sstream>
#include <tuple>

#include "demfem/dem/physics/rigid_body.hpp"
#include "demfem/io/atomic_file.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem/io/output_schedule.hpp"
#include "demfem/io/xdmf.hpp"

namespace demfem::dem {

ParticleOutput::ParticleOutput(std::filesystem::path dir, std::string stem)
    : dir_(std::move(dir)), stem_(std::move(stem)) {
  std::filesystem::create_directories(dir_);
}

std::filesystem::path ParticleOutput::index_path() const {
  return dir_ / (stem_ + ".xdmf");
}

std::filesystem::path ParticleOutput::snapshot_path(std::size_t k) const {
  return dir_ / io::series_file_name(stem_, k);
}

void ParticleOutput::set_shapes(const std::vector<PolyhedronShape>& shapes) {
  surfaces_.clear();
  for (const auto& sh : shapes) {
    Surface s;
    const std::size_t nv = sh.vertices.size() / 3;
    // per vertex the distinct normals of its faces (coplanar triangles count once), summed
    std::vector<std::vector<std::array<double, 3>>> normals(nv);
    for (std::size_t t = 0; t + 2 < sh.triangles.size(); t += 3) {
      const double* a = &sh.vertices[3 * std::size_t(sh.triangles[t])];
      const double* b = &sh.vertices[3 * std::size_t(sh.triangles[t + 1])];
      const double* c = &sh.vertices[3 * std::size_t(sh.triangles[t + 2])];
      const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
      const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
      std::array<double, 3> n{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                              u[0] * v[1] - u[1] * v[0]};
      const double l = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      for (double& x : n) x /= l;
      for (int k = 0; k < 3; ++k) {
        auto& list = normals[std::size_t(sh.triangles[t + k])];
        bool seen = false;
        for (const auto& m : list)
          seen = seen ||
                 (std::abs(m[0] - n[0]) + std::abs(m[1] - n[1]) + std::abs(m[2] - n[2]) < 1e-9);
        if (!seen) list.push_back(n);
      }
      for (int k = 0; k < 3; ++k) s.triangles.push_back(sh.triangles[t + k]);
    }
    for (std::size_t k = 0; k < nv; ++k) {
      double n[3] = {0, 0, 0};
      for (const auto& m : normals[k])
        for (int d = 0; d < 3; ++d) n[d] += m[d];
      const double l = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      for (int d = 0; d < 3; ++d)
        s.vertices.push_back(sh.vertices[3 * k + d] + (l > 0 ? sh.dilation * n[d] / l : 0.0));
    }
    surfaces_.push_back(std::move(s));
  }
}

void ParticleOutput::write(const ParticleState& p, std::span<const std::int64_t> ids, double time,
                           double state_time) {
  const std::size_t n = p.size();
  if (ids.size() != n) throw std::logic_error("particle output: ids and particles differ");
  const auto final_path = snapshot_path(entries_.size());
  Entry entry{time, n};
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
    // the polyhedra as triangle surfaces
    const SurfaceData sd = surfaces(p, ids);
    const std::size_t m = sd.points.size() / 3, nt = sd.triangles.size() / 3;
    if (nt > 0) write_surfaces(f, sd);
    f.close();
    entry.points = m, entry.triangles = nt;
  }
  io::commit_partial(final_path);
  entries_.push_back(entry);
  write_index();
}

ParticleOutput::SurfaceData ParticleOutput::surfaces(const ParticleState& p,
                                                     std::span<const std::int64_t> ids) const {
  SurfaceData out;
  const std::size_t n = p.size();
  if (p.shape_id.size() != n || surfaces_.empty()) return out;
  // Each rock's fields on its cells (triangles) and on its points, so that ParaView's default
  // reader, which merges the spheres' and the rocks' grids into pieces of one data set, finds
  // every field on every piece with either association (issue 34, item 11).
  auto per_rock = [&](PerRock& r, std::size_t i, std::size_t count) {
    for (std::size_t c = 0; c < count; ++c) {
      r.id.push_back(ids[i]);
      r.material.push_back(p.material[i]);
      r.radius.push_back(p.radius[i]);
      r.mass.push_back(p.mass[i]);
      r.angular_velocity.insert(r.angular_velocity.end(), {p.wx[i], p.wy[i], p.wz[i]});
    }
  };
  for (std::size_t i = 0; i < n; ++i) {
    const std::int32_t sid = p.shape_id[i];
    if (sid < 0 || std::size_t(sid) >= surfaces_.size()) continue;
    const Surface& sf = surfaces_[std::size_t(sid)];
    const auto r = phys::rotation(p.qw[i], p.qx[i], p.qy[i], p.qz[i]);
    const phys::Vec3 x{p.px[i], p.py[i], p.pz[i]}, v{p.vx[i], p.vy[i], p.vz[i]},
        w{p.wx[i], p.wy[i], p.wz[i]};
    const auto base = static_cast<std::int64_t>(out.points.size() / 3);
    for (std::size_t k = 0; k < sf.vertices.size(); k += 3) {
      const phys::Vec3 a =
          p.scale[i] *
          phys::to_world(r, phys::Vec3{sf.vertices[k], sf.vertices[k + 1], sf.vertices[k + 2]});
      const phys::Vec3 q = x + a, u = v + phys::cross(w, a);
      out.points.insert(out.points.end(), {q.x, q.y, q.z});
      out.point_velocity.insert(out.point_velocity.end(), {u.x, u.y, u.z});
    }
    for (std::size_t t = 0; t < sf.triangles.size(); ++t)
      out.triangles.push_back(base + sf.triangles[t]);
    for (std::size_t t = 0; t < sf.triangles.size() / 3; ++t)
      out.centre_velocity.insert(out.centre_velocity.end(), {v.x, v.y, v.z});
    per_rock(out.cell, i, sf.triangles.size() / 3);
    per_rock(out.point, i, sf.vertices.size() / 3);
  }
  return out;
}

void ParticleOutput::write_surfaces(io::H5File& f, const SurfaceData& sd) {
  const std::size_t m = sd.points.size() / 3, nt = sd.triangles.size() / 3;
  f.write("surface_points", std::span<const double>(sd.points), {m, 3});
  f.write("surface_velocity", std::span<const double>(sd.point_velocity), {m, 3});
  f.write("surface_triangles", std::span<const std::int64_t>(sd.triangles), {nt, 3});
  f.write("surface_centre_velocity", std::span<const double>(sd.centre_velocity), {nt, 3});
  for (const auto& [prefix, r, count] :
       {std::tuple{"surface_", &sd.cell, nt}, std::tuple{"surface_point_", &sd.point, m}}) {
    const std::string pre = prefix;
    f.write(pre + "id", std::span<const std::int64_t>(r->id), {count});
    f.write(pre + "material", std::span<const std::int64_t>(r->material), {count});
    f.write(pre + "radius", std::span<const double>(r->radius), {count});
    f.write(pre + "mass", std::span<const double>(r->mass), {count});
    f.write(pre + "angular_velocity", std::span<const double>(r->angular_velocity), {count, 3});
  }
  f.set_attribute("/", "surface_points", static_cast<std::int64_t>(m));
  f.set_attribute("/", "surface_triangles", static_cast<std::int64_t>(nt));
}

void ParticleOutput::resume(std::size_t keep) {
  entries_.clear();
  for (std::size_t k = 0; k < keep; ++k) {
    io::H5File f(snapshot_path(k), io::H5File::Mode::read);
    Entry e{f.attribute_double("/", "time"),
            static_cast<std::size_t>(f.attribute_int64("/", "count"))};
    if (f.exists("surface_points")) {
      e.points = static_cast<std::size_t>(f.attribute_int64("/", "surface_points"));
      e.triangles = static_cast<std::size_t>(f.attribute_int64("/", "surface_triangles"));
    }
    entries_.push_back(e);
  }
  write_index();
}

void ParticleOutput::write_sphere_grid(std::ostream& x, std::size_t k,
                                       const std::string& indent) const {
  const auto& e = entries_[k];
  const std::string h5 = snapshot_path(k).filename().string();
  auto item = [&](const std::string& ds, const std::string& dims, const char* type) {
    return io::xdmf_hdf_item(dims, type, h5 + ":/" + ds);
  };
  const std::string n = std::to_string(e.count);
  x << indent << "<Grid Name=\"step_" << k << "\" GridType=\"Uniform\">\n"
    << indent << "  <Time Value=\"" << io::format_time(e.time) << "\"/>\n"
    << indent << "  <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << n
    << "\" NodesPerElement=\"1\">" << item("vertex", n + " 1", "Int") << "</Topology>\n"
    << indent << "  <Geometry GeometryType=\"XYZ\">" << item("position", n + " 3", "Float")
    << "</Geometry>\n";
  // Each particle is a point and a cell: its fields with both associations (the same
  // datasets), as on the rocks' surfaces beside it.
  for (const char* center : {"Node", "Cell"}) {
    const char* vectors[] = {"velocity", "angular_velocity"};
    for (const char* v : vectors) {
      x << indent << "  <Attribute Name=\"" << v << "\" AttributeType=\"Vector\" Center=\""
        << center << "\">" << item(v, n + " 3", "Float") << "</Attribute>\n";
    }
    const std::pair<const char*, const char*> scalars[] = {
        {"radius", "Float"}, {"mass", "Float"}, {"material", "Int"}, {"id", "Int"}};
    for (const auto& [name, type] : scalars) {
      x << indent << "  <Attribute Name=\"" << name << "\" AttributeType=\"Scalar\" Center=\""
        << center << "\">" << item(name, n, type) << "</Attribute>\n";
    }
  }
  x << indent << "</Grid>\n";
}

void ParticleOutput::write_polyhedron_grid(std::ostream& x, std::size_t k,
                                           const std::string& indent) const {
  const auto& e = entries_[k];
  const std::string h5 = snapshot_path(k).filename().string();
  auto item = [&](const std::string& ds, const std::string& dims, const char* type) {
    return io::xdmf_hdf_item(dims, type, h5 + ":/" + ds);
  };
  const std::string m = std::to_string(e.points), t = std::to_string(e.triangles);
  x << indent << "<Grid Name=\"polyhedra_" << k << "\" GridType=\"Uniform\">\n"
    << indent << "  <Time Value=\"" << io::format_time(e.time) << "\"/>\n"
    << indent << "  <Topology TopologyType=\"Triangle\" NumberOfElements=\"" << t << "\">"
    << item("surface_triangles", t + " 3", "Int") << "</Topology>\n"
    << indent << "  <Geometry GeometryType=\"XYZ\">" << item("surface_points", m + " 3", "Float")
    << "</Geometry>\n"
    << indent << "  <Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\">"
    << item("surface_velocity", m + " 3", "Float") << "</Attribute>\n";
  // The rock's fields on its triangles (cells) and on its points; the cells' velocity is the
  // rock centre's (the points': where each point moves).
  auto attribute = [&](const char* name, const char* kind, const char* center,
                       const std::string& ds, const std::string& dims, const char* type) {
    x << indent << "  <Attribute Name=\"" << name << "\" AttributeType=\"" << kind << "\" Center=\""
      << center << "\">" << item(ds, dims, type) << "</Attribute>\n";
  };
  attribute("velocity", "Vector", "Cell", "surface_centre_velocity", t + " 3", "Float");
  for (const auto& [center, pre, count] :
       {std::tuple{"Cell", "surface_", t}, std::tuple{"Node", "surface_point_", m}}) {
    const std::string p = pre;
    attribute("angular_velocity", "Vector", center, p + "angular_velocity", count + " 3", "Float");
    attribute("radius", "Scalar", center, p + "radius", count, "Float");
    attribute("mass", "Scalar", center, p + "mass", count, "Float");
    attribute("material", "Scalar", center, p + "material", count, "Int");
    attribute("id", "Scalar", center, p + "id", count, "Int");
  }
  x << indent << "</Grid>\n";
}

void ParticleOutput::write_index() const {
  std::ostringstream x;
  x << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n  <Domain>\n"
    << "    <Grid Name=\"" << stem_ << "\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (std::size_t k = 0; k < entries_.size(); ++k) {
    if (entries_[k].count == 0) continue;  // an empty grid is not valid XDMF
    if (entries_[k].triangles == 0) {
      write_sphere_grid(x, k, "      ");
      continue;
    }
    // with polyhedra: the particles' points and the surfaces, one spatial collection
    x << "      <Grid Name=\"snapshot_" << k << "\" GridType=\"Collection\" "
      << "CollectionType=\"Spatial\">\n"
      << "        <Time Value=\"" << io::format_time(entries_[k].time) << "\"/>\n";
    write_sphere_grid(x, k, "        ");
    write_polyhedron_grid(x, k, "        ");
    x << "      </Grid>\n";
  }
  x << "    </Grid>\n  </Domain>\n</Xdmf>\n";
  io::write_file_atomic(index_path(), x.str());
}

}  // namespace demfem::dem
