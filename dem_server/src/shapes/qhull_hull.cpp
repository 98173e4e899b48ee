#include "qhull_hull.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

extern "C" {
#include <libqhull_r/qhull_ra.h>
}

namespace demfem::dem::shapes::detail {

namespace {

/// Qhull writes its diagnostics to a FILE*; an in-memory stream keeps them for the message.
class MessageStream {
 public:
  MessageStream() : file_(open_memstream(&buffer_, &size_)) {}
  ~MessageStream() {
    if (file_) std::fclose(file_);
    std::free(buffer_);
  }
  MessageStream(const MessageStream&) = delete;
  MessageStream& operator=(const MessageStream&) = delete;
  FILE* file() const { return file_; }
  /// The first non-empty line written so far (Qhull's "QHnnnn ..." summary).
  std::string first_line() {
    if (!file_) return "";
    std::fflush(file_);
    std::string s(buffer_ ? buffer_ : "", size_);
    const auto b = s.find_first_not_of(" \n");
    if (b == std::string::npos) return "";
    return s.substr(b, s.find('\n', b) - b);
  }

 private:
  char* buffer_ = nullptr;
  std::size_t size_ = 0;
  FILE* file_ = nullptr;
};

/// Owns a qhT: frees Qhull's memory on every path out.
struct QhullRun {
  qhT qh;
  explicit QhullRun(FILE* err) { qh_zero(&qh, err); }
  ~QhullRun() {
    qh_freeqhull(&qh, !qh_ALL);
    int curlong = 0, totlong = 0;
    qh_memfreeshort(&qh, &curlong, &totlong);
  }
  QhullRun(const QhullRun&) = delete;
  QhullRun& operator=(const QhullRun&) = delete;
};

}  // namespace

RawHull qhull_triangulated(std::span<const Vec3> points, std::string_view source) {
  std::vector<coordT> coords;
  coords.reserve(3 * points.size());
  for (const Vec3& p : points) coords.insert(coords.end(), p.begin(), p.end());

  MessageStream messages;
  auto run = std::make_unique<QhullRun>(messages.file() ? messages.file() : stderr);
  qhT* qh = &run->qh;
  char options[] = "qhull Qt";
  const int code = qh_new_qhull(qh, 3, static_cast<int>(points.size()), coords.data(), False,
                                options, nullptr, messages.file());
  if (code != 0) {
    throw ShapeError(std::string(source) + ": Qhull could not build the convex hull of " +
                     std::to_string(points.size()) + " points: " + messages.first_line());
  }

  RawHull hull;
  std::vector<std::int32_t> vertex_of_point(points.size(), -1);
  // Vertices numbered in input order, so that the result does not depend on Qhull's lists.
  std::vector<std::int32_t> used;
  {
    facetT* facet;
    vertexT *vertex, **vertexp;
    FORALLfacets {
      FOREACHvertex_(facet->vertices) {
        used.push_back(static_cast<std::int32_t>(qh_pointid(qh, vertex->point)));
      }
    }
  }
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  for (std::int32_t p : used) {
    vertex_of_point[std::size_t(p)] = static_cast<std::int32_t>(hull.vertices.size());
    hull.vertices.push_back(points[std::size_t(p)]);
    hull.input_index.push_back(p);
  }

  facetT* facet;
  vertexT *vertex, **vertexp;
  FORALLfacets {
    Triangle t{};
    int k = 0;
    FOREACHvertex_(facet->vertices) {
      if (k < 3) t[std::size_t(k)] = vertex_of_point[std::size_t(qh_pointid(qh, vertex->point))];
      ++k;
    }
    if (k != 3) {
      throw ShapeError(std::string(source) + ": Qhull returned a facet with " + std::to_string(k) +
                       " vertices despite triangulation (option Qt)");
    }
    // Qhull's vertex order within a facet follows its own orientation flag; the facet's
    // outward normal decides.
    const Vec3& a = hull.vertices[std::size_t(t[0])];
    const Vec3 n =
        cross(hull.vertices[std::size_t(t[1])] - a, hull.vertices[std::size_t(t[2])] - a);
    const Vec3 outward{facet->normal[0], facet->normal[1], facet->normal[2]};
    if (dot(n, outward) < 0) std::swap(t[1], t[2]);
    hull.triangles.push_back(t);
  }
  // Canonical order: each triangle starting at its smallest index, then sorted.
  for (Triangle& t : hull.triangles) {
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
  }
  std::sort(hull.triangles.begin(), hull.triangles.end());
  return hull;
}

}  // namespace demfem::dem::shapes::detail
