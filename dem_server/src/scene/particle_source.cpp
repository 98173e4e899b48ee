#include "demfem/dem/scene/particle_source.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <numbers>
#include <ostream>
#include <sstream>
#include <unordered_map>

#include "demfem/dem/physics/geometry.hpp"
#include "demfem/dem/physics/grid_cell.hpp"
#include "demfem/dem/placement/state_check.hpp"
#include "demfem/dem/scene/dem_scene.hpp"
#include "demfem/io/file_hash.hpp"
#include "demfem/io/h5_file.hpp"

namespace demfem::dem {

using scene::Range;
using scene::SceneError;
using scene::Table;

namespace {

constexpr const char* kStateFormat = "demfem-dem-state-1";  // DemSystem::save's "format"
// A loaded particle that overlaps another by more than this fraction of the smaller radius
// is reported as a warning (the settled fills of the sheet case, 100 MPa grains, overlap by
// at most 0.3 % (0.8 kg) and 1.1 % (6 kg, 0.27 m deep)).
constexpr double kWarnOverlap = 0.02;

std::int32_t material_by_name(const Table& t, std::string_view key, const std::string& name,
                              const std::vector<Material>& materials) {
  for (std::size_t i = 0; i < materials.size(); ++i)
    if (materials[i].name == name) {
      if (!(materials[i].density > 0))
        t.fail(key, "names material \"" + name + "\", whose density is 0 (particles need > 0)");
      return static_cast<std::int32_t>(i);
    }
  t.fail(key, "names material \"" + name + "\", which [[dem.materials]] does not define");
}

// Where particle i of a file came from: "file:line" for a CSV (`lines` holds each particle's
// line), else "file: particle i".
std::string particle_origin(const std::string& file, const std::vector<std::int64_t>& lines,
                            std::size_t i) {
  return i < lines.size() ? file + ":" + std::to_string(lines[i])
                          : file + ": particle " + std::to_string(i);
}

// What a file's particles carry, before the material mapping.
struct Loaded {
  std::vector<ParticleInit> particles;
  std::vector<std::int64_t> file_material;  // empty: the file has none (CSV)
  std::string file;                         // for messages
  std::vector<std::int64_t> line;           // CSV: each particle's line; else empty
  std::vector<PolyhedronShape> shapes;      // a state's shape table (shape_id indexes it)
  /// "file:line" (CSV) or "file: particle i": kept as numbers, a string per row of a large
  /// CSV took more memory than its particles
  std::string origin(std::size_t i) const { return particle_origin(file, line, i); }
};

[[noreturn]] void data_error(const ParticleSource& s, const std::string& at,
                             const std::string& message) {
  throw SceneError(s.where + ": " + at + ": " + message);
}

std::string trim(std::string_view v) {
  while (!v.empty() && (v.front() == ' ' || v.front() == '\t')) v.remove_prefix(1);
  while (!v.empty() && (v.back() == ' ' || v.back() == '\t' || v.back() == '\r'))
    v.remove_suffix(1);
  return std::string(v);
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::size_t a = 0;
  for (;;) {
    const auto b = line.find(',', a);
    out.push_back(trim(std::string_view(line).substr(a, b == std::string::npos ? b : b - a)));
    if (b == std::string::npos) return out;
    a = b + 1;
  }
}

// Files above this size say how far the reading is, every tenth of the file.
constexpr std::uintmax_t kCsvProgressBytes = std::uintmax_t{100} << 20;

// A CSV's data rows (not empty, not a comment), counted in one pass that keeps nothing: a
// file of more particles than this machine holds (particle_budget_excess) is refused before
// any is read. (A 2 GB file took 6.3 GB of memory before it was refused; the rows it holds
// are counted in seconds.) The header is counted too, one row more than the file holds.
void check_csv_size(const ParticleSource& s, std::ostream* log) {
  std::ifstream in(s.file);
  std::string line;
  std::uint64_t rows = 0;
  const auto bytes = std::filesystem::file_size(s.file);
  if (log && bytes > kCsvProgressBytes)
    *log << "dem: counting the rows of " << s.file.string() << " (" << (bytes >> 20) << " MB)\n";
  while (std::getline(in, line)) {
    const auto first = line.find_first_not_of(" \t\r");
    if (first != std::string::npos && line[first] != '#') ++rows;
  }
  const std::string excess = particle_budget_excess(static_cast<double>(rows));
  if (!excess.empty())
    data_error(s, s.file.string(),
               "holds " + std::to_string(rows > 0 ? rows - 1 : 0) + " particle rows, " + excess +
                   "; load a smaller file (the limit is the particles' memory in the DEM, not "
                   "the file's)");
}

Loaded read_csv(const ParticleSource& s, std::ostream* log) {
  check_csv_size(s, log);
  std::ifstream in(s.file);
  if (!in) data_error(s, s.file.string(), "cannot be opened");
  const std::string name = s.file.string();
  const auto bytes = std::filesystem::file_size(s.file);
  int tenths = 0;
  std::function<void(std::streamoff)> progress;
  if (log && bytes > kCsvProgressBytes)
    progress = [&](std::streamoff at) {
      if (at < 0 || 10 * static_cast<std::uintmax_t>(at) < (tenths + 1) * bytes) return;
      tenths = static_cast<int>(10 * static_cast<std::uintmax_t>(at) / bytes);
      *log << "dem: reading " << name << ": " << 10 * tenths << " %\n" << std::flush;
    };
  std::string line;
  std::size_t lineno = 0;
  std::vector<std::string> header;
  while (header.empty() && std::getline(in, line)) {
    ++lineno;
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    header = split(t);
  }
  if (header.empty()) data_error(s, name, "is empty (expected a header line x,y,z,r[,vx,vy,vz])");
  // Columns by name, in any order.
  const char* known[] = {"x", "y", "z", "r", "vx", "vy", "vz"};
  int col[7] = {-1, -1, -1, -1, -1, -1, -1};
  for (std::size_t c = 0; c < header.size(); ++c) {
    int k = -1;
    for (int q = 0; q < 7; ++q)
      if (header[c] == known[q]) k = q;
    if (k < 0)
      data_error(s, name + ":" + std::to_string(lineno),
                 "unknown column \"" + header[c] + "\" (accepted: x, y, z, r, vx, vy, vz)");
    if (col[k] >= 0)
      data_error(s, name + ":" + std::to_string(lineno), "column \"" + header[c] + "\" twice");
    col[k] = static_cast<int>(c);
  }
  for (int q = 0; q < 4; ++q)
    if (col[q] < 0)
      data_error(s, name + ":" + std::to_string(lineno),
                 std::string("the header has no column \"") + known[q] +
                     "\" (required: x, y, z, r; optional: vx, vy, vz)");
  const int nv = int(col[4] >= 0) + int(col[5] >= 0) + int(col[6] >= 0);
  if (nv != 0 && nv != 3)
    data_error(s, name + ":" + std::to_string(lineno), "give all of vx, vy, vz or none");
  Loaded out;
  out.file = name;
  while (std::getline(in, line)) {
    ++lineno;
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    const std::string at = name + ":" + std::to_string(lineno);
    const auto f = split(t);
    if (f.size() != header.size())
      data_error(
          s, at,
          std::to_string(f.size()) + " values, the header has " + std::to_string(header.size()));
    double v[7] = {0, 0, 0, 0, 0, 0, 0};
    for (int q = 0; q < 7; ++q) {
      if (col[q] < 0) continue;
      const std::string& text = f[static_cast<std::size_t>(col[q])];
      const char* end = text.data() + text.size();
      const auto r = std::from_chars(text.data(), end, v[q]);
      if (r.ec != std::errc() || r.ptr != end)
        data_error(s, at, std::string("column ") + known[q] + ": \"" + text + "\" is not a number");
      if (!std::isfinite(v[q]))
        data_error(s, at, std::string("column ") + known[q] + " is not finite");
    }
    if (!(v[3] > 0)) data_error(s, at, "r = " + f[col[3]] + " must be > 0 m");
    ParticleInit p;
    p.position = {v[0], v[1], v[2]};
    p.radius = v[3];
    if (nv == 3) p.velocity = {v[4], v[5], v[6]};
    out.particles.push_back(p);
    out.line.push_back(static_cast<std::int64_t>(lineno));
    if (progress) progress(in.tellg());
  }
  return out;
}

std::vector<double> optional_doubles(const io::H5File& f, const std::string& name, std::size_t n,
                                     std::size_t width, const ParticleSource& s) {
  if (!f.exists(name)) return std::vector<double>(n * width, 0.0);
  std::vector<std::size_t> dims;
  auto v = f.read_doubles(name, &dims);
  if (v.size() != n * width)
    data_error(s, f.path().string(),
               "dataset " + name + " has " + std::to_string(v.size()) + " values, expected " +
                   std::to_string(n * width));
  return v;
}

Loaded read_snapshot(const ParticleSource& s) {
  io::H5File f(s.file, io::H5File::Mode::read);
  std::vector<std::size_t> dims;
  const auto pos = f.read_doubles("position", &dims);
  if (dims.size() != 2 || dims[1] != 3)
    data_error(s, s.file.string(), "dataset position is not n x 3");
  const std::size_t n = dims[0];
  const auto radius = f.read_doubles("radius");
  if (radius.size() != n)
    data_error(s, s.file.string(),
               "dataset radius has " + std::to_string(radius.size()) + " values for " +
                   std::to_string(n) + " positions");
  const auto vel = optional_doubles(f, "velocity", n, 3, s);
  const auto ang = optional_doubles(f, "angular_velocity", n, 3, s);
  Loaded out;
  out.file = s.file.string();
  if (f.exists("material")) {
    out.file_material = f.read_int64("material");
    if (out.file_material.size() != n)
      data_error(s, s.file.string(), "dataset material does not have one value per particle");
  }
  for (std::size_t i = 0; i < n; ++i) {
    ParticleInit p;
    p.position = {pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]};
    p.velocity = {vel[3 * i], vel[3 * i + 1], vel[3 * i + 2]};
    p.angular_velocity = {ang[3 * i], ang[3 * i + 1], ang[3 * i + 2]};
    p.radius = radius[i];
    out.particles.push_back(p);
  }
  return out;
}

void require_state_group(const io::H5File& f, const ParticleSource& s) {
  if (!f.exists(s.group))
    data_error(s, s.file.string(),
               "has no group '" + s.group + "' (a DEM state: DemSystem::save's group)");
  std::string format;
  try {
    format = f.attribute_string(s.group, "format");
  } catch (const std::exception&) {
  }
  if (format != kStateFormat)
    data_error(s, s.file.string(),
               "group '" + s.group + "' is not a DEM state (attribute format = \"" + format +
                   "\", expected \"" + kStateFormat + "\")");
}

Loaded read_state_particles(const ParticleSource& s) {
  io::H5File f(s.file, io::H5File::Mode::read);
  require_state_group(f, s);
  const std::string g = s.group + "/";
  const auto px = f.read_doubles(g + "px"), py = f.read_doubles(g + "py"),
             pz = f.read_doubles(g + "pz");
  const auto vx = f.read_doubles(g + "vx"), vy = f.read_doubles(g + "vy"),
             vz = f.read_doubles(g + "vz");
  const auto wx = f.read_doubles(g + "wx"), wy = f.read_doubles(g + "wy"),
             wz = f.read_doubles(g + "wz");
  const auto radius = f.read_doubles(g + "radius");
  const auto shape = f.read_uint8(g + "shape");
  const std::size_t n = px.size();
  for (const auto* a : {&py, &pz, &vx, &vy, &vz, &wx, &wy, &wz, &radius})
    if (a->size() != n) data_error(s, s.file.string(), "state arrays of different lengths");
  Loaded out;
  out.file = s.file.string();
  out.file_material = f.read_int64(g + "material");
  if (out.file_material.size() != n || shape.size() != n)
    data_error(s, s.file.string(), "state arrays of different lengths");
  // Polyhedra: their shapes, scales and orientations come along (the shape table is added
  // to this scene's by load_particles).
  bool any_poly = false;
  for (std::size_t i = 0; i < n; ++i)
    any_poly = any_poly || shape[i] == static_cast<std::uint8_t>(ParticleShape::polyhedron);
  std::vector<std::int64_t> shape_id;
  std::vector<double> scale, qw, qx, qy, qz;
  if (any_poly) {
    try {
      out.shapes = read_state_shapes(f, s.group);
    } catch (const std::invalid_argument& e) {
      data_error(s, s.file.string(), e.what());
    }
    shape_id = f.read_int64(g + "shape_id");
    scale = f.read_doubles(g + "scale");
    qw = f.read_doubles(g + "qw"), qx = f.read_doubles(g + "qx"), qy = f.read_doubles(g + "qy"),
    qz = f.read_doubles(g + "qz");
    for (const auto* a : {&scale, &qw, &qx, &qy, &qz})
      if (a->size() != n) data_error(s, s.file.string(), "state arrays of different lengths");
    if (shape_id.size() != n) data_error(s, s.file.string(), "state arrays of different lengths");
  }
  for (std::size_t i = 0; i < n; ++i) {
    ParticleInit p;
    if (shape[i] == static_cast<std::uint8_t>(ParticleShape::polyhedron)) {
      if (shape_id[i] < 0 || shape_id[i] >= std::int64_t(out.shapes.size()))
        data_error(s, s.file.string() + ": particle " + std::to_string(i),
                   "refers to a shape the state's table does not hold");
      p.shape = ParticleShape::polyhedron;
      p.shape_id = static_cast<std::int32_t>(shape_id[i]);  // the file's; remapped when added
      p.scale = scale[i];
      if (!(p.scale > 0) || !std::isfinite(p.scale))
        data_error(s, s.file.string() + ": particle " + std::to_string(i),
                   "dataset " + g + "scale holds " + std::to_string(p.scale) +
                       " (accepted: a finite scale > 0)");
      p.orientation = {qw[i], qx[i], qy[i], qz[i]};
      const double q2 = qw[i] * qw[i] + qx[i] * qx[i] + qy[i] * qy[i] + qz[i] * qz[i];
      if (!(std::abs(q2 - 1.0) <= 1e-6))
        data_error(s, s.file.string() + ": particle " + std::to_string(i),
                   "datasets " + g +
                       "qw, qx, qy, qz: the orientation is not a unit quaternion (|q|^2 = " +
                       std::to_string(q2) + ", accepted 1 +- 1e-6)");
    } else if (shape[i] != static_cast<std::uint8_t>(ParticleShape::sphere)) {
      data_error(s, s.file.string() + ": particle " + std::to_string(i),
                 "has an unknown shape kind " + std::to_string(int(shape[i])));
    }
    p.position = {px[i], py[i], pz[i]};
    p.velocity = {vx[i], vy[i], vz[i]};
    p.angular_velocity = {wx[i], wy[i], wz[i]};
    p.radius = radius[i];
    out.particles.push_back(p);
  }
  return out;
}

// The material of each loaded particle in this scene.
void assign_materials(const ParticleSource& s, Loaded& l, const DemSettings& settings) {
  const std::size_t nmat = settings.materials.size();
  for (std::size_t i = 0; i < l.particles.size(); ++i) {
    std::int64_t m = s.material;
    if (m < 0) {
      if (l.file_material.empty())
        data_error(s, l.origin(i), "the file gives no material: set dem.load.material");
      const std::int64_t fm = l.file_material[i];
      if (!s.material_map.empty()) {
        if (fm < 0 || fm >= static_cast<std::int64_t>(s.material_map.size()))
          data_error(s, l.origin(i),
                     "material index " + std::to_string(fm) +
                         " has no entry in "
                         "dem.load.material_map (" +
                         std::to_string(s.material_map.size()) + " entries)");
        m = s.material_map[static_cast<std::size_t>(fm)];
      } else {
        m = fm;  // the same index in this scene
      }
    }
    if (m < 0 || static_cast<std::size_t>(m) >= nmat || !(settings.materials[m].density > 0))
      data_error(s, l.origin(i),
                 "material index " + std::to_string(m) +
                     " is not a particle material of this scene (give dem.load.material or "
                     "dem.load.material_map)");
    l.particles[i].material = static_cast<std::int32_t>(m);
  }
}

void check_finite(const ParticleSource& s, const Loaded& l) {
  for (std::size_t i = 0; i < l.particles.size(); ++i) {
    const auto& p = l.particles[i];
    bool ok = std::isfinite(p.radius);
    for (int d = 0; d < 3; ++d)
      ok = ok && std::isfinite(p.position[d]) && std::isfinite(p.velocity[d]) &&
           std::isfinite(p.angular_velocity[d]);
    if (!ok) data_error(s, l.origin(i), "a position, velocity or radius is not finite");
    if (!(p.radius > 0))
      data_error(s, l.origin(i), "radius " + std::to_string(p.radius) + " m must be > 0");
  }
}

std::string describe_count(std::size_t n) {
  return std::to_string(n) + " particle" + (n == 1 ? "" : "s");
}

// keep_time: the clock goes on, so a wall with a motion is placed where this scene's motion
// puts it at the state's time, with the drift a force limit had given it (that drift is the
// time it advanced, so another velocity scales the travel). A motion other than the saving
// scene's would move the wall there in the first step, into the bed if it was a compaction
// plate, and the run would blow up blaming its step: said here instead, naming the wall.
void check_walls_continue(const ParticleSource& s, const DemSystem& system,
                          std::span<const WallMesh> walls) {
  for (std::size_t w = 0; w < system.wall_count() && w < walls.size(); ++w) {
    if (walls[w].body.enabled || walls[w].motion.kind == WallMotion::Kind::fixed) continue;
    const auto at = system.wall_vertices(static_cast<std::int32_t>(w));
    const auto goes = system.wall_vertices_at_clock(static_cast<std::int32_t>(w));
    double jump = 0.0;
    for (std::size_t k = 0; k + 2 < at.size(); k += 3)
      jump = std::max(jump, std::hypot(goes[k] - at[k], goes[k + 1] - at[k + 1],
                                       goes[k + 2] - at[k + 2]));
    // the same motion gives the saved vertices bit for bit; 1 nm allows nothing physical
    if (jump > 1e-9) {
      std::ostringstream msg;
      msg << "with keep_time the wall '" << walls[w].name << "' goes on with this scene's motion "
          << "from the state's time " << system.time() << " s, which puts it " << jump
          << " m from where the state left it: its motion (velocity, start or end time, "
             "place) differs from the scene that saved the state (a force-limited drift keeps "
             "the time it advanced, so another velocity changes its travel). Give it the saving "
             "scene's motion, or load without keep_time (the clock and the walls' motions "
             "start again at 0, the wall at its box)";
      data_error(s, s.file.string(), msg.str());
    }
  }
}

// History: the state's walls must be this scene's, at the same place, and its masses this
// scene's densities; then DemSystem::restore continues it exactly.
// Walls that move (a prescribed motion, or a rigid body moved by its contacts) are compared
// by their vertex count only: a body continues from its saved pose, a moving wall takes the
// pose of the scene's clock (keep a moving wall away from the particles at the save, as a
// compaction plate parked above the bed). Returns how many particles the state held frozen
// (all free now).
std::size_t restore_state(const ParticleSource& s, DemSystem& system,
                          std::span<const WallMesh> walls) {
  io::H5File f(s.file, io::H5File::Mode::read);
  require_state_group(f, s);
  const std::string g = s.group + "/";
  std::vector<double> scene_vertices;
  std::vector<std::uint8_t> compared;  // per coordinate
  for (std::size_t w = 0; w < system.wall_count(); ++w) {
    const auto v = system.wall_vertices(static_cast<std::int32_t>(w));
    scene_vertices.insert(scene_vertices.end(), v.begin(), v.end());
    const bool moves = w < walls.size() &&
                       (walls[w].body.enabled || walls[w].motion.kind != WallMotion::Kind::fixed);
    compared.insert(compared.end(), v.size(), moves ? 0 : 1);
  }
  if (f.exists(g + "flex_x") && !f.read_doubles(g + "flex_x").empty())
    data_error(s, s.file.string(),
               "the state holds a coupled (flexible) mesh; its contact history cannot start a "
               "new scene (use history = false)");
  const auto vpos = f.read_doubles(g + "vpos");
  if (vpos.size() != scene_vertices.size())
    data_error(s, s.file.string(),
               "the state has walls of " + std::to_string(vpos.size() / 3) +
                   " vertices, this scene " + std::to_string(scene_vertices.size() / 3) +
                   "; the wall contact history needs the same walls (same [[dem.walls]] in the "
                   "same order), or use history = false");
  for (std::size_t k = 0; k < vpos.size(); ++k)
    if (compared[k] && vpos[k] != scene_vertices[k])
      data_error(s, s.file.string(),
                 "wall vertex " + std::to_string(k / 3) +
                     " is at another place than in this "
                     "scene (coordinate " +
                     std::to_string(k % 3) + ": " + std::to_string(vpos[k]) + " m in the state, " +
                     std::to_string(scene_vertices[k]) +
                     " m here); the wall contact history needs the same walls, or use "
                     "history = false");
  const auto mass = f.read_doubles(g + "mass");
  const auto radius = f.read_doubles(g + "radius");
  const auto material = f.read_int64(g + "material");
  const auto& mats = system.settings().materials;
  if (mass.size() != radius.size() || material.size() != radius.size())
    data_error(s, s.file.string(), "state arrays of different lengths");
  // A polyhedron's mass is density x its shape's volume x scale³ (its radius is the bounding
  // sphere's); states written before polyhedra hold spheres only.
  std::vector<PolyhedronShape> shapes;
  std::vector<std::int64_t> shape_id;
  std::vector<double> scale;
  if (f.exists(g + "shape_id")) {
    try {
      shapes = read_state_shapes(f, s.group);
    } catch (const std::invalid_argument& e) {
      data_error(s, s.file.string(), e.what());
    }
    shape_id = f.read_int64(g + "shape_id");
    scale = f.read_doubles(g + "scale");
    if (shape_id.size() != mass.size() || scale.size() != mass.size())
      data_error(s, s.file.string(), "state arrays of different lengths");
  }
  for (std::size_t i = 0; i < mass.size(); ++i) {
    const std::string at = s.file.string() + ": particle " + std::to_string(i);
    const auto m = material[i];
    if (m < 0 || static_cast<std::size_t>(m) >= mats.size() || !(mats[m].density > 0))
      data_error(s, at,
                 "material index " + std::to_string(m) +
                     " is not a particle material of this scene; with history = true the "
                     "state's material indices are kept (same [[dem.materials]] order)");
    const bool poly = !shape_id.empty() && shape_id[i] >= 0;
    if (poly && shape_id[i] >= std::int64_t(shapes.size()))
      data_error(s, at, "refers to a shape the state's table does not hold");
    const double expect =
        poly ? mats[m].density * shapes[std::size_t(shape_id[i])].volume * scale[i] * scale[i] *
                   scale[i]
             : mats[m].density * 4.0 / 3.0 * std::numbers::pi * radius[i] * radius[i] * radius[i];
    if (!(std::abs(mass[i] - expect) <= 1e-12 * expect))
      data_error(s, at,
                 "mass " + std::to_string(mass[i]) + " kg differs from this scene's density (" +
                     mats[m].name + ": " + std::to_string(expect) +
                     " kg); the history keeps the state's masses, so the materials must be "
                     "the same (or use history = false)");
  }
  try {
    system.restore(f, s.group);
    // as a checkpoint's (DemRun::restore): a non-finite force or velocity would blow the
    // bed up in its first step, blamed on the run instead of the file
    check_particle_state(system.particles(), s.file.string() + ":/" + s.group,
                         "the state cannot start a run (saved as a run blew up, or edited)");
  } catch (const std::exception& e) {
    data_error(s, s.file.string(), e.what());
  }
  if (s.keep_time)
    check_walls_continue(s, system, walls);
  else
    system.reset_clock();
  // The saved run's [dem.freeze] mask comes with the state; which particles are held is this
  // scene's choice (its own [dem.freeze]), not the state's: the next scene of a chain (a trim,
  // the load case) must not carry a layer frozen while another was poured. A checkpoint
  // restart restores the mask through DemRun::restore, not here, so it continues bitwise.
  const std::size_t held = system.frozen_count();
  system.release_frozen();
  return held;
}

}  // namespace

