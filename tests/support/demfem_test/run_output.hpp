#pragma once
// Shared by the tests that run demfem_run as a process: reading its CSV output and the
// solver pids and segment names it prints.

#include <sys/types.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "demfem/io/csv_writer.hpp"

namespace demfem::test {

/// The rows of a CSV file, split at commas (no quoting: demfem writes none).
inline std::vector<std::vector<std::string>> read_csv(const std::filesystem::path& p) {
  return io::read_csv_cells(p);
}

/// The pids of the solver processes a run reports ("started dem_server (pid N)").
inline std::vector<pid_t> started_pids(const std::string& out) {
  std::vector<pid_t> pids;
  std::regex re("started (dem|fem)_server \\(pid ([0-9]+)\\)");
  for (auto it = std::sregex_iterator(out.begin(), out.end(), re); it != std::sregex_iterator();
       ++it)
    pids.push_back(std::stoi((*it)[2]));
  return pids;
}

/// The shared-memory segments a run reports ("segment /demfem-<hex>"), without the slash.
inline std::vector<std::string> segments_of(const std::string& out) {
  std::vector<std::string> segs;
  std::regex re("segment /(demfem-[0-9a-f]+)");
  for (auto it = std::sregex_iterator(out.begin(), out.end(), re); it != std::sregex_iterator();
       ++it)
    segs.push_back((*it)[1]);
  return segs;
}

/// Column `name` of a CSV read by read_csv (header row first); throws std::runtime_error when
/// the file is empty or has no such column.
inline std::vector<double> csv_column(const std::vector<std::vector<std::string>>& rows,
                                      const std::string& name) {
  if (rows.empty()) throw std::runtime_error("csv_column: empty file");
  std::size_t k = 0;
  while (k < rows[0].size() && rows[0][k] != name) ++k;
  if (k == rows[0].size()) throw std::runtime_error("csv_column: no column " + name);
  std::vector<double> v;
  for (std::size_t i = 1; i < rows.size(); ++i) v.push_back(std::stod(rows[i][k]));
  return v;
}

/// The first cell in which two CSV tables (read_csv, header row first) differ, the wall-clock
/// columns (`wall_*`) left out: "" when they agree; else where and what, for a test's message
/// (`CHECK(first_difference_but_wall_times(a, b) == "")` prints it).
inline std::string first_difference_but_wall_times(const std::vector<std::vector<std::string>>& a,
                                                   const std::vector<std::vector<std::string>>& b) {
  if (a.size() != b.size())
    return std::to_string(a.size()) + " rows against " + std::to_string(b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a[i].size() != b[i].size())
      return "row " + std::to_string(i) + ": " + std::to_string(a[i].size()) + " cells against " +
             std::to_string(b[i].size());
    for (std::size_t k = 0; k < a[i].size(); ++k) {
      if (a[0][k].rfind("wall_", 0) == 0) continue;
      if (a[i][k] != b[i][k])
        return "row " + std::to_string(i) + " column " + a[0][k] + ": " + a[i][k] + " against " +
               b[i][k];
    }
  }
  return "";
}

/// Whether the file starts with the PNG signature (a plot was written, not a stub).
inline bool is_png(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  char head[8] = {};
  in.read(head, 8);
  return in && std::string(head, 8) == std::string("\x89PNG\r\n\x1a\n", 8);
}

}  // namespace demfem::test
