#include "demfem/scene/scene_reader.hpp"

#include <toml++/toml.h>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <sstream>

#include "demfem/io/input_file.hpp"
#include "scene_override.hpp"

namespace demfem::scene {

namespace {

std::string format_number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

std::string type_name(const toml::node& n) {
  switch (n.type()) {
    case toml::node_type::table:
      return "a table";
    case toml::node_type::array:
      return "an array";
    case toml::node_type::string:
      return "a string";
    case toml::node_type::integer:
      return "an integer";
    case toml::node_type::floating_point:
      return "a number";
    case toml::node_type::boolean:
      return "a boolean";
    default:
      return "a date/time";
  }
}

// toml++ 3.3 (Debian 12) reaches __builtin_unreachable() in its Unicode whitespace test for
// most code points in U+00A1..U+0499, U+2CDE..U+30D7 and U+FB36..U+FF2F (found by fuzzing,
// tests/fuzz/corpus/scene/toml_unicode_unreachable.toml): undefined behaviour in the shipped
// library. Mirror its table to know which code points would reach that point.
bool toml_whitespace_test_is_undefined(char32_t c) {
  if (c < 0xA0 || c > 0xFEFF) return false;
  if (c == 0xA0 || c == 0x3000 || c == 0xFEFF) return false;
  const auto child = (static_cast<std::uint64_t>(c) - 0xA0ull) / 0x3FAull;
  if ((1ull << child) & 0x7FFFFFFFFFFFF75Eull) return false;
  return child != 0x05 && child != 0x07;
}

// Decodes one UTF-8 sequence at text[i]; returns its length (1 for invalid bytes, which
// toml++ reports itself).
std::size_t decode_utf8(std::string_view text, std::size_t i, char32_t& cp) {
  const auto b = static_cast<unsigned char>(text[i]);
  std::size_t len = b < 0x80           ? 1
                    : (b >> 5) == 0x6  ? 2
                    : (b >> 4) == 0xE  ? 3
                    : (b >> 3) == 0x1E ? 4
                                       : 1;
  if (i + len > text.size()) len = 1;
  cp = len == 1 ? b : len == 2 ? (b & 0x1F) : len == 3 ? (b & 0x0F) : (b & 0x07);
  for (std::size_t k = 1; k < len; ++k)
    cp = (cp << 6) | (static_cast<unsigned char>(text[i + k]) & 0x3F);
  return len;
}

// Makes a scene text safe for toml++: comments are blanked past their first non-ASCII
// character (their content never matters), non-ASCII outside strings and comments is an
// error (TOML keys are ASCII), and code points that would reach the defect above are
// refused inside strings with a message naming the line.
std::string sanitise_for_toml(std::string_view text, const std::string& name) {
  std::string out(text);
  enum class State { normal, comment, basic, literal, ml_basic, ml_literal } state = State::normal;
  std::size_t line = 1;
  std::size_t line_start = 0;
  auto starts = [&](std::size_t i, std::string_view s) { return text.substr(i, s.size()) == s; };
  // A backslash in a basic string skips the character it escapes when that is plain ASCII
  // on the same line (a line-ending backslash or a UTF-8 sequence is scanned as usual).
  auto escape_length = [&](std::size_t i) -> std::size_t {
    return i + 1 < text.size() && text[i + 1] != '\n' &&
                   static_cast<unsigned char>(text[i + 1]) < 0x80
               ? 2
               : 1;
  };
  for (std::size_t i = 0; i < text.size();) {
    const char ch = text[i];
    if (ch == '\n') {
      ++line;
      line_start = i + 1;
      if (state == State::comment || state == State::basic || state == State::literal) {
        state = State::normal;
      }
      ++i;
      continue;
    }
    if (static_cast<unsigned char>(ch) >= 0x80) {
      char32_t cp = 0;
      const std::size_t len = decode_utf8(text, i, cp);
      const std::size_t col = i - line_start + 1;
      if (state == State::comment) {
        for (std::size_t k = i; k < i + len; ++k) out[k] = ' ';
      } else if (state == State::normal) {
        if (!(cp == 0xFEFF && i == 0)) {
          throw SceneError(name + ":" + std::to_string(line) + ":" + std::to_string(col) +
                           ": non-ASCII character outside a string or comment");
        }
      } else if (toml_whitespace_test_is_undefined(cp)) {
        char hex[16];
        std::snprintf(hex, sizeof hex, "U+%04X", static_cast<unsigned>(cp));
        throw SceneError(name + ":" + std::to_string(line) + ":" + std::to_string(col) +
                         ": character " + hex +
                         " in a string is not supported (use ASCII in scene strings)");
      }
      i += len;
      continue;
    }
    switch (state) {
      case State::normal:
        if (ch == '#')
          state = State::comment;
        else if (starts(i, "\"\"\"")) {
          state = State::ml_basic;
          i += 3;
          continue;
        } else if (starts(i, "'''")) {
          state = State::ml_literal;
          i += 3;
          continue;
        } else if (ch == '"')
          state = State::basic;
        else if (ch == '\'')
          state = State::literal;
        break;
      case State::basic:
        if (ch == '\\') {
          i += escape_length(i);
          continue;
        }
        if (ch == '"') state = State::normal;
        break;
      case State::ml_basic:
        if (ch == '\\') {
          i += escape_length(i);
          continue;
        }
        if (starts(i, "\"\"\"")) {
          state = State::normal;
          i += 3;
          continue;
        }
        break;
      case State::literal:
        if (ch == '\'') state = State::normal;
        break;
      case State::ml_literal:
        if (starts(i, "'''")) {
          state = State::normal;
          i += 3;
          continue;
        }
        break;
      case State::comment:
        break;
    }
    ++i;
  }
  return out;
}

}  // namespace

bool Range::contains(double v) const {
  const bool lo_ok = min_open ? v > min : v >= min;
  const bool hi_ok = max_open ? v < max : v <= max;
  return lo_ok && hi_ok;
}

std::string Range::describe() const {
  const bool has_lo = min > -1e307;
  const bool has_hi = max < 1e307;
  if (!has_lo && !has_hi) return "any finite number";
  if (!has_hi) return std::string(min_open ? "> " : ">= ") + format_number(min);
  if (!has_lo) return std::string(max_open ? "< " : "<= ") + format_number(max);
  return std::string(min_open ? "(" : "[") + format_number(min) + ", " + format_number(max) +
         (max_open ? ")" : "]");
}

std::size_t key_distance(std::string_view a, std::string_view b) {
  auto lower = [](char c) { return static_cast<char>(std::tolower(static_cast<unsigned char>(c))); };
  const std::size_t n = a.size(), m = b.size();
  std::vector<std::vector<std::size_t>> d(n + 1, std::vector<std::size_t>(m + 1, 0));
  for (std::size_t i = 0; i <= n; ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= m; ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= n; ++i) {
    for (std::size_t j = 1; j <= m; ++j) {
      const std::size_t cost = lower(a[i - 1]) == lower(b[j - 1]) ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && lower(a[i - 1]) == lower(b[j - 2]) &&
          lower(a[i - 2]) == lower(b[j - 1])) {
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
      }
    }
  }
  return d[n][m];
}

