#include "demfem/fem/time_function.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace demfem::fem {

TimeFunction constant_function(double value) {
  if (!std::isfinite(value)) throw std::invalid_argument("constant value must be finite");
  return [value](double) { return value; };
}

TimeFunction piecewise_linear_function(std::vector<std::pair<double, double>> points) {
  if (points.empty()) throw std::invalid_argument("a table needs at least one (t, f) point");
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!std::isfinite(points[i].first) || !std::isfinite(points[i].second)) {
      throw std::invalid_argument("table point " + std::to_string(i) + " is not finite");
    }
    if (i > 0 && !(points[i].first > points[i - 1].first)) {
      throw std::invalid_argument("table times must increase strictly (point " + std::to_string(i) +
                                  ")");
    }
  }
  return [p = std::move(points)](double t) {
    if (t <= p.front().first) return p.front().second;
    if (t >= p.back().first) return p.back().second;
    // First point with time > t; the segment is [k-1, k].
    const auto it = std::upper_bound(p.begin(), p.end(), t,
                                     [](double v, const auto& q) { return v < q.first; });
    const auto& b = *it;
    const auto& a = *(it - 1);
    const double s = (t - a.first) / (b.first - a.first);
    return a.second + s * (b.second - a.second);
  };
}

TimeFunction sinusoid_function(double mean, double amplitude, double frequency, double phase) {
  if (!std::isfinite(mean) || !std::isfinite(amplitude) || !std::isfinite(frequency) ||
      !std::isfinite(phase)) {
    throw std::invalid_argument("sinusoid parameters must be finite");
  }
  if (frequency < 0.0) throw std::invalid_argument("sinusoid frequency must be >= 0");
  return [=](double t) {
    return mean + amplitude * std::sin(2.0 * std::numbers::pi * frequency * t + phase);
  };
}

double SleeperLoadPattern::operator()(double t) const {
  const double tau = t / time_scale;
  const double t1 = ramp_duration + unload_duration;
  const double t2 = t1 + cycle_duration;
  const double t3 = t2 + ramp_duration;
  if (tau < 0.0) return 0.0;
  if (tau < ramp_duration) return peak_force * tau / ramp_duration;
  if (tau < t1)
    return peak_force + (cycle_min - peak_force) * (tau - ramp_duration) / unload_duration;
  if (tau < t2) {
    const double phase = 2.0 * std::numbers::pi * cycle_frequency * (tau - t1);
    return cycle_min + (cycle_max - cycle_min) * 0.5 * (1.0 - std::cos(phase));
  }
  if (tau < t3) return peak_force * (tau - t2) / ramp_duration;
  return peak_force;
}

TimeFunction sleeper_load_function(const SleeperLoadPattern& p) {
  auto finite_positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!finite_positive(p.ramp_duration) || !finite_positive(p.cycle_duration) ||
      !finite_positive(p.cycle_frequency) || !finite_positive(p.time_scale)) {
    throw std::invalid_argument(
        "sleeper pattern: ramp_duration, cycle_duration, cycle_frequency and time_scale must "
        "be > 0");
  }
  if (!std::isfinite(p.unload_duration) || p.unload_duration < 0.0)
    throw std::invalid_argument("sleeper pattern: unload_duration must be >= 0");
  if (!std::isfinite(p.peak_force) || !std::isfinite(p.cycle_min) || !std::isfinite(p.cycle_max) ||
      p.cycle_min < 0.0 || p.cycle_max < p.cycle_min) {
    throw std::invalid_argument("sleeper pattern: needs 0 <= cycle_min <= cycle_max (finite)");
  }
  return [p](double t) { return p(t); };
}

}  // namespace demfem::fem
