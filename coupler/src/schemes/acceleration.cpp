#include "demfem/coupling/acceleration.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "demfem/io/h5_file.hpp"

namespace demfem::coupling {

const char* acceleration_name(AccelerationKind kind) {
  switch (kind) {
    case AccelerationKind::constant:
      return "constant";
    case AccelerationKind::aitken:
      return "aitken";
    case AccelerationKind::iqn_ils:
      return "iqn-ils";
  }
  return "?";
}

namespace {

// Plain loops in a fixed order: the sums (and so the iterates) are the same bits on every run.
double dot(std::span<const double> a, std::span<const double> b) {
  double s = 0.0;
  for (std::size_t k = 0; k < a.size(); ++k) s += a[k] * b[k];
  return s;
}

double norm(std::span<const double> a) {
  return std::sqrt(dot(a, a));
}

void check_kind(const io::H5File& f, const std::string& group, AccelerationKind kind,
                std::size_t size) {
  const std::string kind_there = f.attribute_string(group, "kind");
  if (kind_there != acceleration_name(kind)) {
    throw std::runtime_error(f.path().string() + ": the accelerator's history is of '" +
                             kind_there + "', the scene's coupling.acceleration is '" +
                             acceleration_name(kind) +
                             "' (resume with the acceleration the checkpoint was taken with)");
  }
  const auto n = f.attribute_int64(group, "size");
  if (n != static_cast<std::int64_t>(size)) {
    throw std::runtime_error(f.path().string() + ": the accelerator's history has vectors of " +
                             std::to_string(n) + " values, this interface " + std::to_string(size));
  }
}

void save_kind(io::H5File& f, const std::string& group, AccelerationKind kind, std::size_t size) {
  f.create_group(group);
  f.set_attribute(group, "kind", std::string(acceleration_name(kind)));
  f.set_attribute(group, "size", static_cast<std::int64_t>(size));
}

class ConstantRelaxation final : public Acceleration {
 public:
  ConstantRelaxation(const AccelerationSettings& s, std::size_t size)
      : Acceleration(size), omega_(s.initial_relaxation) {}
  void next(std::span<const double> x, std::span<const double> xt, std::span<double> out) override {
    for (std::size_t k = 0; k < size_; ++k) out[k] = x[k] + omega_ * (xt[k] - x[k]);
  }
  void end_step(std::span<const double>, std::span<const double>) override {}
  void save(io::H5File& f, const std::string& g) const override {
    save_kind(f, g, AccelerationKind::constant, size_);
  }
  void load(const io::H5File& f, const std::string& g) override {
    check_kind(f, g, AccelerationKind::constant, size_);
  }
  double last_relaxation() const override { return omega_; }

 private:
  double omega_;
};

// Aitken's dynamic relaxation as preCICE does it: omega^k = -omega^{k-1} r^{k-1}.(r^k -
// r^{k-1}) / |r^k - r^{k-1}|^2; the first factor of a step is min(omega_0, |omega| of the last
// step) with that one's sign, so the factor is history carried from step to step.
class AitkenRelaxation final : public Acceleration {
 public:
  AitkenRelaxation(const AccelerationSettings& s, std::size_t size)
      : Acceleration(size), omega0_(s.initial_relaxation), omega_(s.initial_relaxation) {}

  void next(std::span<const double> x, std::span<const double> xt, std::span<double> out) override {
    r_.resize(size_);
    for (std::size_t k = 0; k < size_; ++k) r_[k] = xt[k] - x[k];
    if (iteration_ == 0) {
      omega_ = std::copysign(std::min(omega0_, std::abs(omega_)), omega_);
    } else {
      double num = 0.0, den = 0.0;
      for (std::size_t k = 0; k < size_; ++k) {
        const double dr = r_[k] - r_old_[k];
        num += r_old_[k] * dr;
        den += dr * dr;
      }
      // An unchanged residual (den = 0) carries no information: keep the factor.
      if (den > 0.0) omega_ = -omega_ * num / den;
    }
    for (std::size_t k = 0; k < size_; ++k) out[k] = x[k] + omega_ * r_[k];
    r_old_.swap(r_);
    ++iteration_;
  }
  void end_step(std::span<const double>, std::span<const double>) override { iteration_ = 0; }
  void save(io::H5File& f, const std::string& g) const override {
    save_kind(f, g, AccelerationKind::aitken, size_);
    f.set_attribute(g, "omega", omega_);
  }
  void load(const io::H5File& f, const std::string& g) override {
    check_kind(f, g, AccelerationKind::aitken, size_);
    omega_ = f.attribute_double(g, "omega");
    iteration_ = 0;
  }
  double last_relaxation() const override { return omega_; }

