#include "launch/mpi_job_files.hpp"

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <system_error>

#include <sys/stat.h>
#include <unistd.h>

namespace demfem::coupling::launch {

namespace {

// The value of `key` in /proc/<pid>/environ (NUL-separated "KEY=value" entries).
std::string environment_value(pid_t pid, const std::string& key) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/environ", std::ios::binary);
  if (!in) return {};
  const std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string prefix = key + "=";
  std::size_t begin = 0;
  while (begin < all.size()) {
    std::size_t end = all.find('\0', begin);
    if (end == std::string::npos) end = all.size();
    if (all.compare(begin, prefix.size(), prefix) == 0)
      return all.substr(begin + prefix.size(), end - begin - prefix.size());
    begin = end + 1;
  }
  return {};
}

}  // namespace

bool MpiJobFiles::note_rank(pid_t rank) {
  if (rank <= 0) return false;
  const std::string text = environment_value(rank, "OMPI_MCA_ess_base_jobid");
  if (text.empty()) return false;
  char* end = nullptr;
  const unsigned long job = std::strtoul(text.c_str(), &end, 10);
  if (end == text.c_str() || *end != '\0' || job == 0) return false;
  jobs_.insert(job);
  return true;
}

bool MpiJobFiles::is_job_file(const std::string& name, unsigned long job) {
  std::size_t rest = 0;
  for (const char* prefix : {"vader_segment.", "sm_segment."}) {
    const std::string p(prefix);
    if (name.compare(0, p.size(), p) == 0) rest = p.size();
  }
  if (rest == 0) return false;
  // …<node>.<job hex>.<local rank>: the node name may hold dots, so read from the end.
  const std::size_t last = name.rfind('.');
  if (last == std::string::npos || last + 1 >= name.size() || last <= rest) return false;
  for (std::size_t i = last + 1; i < name.size(); ++i)
    if (name[i] < '0' || name[i] > '9') return false;
  char hex[32];
  std::snprintf(hex, sizeof hex, ".%lx", job);
  const std::string tail(hex);
  // At least one character of node name before the job.
  return last > rest + tail.size() && name.compare(last - tail.size(), tail.size(), tail) == 0;
}

std::vector<std::string> MpiJobFiles::remove_left(const std::string& folder) const {
  std::vector<std::string> removed;
  if (jobs_.empty()) return removed;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(folder, ec)) {
    const std::string name = entry.path().filename().string();
    bool ours = false;
    for (unsigned long job : jobs_) ours = ours || is_job_file(name, job);
    if (!ours) continue;
    struct stat st {};
    // Only this user's files: another user's job with the same id is not ours to remove.
    if (::lstat(entry.path().c_str(), &st) != 0 || st.st_uid != ::getuid()) continue;
    if (::unlink(entry.path().c_str()) == 0) removed.push_back(name);
  }
  return removed;
}

}  // namespace demfem::coupling::launch
