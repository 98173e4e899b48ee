#include "demfem/dem/shapes/sieve_size.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <queue>
#include <utility>
#include <vector>

#include "demfem/dem/shapes/geometry/rng.hpp"
#include "demfem/dem/shapes/mass_properties.hpp"
#include "shape_util.hpp"

namespace demfem::dem::shapes {

namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
constexpr double kPi = std::numbers::pi;

constexpr int kPattern = 16;          // tangent directions per step
constexpr double kFirstStep = 0.05;   // rad
constexpr double kCoarseStep = 1e-3;  // rad: end of the search from each start

/// Andrew's monotone chain: the convex hull of 2-D points, counter-clockwise, no collinear
/// points.
/// (Buffers passed in: the search evaluates this thousands of times per shape.)
void hull_2d(std::vector<Vector2d>& p, std::vector<Vector2d>& h) {
  std::sort(p.begin(), p.end(), [](const Vector2d& a, const Vector2d& b) {
    return a.x() != b.x() ? a.x() < b.x() : a.y() < b.y();
  });
  auto turn = [](const Vector2d& o, const Vector2d& a, const Vector2d& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  h.resize(2 * p.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && turn(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (std::size_t i = p.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && turn(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  h.resize(k > 1 ? k - 1 : k);
}

/// For a fixed direction of passage, the smallest square containing the projection: the
/// minimum over psi in [0, pi/2) of max(W(psi), W(psi + pi/2)), W the projection's width.
/// Exact: between consecutive breakpoints (the hull's edge normals, turned into the first
/// quadrant) W(psi) = c . e(psi) with a constant antipodal difference c; each piece is
/// concave where positive, so the minimum lies at a breakpoint or where the two widths
/// cross. Angles are kept as unit vectors (no trigonometry): in the first quadrant the angle
/// grows with the y component.
struct Square {
  double side;
  Vector2d e;  // w1 = e.x a + e.y b
};

double cross2(const Vector2d& a, const Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

Square smallest_square(const std::vector<Vector2d>& h, std::vector<Vector2d>& breaks) {
  const std::size_t m = h.size();
  breaks.assign({Vector2d(1.0, 0.0), Vector2d(0.0, 1.0)});
  for (std::size_t i = 0; i < m; ++i) {
    const Vector2d d = h[(i + 1) % m] - h[i];
    Vector2d n = Vector2d(d.y(), -d.x()).normalized();
    for (int turn = 0; turn < 3 && !(n.x() > 0 && n.y() >= 0); ++turn) n = Vector2d(n.y(), -n.x());
    breaks.push_back(n);
  }
  std::sort(breaks.begin(), breaks.end(),
            [](const Vector2d& a, const Vector2d& b) { return a.y() < b.y(); });
  // Support vertices in the directions e, -e, e+, -e+ (e+ = e turned by 90 degrees). As e
  // turns counter-clockwise through the sorted intervals each moves forward along the
  // counter-clockwise hull, so hill climbing from the previous one costs O(m) in all.
  std::size_t sup[4] = {0, 0, 0, 0};
  auto climb = [&](std::size_t& i, const Vector2d& e) {
    for (std::size_t step = 0; step < m; ++step) {
      const std::size_t next = (i + 1) % m;
      if (h[next].dot(e) > h[i].dot(e)) {
        i = next;
      } else {
        break;
      }
    }
  };
  auto scan = [&](std::size_t& i, const Vector2d& e) {
    for (std::size_t j = 1; j < m; ++j)
      if (h[j].dot(e) > h[i].dot(e)) i = j;
  };
  bool first = true;
  auto antipodal = [&](const Vector2d& e, std::size_t& ihi, std::size_t& ilo) {
    if (first) {
      scan(ihi, e);
      scan(ilo, -e);
    } else {
      climb(ihi, e);
      climb(ilo, -e);
    }
    return Vector2d(h[ihi] - h[ilo]);
  };
  Square best{INFINITY, Vector2d(1.0, 0.0)};
  for (std::size_t k = 0; k + 1 < breaks.size(); ++k) {
    const Vector2d& ea = breaks[k];
    const Vector2d& eb = breaks[k + 1];
    if (!(cross2(ea, eb) > 0)) continue;  // empty interval
    const Vector2d mid = (ea + eb).normalized();
    const Vector2d c1 = antipodal(mid, sup[0], sup[1]);
    const Vector2d d2 = antipodal(Vector2d(-mid.y(), mid.x()), sup[2], sup[3]);  // e(psi + pi/2)
    first = false;
    const Vector2d c2(d2.y(), -d2.x());  // W(psi + pi/2) = c2 . e(psi)
    auto consider = [&](const Vector2d& e) {
      const double s = std::max(c1.dot(e), c2.dot(e));
      if (s < best.side) best = {s, e};
    };
    consider(ea);
    consider(eb);
    const Vector2d diff = c1 - c2;
    const double len = diff.norm();
    if (len > 0) {
      for (const Vector2d& e :
           {Vector2d(-diff.y() / len, diff.x() / len), Vector2d(diff.y() / len, -diff.x() / len)})
        if (cross2(ea, e) > 0 && cross2(e, eb) > 0) consider(e);
    }
  }
  return best;
}

struct Passage {
  double side;
  Eigen::Matrix3d frame;  // w1, w2, u
};

/// The best square for a passage direction u (the objective of the search over u).
///
/// Only vertices on the silhouette seen along u can be corners of the projection's hull: a
/// vertex is extreme in a direction w normal to u exactly when w lies in its normal cone, i.e.
/// when its faces' normals n do not all point to the same side of the plane normal to u (min
/// n.u <= 0 <= max n.u). Those vertices form a connected band around the body (the normal
/// cones that meet the great circle normal to u are adjacent to one another), found by a flood
/// fill from the vertex farthest along a direction normal to u (reached by hill climbing on the
/// vertex graph, exact on a convex body). A band of |n.u| <= kBandSlack keeps every vertex that
/// round-off could place on the hull, so the hull is that of the whole projection: the same
/// points in the same order. Cost: the band's size (~sqrt(V) on a finely tessellated body)
/// instead of V, which made the V face-normal candidates cost O(V^2 log V) in all.
class SquareFit {
 public:
  SquareFit(const ConvexPolyhedron& k, bool band) : k_(band ? &k : nullptr) {
    for (const Vec3& v : k.vertices()) v_.push_back(detail::to_eigen(v));
    if (band) {
      for (const Vec3& n : k.normals()) n_.push_back(detail::to_eigen(n));
      facing_.resize(n_.size());
      triangle_seen_.assign(n_.size(), 0);
      vertex_seen_.assign(v_.size(), 0);
    }
  }
  Passage operator()(const Vector3d& u_in) const {
    ++evaluations_;
    const Vector3d u = u_in.normalized();
    const Vector3d helper = std::abs(u.x()) < 0.9 ? Vector3d::UnitX() : Vector3d::UnitY();
    const Vector3d a = u.cross(helper).normalized();
    const Vector3d b = u.cross(a);
    points_.clear();
    if (!(k_ && collect_band(u, a, b))) {
      points_.clear();
      for (const Vector3d& v : v_) points_.emplace_back(a.dot(v), b.dot(v));
    }
    hull_2d(points_, hull_);
    const Square sq = smallest_square(hull_, breaks_);
    Passage out;
    out.side = sq.side;
    out.frame.col(0) = sq.e.x() * a + sq.e.y() * b;
    out.frame.col(2) = u;
    out.frame.col(1) = u.cross(out.frame.col(0));
    return out;
  }

 private:
  static constexpr double kBandSlack = 1e-3;  // on n.u, for unit normals

  /// Whether vertex v's faces face both ways along u (within the slack).
  bool on_band(std::int32_t v, const Vector3d& u) const {
    double lo = INFINITY, hi = -INFINITY;
    for (const std::int32_t t : k_->vertex_triangles(std::size_t(v))) {
      const auto i = std::size_t(t);
      if (triangle_seen_[i] != stamp_) {
        triangle_seen_[i] = stamp_;
        facing_[i] = n_[i].dot(u);
      }
      lo = std::min(lo, facing_[i]);
      hi = std::max(hi, facing_[i]);
    }
    return lo <= kBandSlack && hi >= -kBandSlack;
  }

  /// The projections of the silhouette band's vertices into points_; false (nothing
  /// trustworthy collected) when round-off leaves the farthest vertex off the band.
  bool collect_band(const Vector3d& u, const Vector3d& a, const Vector3d& b) const {
    ++stamp_;
    std::int32_t v = start_;
    double h = v_[std::size_t(v)].dot(a);
    for (bool moved = true; moved;) {
      moved = false;
      for (const std::int32_t w : k_->neighbours(std::size_t(v))) {
        const double hw = v_[std::size_t(w)].dot(a);
        if (hw > h) {
          h = hw;
          v = w;
          moved = true;
        }
      }
    }
    start_ = v;  // the next direction is usually near: start climbing there
    if (!on_band(v, u)) return false;
    queue_.assign(1, v);
    vertex_seen_[std::size_t(v)] = stamp_;
    for (std::size_t q = 0; q < queue_.size(); ++q) {
      const std::int32_t x = queue_[q];
      const Vector3d& p = v_[std::size_t(x)];
      points_.emplace_back(a.dot(p), b.dot(p));
      for (const std::int32_t w : k_->neighbours(std::size_t(x))) {
        if (vertex_seen_[std::size_t(w)] == stamp_) continue;
        vertex_seen_[std::size_t(w)] = stamp_;
        if (on_band(w, u)) queue_.push_back(w);
      }
    }
    return true;
  }

 public:
  std::size_t evaluations() const { return evaluations_; }

 private:
  const ConvexPolyhedron* k_;  // null: project every vertex
  std::vector<Vector3d> v_, n_;
  mutable std::vector<Vector2d> points_, hull_, breaks_;  // scratch
  mutable std::vector<double> facing_;                    // n.u of the triangles seen
  mutable std::vector<std::uint64_t> triangle_seen_, vertex_seen_;
  mutable std::vector<std::int32_t> queue_;
  mutable std::uint64_t stamp_ = 0;
  mutable std::int32_t start_ = 0;
  mutable std::size_t evaluations_ = 0;
};

/// Pattern search over the passage direction on the sphere: 16 tangent directions, polled
/// in turn from the last successful one (the first improvement is taken); after a failed
/// poll the step halves and the pattern is turned by a random angle, so that the search
/// cannot stall on a fixed kink of the objective.
Passage local_search(const SquareFit& f, Passage start, double last_step, std::uint64_t seed) {
  Rng rng(seed);
  double h = kFirstStep;
  Passage cur = start;
  Vector3d last = Vector3d::Zero();  // world direction of the last successful move
  while (h > last_step) {
    const Vector3d u = cur.frame.col(2);
    Vector3d t1 = last - last.dot(u) * u;
    if (t1.norm() < 0.5) {
      const double a = rng.uniform(0.0, 2.0 * kPi);
      t1 = std::cos(a) * cur.frame.col(0) + std::sin(a) * cur.frame.col(1);
    }
    t1.normalize();
    const Vector3d t2 = u.cross(t1);
    const double ch = std::cos(h), sh = std::sin(h);
    bool moved = false;
    for (int k = 0; k < kPattern && !moved; ++k) {
      const double beta = 2.0 * kPi * k / kPattern;
      const Vector3d d = std::cos(beta) * t1 + std::sin(beta) * t2;
      const Passage trial = f(ch * u + sh * d);
      if (trial.side < cur.side) {
        cur = trial;
        last = d;
        moved = true;
      }
    }
    if (!moved) {
      h *= 0.5;
      last = Vector3d::Zero();
    }
  }
  return cur;
}

/// The indices of unit vectors sorted along a Morton curve over their octahedral map.
std::vector<std::size_t> curve_order(const std::vector<Vec3>& normals) {
  auto spread = [](std::uint64_t v) {  // 16 bits to the even bits of 32
    v &= 0xffff;
    v = (v | (v << 8)) & 0x00ff00ff;
    v = (v | (v << 4)) & 0x0f0f0f0f;
    v = (v | (v << 2)) & 0x33333333;
    return (v | (v << 1)) & 0x55555555;
  };
  std::vector<std::pair<std::uint64_t, std::size_t>> keyed;
  for (std::size_t t = 0; t < normals.size(); ++t) {
    const Vec3& n = normals[t];
    const double l1 = std::abs(n[0]) + std::abs(n[1]) + std::abs(n[2]);
    double x = n[0] / l1, y = n[1] / l1;
    if (n[2] < 0) {
      const double xf = (1.0 - std::abs(y)) * (x < 0 ? -1.0 : 1.0);
      y = (1.0 - std::abs(x)) * (y < 0 ? -1.0 : 1.0);
      x = xf;
    }
    const auto q = [](double c) {
      return std::uint64_t(std::clamp((c + 1.0) * 32767.5, 0.0, 65535.0));
    };
    keyed.emplace_back(spread(q(x)) | (spread(q(y)) << 1), t);
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<std::size_t> order;
  for (const auto& [key, t] : keyed) order.push_back(t);
  return order;
}

/// The candidate passages in their order (the Fibonacci directions, the face normals, the
/// principal axes), sorted by side (stably): only the first `starts` are used, so a face
/// normal that cannot be among them is not evaluated (side +inf). The objective is Lipschitz:
/// turning the frame by the angle between u and u' moves every width by at most
/// 2 rho |u - u'| (rho: the vertices' largest distance from any fixed point), so
/// f(u) >= f(r) - 2 rho min(|u - r|, |u + r|) for every evaluated direction r (f(-r) = f(r));
/// a normal whose bound exceeds the starts-th best side found so far (a margin of 1e-9 rho
/// covers round-off) cannot enter the first `starts`. Exact: the same first `starts` in the
/// same order as evaluating every normal; on an elongated rock most normals are skipped.
std::vector<Passage> candidate_passages(const ConvexPolyhedron& core, const SquareFit& f,
                                        const SieveSearch& search) {
  const int nd = std::max(1, search.directions);
  const std::size_t nf = core.normals().size();
  std::vector<Passage> out(std::size_t(nd) + nf + 3);
  std::vector<Vector3d> refs;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < nd; ++i) {
    const double z = 1.0 - (i + 0.5) / nd;  // u and -u are the same passage
    const double rho = std::sqrt(1.0 - z * z);
    refs.emplace_back(rho * std::cos(golden * i), rho * std::sin(golden * i), z);
    out[std::size_t(i)] = f(refs.back());
  }
  const auto axes = detail::to_eigen(principal_frame(core_mass_properties(core).inertia).axes);
  for (int k = 0; k < 3; ++k) {
    refs.push_back(axes.col(k).normalized());
    out[std::size_t(nd) + nf + std::size_t(k)] = f(axes.col(k));
  }
  const auto starts = std::size_t(std::clamp(search.local_starts, 1, int(out.size())));
  std::priority_queue<double> best;  // the starts smallest sides so far
  auto keep = [&](double side) {
    best.push(side);
    if (best.size() > starts) best.pop();
  };
  std::vector<double> ref_side;
  for (std::size_t i = 0; i < std::size_t(nd); ++i) ref_side.push_back(out[i].side);
  for (int k = 0; k < 3; ++k) ref_side.push_back(out[std::size_t(nd) + nf + std::size_t(k)].side);
  for (const double side : ref_side) keep(side);
  Eigen::AlignedBox3d box;
  for (const Vec3& v : core.vertices()) box.extend(detail::to_eigen(v));
  double rho = 0.0;
  for (const Vec3& v : core.vertices())
    rho = std::max(rho, (detail::to_eigen(v) - box.center()).norm());
  const double slope = 2.0 * rho, margin = 1e-9 * rho;
  // Evaluated in the order of a space-filling curve over the normals (each result goes to its
  // own slot, so the order changes nothing but the cost): the next direction's silhouette band
  // is near the last one's, its vertices in cache and the climb to it short.
  const std::vector<std::size_t> order = curve_order(core.normals());
  for (std::size_t step = 0; step < nf; ++step) {
    const std::size_t t = order[step];
    const Vector3d u = detail::to_eigen(core.normals()[t]);
    const double bar =
        best.size() < starts || !search.skip_hopeless_normals ? INFINITY : best.top();
    bool skip = false;
    for (std::size_t r = 0; r < refs.size() && !skip; ++r) {
      const double d = std::min((u - refs[r]).norm(), (u + refs[r]).norm());
      skip = ref_side[r] - slope * d - margin > bar;
    }
    out[std::size_t(nd) + t] = skip ? Passage{INFINITY, Eigen::Matrix3d::Identity()} : f(u);
    if (!skip) keep(out[std::size_t(nd) + t].side);
    if (search.progress && (step + 1) % 4096 == 0)
      search.progress("candidates", step + 1, nf, f.evaluations());
  }
  if (search.progress) search.progress("candidates", nf, nf, f.evaluations());
  std::stable_sort(out.begin(), out.end(),
                   [](const Passage& x, const Passage& y) { return x.side < y.side; });
  out.resize(starts);
  return out;
}

}  // namespace

SieveFit sieve_size(const ConvexPolyhedron& core, const SieveSearch& search) {
  SieveFit fit;
  fit.frame = detail::mat_from_eigen(Eigen::Matrix3d::Identity());
  if (core.is_point()) return fit;
  const SquareFit f(core, int(core.vertices().size()) >= search.band_from_vertices);
  const std::vector<Passage> candidates = candidate_passages(core, f, search);
  // Coarse searches from the best candidates (distinct basins), refinement of the best two.
  const auto refined = std::size_t(std::clamp(search.refined, 1, int(candidates.size())));
  std::vector<Passage> coarse;
  for (std::size_t s = 0; s < candidates.size(); ++s) {
    coarse.push_back(local_search(f, candidates[s], kCoarseStep, 0x5eed0000u + std::uint64_t(s)));
    if (search.progress)
      search.progress("local searches", s + 1, candidates.size() + refined, f.evaluations());
  }
  std::stable_sort(coarse.begin(), coarse.end(),
                   [](const Passage& x, const Passage& y) { return x.side < y.side; });
  Passage best = coarse.front();
  for (std::size_t s = 0; s < refined; ++s) {
    const Passage p = local_search(f, coarse[s], search.final_step, 0x5eed1000u + s);
    if (p.side < best.side) best = p;
    if (search.progress)
      search.progress("local searches", candidates.size() + s + 1, candidates.size() + refined,
                      f.evaluations());
  }
  fit.size = best.side;
  fit.frame = detail::mat_from_eigen(best.frame);
  return fit;
}

}  // namespace demfem::dem::shapes