namespace {

std::string hex16(std::uint64_t h) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(h));
  return text;
}

// A scene's content hash (scene_text_hash) of a document already loaded.
std::string content_hash(const scene::Document& doc) {
  return hex16(io::fnv1a64(doc.canonical_text()));
}

// A TOML basic string of `s` (a path): quotes and backslashes escaped.
std::string toml_string(const std::string& s) {
  std::string q = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') q += '\\';
    q += c;
  }
  return q + "\"";
}

// [dem.load] seed_offset: a run.seed that `pass` passes on reaches the prepare scene shifted by
// it. The layers of one chain then draw from seeds apart while one --set run.seed names the
// whole chain, and a chain whose scenes were written with seeds apart (the tiled sleeper
// chain: its second layer 12, its first layer 11) is the chain of its last seed unchanged.
// Only a passed run.seed is shifted, not one of `set`.
scene::Override shift_passed_seed(const Table& t, scene::Override o, std::int64_t offset) {
  std::string digits;
  for (const char c : o.value)
    if (c != '_' && c != '+' && c != ' ') digits += c;
  std::int64_t seed = -1;
  const auto r = std::from_chars(digits.data(), digits.data() + digits.size(), seed);
  if (r.ec != std::errc{} || r.ptr != digits.data() + digits.size() || seed < 0)
    t.fail("seed_offset", "cannot shift " + o.text() + ": run.seed is a decimal integer >= 0");
  if (seed + offset < 0)
    t.fail("seed_offset", std::to_string(offset) + " shifts " + o.text() + " to " +
                              std::to_string(seed + offset) +
                              ", below 0 (run.seed >= 0): choose a seed of at least " +
                              std::to_string(-offset));
  o.value = std::to_string(seed + offset);
  return o;
}

