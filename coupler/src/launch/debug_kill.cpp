#include "launch/debug_kill.hpp"

#include <csignal>
#include <stdexcept>

namespace demfem::coupling::launch {

std::optional<DebugKill> parse_debug_kill(const std::string& text) {
  if (text.empty()) return std::nullopt;
  DebugKill k;
  const auto c1 = text.find(':');
  if (c1 == std::string::npos) throw std::invalid_argument(text);
  k.role = text.substr(0, c1);
  std::string rest = text.substr(c1 + 1);
  if (const auto c2 = rest.find(':'); c2 != std::string::npos) {
    const std::string how = rest.substr(c2 + 1);
    if (how == "always") {
      k.always = true;
    } else if (how == "stop") {
      k.stop = true;  // SIGSTOP: a hung process, found by its stale heartbeat
    } else if (how == "usr1" || how == "usr2") {
      k.job_signal = how == "usr1" ? SIGUSR1 : SIGUSR2;
    } else {
      throw std::invalid_argument(text);
    }
    rest = rest.substr(0, c2);
  }
  std::size_t used = 0;
  k.step = std::stoll(rest, &used);
  if (used != rest.size() || k.step < 0 ||
      (k.role != "dem" && k.role != "fem" && k.role != "coupler" && k.role != "job") ||
      ((k.role == "job") != (k.job_signal != 0))) {
    throw std::invalid_argument(text);
  }
  return k;
}

}  // namespace demfem::coupling::launch
