#include "demfem/dem/shapes/geometry/stl_reader.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <unordered_map>
#include <vector>

#include "demfem/io/input_file.hpp"

// Binary STL is little endian; the supported platforms (x86-64, aarch64) are too.
static_assert(std::endian::native == std::endian::little, "binary STL I/O assumes little endian");

namespace demfem::dem {

namespace {

using Vec3 = std::array<double, 3>;

Vec3 sub(const Vec3& a, const Vec3& b) {
  return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double norm(const Vec3& a) {
  return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
}

/// Raw triangles as read, with the line of each (0 for binary) for messages.
struct RawTriangles {
  std::vector<Vec3> corners;  // 3 per triangle
  std::vector<std::size_t> lines;
};

std::string triangle_label(const std::string& file, std::size_t t, std::size_t line) {
  std::string s = file + ": triangle " + std::to_string(t + 1);
  if (line > 0) s = file + ":" + std::to_string(line) + ": triangle " + std::to_string(t + 1);
  return s;
}

void check_triangle(const std::string& file, const RawTriangles& raw, std::size_t t) {
  const Vec3& a = raw.corners[3 * t];
  const Vec3& b = raw.corners[3 * t + 1];
  const Vec3& c = raw.corners[3 * t + 2];
  for (const Vec3* v : {&a, &b, &c}) {
    for (double x : *v) {
      if (!std::isfinite(x)) {
        throw StlError(triangle_label(file, t, raw.lines[t]) +
                       " has a non-finite vertex coordinate");
      }
    }
  }
  const double longest = std::max({norm(sub(b, a)), norm(sub(c, b)), norm(sub(a, c))});
  const double area2 = norm(cross(sub(b, a), sub(c, a)));
  // Relative test: a triangle whose area is below 1e-12 of its longest edge squared has no
  // usable normal; a plain == 0 would let round-off slivers through.
  if (!(area2 > 1e-12 * longest * longest)) {
    throw StlError(triangle_label(file, t, raw.lines[t]) + " has zero area");
  }
}

RawTriangles parse_binary(const std::string& file, const std::string& bytes, std::uint32_t count) {
  RawTriangles raw;
  raw.corners.reserve(3 * std::size_t(count));
  raw.lines.assign(count, 0);
  for (std::uint32_t t = 0; t < count; ++t) {
    const char* rec = bytes.data() + 84 + 50 * std::size_t(t);
    float f[12];
    std::memcpy(f, rec, sizeof f);
    for (int k = 0; k < 3; ++k) raw.corners.push_back({f[3 + 3 * k], f[4 + 3 * k], f[5 + 3 * k]});
  }
  (void)file;
  return raw;
}

RawTriangles parse_ascii(const std::string& file, const std::string& text) {
  RawTriangles raw;
  std::istringstream in(text);
  std::string line;
  std::size_t line_no = 0;
  // States: expecting what next.
  enum class S { solid, facet_or_end, outer, vertex, endloop, endfacet, done } s = S::solid;
  int vertex_in_facet = 0;
  std::size_t facet_line = 0;
  auto fail = [&](const std::string& msg) -> void {
    throw StlError(file + ":" + std::to_string(line_no) + ": " + msg);
  };
  auto parse_number = [&](const std::string& tok) {
    const char* b = tok.c_str();
    char* e = nullptr;
    const double v = std::strtod(b, &e);
    if (e == b || *e != '\0') fail("'" + tok + "' is not a number");
    return v;
  };
  while (std::getline(in, line)) {
    ++line_no;
    std::istringstream ls(line);
    std::vector<std::string> tok{std::istream_iterator<std::string>(ls),
                                 std::istream_iterator<std::string>()};
    if (tok.empty()) continue;
    const std::string& k = tok[0];
    switch (s) {
      case S::solid:
        if (k != "solid") fail("expected 'solid', found '" + k + "'");
        s = S::facet_or_end;
        break;
      case S::facet_or_end:
        if (k == "endsolid") {
          s = S::done;
        } else if (k == "facet") {
          if (tok.size() != 5 || tok[1] != "normal") fail("expected 'facet normal nx ny nz'");
          facet_line = line_no;
          s = S::outer;
        } else {
          fail("expected 'facet' or 'endsolid', found '" + k + "'");
        }
        break;
      case S::outer:
        if (k != "outer" || tok.size() != 2 || tok[1] != "loop") fail("expected 'outer loop'");
        vertex_in_facet = 0;
        s = S::vertex;
        break;
      case S::vertex:
        if (k == "endloop") {
          fail("facet " + std::to_string(raw.lines.size() + 1) + " has " +
               std::to_string(vertex_in_facet) + " vertices, expected 3");
        }
        if (k != "vertex") fail("expected 'vertex x y z', found '" + k + "'");
        if (tok.size() != 4) fail("expected 'vertex x y z' with three coordinates");
        {
          Vec3 v{parse_number(tok[1]), parse_number(tok[2]), parse_number(tok[3])};
          for (double x : v) {
            if (!std::isfinite(x)) {
              fail("triangle " + std::to_string(raw.lines.size() + 1) +
                   " has a non-finite vertex coordinate");
            }
          }
          raw.corners.push_back(v);
        }
        if (++vertex_in_facet == 3) s = S::endloop;
        break;
      case S::endloop:
        if (k != "endloop") {
          fail("facet " + std::to_string(raw.lines.size() + 1) +
               " has more than 3 vertices (expected 'endloop')");
        }
        s = S::endfacet;
        break;
      case S::endfacet:
        if (k != "endfacet") fail("expected 'endfacet', found '" + k + "'");
        raw.lines.push_back(facet_line);
        s = S::facet_or_end;
        break;
      case S::done:
        // Some exporters concatenate several solids.
        if (k != "solid") fail("unexpected '" + k + "' after 'endsolid'");
        s = S::facet_or_end;
        break;
    }
  }
  if (s != S::done) {
    throw StlError(file + ":" + std::to_string(line_no) +
                   ": ends inside a solid (truncated? expected 'endsolid')");
  }
  return raw;
}

/// Merges vertices within `tol` (first come, first kept, so the result is deterministic).
TriangleMesh weld(const std::string& file, const RawTriangles& raw, double tol) {
  TriangleMesh mesh;
  const std::size_t nt = raw.lines.size();
  const double cell = tol > 0 ? tol : 1.0;
  struct KeyHash {
    std::size_t operator()(const std::array<std::int64_t, 3>& k) const {
      // Unsigned arithmetic: wraps instead of overflowing for tiny tolerances.
      return std::size_t(std::uint64_t(k[0]) * 73856093u) ^
             std::size_t(std::uint64_t(k[1]) * 19349663u) ^
             std::size_t(std::uint64_t(k[2]) * 83492791u);
    }
  };
  std::unordered_map<std::array<std::int64_t, 3>, std::vector<std::int32_t>, KeyHash> grid;
  auto key_of = [&](const Vec3& p) {
    // Clamped so that absurd coordinates or tolerances cannot overflow the conversion.
    auto k = [&](double x) { return std::int64_t(std::clamp(std::floor(x / cell), -4e18, 4e18)); };
    return std::array<std::int64_t, 3>{k(p[0]), k(p[1]), k(p[2])};
  };
  auto find_or_add = [&](const Vec3& p) -> std::int32_t {
    const auto k = key_of(p);
    std::int32_t best = -1;
    double best_d = 0.0;
    for (std::int64_t dx = -1; dx <= 1; ++dx)
      for (std::int64_t dy = -1; dy <= 1; ++dy)
        for (std::int64_t dz = -1; dz <= 1; ++dz) {
          auto it = grid.find({k[0] + dx, k[1] + dy, k[2] + dz});
          if (it == grid.end()) continue;
          for (std::int32_t v : it->second) {
            const Vec3 q{mesh.vertices[3 * v], mesh.vertices[3 * v + 1], mesh.vertices[3 * v + 2]};
            const double d = norm(sub(p, q));
            if (d <= tol && (best < 0 || d < best_d || (d == best_d && v < best))) {
              best = v;
              best_d = d;
            }
          }
        }
    if (best >= 0) return best;
    const auto id = static_cast<std::int32_t>(mesh.vertices.size() / 3);
    mesh.vertices.insert(mesh.vertices.end(), p.begin(), p.end());
    grid[k].push_back(id);
    return id;
  };
  mesh.triangles.reserve(3 * nt);
  for (std::size_t t = 0; t < nt; ++t) {
    std::int32_t ids[3];
    for (int c = 0; c < 3; ++c) ids[c] = find_or_add(raw.corners[3 * t + c]);
    if (ids[0] == ids[1] || ids[1] == ids[2] || ids[0] == ids[2]) {
      throw StlError(triangle_label(file, t, raw.lines[t]) +
                     " has zero area after welding vertices closer than " + std::to_string(tol) +
                     " m");
    }
    mesh.triangles.insert(mesh.triangles.end(), ids, ids + 3);
  }
  return mesh;
}

}  // namespace

TriangleMesh read_stl(const std::filesystem::path& path, double weld_tolerance) {
  const std::string file = path.string();
  std::string bytes;
  try {
    bytes = io::read_regular_file(path, io::kMeshFileLimit, "an STL file (ASCII or binary)");
  } catch (const io::InputFileError& e) {
    throw StlError(e.what());
  }
  if (bytes.empty()) throw StlError(file + ": is empty");

  bool binary = false;
  std::uint32_t count = 0;
  if (bytes.size() >= 84) {
    std::memcpy(&count, bytes.data() + 80, 4);
    binary = 84 + 50 * std::uint64_t(count) == bytes.size();
  }
  const auto first = bytes.find_first_not_of(" \t\r\n");
  const bool starts_solid = first != std::string::npos && bytes.compare(first, 5, "solid") == 0;
  RawTriangles raw;
  if (binary) {
    raw = parse_binary(file, bytes, count);
  } else if (starts_solid && bytes.find('\0') == std::string::npos) {
    raw = parse_ascii(file, bytes);
  } else if (bytes.size() < 84) {
    throw StlError(file + ": " + std::to_string(bytes.size()) +
                   " bytes: neither ASCII STL (no 'solid' keyword) nor binary STL (shorter than "
                   "its 84-byte header)");
  } else {
    throw StlError(file + ": binary STL header announces " + std::to_string(count) +
                   " triangles, i.e. 84 + 50 * " + std::to_string(count) + " = " +
                   std::to_string(84 + 50 * std::uint64_t(count)) + " bytes, but the file has " +
                   std::to_string(bytes.size()) + " bytes (truncated or wrong triangle count)");
  }
  if (raw.lines.empty()) throw StlError(file + ": has no triangles");
  for (std::size_t t = 0; t < raw.lines.size(); ++t) check_triangle(file, raw, t);

  double tol = weld_tolerance;
  if (tol < 0) {
    Vec3 lo = raw.corners[0], hi = raw.corners[0];
    for (const Vec3& p : raw.corners)
      for (int k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], p[k]);
        hi[k] = std::max(hi[k], p[k]);
      }
    tol = 1e-9 * norm(sub(hi, lo));
  }
  TriangleMesh mesh = weld(file, raw, tol);
  mesh.name = path.stem().string();
  return mesh;
}

