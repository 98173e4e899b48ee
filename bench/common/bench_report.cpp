#include "bench_report.hpp"

#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace demfem::bench {

namespace {

std::string cell_text(const Cell& c) {
  if (const auto* s = std::get_if<std::string>(&c)) return *s;
  if (const auto* i = std::get_if<long long>(&c)) return std::to_string(*i);
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", std::get<double>(c));
  return buf;
}

std::string json_escape(const std::string& s) {
  std::string out;
  for (char ch : s) {
    if (ch == '"' || ch == '\\') out += '\\';
    if (static_cast<unsigned char>(ch) < 0x20) continue;
    out += ch;
  }
  return out;
}

std::string cell_json(const Cell& c) {
  if (const auto* s = std::get_if<std::string>(&c)) {
    std::string q(1, '"');
    q += json_escape(*s);
    q += '"';
    return q;
  }
  if (const auto* i = std::get_if<long long>(&c)) return std::to_string(*i);
  const double d = std::get<double>(c);
  if (!std::isfinite(d)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", d);
  return buf;
}

std::string run_command(const char* cmd) {
  std::string out;
  if (FILE* p = popen(cmd, "r")) {
    std::array<char, 256> buf{};
    while (fgets(buf.data(), buf.size(), p)) out += buf.data();
    pclose(p);
  }
  while (!out.empty() && (out.back() == '\n' || out.back() == ' ')) out.pop_back();
  return out;
}

}  // namespace

Report::Report(std::string benchmark, std::vector<std::string> columns)
    : benchmark_(std::move(benchmark)), columns_(std::move(columns)) {}

void Report::add_row(std::vector<Cell> row) {
  if (row.size() != columns_.size()) throw std::logic_error("bench row has wrong column count");
  rows_.push_back(std::move(row));
}

void Report::set_info(const std::string& key, const Cell& value) {
  for (auto& [k, v] : info_) {
    if (k == key) {
      v = value;
      return;
    }
  }
  info_.emplace_back(key, value);
}

void Report::print() const {
  std::vector<std::size_t> width(columns_.size());
  for (std::size_t c = 0; c < columns_.size(); ++c) {
    width[c] = columns_[c].size();
    for (const auto& r : rows_) width[c] = std::max(width[c], cell_text(r[c]).size());
  }
  std::cout << "# " << benchmark_ << "  (" << machine_description() << ", commit " << git_commit()
            << ")\n";
  for (const auto& [k, v] : info_) std::cout << "#   " << k << " = " << cell_text(v) << "\n";
  for (std::size_t c = 0; c < columns_.size(); ++c) {
    std::cout << std::setw(static_cast<int>(width[c]) + 2) << columns_[c];
  }
  std::cout << "\n";
  for (const auto& r : rows_) {
    for (std::size_t c = 0; c < columns_.size(); ++c) {
      std::cout << std::setw(static_cast<int>(width[c]) + 2) << cell_text(r[c]);
    }
    std::cout << "\n";
  }
  std::cout.flush();
}

void Report::write_json(const std::string& path) const {
  if (path.empty()) return;
  std::ofstream out(path, std::ios::trunc);
  if (!out) throw std::runtime_error(path + ": cannot write benchmark JSON");
  out << "{\n  \"benchmark\": \"" << json_escape(benchmark_) << "\",\n";
  out << "  \"machine\": \"" << json_escape(machine_description()) << "\",\n";
  out << "  \"commit\": \"" << json_escape(git_commit()) << "\",\n  \"info\": {";
  for (std::size_t i = 0; i < info_.size(); ++i) {
    out << (i ? ", " : "") << "\"" << json_escape(info_[i].first)
        << "\": " << cell_json(info_[i].second);
  }
  out << "},\n  \"rows\": [\n";
  for (std::size_t r = 0; r < rows_.size(); ++r) {
    out << "    {";
    for (std::size_t c = 0; c < columns_.size(); ++c) {
      out << (c ? ", " : "") << "\"" << json_escape(columns_[c])
          << "\": " << cell_json(rows_[r][c]);
    }
    out << "}" << (r + 1 < rows_.size() ? "," : "") << "\n";
  }
  out << "  ]\n}\n";
  std::cout << "# wrote " << path << "\n";
}

// Both are asked by print() and write_json(); they shell out, so each is computed once.
std::string machine_description() {
  static const std::string cached = [] {
    std::string cpu = run_command("grep -m1 'model name' /proc/cpuinfo | cut -d: -f2");
    while (!cpu.empty() && cpu.front() == ' ') cpu.erase(cpu.begin());
    std::string gpu = run_command("nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null");
    std::ostringstream s;
    s << (cpu.empty() ? "unknown CPU" : cpu) << ", " << std::thread::hardware_concurrency()
      << " hardware threads";
    if (!gpu.empty()) s << ", GPU " << gpu;
    return s.str();
  }();
  return cached;
}

std::string git_commit() {
  static const std::string cached = []() -> std::string {
    std::string c = run_command("git -C " DEMFEM_SOURCE_DIR " rev-parse --short HEAD 2>/dev/null");
    if (c.empty()) return "unknown";
    const std::string dirty = run_command("git -C " DEMFEM_SOURCE_DIR
                                          " status --porcelain --untracked-files=no 2>/dev/null");
    return dirty.empty() ? c : c + "-dirty";
  }();
  return cached;
}

}  // namespace demfem::bench
