#include "launch/run_record.hpp"

#include <unistd.h>

#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <sstream>

#include "demfem/coupling/checkpoint.hpp"
#include "demfem/io/atomic_file.hpp"
#include "demfem_build_info.hpp"

namespace demfem::coupling {

namespace {

std::string quoted(const std::string& text) {
  std::string s = "\"";
  for (const char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    switch (ch) {
      case '"':
        s += "\\\"";
        break;
      case '\\':
        s += "\\\\";
        break;
      case '\n':
        s += "\\n";
        break;
      case '\t':
        s += "\\t";
        break;
      default:
        if (c < 0x20) {
          char u[8];
          std::snprintf(u, sizeof(u), "\\u%04x", c);
          s += u;
        } else {
          s += ch;
        }
    }
  }
  return s + "\"";
}

std::string number(double v) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.17g", v);
  return text;
}

std::string strings(const std::vector<std::string>& v) {
  std::string s = "[";
  for (std::size_t k = 0; k < v.size(); ++k) s += (k ? ", " : "") + quoted(v[k]);
  return s + "]";
}

// The text of `"key": "value"` or `"key": value` in a run.json written by to_json().
std::optional<std::string> field(const std::string& text, const std::string& key) {
  const std::string tag = "\"" + key + "\": ";
  const auto at = text.find(tag);
  if (at == std::string::npos) return std::nullopt;
  const auto b = at + tag.size();
  if (b < text.size() && text[b] == '"') {
    const auto e = text.find('"', b + 1);
    if (e == std::string::npos) return std::nullopt;
    return text.substr(b + 1, e - b - 1);
  }
  const auto e = text.find_first_of(",\n}", b);
  return text.substr(b, e == std::string::npos ? std::string::npos : e - b);
}

}  // namespace

std::string to_json(const RunRecord& r) {
  std::ostringstream j;
  auto opt_text = [](const std::string& s) { return s.empty() ? std::string("null") : quoted(s); };
  j << "{\n"
    << "  \"format\": \"demfem-run-1\",\n"
    << "  \"status\": " << quoted(r.status) << ",\n"
    << "  \"exit_code\": " << (r.exit_code < 0 ? "null" : std::to_string(r.exit_code)) << ",\n"
    << "  \"signal\": " << (r.signal > 0 ? std::to_string(r.signal) : "null") << ",\n"
    << "  \"reason\": " << opt_text(r.reason) << ",\n"
    << "  \"scene\": " << quoted(r.scene.string()) << ",\n"
    << "  \"scene_hash\": " << quoted(r.scene_hash) << ",\n"
    << "  \"overrides\": " << strings(r.overrides) << ",\n"
    << "  \"output_dir\": " << quoted(r.output_dir.string()) << ",\n"
    << "  \"checkpoint_dir\": " << opt_text(r.checkpoint_dir.string()) << ",\n"
    << "  \"resumed_from\": " << opt_text(r.resumed_from) << ",\n"
    << "  \"resumed_step\": " << (r.resumed_step < 0 ? "null" : std::to_string(r.resumed_step))
    << ",\n"
    << "  \"copied_series_from\": " << opt_text(r.copied_from) << ",\n"
    << "  \"cleared_files\": " << strings(r.cleared) << ",\n"
    << "  \"mode\": " << quoted(r.in_process ? "in process" : "three processes") << ",\n"
    << "  \"command_line\": " << strings(r.command_line) << ",\n"
    << "  \"demfem_version\": " << quoted(demfem_version()) << ",\n"
    << "  \"git_commit\": " << quoted(demfem_git_commit()) << ",\n"
    << "  \"git_dirty\": " << (demfem_git_dirty() ? "true" : "false") << ",\n"
    << "  \"host\": " << quoted(r.host) << ",\n"
    << "  \"pid\": " << r.pid << ",\n"
    << "  \"dem_backend\": " << opt_text(r.dem_backend) << ",\n"
    << "  \"dem_threads\": " << (r.dem_backend.empty() || r.dem_backend == "external"
                                    ? "null"
                                    : std::to_string(r.dem_threads))
    << ",\n"
    << "  \"fem_backend\": " << opt_text(r.fem_backend) << ",\n"
    << "  \"fem_command\": " << (r.fem_command.empty() ? "null" : strings(r.fem_command)) << ",\n"
    << "  \"dem_command\": " << (r.dem_command.empty() ? "null" : strings(r.dem_command)) << ",\n"
    << "  \"omp_num_threads\": " << opt_text(r.omp_num_threads) << ",\n"
    << "  \"hardware_threads\": " << r.hardware_threads << ",\n"
    << "  \"start_time\": " << quoted(r.start_time) << ",\n"
    << "  \"end_time\": " << opt_text(r.end_time) << ",\n"
    << "  \"run_end_time\": " << number(r.end_time_simulated) << ",\n"
    << "  \"step_count\": " << r.step_count << ",\n"
    << "  \"steps_done\": " << (r.steps_done < 0 ? "null" : std::to_string(r.steps_done)) << ",\n"
    << "  \"time_reached\": " << (r.time_reached < 0 ? "null" : number(r.time_reached)) << "\n"
    << "}\n";
  return j.str();
}