namespace {

Vec3 vertex(const TriangleMesh& m, std::int32_t i) {
  return {m.vertices[3 * i], m.vertices[3 * i + 1], m.vertices[3 * i + 2]};
}

Vec3 unit_normal(const TriangleMesh& m, std::size_t t) {
  const Vec3 a = vertex(m, m.triangles[3 * t]), b = vertex(m, m.triangles[3 * t + 1]),
             c = vertex(m, m.triangles[3 * t + 2]);
  Vec3 n = cross(sub(b, a), sub(c, a));
  const double l = norm(n);
  if (l > 0) n = {n[0] / l, n[1] / l, n[2] / l};
  return n;
}

}  // namespace

void write_stl_ascii(const std::filesystem::path& file, const TriangleMesh& mesh) {
  std::ofstream out(file, std::ios::trunc);
  if (!out) throw StlError(file.string() + ": cannot create STL file");
  out.precision(17);
  out << "solid " << mesh.name << "\n";
  for (std::size_t t = 0; t < mesh.triangles.size() / 3; ++t) {
    const Vec3 n = unit_normal(mesh, t);
    out << "  facet normal " << n[0] << " " << n[1] << " " << n[2] << "\n    outer loop\n";
    for (int c = 0; c < 3; ++c) {
      const Vec3 v = vertex(mesh, mesh.triangles[3 * t + c]);
      out << "      vertex " << v[0] << " " << v[1] << " " << v[2] << "\n";
    }
    out << "    endloop\n  endfacet\n";
  }
  out << "endsolid " << mesh.name << "\n";
  if (!out.flush()) throw StlError(file.string() + ": write failed");
}

