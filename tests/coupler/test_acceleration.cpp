// The accelerators of the implicit scheme (acceleration.hpp) on small analytic fixed-point
// problems x = H(x) = A x + b with a known solution x* = (I - A)^{-1} b: Aitken is the secant
// method (exact in the second update for a scalar map), IQN-ILS is a multisecant method that
// solves an affine map of dimension n in at most n + 1 updates (like GMRES, in exact
// arithmetic), reuses the columns of earlier steps, drops linearly dependent columns and keeps
// its history through save/load.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <random>
#include <vector>

#include "demfem/coupling/acceleration.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem;
using namespace demfem::coupling;

namespace {

using Vec = std::vector<double>;
using Mat = std::vector<Vec>;  // rows

// An affine map H(x) = A x + b.
struct Affine {
  Mat a;
  Vec b;
  Vec operator()(const Vec& x) const {
    Vec y = b;
    for (std::size_t i = 0; i < b.size(); ++i)
      for (std::size_t j = 0; j < b.size(); ++j) y[i] += a[i][j] * x[j];
    return y;
  }
};

// x* of x = A x + b, by Gaussian elimination with partial pivoting of (I - A) x = b.
Vec solve_fixed_point(const Affine& h) {
  const std::size_t n = h.b.size();
  Mat m(n, Vec(n + 1));
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < n; ++j) m[i][j] = (i == j ? 1.0 : 0.0) - h.a[i][j];
    m[i][n] = h.b[i];
  }
  for (std::size_t c = 0; c < n; ++c) {
    std::size_t p = c;
    for (std::size_t r = c + 1; r < n; ++r)
      if (std::abs(m[r][c]) > std::abs(m[p][c])) p = r;
    std::swap(m[c], m[p]);
    for (std::size_t r = 0; r < n; ++r) {
      if (r == c) continue;
      const double f = m[r][c] / m[c][c];
      for (std::size_t k = c; k <= n; ++k) m[r][k] -= f * m[c][k];
    }
  }
  Vec x(n);
  for (std::size_t i = 0; i < n; ++i) x[i] = m[i][n] / m[i][i];
  return x;
}

double dist(const Vec& a, const Vec& b) {
  double s = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) s += (a[i] - b[i]) * (a[i] - b[i]);
  return std::sqrt(s);
}

// Iterates one step from x0 until |H(x) - x| <= tol |H(x)|; returns the number of
// evaluations of H (iterations, as the coupler counts them) or -1 past `limit`.
int iterate(Acceleration& acc, const Affine& h, Vec x, double tol, int limit, Vec* result) {
  for (int k = 1; k <= limit; ++k) {
    const Vec xt = h(x);
    if (relative_change(xt, x) <= tol) {
      acc.end_step(x, xt);
      if (result) *result = xt;
      return k;
    }
    Vec next(x.size());
    acc.next(x, xt, next);
    x = next;
  }
  return -1;
}

// A = Q diag(lambda) Q^T with a random orthogonal Q (n x n); lambda given.
Affine symmetric_map(const Vec& lambda, unsigned seed) {
  const std::size_t n = lambda.size();
  std::mt19937 gen(seed);
  std::normal_distribution<double> g;
  Mat q(n, Vec(n));
  for (auto& row : q)
    for (double& v : row) v = g(gen);
  // Gram-Schmidt on the rows.
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      double d = 0.0;
      for (std::size_t k = 0; k < n; ++k) d += q[i][k] * q[j][k];
      for (std::size_t k = 0; k < n; ++k) q[i][k] -= d * q[j][k];
    }
    double nn = 0.0;
    for (double v : q[i]) nn += v * v;
    for (double& v : q[i]) v /= std::sqrt(nn);
  }
  Affine h;
  h.a.assign(n, Vec(n, 0.0));
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j)
      for (std::size_t k = 0; k < n; ++k) h.a[i][j] += q[k][i] * lambda[k] * q[k][j];
  h.b.resize(n);
  for (double& v : h.b) v = g(gen);
  return h;
}

AccelerationSettings settings(AccelerationKind kind) {
  AccelerationSettings s;
  s.kind = kind;
  s.initial_relaxation = 0.5;
  return s;
}

}  // namespace