// [dem.load] set and pass: the overrides the prepare scene runs with, and its own folder.
std::vector<scene::Override> read_prepare_overrides(const Table& t,
                                                    const std::filesystem::path& prepare_scene,
                                                    const std::string& where) {
  std::vector<scene::Override> e;
  const bool shifts = t.has("seed_offset");
  const std::int64_t seed_offset =
      shifts ? t.integer("seed_offset", -1'000'000'000, 1'000'000'000) : 0;
  if (shifts && !t.has("pass"))
    t.fail("seed_offset", "shifts the run.seed that 'pass' passes on: give pass = "
                          "[\"run.seed\"] too");
  if (t.has("set")) {
    for (const auto& a : t.strings("set")) {
      try {
        e.push_back(scene::Override::parse(a));
      } catch (const SceneError& x) {
        t.fail("set", std::string(x.what()) + " (each entry is \"KEY=VALUE\", as for --set)");
      }
    }
  }
  if (t.has("pass")) {
    const auto prefixes = t.strings("pass");
    for (const auto& p : prefixes)
      if (p.empty() || p.find_first_of("= ") != std::string::npos || p == "run.output_dir")
        t.fail("pass", "'" + p +
                           "' is not a key prefix (a dotted scene key such as \"dem.pairs\" or "
                           "\"run.seed\"; run.output_dir is never passed)");
    for (const auto& o : t.overrides())
      if (o.key != "run.output_dir" &&
          std::any_of(prefixes.begin(), prefixes.end(),
                      [&](const std::string& p) { return o.under(p); }))
        e.push_back(shifts && o.key == "run.seed" ? shift_passed_seed(t, o, seed_offset) : o);
  }
  const bool own_folder = std::none_of(e.begin(), e.end(), [](const scene::Override& o) {
    return o.key == "run.output_dir" || o.key == "run";
  });
  if (e.empty() || !own_folder) return e;
  // each variant in a folder of its own, named by its content: runs started in one folder
  // that ask for the same bed share it (and its lock), others do not overwrite each other's
  try {
    const auto doc = scene::Document::load(prepare_scene, e);
    const auto run = scene::read_run_settings(doc);
    const std::string h = content_hash(doc);
    e.push_back(scene::Override{"run.output_dir",
                                toml_string((run.output_dir / ("set-" + h)).generic_string())});
  } catch (const SceneError& x) {
    throw SceneError(where +
                     ": the prepare scene cannot be used with the overrides of 'set' and "
                     "'pass': " +
                     x.what());
  }
  return e;
}

}  // namespace