bool is_misspelling(std::string_view written, std::string_view known) {
  if (written == known) return false;
  // No key is this long, and the distance table is quadratic in the lengths (a fuzzed key).
  if (written.size() > 64 || known.size() > 64) return false;
  const std::size_t longer = std::max(written.size(), known.size());
  if (longer - std::min(written.size(), known.size()) > 3) return false;
  const std::size_t dist = key_distance(written, known);
  if (known.size() <= 2) {
    // Too short for a distance to mean anything ('a' and 'b'): only a key that contains it,
    // in any case ('dtt', 'DT'), counts.
    auto lower = [](std::string_view s) {
      std::string l(s);
      for (char& c : l) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      return l;
    };
    return dist <= 1 && lower(written).find(lower(known)) != std::string::npos;
  }
  const std::size_t limit = known.size() <= 5 ? 1 : known.size() <= 9 ? 2 : 3;
  return dist <= limit;
}

Table::Table(const toml::table* table, std::shared_ptr<const std::string> file, std::string path,
             std::shared_ptr<const std::vector<Override>> overrides)
    : table_(table),
      file_(std::move(file)),
      path_(std::move(path)),
      used_(std::make_shared<std::set<std::string, std::less<>>>()),
      overrides_(std::move(overrides)),
      asked_(std::make_shared<std::set<std::string, std::less<>>>()) {}

