#pragma once
// CSV time series written with full precision (17 significant digits) so that a restarted run
// can be compared bitwise with an uninterrupted one.

#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <vector>

namespace demfem::io {

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