// ---------------------------------------------------------------------------------------
ParticleSource read_particle_source(const Table& t, const std::vector<Material>& materials) {
  ParticleSource s;
  const int given = int(t.has("file")) + int(t.has("scene"));
  if (given != 1)
    t.fail("file", "[dem.load] needs exactly one of 'file' and 'scene' (found " +
                       std::to_string(given) + ")");
  if (t.has("file")) {
    s.file = t.path("file");
    s.where = t.where("file");
    if (!std::filesystem::is_regular_file(s.file))
      t.fail("file", "\"" + s.file.string() + "\" does not exist or is not a file");
    for (const char* key : {"set", "pass", "seed_offset"})
      if (t.has(key)) t.fail(key, "is only used with 'scene' (the overrides of a prepare scene)");
  } else {
    s.prepare_scene = t.path("scene");
    s.where = t.where("scene");
    if (!std::filesystem::is_regular_file(s.prepare_scene))
      t.fail("scene", "\"" + s.prepare_scene.string() + "\" does not exist or is not a file");
    s.prepare_overrides = read_prepare_overrides(t, s.prepare_scene, s.where);
    s.file = prepared_state_path(s.prepare_scene, s.prepare_overrides, s.where);
  }
  std::string ext = s.file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  const std::string fallback = !s.prepare_scene.empty() ? "state" : ext == ".csv" ? "csv" : "auto";
  std::string format = t.choice("format", fallback, {"auto", "snapshot", "state", "csv"});
  if (format == "auto") {
    if (ext != ".h5" && ext != ".hdf5")
      t.fail("format", "cannot tell the format of \"" + s.file.string() +
                           "\" from its extension (.csv, .h5, .hdf5); give format");
    try {
      io::H5File f(s.file, io::H5File::Mode::read);
      format = f.exists("position") ? "snapshot" : "state";
    } catch (const io::H5Error& e) {
      t.fail("file", "\"" + s.file.string() + "\" cannot be read as HDF5 (" + e.what() +
                         "); a .h5 / .hdf5 file must be a snapshot or a DEM state, a .csv a "
                         "table x,y,z,r[,vx,vy,vz]");
    }
  }
  s.format = format == "snapshot" ? ParticleSource::Format::snapshot
             : format == "state"  ? ParticleSource::Format::state
                                  : ParticleSource::Format::csv;
  s.group = t.string("group", "dem");
  const bool is_state = s.format == ParticleSource::Format::state;
  if (!is_state && t.has("group")) t.fail("group", "is only used with a state file");
  s.history = t.boolean("history", is_state);
  if (s.history && !is_state)
    t.fail("history", "needs a state file (a snapshot or a CSV has no contact history)");
  s.velocities = t.boolean("velocities", true);
  s.keep_time = t.boolean("keep_time", false);
  if (s.keep_time && !s.history) t.fail("keep_time", "is only used with history = true");
  if (t.has("material") && t.has("material_map"))
    t.fail("material_map", "give 'material' or 'material_map', not both");
  if (t.has("material"))
    s.material = material_by_name(t, "material", t.string("material"), materials);
  if (t.has("material_map"))
    for (const auto& name : t.strings("material_map"))
      s.material_map.push_back(material_by_name(t, "material_map", name, materials));
  if (s.format == ParticleSource::Format::csv && s.material < 0)
    t.fail("material", "is required with a CSV file (it has no material column)");
  if (t.has("shift")) s.shift = t.vec3("shift");
  if (s.history) {
    for (const char* key : {"material", "material_map"})
      if (t.has(key))
        t.fail(key, "cannot be used with history = true: the state's material indices are kept");
    if (!s.velocities) t.fail("velocities", "must be true with history = true");
    if (s.shift != std::array<double, 3>{0, 0, 0})
      t.fail("shift", "cannot be used with history = true (the walls of the state stay put)");
  }
  s.max_overlap = t.number("max_overlap", 0.05, Range::positive());
  const std::string outside = t.choice("outside", "error", {"error", "remove", "keep", "crop"});
  s.outside = outside == "error"    ? ParticleSource::Outside::error
              : outside == "remove" ? ParticleSource::Outside::remove
              : outside == "crop"   ? ParticleSource::Outside::crop
                                    : ParticleSource::Outside::keep;
  if (t.has("tile")) {
    const auto k = t.numbers("tile", 3, Range::closed(1.0, 1000.0));
    for (int d = 0; d < 3; ++d) {
      if (k[d] != std::floor(k[d])) t.fail("tile", "copies must be whole numbers in [1, 1000]");
      s.tile[d] = static_cast<int>(k[d]);
    }
    if (!is_state)
      t.fail("tile", "needs a state file of a periodic block (format = \"state\")");
    s.tile_where = t.where("tile");
  }
  t.finish();
  return s;
}