TEST_CASE("Aitken: the secant step is exact for a scalar affine map") {
  // x = -3 x + 2 diverges under plain iteration (|a| > 1); x* = 0.5.
  Affine h{{{-3.0}}, {2.0}};
  auto acc = make_acceleration(settings(AccelerationKind::aitken), 1);
  Vec x = {0.0}, xt = h(x), x1(1), x2(1);
  acc->next(x, xt, x1);  // relaxed with omega_0 = 0.5
  CHECK(x1[0] == Approx(1.0));
  acc->next(x1, h(x1), x2);  // secant through the two residuals: the root
  CHECK(std::abs(x2[0] - 0.5) < 1e-14);
  // The coupler's count: x0, x1, x2 evaluated, x2 converged: 3 iterations.
  auto acc2 = make_acceleration(settings(AccelerationKind::aitken), 1);
  Vec sol;
  CHECK(iterate(*acc2, h, {0.0}, 1e-12, 20, &sol) == 3);
  CHECK(std::abs(sol[0] - 0.5) < 1e-12);
}

TEST_CASE("Aitken: the factor is carried to the next step, bounded by omega_0") {
  Affine h{{{-3.0}}, {2.0}};
  auto acc = make_acceleration(settings(AccelerationKind::aitken), 1);
  REQUIRE(iterate(*acc, h, {0.0}, 1e-12, 20, nullptr) == 3);
  // The secant factor of a = -3 is 1/(1 - a) = 0.25 (< omega_0 = 0.5): kept for step 2, whose
  // first update is then already exact.
  CHECK(acc->last_relaxation() == Approx(0.25));
  Affine h2{{{-3.0}}, {6.0}};  // x* = 1.5
  Vec x = {0.0}, next(1);
  acc->next(x, h2(x), next);
  CHECK(acc->last_relaxation() == Approx(0.25));
  CHECK(std::abs(next[0] - 1.5) < 1e-14);
}

TEST_CASE("constant relaxation converges only where |1 - omega (1 - a)| < 1") {
  auto acc = make_acceleration(settings(AccelerationKind::constant), 1);
  Vec sol;
  const int n = iterate(*acc, Affine{{{0.5}}, {1.0}}, {0.0}, 1e-12, 100, &sol);  // factor 0.75
  CHECK(n > 20);
  CHECK(std::abs(sol[0] - 2.0) < 1e-10);
  auto acc2 = make_acceleration(settings(AccelerationKind::constant), 1);
  CHECK(iterate(*acc2, Affine{{{-5.0}}, {1.0}}, {0.0}, 1e-12, 100, nullptr) == -1);  // |-2| > 1
}

TEST_CASE("IQN-ILS solves an n-dimensional affine map in at most n + 2 iterations") {
  // Eigenvalues up to -20: plain iteration diverges, constant relaxation would need
  // omega < 2 / 21 and hundreds of iterations.
  for (unsigned seed = 1; seed <= 5; ++seed) {
    const Vec lambda = {-20.0, -7.0, 3.0, 0.9, -0.5, 0.2};
    const Affine h = symmetric_map(lambda, seed);
    const Vec exact = solve_fixed_point(h);
    auto acc = make_acceleration(settings(AccelerationKind::iqn_ils), lambda.size());
    Vec sol;
    const int n = iterate(*acc, h, Vec(lambda.size(), 0.0), 1e-10, 50, &sol);
    INFO("seed " << seed << ": " << n << " iterations");
    // n + 1 updates after the first relaxed one: at most n + 2 evaluations.
    CHECK(n > 0);
    CHECK(n <= static_cast<int>(lambda.size()) + 2);
    CHECK(dist(sol, exact) < 1e-8 * (1.0 + dist(exact, Vec(exact.size(), 0.0))));
  }
}

TEST_CASE("IQN-ILS: a map with few strong directions converges in a few iterations") {
  // 60 unknowns, 2 unstable directions (eigenvalues -30 and -8), the rest contracting weakly:
  // the least-squares model needs only the columns that span the strong ones.
  Vec lambda(60, 0.05);
  lambda[0] = -30.0, lambda[1] = -8.0;
  const Affine h = symmetric_map(lambda, 7);
  auto acc = make_acceleration(settings(AccelerationKind::iqn_ils), 60);
  const int n = iterate(*acc, h, Vec(60, 0.0), 1e-8, 60, nullptr);
  INFO(n << " iterations");
  CHECK(n > 0);
  CHECK(n <= 8);
  // Aitken (one scalar factor) cannot treat two directions of opposite scale as well.
  auto aitken = make_acceleration(settings(AccelerationKind::aitken), 60);
  const int na = iterate(*aitken, h, Vec(60, 0.0), 1e-8, 200, nullptr);
  INFO("Aitken: " << na);
  CHECK((na == -1 || na > n));
}

