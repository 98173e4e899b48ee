#include "demfem/coupling/checkpoint.hpp"

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "demfem/io/atomic_file.hpp"

namespace fs = std::filesystem;

namespace demfem::coupling {

namespace {

constexpr const char* kManifest = "manifest.json";

std::string hex64(std::uint64_t v) {
  char text[17];
  std::snprintf(text, sizeof(text), "%016" PRIx64, v);
  return text;
}

// The value of `"key": ...` on a manifest line (the text after the colon up to ',' or '}'),
// without quotes; nullopt when the line does not hold the key.
std::optional<std::string> field(const std::string& line, const std::string& key) {
  const std::string tag = "\"" + key + "\":";
  const auto at = line.find(tag);
  if (at == std::string::npos) return std::nullopt;
  std::size_t b = at + tag.size();
  while (b < line.size() && line[b] == ' ') ++b;
  if (b < line.size() && line[b] == '"') {
    const auto e = line.find('"', b + 1);
    if (e == std::string::npos) return std::nullopt;
    return line.substr(b + 1, e - b - 1);
  }
  auto e = line.find_first_of(",}", b);
  if (e == std::string::npos) e = line.size();
  return line.substr(b, e - b);
}

std::int64_t step_of_folder(const fs::path& p) {
  const std::string n = p.filename().string();
  if (n.rfind("step-", 0) != 0) return -1;
  try {
    std::size_t used = 0;
    const long long v = std::stoll(n.substr(5), &used);
    return used == n.size() - 5 ? v : -1;
  } catch (...) {
    return -1;
  }
}

}  // namespace


std::string checkpoint_folder_name(std::int64_t step) {
  char text[32];
  std::snprintf(text, sizeof(text), "step-%06lld", static_cast<long long>(step));
  return text;
}

CheckpointManifest commit_checkpoint(const fs::path& folder, std::int64_t step, double time,
                                     const std::string& scheme,
                                     const std::vector<std::string>& names) {
  CheckpointManifest m;
  m.step = step;
  m.time = time;
  m.scheme = scheme;
  std::ostringstream text;
  char num[64];
  std::snprintf(num, sizeof(num), "%.17g", time);
  text << "{\n  \"format\": \"demfem-checkpoint-1\",\n  \"step\": " << step
       << ",\n  \"time\": " << num << ",\n  \"scheme\": \"" << scheme << "\",\n  \"parts\": [\n";
  for (std::size_t k = 0; k < names.size(); ++k) {
    const fs::path p = folder / names[k];
    std::error_code ec;
    const auto size = fs::file_size(p, ec);
    if (ec) throw std::runtime_error(p.string() + ": checkpoint part missing: " + ec.message());
    CheckpointPart part{names[k], size, fnv1a64_file(p)};
    text << "    {\"name\": \"" << part.name << "\", \"size\": " << part.size << ", \"fnv1a64\": \""
         << hex64(part.checksum) << "\"}" << (k + 1 < names.size() ? "," : "") << "\n";
    m.parts.push_back(part);
  }
  text << "  ]\n}\n";
  io::write_file_atomic(folder / kManifest, text.str());
  return m;
}

CheckpointManifest verify_checkpoint(const fs::path& folder,
                                     const std::vector<std::string>& required) {
  const fs::path mp = folder / kManifest;
  std::ifstream in(mp);
  if (!in) throw std::runtime_error(mp.string() + ": missing (the checkpoint was not committed)");
  CheckpointManifest m;
  bool has_step = false, has_format = false, closed = false;
  std::string line;
  int lineno = 0;
  auto bad = [&](const std::string& why) {
    return std::runtime_error(mp.string() + ":" + std::to_string(lineno) + ": " + why);
  };
  while (std::getline(in, line)) {
    ++lineno;
    if (auto f = field(line, "format")) {
      if (*f != "demfem-checkpoint-1") throw bad("key 'format': unknown format '" + *f + "'");
      has_format = true;
    } else if (auto name = field(line, "name")) {
      CheckpointPart p;
      p.name = *name;
      const auto size = field(line, "size");
      const auto sum = field(line, "fnv1a64");
      if (!size || !sum) throw bad("part '" + p.name + "' lacks key 'size' or 'fnv1a64'");
      try {
        p.size = std::stoull(*size);
        std::size_t used = 0;
        p.checksum = std::stoull(*sum, &used, 16);
        if (used != sum->size() || sum->size() != 16) throw std::invalid_argument("hex");
      } catch (const std::exception&) {
        throw bad("part '" + p.name + "': key 'size' or 'fnv1a64' is malformed");
      }
      if (p.name.empty() || p.name.find('/') != std::string::npos) {
        throw bad("key 'name': '" + p.name + "' is not a file name");
      }
      m.parts.push_back(p);
    } else if (auto step = field(line, "step")) {
      try {
        m.step = std::stoll(*step);
      } catch (const std::exception&) {
        throw bad("key 'step' is malformed");
      }
      if (m.step < 0) throw bad("key 'step' must be >= 0");
      has_step = true;
    } else if (auto time = field(line, "time")) {
      try {
        m.time = std::stod(*time);
      } catch (const std::exception&) {
        throw bad("key 'time' is malformed");
      }
    } else if (auto scheme = field(line, "scheme")) {
      m.scheme = *scheme;
    } else if (line == "}") {
      closed = true;
    }
  }
  if (!has_format) throw bad("key 'format' missing");
  if (!has_step) throw bad("key 'step' missing");
  if (!closed) throw bad("incomplete (no closing brace)");
  const std::int64_t folder_step = step_of_folder(folder);
  if (folder_step >= 0 && folder_step != m.step) {
    throw std::runtime_error(mp.string() + ": key 'step' = " + std::to_string(m.step) +
                             " does not match the folder name");
  }
  for (const auto& r : required) {
    if (std::none_of(m.parts.begin(), m.parts.end(),
                     [&](const CheckpointPart& p) { return p.name == r; })) {
      throw std::runtime_error(mp.string() + ": part '" + r + "' is not listed");
    }
  }
  for (const auto& p : m.parts) {
    const fs::path f = folder / p.name;
    std::error_code ec;
    const auto size = fs::file_size(f, ec);
    if (ec) throw std::runtime_error(f.string() + ": part missing (listed in " + mp.string() + ")");
    if (size != p.size) {
      throw std::runtime_error(f.string() + ": size " + std::to_string(size) + " bytes, " +
                               mp.string() + " lists " + std::to_string(p.size) +
                               " (truncated or changed)");
    }
    const std::uint64_t sum = fnv1a64_file(f);
    if (sum != p.checksum) {
      throw std::runtime_error(f.string() + ": checksum " + hex64(sum) + ", " + mp.string() +
                               " lists " + hex64(p.checksum) + " (corrupt)");
    }
  }
  return m;
}

std::vector<fs::path> list_checkpoints(const fs::path& dir) {
  std::vector<std::pair<std::int64_t, fs::path>> found;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return {};
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::int64_t s = step_of_folder(e.path());
    if (s >= 0 && e.is_directory() && fs::exists(e.path() / kManifest))
      found.emplace_back(s, e.path());
  }
  std::sort(found.begin(), found.end(),
            [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<fs::path> out;
  for (auto& f : found) out.push_back(f.second);
  return out;
}

std::optional<fs::path> latest_valid_checkpoint(
    const fs::path& dir, const std::vector<std::string>& required,
    const std::function<void(const std::string&)>& report) {
  // Every step folder, committed or not, newest first: an uncommitted one is reported too.
  std::vector<std::pair<std::int64_t, fs::path>> all;
  std::error_code ec;
  if (fs::is_directory(dir, ec)) {
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      const std::int64_t s = step_of_folder(e.path());
      if (s >= 0 && e.is_directory()) all.emplace_back(s, e.path());
    }
  }
  std::sort(all.begin(), all.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  for (const auto& [step, c] : all) {
    try {
      (void)verify_checkpoint(c, required);
      return c;
    } catch (const std::exception& e) {
      if (report) report("skipping checkpoint " + c.string() + ": " + e.what());
    }
  }
  return std::nullopt;
}

void prune_checkpoints(const fs::path& dir, std::int64_t keep) {
  const auto committed = list_checkpoints(dir);
  if (committed.empty()) return;
  std::error_code ec;
  for (std::size_t k = static_cast<std::size_t>(std::max<std::int64_t>(keep, 1));
       k < committed.size(); ++k) {
    fs::remove_all(committed[k], ec);
  }
  // Folders without a manifest below the newest committed step were never committed.
  const std::int64_t newest = step_of_folder(committed.front());
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::int64_t s = step_of_folder(e.path());
    if (s >= 0 && s < newest && !fs::exists(e.path() / kManifest)) fs::remove_all(e.path(), ec);
  }
}

void discard_checkpoints_after(const fs::path& dir, std::int64_t step) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return;
  std::vector<fs::path> doomed;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (step_of_folder(e.path()) > step) doomed.push_back(e.path());
  }
  for (const auto& p : doomed) fs::remove_all(p, ec);
}

}  // namespace demfem::coupling