std::filesystem::path prepared_state_path(const std::filesystem::path& prepare_scene,
                                          const std::vector<scene::Override>& overrides,
                                          const std::string& where) {
  try {
    const auto doc = scene::Document::load(prepare_scene, overrides);
    const auto run = scene::read_run_settings(doc);
    const auto dem = doc.root().table("dem");
    const auto out = dem ? dem->table("output") : std::nullopt;
    if (!out || !out->has("state") || !out->boolean("state"))
      throw SceneError(prepare_scene.string() +
                       ": does not write its end state ([dem.output] state = true)");
    return run.output_dir / kStateFileName;
  } catch (const SceneError& e) {
    throw SceneError(where + ": the prepare scene cannot be used: " + e.what());
  }
}

std::string scene_text_hash(const std::filesystem::path& file,
                            const std::vector<scene::Override>& overrides) {
  return content_hash(scene::Document::load(file, overrides));
}

bool state_is_current(const std::filesystem::path& state, const std::filesystem::path& scene,
                      const std::vector<scene::Override>& overrides) {
  if (!std::filesystem::is_regular_file(state)) return false;
  try {
    io::H5File f(state, io::H5File::Mode::read);
    const std::string made_by = f.attribute_string("/", "scene_hash");
    if (made_by == scene_text_hash(scene, overrides)) return true;
    // States written before the hash was of the content carry the hash of the file's bytes:
    // still current while the file is byte for byte the same (a bed of hours is not redone).
    return overrides.empty() && made_by == hex16(io::fnv1a64_file(scene));
  } catch (const std::exception&) {
    return false;
  }
}

