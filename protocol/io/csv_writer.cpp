#include "demfem/io/csv_writer.hpp"

#include <cstdio>
#include <algorithm>
#include <sstream>
#include <stdexcept>

namespace demfem::io {

CsvWriter::CsvWriter(const std::filesystem::path& path, const std::vector<std::string>& columns)
    : path_(path), columns_(columns.size()) {
  if (!path.parent_path().empty()) std::filesystem::create_directories(path.parent_path());
  out_.open(path, std::ios::trunc);
  if (!out_) throw std::runtime_error(path.string() + ": cannot create CSV file");
  for (std::size_t i = 0; i < columns.size(); ++i) out_ << (i ? "," : "") << columns[i];
  out_ << '\n';
}

CsvWriter CsvWriter::resume(const std::filesystem::path& path, std::size_t keep_rows) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path.string() + ": cannot open CSV series to resume");
  std::string header;
  std::getline(in, header);
  std::vector<std::string> lines;
  std::string line;
  while (lines.size() < keep_rows && std::getline(in, line)) lines.push_back(line);
  if (lines.size() < keep_rows) {
    throw std::runtime_error(path.string() + ": has " + std::to_string(lines.size()) +
                             " rows, the checkpoint expects at least " +
                             std::to_string(keep_rows));
  }
  in.close();
  CsvWriter w;
  w.path_ = path;
  w.columns_ = static_cast<std::size_t>(std::count(header.begin(), header.end(), ',')) + 1;
  w.out_.open(path, std::ios::trunc);
  w.out_ << header << '\n';
  for (const auto& l : lines) w.out_ << l << '\n';
  w.rows_ = keep_rows;
  return w;
}

void CsvWriter::row(std::span<const double> values) {
  if (values.size() != columns_) {
    throw std::logic_error(path_.string() + ": row of " + std::to_string(values.size()) +
                           " values for " + std::to_string(columns_) + " columns");
  }
  char buf[32];
  for (std::size_t i = 0; i < values.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%.17g", values[i]);
    out_ << (i ? "," : "") << buf;
  }
  out_ << '\n';
  ++rows_;
}

void CsvWriter::flush() { out_.flush(); }

}  // namespace demfem::io