std::string Table::full_key(std::string_view key) const {
  return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
}

const Override* Table::override_of(const std::string& full) const {
  if (!overrides_) return nullptr;
  auto within = [](const std::string& inner, const std::string& outer) {
    return inner.size() > outer.size() && inner.compare(0, outer.size(), outer) == 0 &&
           (inner[outer.size()] == '.' || inner[outer.size()] == '[');
  };
  // The last override of a key is the one in effect.
  for (auto o = overrides_->rbegin(); o != overrides_->rend(); ++o) {
    if (o->key == full || within(full, o->key)) return &*o;
    if (o->key.size() > full.size() && o->key.compare(0, full.size(), full) == 0 &&
        o->key[full.size()] == '[') {
      return &*o;  // an entry of this array was set
    }
  }
  return nullptr;
}

std::string Table::where(std::string_view key) const {
  const std::string full = full_key(key);
  if (const Override* o = override_of(full)) {
    // Its line would be that of the override's text, not of the file.
    return *file_ + ": key '" + full + "' (from " + o->text() + ")";
  }
  const toml::node* n = table_ ? table_->get(key) : nullptr;
  const auto& src = n ? n->source() : table_->source();
  std::ostringstream s;
  s << *file_;
  if (src.begin.line > 0) s << ":" << src.begin.line << ":" << src.begin.column;
  s << ": key '" << full << "'";
  return s.str();
}

void Table::fail(std::string_view key, const std::string& message) const {
  throw SceneError(where(key) + ": " + message);
}

const std::vector<Override>& Table::overrides() const {
  static const std::vector<Override> none;
  return overrides_ ? *overrides_ : none;
}

bool Table::has(std::string_view key) const {
  asked_->emplace(key);
  return table_->contains(key);
}

const toml::node* Table::get(std::string_view key) const {
  asked_->emplace(key);
  const toml::node* n = table_->get(key);
  if (n) used_->emplace(key);
  return n;
}

const toml::node& Table::require(std::string_view key) const {
  const toml::node* n = get(key);
  if (!n) fail_missing(key);
  return *n;
}

void Table::fail_missing(std::string_view key, const std::string& hint) const {
  // A present key that no reader has asked for and that is spelt like the missing one is
  // almost surely it, misspelt: name both, so the user need not guess.
  std::string best;
  std::size_t best_distance = 0;
  for (const auto& [k, v] : *table_) {
    const std::string name(k.str());
    if (asked_->contains(name) || !is_misspelling(name, key)) continue;
    const std::size_t d = key_distance(name, key);
    if (best.empty() || d < best_distance) best = name, best_distance = d;
  }
  std::string message = "is required but missing";
  if (!hint.empty()) message += " (" + hint + ")";
  if (!best.empty()) {
    const auto line = table_->get(best)->source().begin.line;
    message += "; this table has '" + best + "'" +
               (line > 0 ? " (line " + std::to_string(line) + ")" : std::string()) +
               ", which is not a known key here: did you mean '" + std::string(key) + "'?";
  }
  fail(key, message);
}

double Table::as_finite(std::string_view key, const toml::node& n, Range range) const {
  double v = 0.0;
  if (auto i = n.value_exact<std::int64_t>()) {
    v = static_cast<double>(*i);
  } else if (auto d = n.value_exact<double>()) {
    v = *d;
  } else {
    fail(key, "must be a number, found " + type_name(n));
  }
  if (!std::isfinite(v)) fail(key, "must be finite, found " + format_number(v));
  if (!range.contains(v)) {
    fail(key, "is " + format_number(v) + ", outside the accepted range " + range.describe());
  }
  return v;
}

double Table::number(std::string_view key, Range range) const {
  return as_finite(key, require(key), range);
}