 private:
  double omega0_;
  double omega_;
  std::int64_t iteration_ = 0;
  std::vector<double> r_, r_old_;
};

// IQN-ILS. Columns are kept newest first: v = r^k - r^{k-1} (residual differences) and
// w = xt^k - xt^{k-1} (output differences), each tagged by the step that made it. The update
// is x^{k+1} = xt^k + W alpha with alpha = argmin |V alpha + r^k|, solved by a QR
// decomposition of V that is built afresh every iteration by Gram-Schmidt (twice, for
// orthogonality), newest column first; a column that adds less than qr_filter of its norm to
// the span of the newer ones is dropped for good (QR2 filter). Without a column the step
// relaxes with omega_0.
class InterfaceQuasiNewton final : public Acceleration {
 public:
  InterfaceQuasiNewton(const AccelerationSettings& s, std::size_t size)
      : Acceleration(size), s_(s) {}

  void next(std::span<const double> x, std::span<const double> xt, std::span<double> out) override {
    std::vector<double> r(size_);
    for (std::size_t k = 0; k < size_; ++k) r[k] = xt[k] - x[k];
    if (iteration_ > 0) add_column(r, xt);
    if (iteration_ == 1 && s_.reuse_steps == 0) drop_older_steps();
    r_old_ = r;
    xt_old_.assign(xt.begin(), xt.end());
    ++iteration_;

    filter_and_factorise();
    if (q_.empty()) {
      relaxation_ = s_.initial_relaxation;
      columns_used_ = 0;
      for (std::size_t k = 0; k < size_; ++k) out[k] = x[k] + relaxation_ * r[k];
      return;
    }
    // alpha = -R^{-1} Q^T r (R upper triangular, m x m, row-major).
    const std::size_t m = q_.size();
    std::vector<double> alpha(m);
    for (std::size_t i = 0; i < m; ++i) alpha[i] = -dot(q_[i], r);
    for (std::size_t i = m; i-- > 0;) {
      double v = alpha[i];
      for (std::size_t j = i + 1; j < m; ++j) v -= r_[i * m + j] * alpha[j];
      alpha[i] = v / r_[i * m + i];
    }
    for (std::size_t k = 0; k < size_; ++k) out[k] = xt[k];
    for (std::size_t i = 0; i < m; ++i) {
      const auto& w = columns_[i].w;
      for (std::size_t k = 0; k < size_; ++k) out[k] += alpha[i] * w[k];
    }
    relaxation_ = 0.0;
    columns_used_ = m;
  }

  void end_step(std::span<const double> x, std::span<const double> xt) override {
    // The last iteration's differences are information for the next steps too (preCICE adds
    // them when the step has converged).
    if (iteration_ > 0) {
      std::vector<double> r(size_);
      for (std::size_t k = 0; k < size_; ++k) r[k] = xt[k] - x[k];
      add_column(r, xt);
      if (s_.reuse_steps == 0) drop_older_steps();
    }
    // Keep the columns of the last max(R, 1) steps (with R = 0 the previous step's serve only
    // the first iteration of the next one).
    const std::int64_t keep = std::max<std::int64_t>(s_.reuse_steps, 1);
    ++step_;
    std::erase_if(columns_, [&](const Column& c) { return c.step <= step_ - 1 - keep; });
    iteration_ = 0;
    r_old_.clear();
    xt_old_.clear();
  }

  void save(io::H5File& f, const std::string& g) const override {
    save_kind(f, g, AccelerationKind::iqn_ils, size_);
    f.set_attribute(g, "step", step_);
    f.set_attribute(g, "columns", static_cast<std::int64_t>(columns_.size()));
    // Never empty (HDF5 datasets here are not): one trailing entry.
    std::vector<double> v, w;
    std::vector<std::int64_t> steps;
    for (const auto& c : columns_) {
      v.insert(v.end(), c.v.begin(), c.v.end());
      w.insert(w.end(), c.w.begin(), c.w.end());
      steps.push_back(c.step);
    }
    v.push_back(0.0), w.push_back(0.0), steps.push_back(0);
    f.write(g + "/V", std::span<const double>(v));
    f.write(g + "/W", std::span<const double>(w));
    f.write(g + "/column_steps", std::span<const std::int64_t>(steps));
  }

  void load(const io::H5File& f, const std::string& g) override {
    check_kind(f, g, AccelerationKind::iqn_ils, size_);
    step_ = f.attribute_int64(g, "step");
    const auto m = static_cast<std::size_t>(f.attribute_int64(g, "columns"));
    const auto v = f.read_doubles(g + "/V");
    const auto w = f.read_doubles(g + "/W");
    const auto steps = f.read_int64(g + "/column_steps");
    if (v.size() != m * size_ + 1 || w.size() != m * size_ + 1 || steps.size() != m + 1) {
      throw std::runtime_error(f.path().string() + ": " + g +
                               ": the quasi-Newton columns do not match their count");
    }
    columns_.assign(m, Column{});
    for (std::size_t i = 0; i < m; ++i) {
      columns_[i].v.assign(v.begin() + i * size_, v.begin() + (i + 1) * size_);
      columns_[i].w.assign(w.begin() + i * size_, w.begin() + (i + 1) * size_);
      columns_[i].step = steps[i];
    }
    iteration_ = 0;
    r_old_.clear();
    xt_old_.clear();
  }