void write_run_record(const std::filesystem::path& dir, const RunRecord& record) {
  io::write_file_atomic(dir / "run.json", to_json(record));
}

std::optional<RecordedRun> read_run_status(const std::filesystem::path& dir) {
  std::ifstream in(dir / "run.json");
  if (!in) return std::nullopt;
  std::stringstream s;
  s << in.rdbuf();
  const std::string text = s.str();
  const auto status = field(text, "status");
  if (!status) return std::nullopt;
  RecordedRun r;
  r.status = *status;
  if (const auto pid = field(text, "pid")) r.pid = static_cast<pid_t>(std::atol(pid->c_str()));
  r.host = field(text, "host").value_or("");
  r.start_time = field(text, "start_time").value_or("");
  return r;
}

namespace {

// Seconds since the epoch when process `pid` started (/proc/<pid>/stat field 22, in clock ticks
// after boot, plus the boot time of /proc/stat); -1 when it cannot be read.
double process_start_time(pid_t pid) {
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(stat, line)) return -1.0;
  const auto close = line.rfind(')');  // the command name may hold spaces and parentheses
  if (close == std::string::npos) return -1.0;
  std::istringstream rest(line.substr(close + 2));
  std::string state, value;
  rest >> state;
  if (state == "Z" || state == "X") return -1.0;  // ended, not yet reaped
  for (int field_no = 4; field_no <= 22 && (rest >> value); ++field_no) {
    if (field_no == 22) {
      std::ifstream boot("/proc/stat");
      std::string key;
      double btime = -1.0;
      while (boot >> key) {
        if (key == "btime") {
          boot >> btime;
          break;
        }
      }
      if (btime < 0) return -1.0;
      return btime + std::atof(value.c_str()) / static_cast<double>(::sysconf(_SC_CLK_TCK));
    }
  }
  return -1.0;
}

}  // namespace

bool recorded_run_alive(const RecordedRun& run) {
  if (run.status != "running" || run.pid <= 0 || run.pid == ::getpid()) return false;
  char host[256] = {};
  ::gethostname(host, sizeof(host) - 1);
  if (!run.host.empty() && run.host != host) return false;  // its pid means nothing here
  std::ifstream cmd("/proc/" + std::to_string(run.pid) + "/cmdline");
  std::string argv0;
  if (!std::getline(cmd, argv0, '\0')) return false;
  const std::string name = std::filesystem::path(argv0).filename().string();
  if (name != "demfem_run" && name != "coupler") return false;
  const double started = process_start_time(run.pid);
  std::tm tm{};
  if (started < 0 || !::strptime(run.start_time.c_str(), "%Y-%m-%dT%H:%M:%SZ", &tm)) return false;
  // The record is written after the scene was read: the process started before it (a second
  // of slack for the rounding of both clocks).
  return started <= static_cast<double>(::timegm(&tm)) + 1.5;
}

std::string scene_hash(const std::filesystem::path& scene,
                       const std::vector<std::string>& overrides) {
  std::uint64_t h = fnv1a64_file(scene);
  for (const auto& o : overrides) {
    for (const char c : "\n" + o) {
      h ^= static_cast<unsigned char>(c);
      h *= 1099511628211ULL;  // FNV-1a 64 prime, continuing the file's hash
    }
  }
  char text[17];
  std::snprintf(text, sizeof(text), "%016" PRIx64, h);
  return text;
}

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  ::gmtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

std::string demfem_version() {
  return DEMFEM_VERSION;
}
std::string demfem_git_commit() {
  return DEMFEM_GIT_COMMIT;
}
bool demfem_git_dirty() {
  return DEMFEM_GIT_DIRTY;
}

}  // namespace demfem::coupling
