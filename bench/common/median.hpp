#pragma once
// The median the benches report over repeated runs or over the steps of a run: the middle
// value, the mean of the middle two for an even count (NaN for none). With the best run it
// is what a loaded, shared machine leaves comparable between variants measured in turns.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <utility>
#include <vector>

namespace demfem::bench {

inline double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// Sorts repeated runs fastest first (by their `rate`, higher is faster) and returns the
/// median rate; `runs.front()` is then the best run.
template <class Run>
double sort_fastest_first(std::vector<Run>& runs) {
  std::sort(runs.begin(), runs.end(), [](const Run& a, const Run& b) { return a.rate > b.rate; });
  std::vector<double> rates;
  rates.reserve(runs.size());
  for (const Run& r : runs) rates.push_back(r.rate);
  return median(std::move(rates));
}

}  // namespace demfem::bench
