#include "inp_deck.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <sstream>

#include "demfem/io/input_file.hpp"

namespace demfem::fem::inp {

std::optional<std::string> Keyword::param(std::string_view key) const {
  for (const auto& [k, v] : params) {
    if (k == key) return v;
  }
  return std::nullopt;
}

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

std::string trim(std::string_view s) {
  std::size_t b = 0;
  std::size_t e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1]))) --e;
  return std::string(s.substr(b, e - b));
}

std::vector<std::string> split_commas(std::string_view line) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= line.size()) {
    const std::size_t comma = line.find(',', start);
    const std::size_t end = comma == std::string_view::npos ? line.size() : comma;
    out.push_back(trim(line.substr(start, end - start)));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  if (!out.empty() && out.back().empty()) out.pop_back();
  return out;
}

bool ends_with_comma(std::string_view line) {
  const std::string t = trim(line);
  return !t.empty() && t.back() == ',';
}

bool is_keyword(const std::string& t) {
  return !t.empty() && t[0] == '*';
}

bool looks_numeric(const std::string& token) {
  return !token.empty() &&
         (std::isdigit(static_cast<unsigned char>(token[0])) || token[0] == '-' || token[0] == '+');
}

bool is_label_token(const std::string& token) {
  if (looks_numeric(token)) return true;
  const auto dot = token.rfind('.');
  return dot != std::string::npos && looks_numeric(token.substr(dot + 1));
}

Deck::Deck(const std::string& text, const std::string& name, bool allow_include)
    : allow_include_(allow_include) {
  files_.push_back(name);
  std::vector<std::string> stack;
  std::error_code ec;
  const auto canonical = std::filesystem::weakly_canonical(name, ec);
  stack.push_back(ec ? name : canonical.string());
  bytes_ = text.size();
  add_text(text, 0, 0, stack);
}

std::string Deck::where(Loc loc) const {
  return files_[static_cast<std::size_t>(loc.file)] + ":" + std::to_string(loc.line);
}

void Deck::fail(Loc loc, const std::string& message) const {
  throw InpError(where(loc) + ": " + message);
}

void Deck::add_text(const std::string& text, std::int32_t file, int depth,
                    std::vector<std::string>& stack) {
  std::istringstream in(text);
  std::string s;
  std::int32_t n = 0;
  while (std::getline(in, s)) {
    ++n;
    if (!s.empty() && s.back() == '\r') s.pop_back();
    std::string t = trim(s);
    if (t.empty() || t.rfind("**", 0) == 0) continue;  // blank or comment
    // *INCLUDE is expanded where it stands, as Abaqus does.
    if (is_keyword(t)) {
      std::string head = upper(trim(std::string_view(t).substr(1, t.find(',') - 1)));
      std::string compact;
      for (char c : head)
        if (!std::isspace(static_cast<unsigned char>(c))) compact += c;
      if (compact == "INCLUDE") {
        include(t, {file, n}, depth, stack);
        continue;
      }
    }
    lines_.push_back({std::move(t), {file, n}});
  }
}

void Deck::include(const std::string& line, Loc loc, int depth, std::vector<std::string>& stack) {
  if (!allow_include_) fail(loc, "*INCLUDE is not available here (no file access)");
  std::string input;
  for (const auto& part : split_commas(std::string_view(line).substr(1))) {
    const auto eq = part.find('=');
    if (eq == std::string::npos) continue;
    if (upper(trim(part.substr(0, eq))) == "INPUT") input = trim(part.substr(eq + 1));
  }
  if (input.size() >= 2 && (input.front() == '"' || input.front() == '\'') &&
      input.back() == input.front())
    input = input.substr(1, input.size() - 2);
  if (input.empty()) fail(loc, "*INCLUDE needs INPUT=<file>");
  if (depth + 1 > kInpIncludeDepth) {
    fail(loc, "*INCLUDE nested deeper than " + std::to_string(kInpIncludeDepth) +
                  " files (a chain of includes that never ends?)");
  }
  // Relative to the including file's folder (CalculiX's rule; Abaqus uses the job folder,
  // which is the same for decks that include files next to them).
  std::filesystem::path path(input);
  if (path.is_relative()) {
    path = std::filesystem::path(files_[static_cast<std::size_t>(loc.file)]).parent_path() / path;
  }
  std::error_code ec;
  const auto canonical = std::filesystem::weakly_canonical(path, ec);
  const std::string key = ec ? path.lexically_normal().string() : canonical.string();
  for (const auto& open : stack) {
    if (open == key) {
      fail(loc, "*INCLUDE of " + path.string() +
                    " includes itself (directly or through other files): a cycle");
    }
  }
  std::string text;
  try {
    text = io::read_regular_file(path, io::kMeshFileLimit, "an Abaqus input file (.inp)");
  } catch (const io::InputFileError& e) {
    fail(loc, std::string("*INCLUDE: ") + e.what());
  }
  bytes_ += text.size();
  if (bytes_ > io::kMeshFileLimit) {
    fail(loc, "*INCLUDE: the deck and its included files hold more than " +
                  io::describe_size(io::kMeshFileLimit) + " together");
  }
  files_.push_back(path.string());
  stack.push_back(key);
  add_text(text, static_cast<std::int32_t>(files_.size() - 1), depth + 1, stack);
  stack.pop_back();
}

Keyword Deck::keyword(std::size_t i, std::size_t& next) const {
  std::string text = lines_[i].text;
  next = i + 1;
  while (ends_with_comma(text) && next < lines_.size() && !is_keyword(lines_[next].text)) {
    text += lines_[next].text;
    ++next;
  }
  Keyword kw;
  kw.loc = lines_[i].loc;
  auto parts = split_commas(std::string_view(text).substr(1));
  if (parts.empty() || parts[0].empty()) fail(kw.loc, "empty keyword");
  {
    std::string name;
    std::istringstream words(upper(parts[0]));
    std::string w;
    while (words >> w) name += (name.empty() ? "" : " ") + w;
    kw.name = name;
  }
  for (std::size_t p = 1; p < parts.size(); ++p) {
    if (parts[p].empty()) continue;
    const auto eq = parts[p].find('=');
    std::string key;
    {
      std::istringstream words(upper(trim(parts[p].substr(0, eq))));
      std::string w;
      while (words >> w) key += (key.empty() ? "" : " ") + w;
    }
    std::string value = eq == std::string::npos ? "" : trim(parts[p].substr(eq + 1));
    if (value.size() >= 2 && value.front() == '"' && value.back() == '"') {
      value = value.substr(1, value.size() - 2);
    }
    kw.params.emplace_back(std::move(key), std::move(value));
  }
  return kw;
}

double Deck::number(const std::string& token, Loc loc, const std::string& what) const {
  if (token.empty()) fail(loc, what + " is missing");
  const char* begin = token.c_str();
  char* end = nullptr;
  const double v = std::strtod(begin, &end);
  if (end == begin || *end != '\0') fail(loc, what + " '" + token + "' is not a number");
  if (!std::isfinite(v)) fail(loc, what + " is " + token + ", not a finite number");
  return v;
}

std::int64_t Deck::label(const std::string& token, Loc loc, const std::string& what) const {
  std::int64_t v = 0;
  const auto* b = token.data();
  const auto* e = token.data() + token.size();
  auto [ptr, ec] = std::from_chars(b, e, v);
  if (token.empty() || ec != std::errc() || ptr != e) {
    fail(loc, what + " '" + token + "' is not an integer label");
  }
  if (v <= 0) fail(loc, what + " " + token + " must be a positive label");
  return v;
}

}  // namespace demfem::fem::inp