TEST_CASE("IQN-ILS reuses the columns of earlier steps; R = 0 keeps only the last step's") {
  // A sequence of steps with the same Jacobian and new right-hand sides: with the columns of
  // the first step the second one's first update is already quasi-Newton.
  Vec lambda(12, 0.1);
  lambda[0] = -15.0, lambda[1] = -4.0, lambda[2] = 2.5;
  const Affine h0 = symmetric_map(lambda, 3);
  auto run_steps = [&](std::int64_t reuse) {
    AccelerationSettings s = settings(AccelerationKind::iqn_ils);
    s.reuse_steps = reuse;
    auto acc = make_acceleration(s, 12);
    std::vector<int> counts;
    for (int step = 0; step < 4; ++step) {
      Affine h = h0;
      for (std::size_t i = 0; i < h.b.size(); ++i) h.b[i] += 0.3 * step * std::sin(1.0 + i);
      counts.push_back(iterate(*acc, h, Vec(12, 0.0), 1e-9, 60, nullptr));
    }
    return counts;
  };
  const auto r8 = run_steps(8);
  const auto r0 = run_steps(0);
  INFO("reuse 8: " << r8[0] << " " << r8[1] << " " << r8[2] << " " << r8[3]);
  INFO("reuse 0: " << r0[0] << " " << r0[1] << " " << r0[2] << " " << r0[3]);
  for (int c : r8) CHECK(c > 0);
  for (int c : r0) CHECK(c > 0);
  CHECK(r8[0] == r0[0]);  // the first step has nothing to reuse either way
  CHECK(r8[3] < r8[0]);   // later steps converge faster with the columns of earlier ones
  CHECK(r8[3] <= 3);
}

TEST_CASE("IQN-ILS: the QR filter keeps the least-squares system well posed") {
  // Three unknowns, many steps reusing columns: without dropping the nearly dependent ones the
  // system would have far more columns than rows.
  const Affine h0 = symmetric_map({-9.0, -2.0, 0.4}, 11);
  AccelerationSettings s = settings(AccelerationKind::iqn_ils);
  s.reuse_steps = 20;
  auto acc = make_acceleration(s, 3);
  for (int step = 0; step < 10; ++step) {
    Affine h = h0;
    h.b[0] += 0.1 * step;
    const int n = iterate(*acc, h, Vec(3, 0.0), 1e-12, 40, nullptr);
    INFO("step " << step);
    REQUIRE(n > 0);
    CHECK(acc->last_columns() <= 3);
  }
}

TEST_CASE("accelerators: save/load between steps continues bit for bit") {
  const Affine h0 = symmetric_map({-12.0, -3.0, 0.5, 0.1, -0.2}, 5);
  demfem::test::TempDir dir;
  for (auto kind : {AccelerationKind::aitken, AccelerationKind::iqn_ils}) {
    INFO(acceleration_name(kind));
    auto a = make_acceleration(settings(kind), 5);
    REQUIRE(iterate(*a, h0, Vec(5, 0.0), 1e-10, 60, nullptr) > 0);
    const auto file = dir.path / (std::string(acceleration_name(kind)) + ".h5");
    {
      io::H5File h5(file, io::H5File::Mode::create);
      a->save(h5, "acceleration");
    }
    auto b = make_acceleration(settings(kind), 5);
    {
      io::H5File h5(file, io::H5File::Mode::read);
      b->load(h5, "acceleration");
    }
    Affine h1 = h0;
    h1.b[2] += 1.0;
    Vec xa(5, 0.0), xb(5, 0.0);
    for (int k = 0; k < 4; ++k) {
      Vec na(5), nb(5);
      a->next(xa, h1(xa), na);
      b->next(xb, h1(xb), nb);
      REQUIRE(na == nb);  // the same bits
      xa = na, xb = nb;
    }
    // Another kind, or another size, is refused naming the file.
    auto other =
        make_acceleration(settings(kind == AccelerationKind::aitken ? AccelerationKind::iqn_ils
                                                                    : AccelerationKind::aitken),
                          5);
    io::H5File h5(file, io::H5File::Mode::read);
    CHECK_THROWS_WITH(other->load(h5, "acceleration"), Catch::Contains(file.string()));
    auto wrong_size = make_acceleration(settings(kind), 6);
    CHECK_THROWS_WITH(wrong_size->load(h5, "acceleration"), Catch::Contains("6"));
  }
}

TEST_CASE("relative_change: preCICE's relative measure, with its limits") {
  double change = -1.0;
  CHECK(relative_change(Vec{3.0, 4.0}, Vec{3.0, 4.0}, &change) == 0.0);
  CHECK(change == 0.0);
  CHECK(relative_change(Vec{0.0, 0.0}, Vec{0.0, 0.0}) == 0.0);
  CHECK(std::isinf(relative_change(Vec{0.0, 0.0}, Vec{1.0, 0.0}, &change)));
  CHECK(change == 1.0);
  CHECK(relative_change(Vec{3.0, 4.0}, Vec{3.0, 3.0}, &change) == Approx(0.2));
  CHECK(change == Approx(1.0));
}