void write_stl_binary(const std::filesystem::path& file, const TriangleMesh& mesh) {
  std::ofstream out(file, std::ios::trunc | std::ios::binary);
  if (!out) throw StlError(file.string() + ": cannot create STL file");
  char header[80] = {};
  // Deliberately starts with "solid": binary files in the wild often do.
  std::snprintf(header, sizeof header, "solid %s (binary, demfem)", mesh.name.c_str());
  out.write(header, 80);
  const auto n = static_cast<std::uint32_t>(mesh.triangles.size() / 3);
  out.write(reinterpret_cast<const char*>(&n), 4);
  for (std::uint32_t t = 0; t < n; ++t) {
    float f[12];
    const Vec3 nn = unit_normal(mesh, t);
    for (int k = 0; k < 3; ++k) f[k] = static_cast<float>(nn[k]);
    for (int c = 0; c < 3; ++c) {
      const Vec3 v = vertex(mesh, mesh.triangles[3 * t + c]);
      for (int k = 0; k < 3; ++k) f[3 + 3 * c + k] = static_cast<float>(v[k]);
    }
    out.write(reinterpret_cast<const char*>(f), sizeof f);
    const std::uint16_t attr = 0;
    out.write(reinterpret_cast<const char*>(&attr), 2);
  }
  if (!out.flush()) throw StlError(file.string() + ": write failed");
}