OverlapReport largest_overlap(const ParticleState& p, std::span<const WallMesh> walls) {
  OverlapReport r;
  const std::size_t n = p.size();
  if (n == 0) return r;
  const double rmax = *std::max_element(p.radius.begin(), p.radius.end());
  const double cell = 2.0 * rmax;
  auto key = [&](double x, double y, double z) {
    const auto c = [&](double v) { return phys::saturated_cell(v / cell); };
    // 21 bits per axis is enough for any scene of sensible extent.
    return ((c(x) & 0x1fffff) << 42) | ((c(y) & 0x1fffff) << 21) | (c(z) & 0x1fffff);
  };
  std::unordered_map<std::int64_t, std::vector<std::int64_t>> grid;
  grid.reserve(n);
  for (std::size_t i = 0; i < n; ++i)
    grid[key(p.px[i], p.py[i], p.pz[i])].push_back(std::int64_t(i));
  // Polyhedra are left out: their radius is the bounding sphere's, which overlaps in any
  // packed bed; the engine's stability guard measures their true overlap at the first steps.
  auto sphere = [&](std::size_t i) {
    return p.shape.size() != n || p.shape[i] == static_cast<std::uint8_t>(ParticleShape::sphere);
  };
  auto consider = [&](double depth, double rsmall, std::int64_t i, std::int64_t j) {
    if (!(depth > 0)) return;
    ++r.touching;
    if (depth / rsmall > r.fraction) r.fraction = depth / rsmall, r.depth = depth, r.i = i, r.j = j;
  };
  for (std::size_t i = 0; i < n; ++i) {
    if (!sphere(i)) {
      ++r.unchecked;
      continue;
    }
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it =
              grid.find(key(p.px[i] + dx * cell, p.py[i] + dy * cell, p.pz[i] + dz * cell));
          if (it == grid.end()) continue;
          for (std::int64_t j : it->second) {
            if (j <= std::int64_t(i) || !sphere(std::size_t(j))) continue;
            const double ex = p.px[j] - p.px[i], ey = p.py[j] - p.py[i], ez = p.pz[j] - p.pz[i];
            const double d = std::sqrt(ex * ex + ey * ey + ez * ez);
            consider(p.radius[i] + p.radius[j] - d, std::min(p.radius[i], p.radius[j]),
                     std::int64_t(i), j);
          }
        }
  }
  // Walls: each triangle against the particles in the cells its box (grown by rmax) covers.
  for (const auto& w : walls) {
    for (std::size_t t = 0; t + 2 < w.triangles.size(); t += 3) {
      phys::Vec3 v[3];
      double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
      for (int k = 0; k < 3; ++k) {
        const double* x = w.vertices.data() + 3 * w.triangles[t + k];
        v[k] = {x[0], x[1], x[2]};
        for (int d = 0; d < 3; ++d)
          lo[d] = std::min(lo[d], x[d] - rmax), hi[d] = std::max(hi[d], x[d] + rmax);
      }
      const auto cells = [&](int d) {
        return static_cast<std::int64_t>(std::floor(hi[d] / cell) - std::floor(lo[d] / cell)) + 1;
      };
      // A huge triangle (a floor) over a small bed: walk the particles instead of the cells.
      const bool walk_cells = double(cells(0)) * double(cells(1)) * double(cells(2)) < double(n);
      auto test = [&](std::int64_t i) {
        if (!sphere(std::size_t(i))) return;
        const phys::Vec3 c{p.px[i], p.py[i], p.pz[i]};
        const auto cp = phys::closest_point_triangle(c, v[0], v[1], v[2]);
        const phys::Vec3 e = c - cp.point;
        consider(p.radius[i] - std::sqrt(phys::norm2(e)), p.radius[i], i, -1);
      };
      if (walk_cells) {
        for (double x = std::floor(lo[0] / cell) * cell; x <= hi[0]; x += cell)
          for (double y = std::floor(lo[1] / cell) * cell; y <= hi[1]; y += cell)
            for (double z = std::floor(lo[2] / cell) * cell; z <= hi[2]; z += cell) {
              const auto it = grid.find(key(x + 0.5 * cell, y + 0.5 * cell, z + 0.5 * cell));
              if (it != grid.end())
                for (std::int64_t i : it->second) test(i);
            }
      } else {
        for (std::size_t i = 0; i < n; ++i)
          if (p.px[i] >= lo[0] && p.px[i] <= hi[0] && p.py[i] >= lo[1] && p.py[i] <= hi[1] &&
              p.pz[i] >= lo[2] && p.pz[i] <= hi[2])
            test(std::int64_t(i));
      }
    }
  }
  return r;
}

