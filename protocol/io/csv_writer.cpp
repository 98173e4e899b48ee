#include "demfem/io/csv_writer.hpp"

#include <cstdio>
#include <algorithm>
#include <cstdint>
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

namespace {

// Byte offsets just past each complete line ('\n'-terminated) of the file.
std::vector<std::uintmax_t> line_ends(const std::filesystem::path& path, std::string* text) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path.string() + ": cannot open CSV series to resume");
  std::ostringstream all;
  all << in.rdbuf();
  *text = all.str();
  std::vector<std::uintmax_t> ends;
  for (std::size_t i = 0; i < text->size(); ++i)
    if ((*text)[i] == '\n') ends.push_back(i + 1);
  return ends;
}

}  // namespace

void keep_csv_rows(const std::filesystem::path& path, std::size_t keep_rows,
                   const std::string& expected) {
  std::string text;
  const auto ends = line_ends(path, &text);
  const std::size_t rows = ends.empty() ? 0 : ends.size() - 1;  // the first line is the header
  if (ends.empty() || rows < keep_rows) {
    throw std::runtime_error(path.string() + ": has " + std::to_string(rows) + " rows, " +
                             expected + " expects at least " + std::to_string(keep_rows));
  }
  if (ends[keep_rows] != text.size()) std::filesystem::resize_file(path, ends[keep_rows]);
}

std::vector<std::string> read_csv_rows(const std::filesystem::path& path) {
  std::string text;
  const auto ends = line_ends(path, &text);
  std::vector<std::string> rows;
  for (std::size_t k = 1; k < ends.size(); ++k)
    rows.emplace_back(text.substr(ends[k - 1], ends[k] - ends[k - 1] - 1));
  return rows;
}

std::vector<std::vector<std::string>> read_csv_cells(const std::filesystem::path& path) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> row;
    std::stringstream s(line);
    std::string cell;
    while (std::getline(s, cell, ',')) row.push_back(cell);
    rows.push_back(row);
  }
  return rows;
}

CsvWriter CsvWriter::resume(const std::filesystem::path& path, std::size_t keep_rows) {
  keep_csv_rows(path, keep_rows);
  std::string header;
  {
    std::ifstream in(path);
    std::getline(in, header);
  }
  CsvWriter w;
  w.path_ = path;
  w.columns_ = static_cast<std::size_t>(std::count(header.begin(), header.end(), ',')) + 1;
  w.out_.open(path, std::ios::app);
  if (!w.out_) throw std::runtime_error(path.string() + ": cannot append to the CSV series");
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
