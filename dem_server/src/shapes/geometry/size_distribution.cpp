#include "demfem/dem/shapes/geometry/size_distribution.hpp"

#include <cmath>
#include <cstdio>
#include <numeric>
#include <sstream>
#include <stdexcept>

namespace demfem::dem {

SizeDistribution SizeDistribution::constant(double d) {
  SizeDistribution s;
  s.kind = Kind::constant;
  s.d_min = s.d_max = d;
  s.validate();
  return s;
}

SizeDistribution SizeDistribution::uniform(double d_min, double d_max) {
  SizeDistribution s;
  s.kind = Kind::uniform;
  s.d_min = d_min;
  s.d_max = d_max;
  s.validate();
  return s;
}

SizeDistribution SizeDistribution::normal(double mean, double stddev, double d_min, double d_max) {
  SizeDistribution s;
  s.kind = Kind::normal;
  s.mean = mean;
  s.stddev = stddev;
  s.d_min = d_min;
  s.d_max = d_max;
  s.validate();
  return s;
}

SizeDistribution SizeDistribution::gradation(std::vector<double> sieves,
                                             std::vector<double> mass_fractions) {
  SizeDistribution s;
  s.kind = Kind::gradation;
  s.sieves = std::move(sieves);
  s.mass_fractions = std::move(mass_fractions);
  s.validate();
  s.d_min = s.sieves.front();
  s.d_max = s.sieves.back();
  return s;
}

namespace {
double normal_cdf(double x) {
  return 0.5 * std::erfc(-x / std::sqrt(2.0));
}
}  // namespace

void SizeDistribution::validate() const {
  auto bad = [](const std::string& m) { throw std::invalid_argument(m); };
  switch (kind) {
    case Kind::constant:
      if (!(d_min > 0) || !std::isfinite(d_min)) bad("diameter must be > 0");
      break;
    case Kind::uniform:
    case Kind::normal:
      if (!(d_min > 0) || !std::isfinite(d_max)) bad("d_min must be > 0 and d_max finite");
      if (!(d_max >= d_min)) bad("d_max must be >= d_min");
      if (kind == Kind::normal) {
        if (!(stddev > 0) || !std::isfinite(mean)) bad("stddev must be > 0 and mean finite");
        const double p = normal_cdf((d_max - mean) / stddev) - normal_cdf((d_min - mean) / stddev);
        // Rejection sampling needs ~1/p draws per diameter.
        if (!(p >= 1e-4)) {
          bad("only a fraction " + std::to_string(p) +
              " of the normal distribution lies within [d_min, d_max]; move the bounds or the "
              "mean");
        }
      }
      break;
    case Kind::gradation: {
      if (sieves.size() < 2) bad("gradation needs at least two sieve sizes");
      if (mass_fractions.size() != sieves.size() - 1) {
        bad("gradation needs one mass fraction per class: " + std::to_string(sieves.size() - 1) +
            " for " + std::to_string(sieves.size()) + " sieve sizes, found " +
            std::to_string(mass_fractions.size()));
      }
      if (!(sieves[0] > 0)) bad("sieve sizes must be > 0");
      for (std::size_t i = 1; i < sieves.size(); ++i)
        if (!(sieves[i] > sieves[i - 1])) bad("sieve sizes must increase strictly");
      double sum = 0.0;
      for (double f : mass_fractions) {
        if (!(f >= 0)) bad("mass fractions must be >= 0");
        sum += f;
      }
      // 1e-9: decimal fractions as typed (0.1 + 0.2 + 0.7) sum to 1 within 1e-15; a table
      // that misses by more is a typo, not round-off.
      if (std::abs(sum - 1.0) > 1e-9) {
        char buf[64];
        std::snprintf(buf, sizeof buf, "%.12g", sum);  // resolves 1e-9
        bad("mass_fractions must sum to 1 (within 1e-9), they sum to " + std::string(buf));
      }
      break;
    }
  }
}

double SizeDistribution::smallest() const {
  return kind == Kind::gradation ? sieves.front() : d_min;
}
double SizeDistribution::largest() const {
  return kind == Kind::gradation ? sieves.back() : d_max;
}

namespace {
/// E[d^3] for d uniform in [a, b].
double uniform_mean_cube(double a, double b) {
  if (b - a <= 0) return a * a * a;
  return (b * b * b * b - a * a * a * a) / (4.0 * (b - a));
}
}  // namespace

double SizeDistribution::sample(Rng& rng) const {
  switch (kind) {
    case Kind::constant:
      return d_min;
    case Kind::uniform:
      return d_min == d_max ? d_min : rng.uniform(d_min, d_max);
    case Kind::normal:
      for (;;) {
        const double d = mean + stddev * rng.normal();
        if (d >= d_min && d <= d_max) return d;
      }
    case Kind::gradation: {
      // A class is chosen with its number probability, proportional to its mass fraction
      // divided by the mean particle volume in it, so that the mass fractions come out right.
      const std::size_t k = mass_fractions.size();
      double total = 0.0;
      for (std::size_t i = 0; i < k; ++i)
        total += mass_fractions[i] / uniform_mean_cube(sieves[i], sieves[i + 1]);
      double u = rng.uniform() * total;
      std::size_t c = 0;
      for (; c + 1 < k; ++c) {
        const double w = mass_fractions[c] / uniform_mean_cube(sieves[c], sieves[c + 1]);
        if (u < w) break;
        u -= w;
      }
      while (mass_fractions[c] == 0.0 && c > 0) --c;  // never land in an empty class by round-off
      return rng.uniform(sieves[c], sieves[c + 1]);
    }
  }
  return d_min;
}

double SizeDistribution::mean_cube() const {
  switch (kind) {
    case Kind::constant:
      return d_min * d_min * d_min;
    case Kind::uniform:
      return uniform_mean_cube(d_min, d_max);
    case Kind::normal: {
      // Simpson on [d_min, d_max] of the truncated density.
      const int n = 2000;
      const double h = (d_max - d_min) / n;
      if (h == 0) return d_min * d_min * d_min;
      double num = 0.0, den = 0.0;
      for (int i = 0; i <= n; ++i) {
        const double d = d_min + i * h;
        const double z = (d - mean) / stddev;
        const double w = (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0);
        const double f = std::exp(-0.5 * z * z);
        num += w * f * d * d * d;
        den += w * f;
      }
      return num / den;
    }
    case Kind::gradation: {
      // Number-weighted: 1 / E[d^3] = sum_i f_i / E_i[d^3] (mass fractions f_i).
      double inv = 0.0;
      for (std::size_t i = 0; i < mass_fractions.size(); ++i)
        inv += mass_fractions[i] / uniform_mean_cube(sieves[i], sieves[i + 1]);
      return 1.0 / inv;
    }
  }
  return 0.0;
}

std::string SizeDistribution::describe() const {
  std::ostringstream s;
  switch (kind) {
    case Kind::constant:
      s << "constant d = " << d_min << " m";
      break;
    case Kind::uniform:
      s << "uniform d in [" << d_min << ", " << d_max << "] m";
      break;
    case Kind::normal:
      s << "normal d (mean " << mean << ", stddev " << stddev << ") in [" << d_min << ", " << d_max
        << "] m";
      break;
    case Kind::gradation:
      s << "gradation of " << mass_fractions.size() << " classes in [" << sieves.front() << ", "
        << sieves.back() << "] m";
      break;
  }
  return s.str();
}

}  // namespace demfem::dem