std::size_t load_particles(const ParticleSource& s, DemSystem& system,
                           std::span<const WallMesh> walls, std::ostream* log) {
  if (system.particle_count() != 0)
    throw std::logic_error("load_particles: the system must have no particles yet");
  if (!std::filesystem::is_regular_file(s.file)) {
    if (!s.prepare_scene.empty())
      throw SceneError(s.where + ": the end state of " + s.prepare_scene.string() + " (" +
                       s.file.string() +
                       ") does not exist yet; `demfem run` makes it first, or "
                       "run that scene yourself");
    throw SceneError(s.where + ": \"" + s.file.string() + "\" does not exist");
  }
  if (!s.prepare_scene.empty() && !state_is_current(s.file, s.prepare_scene, s.prepare_overrides))
    throw SceneError(s.where + ": " + s.file.string() + " was made by another version of " +
                     s.prepare_scene.string() +
                     " (its scene_hash differs); run that scene "
                     "again (`demfem run` does so itself)");
  std::vector<std::int64_t> origin_line;  // a CSV's: its lines
  PeriodicRange block;  // a state's periodic directions (the block a tiled bed is made of)
  std::size_t released = 0;  // particles the state held frozen, free here
  try {
    if (s.history) {
      released = restore_state(s, system, walls);
    } else {
      Loaded l = s.format == ParticleSource::Format::csv        ? read_csv(s, log)
                 : s.format == ParticleSource::Format::snapshot ? read_snapshot(s)
                                                                : read_state_particles(s);
      check_finite(s, l);
      assign_materials(s, l, system.settings());
      for (auto& p : l.particles) {
        for (int d = 0; d < 3; ++d) p.position[d] += s.shift[d];
        if (!s.velocities) p.velocity = {}, p.angular_velocity = {};
      }
      if (l.particles.empty()) data_error(s, s.file.string(), "holds no particles");
      if (l.particles.size() > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
        data_error(s, s.file.string(), "holds more particles than a scene can (2^31 - 1)");
      if (!l.shapes.empty()) {  // the state's shapes join this scene's table
        std::vector<std::int32_t> id(l.shapes.size());
        for (std::size_t k = 0; k < l.shapes.size(); ++k) {
          try {
            id[k] = system.add_shape(l.shapes[k]);
          } catch (const std::invalid_argument& e) {
            data_error(s, s.file.string() + ": shape " + std::to_string(k), e.what());
          }
        }
        for (auto& p : l.particles)
          if (p.shape == ParticleShape::polyhedron) p.shape_id = id[std::size_t(p.shape_id)];
      }
      try {
        system.add_particles(l.particles);
      } catch (const std::invalid_argument& e) {  // what the checks above left to the engine
        data_error(s, s.file.string(), e.what());
      }
      origin_line = std::move(l.line);
    }
    if (s.format == ParticleSource::Format::state &&
        (s.tile != std::array<int, 3>{1, 1, 1} || s.outside == ParticleSource::Outside::crop)) {
      io::H5File f(s.file, io::H5File::Mode::read);
      block = read_state_periodic(f, s.group);
      try {
        if (s.tile != std::array<int, 3>{1, 1, 1}) system.tile(block, s.tile, s.velocities);
      } catch (const std::invalid_argument& e) {
        throw SceneError(s.tile_where + ": " + s.file.string() + ": " + e.what());
      }
    }
  } catch (const io::H5Error& e) {
    throw SceneError(s.where + ": " + e.what());
  }
  const std::size_t n = system.particle_count();
  if (n == 0) data_error(s, s.file.string(), "holds no particles");
  if (s.history) {  // a state is restored as saved: check what a CSV or snapshot is checked for
    const auto& q = system.particles();
    for (std::size_t i = 0; i < n; ++i) {
      const double v[] = {q.px[i], q.py[i], q.pz[i], q.vx[i], q.vy[i],
                          q.vz[i], q.wx[i], q.wy[i], q.wz[i], q.radius[i]};
      for (double x : v)
        if (!std::isfinite(x))
          data_error(s, s.file.string() + ": particle " + std::to_string(i),
                     "a position, velocity or radius is not finite");
      if (!(q.radius[i] > 0))
        data_error(s, s.file.string() + ": particle " + std::to_string(i), "radius must be > 0");
    }
  }
  auto name_of = [&](std::int64_t i) {
    return particle_origin(s.file.string(), origin_line, static_cast<std::size_t>(i));
  };
  const auto& p = system.particles();

  // Outside the walls' bounding box.
  std::size_t outside = 0;
  std::vector<std::uint8_t> keep(n, 1);
  if (!walls.empty()) {
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (const auto& w : walls)
      for (std::size_t k = 0; k + 2 < w.vertices.size(); k += 3)
        for (int d = 0; d < 3; ++d)
          lo[d] = std::min(lo[d], w.vertices[k + d]), hi[d] = std::max(hi[d], w.vertices[k + d]);
    for (std::size_t i = 0; i < n; ++i) {
      const double x[3] = {p.px[i], p.py[i], p.pz[i]};
      bool in = true;
      for (int d = 0; d < 3; ++d) in = in && x[d] >= lo[d] && x[d] <= hi[d];
      // crop: in a direction the block was periodic in and this scene is not (tiled or
      // not: a block tiled once still has rocks across its seam, which a wall there would
      // cut), the whole bounding sphere; the floor, in a direction the block was not
      // periodic in, carries the bed as it did the block
      for (int d = 0; d < 3 && s.outside == ParticleSource::Outside::crop; ++d)
        if (block.on[d] && !system.settings().periodic.on[d])
          in = in && x[d] - p.radius[i] >= lo[d] && x[d] + p.radius[i] <= hi[d];
      if (in) continue;
      ++outside;
      keep[i] = 0;
      if (s.outside == ParticleSource::Outside::error) {
        std::ostringstream m;
        m << "the centre (" << x[0] << ", " << x[1] << ", " << x[2]
          << ") m lies outside the walls' bounding box [" << lo[0] << ", " << hi[0] << "] x ["
          << lo[1] << ", " << hi[1] << "] x [" << lo[2] << ", " << hi[2]
          << "] m (dem.load.outside = \"remove\" drops such particles, \"keep\" keeps them)";
        data_error(s, name_of(std::int64_t(i)), m.str());
      }
    }
  }
  if (outside > 0 && (s.outside == ParticleSource::Outside::remove ||
                      s.outside == ParticleSource::Outside::crop))
    system.remove_particles(keep);

  const OverlapReport ov = largest_overlap(system.particles(), walls);
  if (ov.fraction > s.max_overlap) {
    std::ostringstream m;
    m << "overlaps " << (ov.j < 0 ? std::string("a wall") : name_of(ov.j)) << " by " << ov.depth
      << " m, " << ov.fraction
      << " of the smaller radius (at most dem.load.max_overlap = " << s.max_overlap
      << "): the contact would explode. Were the particles made for other "
      << "walls, or scaled?";
    data_error(s, name_of(ov.i), m.str());
  }
  if (log) {
    const char* kind = s.format == ParticleSource::Format::csv        ? "CSV"
                       : s.format == ParticleSource::Format::snapshot ? "snapshot"
                                                                      : "state";
    *log << "dem: loaded " << describe_count(system.particle_count()) << " from " << kind << " "
         << s.file.string() << (s.history ? " with contact history" : "")
         << (s.history && s.keep_time ? " (time kept)" : "");
    if (released > 0)
      *log << "; " << released << " particles frozen in the state are free in this scene (its "
           << "own [dem.freeze] decides what is held)";
    if (outside > 0)
      *log << "; " << outside << " outside the walls' bounding box "
           << (s.outside == ParticleSource::Outside::keep ? "kept" : "removed")
           << (s.outside == ParticleSource::Outside::crop ? " (or crossing its faces)" : "");
    if (ov.unchecked < system.particle_count())
      *log << "; largest overlap " << ov.depth << " m (" << ov.fraction
           << " of the smaller radius) among " << ov.touching << " touching pairs"
           << (ov.unchecked > 0 ? " of spheres" : "");
    if (ov.unchecked > 0)
      *log << "; " << ov.unchecked
           << " polyhedra not checked here (their true overlap is measured by the engine's "
              "guard at the first steps)";
    *log << "\n";
    if (ov.fraction > kWarnOverlap)
      *log << "dem: warning: the loaded particles overlap by up to " << ov.fraction
           << " of a radius (a settled bed of stiff grains overlaps by about a per cent or "
              "less); expect a jolt at the start\n";
  }
  return system.particle_count();
}

}  // namespace demfem::dem