double Table::number(std::string_view key, double fallback, Range range) const {
  const toml::node* n = get(key);
  return n ? as_finite(key, *n, range) : fallback;
}

std::int64_t Table::integer(std::string_view key, std::int64_t lo, std::int64_t hi) const {
  const toml::node& n = require(key);
  auto i = n.value_exact<std::int64_t>();
  if (!i) fail(key, "must be an integer, found " + type_name(n));
  if (*i < lo || *i > hi) {
    fail(key, "is " + std::to_string(*i) + ", outside the accepted range [" + std::to_string(lo) +
                  ", " + std::to_string(hi) + "]");
  }
  return *i;
}

std::int64_t Table::integer(std::string_view key, std::int64_t fallback, std::int64_t lo,
                            std::int64_t hi) const {
  return has(key) ? integer(key, lo, hi) : fallback;
}

bool Table::boolean(std::string_view key) const {
  const toml::node& n = require(key);
  auto b = n.value_exact<bool>();
  if (!b) fail(key, "must be true or false, found " + type_name(n));
  return *b;
}

bool Table::boolean(std::string_view key, bool fallback) const {
  return has(key) ? boolean(key) : fallback;
}

std::string Table::string(std::string_view key) const {
  const toml::node& n = require(key);
  auto s = n.value_exact<std::string>();
  if (!s) fail(key, "must be a string, found " + type_name(n));
  return *s;
}

std::string Table::string(std::string_view key, std::string_view fallback) const {
  return has(key) ? string(key) : std::string(fallback);
}

std::string Table::choice(std::string_view key,
                          std::initializer_list<std::string_view> choices) const {
  std::string s = string(key);
  for (auto c : choices) {
    if (c == s) return s;
  }
  std::string list;
  for (auto c : choices)
    list += (list.empty() ? "" : ", ") + std::string("\"") + std::string(c) + "\"";
  fail(key, "is \"" + s + "\", accepted: " + list);
}

std::string Table::choice(std::string_view key, std::string_view fallback,
                          std::initializer_list<std::string_view> choices) const {
  return has(key) ? choice(key, choices) : std::string(fallback);
}

std::vector<double> Table::numbers(std::string_view key, std::size_t size, Range range) const {
  const toml::node& n = require(key);
  const toml::array* a = n.as_array();
  if (!a) fail(key, "must be an array of numbers, found " + type_name(n));
  if (size != 0 && a->size() != size) {
    fail(key, "must have " + std::to_string(size) + " entries, found " + std::to_string(a->size()));
  }
  if (a->empty()) fail(key, "must not be empty");
  std::vector<double> out;
  out.reserve(a->size());
  for (const toml::node& e : *a) out.push_back(as_finite(key, e, range));
  return out;
}

std::vector<std::vector<double>> Table::number_rows(std::string_view key, std::size_t row_size,
                                                    Range range) const {
  const toml::node& n = require(key);
  const toml::array* a = n.as_array();
  if (!a) fail(key, "must be an array of arrays of numbers, found " + type_name(n));
  if (a->empty()) fail(key, "must not be empty");
  std::vector<std::vector<double>> out;
  for (std::size_t r = 0; r < a->size(); ++r) {
    const toml::array* row = a->get(r)->as_array();
    if (!row) fail(key, "entry " + std::to_string(r) + " must be an array of numbers");
    if (row->empty() || (row_size != 0 && row->size() != row_size)) {
      fail(key, "entry " + std::to_string(r) + " must have " +
                    (row_size ? std::to_string(row_size) : std::string("at least one")) +
                    " entries, found " + std::to_string(row->size()));
    }
    std::vector<double> v;
    for (const toml::node& e : *row) v.push_back(as_finite(key, e, range));
    out.push_back(std::move(v));
  }
  return out;
}

std::vector<std::string> Table::strings(std::string_view key) const {
  const toml::node& n = require(key);
  const toml::array* a = n.as_array();
  if (!a) fail(key, "must be an array of strings, found " + type_name(n));
  if (a->empty()) fail(key, "must not be empty");
  std::vector<std::string> out;
  for (const toml::node& e : *a) {
    auto s = e.value_exact<std::string>();
    if (!s) fail(key, "must be an array of strings, found an entry that is " + type_name(e));
    out.push_back(*s);
  }
  return out;
}

