#pragma once
// coupling.csv: its columns, one row per StepDiagnostics, and the file that holds the series
// (written row by row, continued after a resume). Private to the coupling library.

#include <charconv>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "demfem/coupling/coupling_run.hpp"
#include "demfem/io/csv_writer.hpp"

namespace demfem::coupling {

/// @brief The columns of coupling.csv (docs/coupling.md, "Diagnostics").
const std::vector<std::string>& coupling_columns();
/// @brief One row of coupling.csv, in coupling_columns() order.
std::vector<double> row_of(const StepDiagnostics& d);
/// @brief The inverse of row_of() (a checkpoint keeps the last row).
StepDiagnostics diagnostics_of(std::span<const double> row);

// coupling.csv, one row per coupling step. Numbers are written with std::to_chars in their
// shortest form that reads back as the same double (exact, like CsvWriter's %.17g, but about
// five times faster: at one row per step, formatting was most of the coupler's own time).
class SeriesFile {
 public:
  SeriesFile(const std::filesystem::path& path, const std::vector<std::string>& columns)
      : path_(path), out_(path, std::ios::trunc) {
    if (!out_) throw std::runtime_error("cannot write " + path.string());
    for (std::size_t k = 0; k < columns.size(); ++k) out_ << (k ? "," : "") << columns[k];
    out_ << '\n';
  }
  /// Continues an existing series: keeps the header and the first `keep_rows` rows (those
  /// of a checkpoint being resumed), drops the rest.
  SeriesFile(const std::filesystem::path& path, std::size_t keep_rows) : path_(path) {
    if (!std::filesystem::exists(path)) {
      throw std::runtime_error(path.string() +
                               ": cannot read the series to continue (the output folder does "
                               "not hold the output of the run that took the checkpoint: resume "
                               "into that run's output folder)");
    }
    io::keep_csv_rows(path, keep_rows);
    out_.open(path, std::ios::app);
    if (!out_) throw std::runtime_error("cannot write " + path.string());
  }
  void row(std::span<const double> values) {
    char text[40];
    line_.clear();
    for (std::size_t k = 0; k < values.size(); ++k) {
      if (k) line_ += ',';
      const auto r = std::to_chars(text, text + sizeof(text), values[k]);
      line_.append(text, r.ptr);
    }
    line_ += '\n';
    out_ << line_;
  }
  void flush() {
    out_.flush();
    if (!out_) throw std::runtime_error("cannot write " + path_.string());
  }

 private:
  std::filesystem::path path_;
  std::ofstream out_;
  std::string line_;
};

}  // namespace demfem::coupling
