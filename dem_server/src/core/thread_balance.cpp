// The threads' particle ranges of the CPU force pass (thread_balance.hpp).

#include "thread_balance.hpp"

#include <algorithm>

namespace demfem::dem::detail {

void ThreadBalance::ensure(int threads, std::int64_t count) {
  const auto T = static_cast<std::size_t>(threads);
  if (split.size() == T + 1 && split.back() == count) return;
  split.resize(T + 1);
  for (std::size_t k = 0; k <= T; ++k)
    split[k] = count * static_cast<std::int64_t>(k) / static_cast<std::int64_t>(T);
  busy.assign(T, 0.0);
  waiting.resize(T);
}

void ThreadBalance::adapt() {
  const std::size_t T = busy.size();
  if (T < 2) return;
  std::vector<double> rate(T);
  double sum = 0.0;
  for (std::size_t k = 0; k < T; ++k) {
    const double cnt = static_cast<double>(split[k + 1] - split[k]);
    rate[k] = busy[k] > 0.0 && cnt > 0.0 ? cnt / busy[k] : 0.0;
    if (!(rate[k] > 0.0)) return;  // no usable timing
    sum += rate[k];
  }
  const std::int64_t count = split.back();
  double acc = 0.0;
  for (std::size_t k = 1; k < T; ++k) {
    acc += rate[k - 1];
    const double target = static_cast<double>(count) * acc / sum;
    const auto next = static_cast<std::int64_t>(0.5 * (static_cast<double>(split[k]) + target));
    // at least one particle per thread, bounds ascending
    split[k] =
        std::clamp<std::int64_t>(next, split[k - 1] + 1, count - static_cast<std::int64_t>(T - k));
  }
}

}  // namespace demfem::dem::detail