std::array<double, 3> Table::vec3(std::string_view key, Range range) const {
  auto v = numbers(key, 3, range);
  return {v[0], v[1], v[2]};
}

std::array<double, 3> Table::vec3(std::string_view key, std::array<double, 3> fallback,
                                  Range range) const {
  return has(key) ? vec3(key, range) : fallback;
}

std::filesystem::path Table::path(std::string_view key) const {
  std::filesystem::path p = string(key);
  if (p.empty()) fail(key, "must not be empty");
  if (p.is_absolute()) return p;
  return std::filesystem::path(*file_).parent_path() / p;
}

std::optional<Table> Table::table(std::string_view key) const {
  const toml::node* n = get(key);
  if (!n) return std::nullopt;
  const toml::table* t = n->as_table();
  if (!t) fail(key, "must be a table, found " + type_name(*n));
  return Table(t, file_, full_key(key), overrides_);
}

Table Table::required_table(std::string_view key) const {
  auto t = table(key);
  if (!t) fail_missing(key);
  return *t;
}

std::vector<Table> Table::tables(std::string_view key) const {
  std::vector<Table> out;
  const toml::node* n = get(key);
  if (!n) return out;
  const toml::array* a = n->as_array();
  if (!a) fail(key, "must be an array of tables ([[" + full_key(key) + "]])");
  for (std::size_t i = 0; i < a->size(); ++i) {
    const toml::table* t = a->get(i)->as_table();
    if (!t) fail(key, "entry " + std::to_string(i) + " must be a table");
    out.emplace_back(t, file_, full_key(key) + "[" + std::to_string(i) + "]", overrides_);
  }
  return out;
}

void Table::skip(std::string_view key) const {
  asked_->emplace(key);
  if (table_->contains(key)) used_->emplace(key);
}

void Table::finish() const {
  for (const auto& [k, v] : *table_) {
    if (used_->contains(k.str())) continue;
    // The closest key the reader asked for, when the unknown one looks like a misspelling.
    std::string best;
    std::size_t best_distance = 0;
    for (const auto& known : *asked_) {
      if (!is_misspelling(k.str(), known)) continue;
      const std::size_t d = key_distance(k.str(), known);
      if (best.empty() || d < best_distance) best = known, best_distance = d;
    }
    fail(k.str(), "is not a known key here (misspelt, or not accepted in this section)" +
                      (best.empty() ? std::string() : ": did you mean '" + best + "'?"));
  }
}

Document Document::load(const std::filesystem::path& file, const std::vector<Override>& overrides) {
  std::string text;
  try {
    text = io::read_regular_file(file, io::kSceneFileLimit, "a scene file (TOML)");
  } catch (const io::InputFileError& e) {
    throw SceneError(e.what());
  }
  Document d = parse(text, file.string(), overrides);
  d.file_ = file;
  return d;
}

Document Document::parse(std::string_view text, const std::string& name,
                         const std::vector<Override>& overrides) {
  Document d;
  d.file_ = name;
  try {
    const std::string safe = sanitise_for_toml(text, name);
    d.tree_ = std::make_shared<toml::table>(toml::parse(safe, name));
  } catch (const toml::parse_error& e) {
    std::ostringstream s;
    s << name << ":" << e.source().begin.line << ":" << e.source().begin.column
      << ": TOML syntax error: " << e.description();
    throw SceneError(s.str());
  }
  // Overrides go in here, before anyone reads a table, so that every reader of every process
  // sees the same scene. One under a prefix of [dem.load] pass whose table or array entry this
  // scene lacks is for the prepare scene only (a bed's rock shapes in a sweep of the load
  // case): it is kept in the list (passed on, hashed) but not applied here.
  std::vector<std::string> pass;
  if (const auto* list = d.tree_->at_path("dem.load.pass").as_array()) {
    for (const auto& e : *list)
      if (const auto* str = e.as_string()) pass.push_back(str->get());
  }
  for (const Override& o : overrides) {
    if (std::any_of(pass.begin(), pass.end(), [&](const std::string& p) { return o.under(p); }) &&
        !detail::override_target_exists(*d.tree_, o, name))
      continue;
    toml::table value;
    try {
      value = toml::parse(sanitise_for_toml("value = " + o.value, o.text()), o.text());
    } catch (const toml::parse_error& e) {
      throw SceneError(name + ": " + o.text() + ": VALUE is not a TOML value (" +
                       std::string(e.description()) +
                       "); strings need quotes, e.g. --set dem.backend='\"cuda\"'");
    } catch (const SceneError& e) {
      throw SceneError(name + ": " + e.what());
    }
    if (value.size() != 1 || !value.contains("value")) {
      throw SceneError(name + ": " + o.text() + ": VALUE must be one TOML value");
    }
    detail::assign_override(*d.tree_, o, std::move(*value.get("value")), name);
  }
  d.overrides_ = std::make_shared<const std::vector<Override>>(overrides);
  return d;
}