TriangleMesh make_box_mesh(const std::array<double, 3>& lo, const std::array<double, 3>& hi,
                           bool open_top) {
  TriangleMesh m;
  m.name = "box";
  for (int i = 0; i < 8; ++i) {
    m.vertices.push_back((i & 1) ? hi[0] : lo[0]);
    m.vertices.push_back((i & 2) ? hi[1] : lo[1]);
    m.vertices.push_back((i & 4) ? hi[2] : lo[2]);
  }
  const int quads[6][4] = {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}};
  const Vec3 centre{0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
  for (int q = 0; q < 6; ++q) {
    if (open_top && q == 1) continue;  // quad 1 is the face z = hi
    const int* v = quads[q];
    for (const std::array<int, 3> tri :
         {std::array<int, 3>{v[0], v[1], v[2]}, std::array<int, 3>{v[0], v[2], v[3]}}) {
      m.triangles.insert(m.triangles.end(), tri.begin(), tri.end());
      // Orient each triangle so its normal points to the box centre (the particle side).
      const std::size_t t = m.triangles.size() / 3 - 1;
      const Vec3 n = unit_normal(m, t);
      const Vec3 a = vertex(m, tri[0]);
      const Vec3 to_c = sub(centre, a);
      if (n[0] * to_c[0] + n[1] * to_c[1] + n[2] * to_c[2] < 0) {
        std::swap(m.triangles[3 * t + 1], m.triangles[3 * t + 2]);
      }
    }
  }
  return m;
}

TriangleMesh make_plane_mesh(const std::array<double, 3>& point,
                             const std::array<double, 3>& normal, double size) {
  const double l = norm(normal);
  if (!(l > 0) || !(size > 0)) throw std::invalid_argument("make_plane_mesh: zero normal or size");
  const Vec3 n{normal[0] / l, normal[1] / l, normal[2] / l};
  // Any vector not parallel to n gives the in-plane basis.
  const Vec3 helper = std::abs(n[0]) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
  Vec3 u = cross(n, helper);
  const double lu = norm(u);
  u = {u[0] / lu, u[1] / lu, u[2] / lu};
  const Vec3 w = cross(n, u);
  const double h = 0.5 * size;
  TriangleMesh m;
  m.name = "plane";
  const double su[4] = {-h, h, h, -h}, sw[4] = {-h, -h, h, h};
  for (int i = 0; i < 4; ++i)
    for (int k = 0; k < 3; ++k) m.vertices.push_back(point[k] + su[i] * u[k] + sw[i] * w[k]);
  // u x w = n, so (0, 1, 2) is counter-clockwise seen from the normal side.
  m.triangles = {0, 1, 2, 0, 2, 3};
  return m;
}

double mesh_area(const std::vector<double>& vertices, const std::vector<std::int32_t>& triangles) {
  double a = 0.0;
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3) {
    auto v = [&](int c) {
      const std::int32_t i = triangles[t + c];
      return Vec3{vertices[3 * i], vertices[3 * i + 1], vertices[3 * i + 2]};
    };
    a += 0.5 * norm(cross(sub(v(1), v(0)), sub(v(2), v(0))));
  }
  return a;
}

}  // namespace demfem::dem
