#pragma once
// The lines of an Abaqus deck (internal to the .inp reader): the text of the main file with
// every *INCLUDE expanded in place (relative to the including file, at most kInpIncludeDepth
// deep, cycles refused, all files together within io::kMeshFileLimit), comments and blank
// lines dropped, each line with its file and line number; keyword lines parsed into name and
// parameters; number and label parsing with messages that name the file and line.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "demfem/fem/inp_reader.hpp"

namespace demfem::fem::inp {

/// Where a line came from: Deck::files()[file], 1-based line.
struct Loc {
  std::int32_t file = 0;
  std::int32_t line = 0;
};

struct Line {
  std::string text;  ///< trimmed
  Loc loc;
};

struct Keyword {
  std::string name;                                         ///< upper case, single spaces
  std::vector<std::pair<std::string, std::string>> params;  ///< upper-case key, raw value
  Loc loc;

  std::optional<std::string> param(std::string_view key) const;
  bool flag(std::string_view key) const { return param(key).has_value(); }
};

std::string upper(std::string s);
std::string trim(std::string_view s);
/// Splits at commas; entries trimmed; a trailing comma gives no empty last entry.
std::vector<std::string> split_commas(std::string_view line);
bool ends_with_comma(std::string_view line);
bool is_keyword(const std::string& trimmed_line);
/// A token that is a label (digits, sign) rather than a name.
bool looks_numeric(const std::string& token);
/// A label, plain ("17") or qualified by an instance ("PART-1-1.17"), rather than a set name.
bool is_label_token(const std::string& token);

class Deck {
 public:
  /// `text` is the content of the main file `name`.
  Deck(const std::string& text, const std::string& name, bool allow_include);

  const std::vector<Line>& lines() const { return lines_; }
  const std::vector<std::string>& files() const { return files_; }
  /// "file:line".
  std::string where(Loc loc) const;
  [[noreturn]] void fail(Loc loc, const std::string& message) const;

  /// Parses the keyword line at `i` (joining continuation lines that end with a comma);
  /// `next` becomes the index of the first line after it.
  Keyword keyword(std::size_t i, std::size_t& next) const;

  /// A finite number; `what` names the value in messages.
  double number(const std::string& token, Loc loc, const std::string& what) const;
  /// A positive integer label.
  std::int64_t label(const std::string& token, Loc loc, const std::string& what) const;

 private:
  void add_text(const std::string& text, std::int32_t file, int depth,
                std::vector<std::string>& stack);
  void include(const std::string& line, Loc loc, int depth, std::vector<std::string>& stack);

  std::vector<Line> lines_;
  std::vector<std::string> files_;
  bool allow_include_;
  std::uint64_t bytes_ = 0;  ///< all files read so far
};

}  // namespace demfem::fem::inp
