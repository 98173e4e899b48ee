#include "demfem/io/output_schedule.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace demfem::io {

namespace {

// Half-open window [t - step/2 - e, t + step/2 - e) of the nominal times a state at t is the
// nearest step end of; e = 1e-9 step puts a tie (a nominal time half way between two step
// ends) in the later step's window whatever the rounding of t.
double window_end(double t, double step) {
  return t + step * (0.5 - 1e-9);
}
double window_begin(double t, double step) {
  return t - step * (0.5 + 1e-9);
}

// Largest output index (nearest() saturates there) and how many rounding corrections of an
// index estimate are made; two suffice while k * interval resolves neighbouring outputs.
constexpr std::int64_t kMaxIndex = 9'000'000'000'000'000'000;
constexpr int kCorrections = 8;

}  // namespace

double decimal_time(double t) {
  if (!std::isfinite(t) || t == 0.0) return t;
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.15g", t);
  return std::strtod(buf, nullptr);
}

std::string format_time(double t) {
  char buf[40];
  const auto r = std::to_chars(buf, buf + sizeof buf, t, std::chars_format::general);
  return std::string(buf, r.ptr);
}

double OutputSchedule::nominal(std::int64_t k) const {
  return decimal_time(static_cast<double>(k) * interval_);
}

std::int64_t OutputSchedule::nearest(double t) const {
  const double k = std::round(t / interval_);
  if (!(k >= 0.0)) return 0;
  if (k > static_cast<double>(kMaxIndex)) return kMaxIndex;
  return static_cast<std::int64_t>(k);
}

bool OutputSchedule::due(double t, double step) const {
  return active() && nominal(next_) < window_end(t, step);
}

double OutputSchedule::take(double t, double step) {
  if (!due(t, step)) return label(t, step);
  const double end = window_end(t, step);
  // The last nominal time inside the window: start near it, then correct for rounding (one
  // or two steps). The corrections are bounded: for an interval below the resolution of the
  // times (run.output_interval = 1e-300: k beyond 1e15, or nearest() saturated) neighbouring
  // nominal times are equal and the loops would never end (issue 19: a hang).
  std::int64_t k = std::max(next_, nearest(end));
  for (int i = 0; i < kCorrections && k > next_ && !(nominal(k) < end); ++i) --k;
  for (int i = 0; i < kCorrections && k < kMaxIndex && nominal(k + 1) < end; ++i) ++k;
  next_ = k + 1;
  // Saturated, nominal(k) is not a time near t: the state's own time is the label.
  return k >= kMaxIndex ? decimal_time(t) : nominal(k);
}

double OutputSchedule::label(double t, double step) const {
  if (active()) {
    const std::int64_t k = nearest(t);
    for (std::int64_t j = std::max<std::int64_t>(0, k - 1); j <= k + 1; ++j) {
      const double n = nominal(j);
      if (n >= window_begin(t, step) && n < window_end(t, step)) return n;
    }
  }
  return decimal_time(t);
}

void OutputSchedule::skip_to_after(double t) {
  if (!active()) return;
  std::int64_t k = nearest(t);
  const double limit = t + 1e-9 * interval_;
  for (int i = 0; i < kCorrections && k > 0 && nominal(k - 1) > limit; ++i) --k;
  for (int i = 0; i < kCorrections && k < kMaxIndex && !(nominal(k) > limit); ++i) ++k;
  next_ = k;
}

}  // namespace demfem::io