  double last_relaxation() const override { return relaxation_; }
  std::size_t last_columns() const override { return columns_used_; }

 private:
  struct Column {
    std::vector<double> v, w;
    std::int64_t step = 0;
  };

  void add_column(const std::vector<double>& r, std::span<const double> xt) {
    Column c;
    c.v.resize(size_);
    c.w.resize(size_);
    for (std::size_t k = 0; k < size_; ++k) {
      c.v[k] = r[k] - r_old_[k];
      c.w[k] = xt[k] - xt_old_[k];
    }
    if (!(norm(c.v) > 0.0)) return;  // the same residual twice: nothing to learn
    c.step = step_;
    columns_.insert(columns_.begin(), std::move(c));
    // The most columns, and never more than the rows (then V could not have full rank).
    const auto limit = static_cast<std::size_t>(std::max<std::int64_t>(
        1, std::min<std::int64_t>(s_.max_columns, static_cast<std::int64_t>(size_))));
    if (columns_.size() > limit) columns_.resize(limit);
  }

  void drop_older_steps() {
    std::erase_if(columns_, [&](const Column& c) { return c.step < step_; });
  }

  // Q (columns q_[i]) and R (r_, m x m row-major) of the kept columns, dropping the ones the
  // filter rejects from columns_ for good.
  void filter_and_factorise() {
    q_.clear();
    std::vector<std::vector<double>> rcols;  // column j of R: its first j+1 entries
    std::vector<Column> kept;
    for (auto& c : columns_) {
      std::vector<double> u = c.v;
      const double rho0 = norm(u);
      std::vector<double> coef(q_.size(), 0.0);
      for (int pass = 0; pass < 2; ++pass) {  // classical Gram-Schmidt, twice
        std::vector<double> s(q_.size());
        for (std::size_t i = 0; i < q_.size(); ++i) s[i] = dot(q_[i], u);
        for (std::size_t i = 0; i < q_.size(); ++i) {
          coef[i] += s[i];
          for (std::size_t k = 0; k < size_; ++k) u[k] -= s[i] * q_[i][k];
        }
      }
      const double rho = norm(u);
      const bool dependent =
          !(rho > std::numeric_limits<double>::min()) || rho < s_.qr_filter * rho0;
      if (dependent || q_.size() >= size_) continue;  // dropped
      for (double& e : u) e /= rho;
      q_.push_back(std::move(u));
      coef.push_back(rho);
      rcols.push_back(std::move(coef));
      kept.push_back(std::move(c));
    }
    columns_ = std::move(kept);
    const std::size_t m = q_.size();
    r_.assign(m * m, 0.0);
    for (std::size_t j = 0; j < m; ++j)
      for (std::size_t i = 0; i <= j; ++i) r_[i * m + j] = rcols[j][i];
  }

  AccelerationSettings s_;
  std::vector<Column> columns_;  // newest first
  std::int64_t step_ = 0;        // steps ended so far
  std::int64_t iteration_ = 0;   // of the current step
  std::vector<double> r_old_, xt_old_;
  std::vector<std::vector<double>> q_;
  std::vector<double> r_;
  double relaxation_ = 0.0;
  std::size_t columns_used_ = 0;
};

}  // namespace

std::unique_ptr<Acceleration> make_acceleration(const AccelerationSettings& s, std::size_t size) {
  switch (s.kind) {
    case AccelerationKind::constant:
      return std::make_unique<ConstantRelaxation>(s, size);
    case AccelerationKind::aitken:
      return std::make_unique<AitkenRelaxation>(s, size);
    case AccelerationKind::iqn_ils:
      return std::make_unique<InterfaceQuasiNewton>(s, size);
  }
  throw std::logic_error("make_acceleration: unknown kind");
}

double relative_change(std::span<const double> now, std::span<const double> before,
                       double* change) {
  double d = 0.0, n = 0.0;
  for (std::size_t k = 0; k < now.size(); ++k) {
    const double e = now[k] - before[k];
    d += e * e;
    n += now[k] * now[k];
  }
  d = std::sqrt(d);
  n = std::sqrt(n);
  if (change) *change = d;
  if (d == 0.0) return 0.0;
  if (n == 0.0) return std::numeric_limits<double>::infinity();
  return d / n;
}

}  // namespace demfem::coupling