Table Document::root() const {
  return Table(tree_.get(), std::make_shared<const std::string>(file_.string()), "", overrides_);
}

std::string Document::canonical_text() const {
  std::ostringstream s;
  s << toml::toml_formatter{*tree_};  // tables are ordered by key
  return s.str();
}

namespace {

// run.name becomes a folder (out/<name>) and part of file names: one path component of
// ordinary characters, so that "../../x" or "a/b" cannot write outside out/.
void check_run_name(const Table& run, const std::string& name) {
  constexpr std::size_t kMaxLength = 128;
  const char* rule =
      " (accepted: 1 to 128 letters, digits and . _ - + = , @, not starting with '.' or '-'; "
      "to write elsewhere set run.output_dir or --output-dir)";
  if (name.size() > kMaxLength) run.fail("name", "is longer than 128 bytes" + std::string(rule));
  if (name.front() == '.' || name.front() == '-') {
    run.fail("name", "'" + name + "' starts with '" + name.substr(0, 1) + "'" + rule);
  }
  for (const char ch : name) {
    const auto c = static_cast<unsigned char>(ch);
    const bool ok = c >= 0x80 || std::isalnum(c) != 0 || std::strchr("._-+=,@", c) != nullptr;
    if (!ok) {
      std::string shown = c >= 0x20 && c < 0x7f ? std::string("'") + ch + "'" : "a control code";
      if (c == '/' || c == '\\') shown += " (a path separator)";
      run.fail("name", "'" + name + "' contains " + shown + rule);
    }
  }
}

}  // namespace

RunSettings read_run_settings(const Document& scene) {
  Table root = scene.root();
  Table run = root.required_table("run");
  RunSettings s;
  s.name = run.string("name", scene.file().stem().string());
  if (s.name.empty()) run.fail("name", "must not be empty");
  if (run.has("name")) check_run_name(run, s.name);
  s.end_time = run.number("end_time", Range::positive());
  s.end_time_where = run.where("end_time");
  s.output_dir = run.has("output_dir") ? std::filesystem::path(run.string("output_dir"))
                                       : std::filesystem::path("out") / s.name;
  s.seed = static_cast<std::uint64_t>(run.integer("seed", 1, 0, INT64_MAX));
  s.output_interval = run.number("output_interval", 0.0, Range::non_negative());
  s.peer_timeout = run.number("peer_timeout", s.peer_timeout, Range::closed(0.2, 3600.0));
  run.finish();
  for (auto section : kSceneSections) root.skip(section);
  root.finish();
  return s;
}

void check_step_count(const RunSettings& run, double dt, const std::string& dt_where, double limit,
                      const std::string& solver) {
  const double steps = run.end_time / dt;
  if (steps <= limit) return;  // NaN (an unset dt) is refused too
  char text[256];
  std::snprintf(text, sizeof text,
                " = %.6g s and %s = %.6g s make %.3g %s steps; at most %.3g are accepted. "
                "Lower run.end_time or raise the time step (both in seconds)",
                run.end_time, dt_where.c_str(), dt, steps, solver.c_str(), limit);
  throw SceneError(run.end_time_where + text);
}

}  // namespace demfem::scene
