#include "demfem/dem/shapes/sieve_size.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>

#include "demfem/dem/shapes/mass_properties.hpp"
#include "demfem/dem/size_distribution.hpp"
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

class SquareFit {
 public:
  explicit SquareFit(const ConvexPolyhedron& k) {
    for (const Vec3& v : k.vertices()) v_.push_back(detail::to_eigen(v));
  }
  Passage operator()(const Vector3d& u_in) const {
    const Vector3d u = u_in.normalized();
    const Vector3d helper = std::abs(u.x()) < 0.9 ? Vector3d::UnitX() : Vector3d::UnitY();
    const Vector3d a = u.cross(helper).normalized();
    const Vector3d b = u.cross(a);
    points_.clear();
    for (const Vector3d& v : v_) points_.emplace_back(a.dot(v), b.dot(v));
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
  std::vector<Vector3d> v_;
  mutable std::vector<Vector2d> points_, hull_, breaks_;  // scratch
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

}  // namespace

SieveFit sieve_size(const ConvexPolyhedron& core, const SieveSearch& search) {
  SieveFit fit;
  fit.frame = detail::mat_from_eigen(Eigen::Matrix3d::Identity());
  if (core.is_point()) return fit;
  const SquareFit f(core);
  std::vector<Passage> candidates;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  const int nd = std::max(1, search.directions);
  for (int i = 0; i < nd; ++i) {
    const double z = 1.0 - (i + 0.5) / nd;  // u and -u are the same passage
    const double rho = std::sqrt(1.0 - z * z);
    candidates.push_back(f(Vector3d(rho * std::cos(golden * i), rho * std::sin(golden * i), z)));
  }
  for (const Vec3& n : core.normals()) candidates.push_back(f(detail::to_eigen(n)));
  const auto axes = detail::to_eigen(principal_frame(core_mass_properties(core).inertia).axes);
  for (int k = 0; k < 3; ++k) candidates.push_back(f(axes.col(k)));
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const Passage& x, const Passage& y) { return x.side < y.side; });
  // Coarse searches from the best candidates (distinct basins), refinement of the best two.
  const int starts = std::clamp(search.local_starts, 1, int(candidates.size()));
  std::vector<Passage> coarse;
  for (int s = 0; s < starts; ++s) {
    coarse.push_back(
        local_search(f, candidates[std::size_t(s)], kCoarseStep, 0x5eed0000u + std::uint64_t(s)));
  }
  std::stable_sort(coarse.begin(), coarse.end(),
                   [](const Passage& x, const Passage& y) { return x.side < y.side; });
  Passage best = coarse.front();
  const auto refined = std::size_t(std::clamp(search.refined, 1, int(coarse.size())));
  for (std::size_t s = 0; s < refined; ++s) {
    const Passage p = local_search(f, coarse[s], search.final_step, 0x5eed1000u + s);
    if (p.side < best.side) best = p;
  }
  fit.size = best.side;
  fit.frame = detail::mat_from_eigen(best.frame);
  return fit;
}

}  // namespace demfem::dem::shapes
