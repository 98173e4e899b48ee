#pragma once
// CSV time series written with full precision (17 significant digits) so that a restarted run
// can be compared bitwise with an uninterrupted one.

#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <vector>

namespace demfem::io {

/// @brief Cuts a CSV series back to its header and first `keep_rows` data rows, in place: one
/// truncate, so that a process killed meanwhile leaves either the old file or the cut one,
/// never fewer rows (rewriting the kept rows could be stopped half-way, and the checkpoint
/// that needs them would be lost for good). A last line without its newline (a writer killed
/// inside a row) is no row. Throws, naming the file, when it holds fewer rows than
/// `keep_rows` or cannot be read; `expected` says who expects them ("the checkpoint").
void keep_csv_rows(const std::filesystem::path& path, std::size_t keep_rows,
                   const std::string& expected = "the checkpoint");

/// The complete data rows of a CSV series (header and a last line without newline left out).
std::vector<std::string> read_csv_rows(const std::filesystem::path& path);

/// Every line of a CSV file, the header first, split at commas (demfem writes no quoting); an
/// unreadable file gives no rows. For readers that take a table as it stands (tests, benches).
std::vector<std::vector<std::string>> read_csv_cells(const std::filesystem::path& path);

/// @brief Appends rows of numbers under a fixed header.
class CsvWriter {
 public:
  /// Creates (truncates) the file and writes the header.
  CsvWriter(const std::filesystem::path& path, const std::vector<std::string>& columns);
  /// Opens an existing series to continue it: keeps the header and the first `keep_rows`
  /// data rows, drops the rest (rows written after a checkpoint that is being resumed).
  static CsvWriter resume(const std::filesystem::path& path, std::size_t keep_rows);

  void row(std::span<const double> values);
  void row(std::initializer_list<double> values) { row(std::span(values.begin(), values.size())); }
  void flush();
  std::size_t rows() const { return rows_; }
  const std::filesystem::path& path() const { return path_; }

 private:
  CsvWriter() = default;
  std::filesystem::path path_;
  std::ofstream out_;
  std::size_t columns_ = 0;
  std::size_t rows_ = 0;
};

}  // namespace demfem::io
