#pragma once
// Shared output of every benchmark: an aligned table on stdout and the same rows as JSON,
// with the machine and the git commit, so results can be compared across commits.

#include <string>
#include <variant>
#include <vector>

namespace demfem::bench {

using Cell = std::variant<std::string, double, long long>;

/// @brief Rows of named columns, printed as a table and written as JSON.
class Report {
 public:
  Report(std::string benchmark, std::vector<std::string> columns);
  void add_row(std::vector<Cell> row);
  /// Free-form facts about the run (threads, backend, parameters).
  void set_info(const std::string& key, const Cell& value);
  void print() const;
  /// Writes JSON; does nothing when `path` is empty.
  void write_json(const std::string& path) const;

 private:
  std::string benchmark_;
  std::vector<std::string> columns_;
  std::vector<std::vector<Cell>> rows_;
  std::vector<std::pair<std::string, Cell>> info_;
};

/// @brief CPU model and core count, and the GPU where one is given.
std::string machine_description();
/// @brief `git rev-parse --short HEAD` of the source tree, or "unknown".
std::string git_commit();

}  // namespace demfem::bench
