#include "scene_override.hpp"

#include <cctype>
#include <cstddef>
#include <string_view>
#include <vector>

namespace demfem::scene {

Override Override::parse(std::string_view assignment) {
  const auto eq = assignment.find('=');
  if (eq == std::string_view::npos || eq == 0 || eq + 1 == assignment.size()) {
    throw SceneError("--set " + std::string(assignment) +
                     ": expected KEY=VALUE, e.g. --set dem.pairs[0].friction=0.3");
  }
  return {std::string(assignment.substr(0, eq)), std::string(assignment.substr(eq + 1))};
}

bool Override::under(std::string_view prefix) const {
  if (key.compare(0, prefix.size(), prefix) != 0) return false;
  return key.size() == prefix.size() || key[prefix.size()] == '.' || key[prefix.size()] == '[';
}

namespace detail {

namespace {

// One dotted segment of a key: a bare TOML key and the array indices after it.
struct KeyStep {
  std::string name;
  std::vector<std::size_t> indices;
};

bool bare_key_char(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_' || c == '-';
}

std::vector<KeyStep> parse_key(const Override& o, const std::string& file) {
  auto bad = [&](const std::string& why) -> SceneError {
    return SceneError(file + ": " + o.text() + ": KEY " + why +
                      " (a dotted scene key such as dem.pairs[0].friction)");
  };
  std::vector<KeyStep> steps;
  const std::string& k = o.key;
  std::size_t i = 0;
  while (true) {
    KeyStep step;
    while (i < k.size() && bare_key_char(k[i])) step.name += k[i++];
    if (step.name.empty())
      throw bad("has an empty or non-bare segment at character " + std::to_string(i + 1));
    while (i < k.size() && k[i] == '[') {
      const std::size_t close = k.find(']', i);
      const std::string digits =
          close == std::string::npos ? std::string() : k.substr(i + 1, close - i - 1);
      if (digits.empty() || digits.size() > 9 ||
          digits.find_first_not_of("0123456789") != std::string::npos) {
        throw bad("has a malformed array index at character " + std::to_string(i + 1));
      }
      step.indices.push_back(std::stoul(digits));
      i = close + 1;
    }
    steps.push_back(std::move(step));
    if (i == k.size()) return steps;
    if (k[i] != '.')
      throw bad("has an unexpected '" + std::string(1, k[i]) + "' at character " +
                std::to_string(i + 1));
    ++i;
  }
}

}  // namespace

void assign_override(toml::table& root, const Override& o, toml::node&& value,
                     const std::string& file) {
  const std::vector<KeyStep> steps = parse_key(o, file);
  auto refuse = [&](const std::string& why) -> SceneError {
    return SceneError(file + ": " + o.text() + ": " + why);
  };
  toml::node* cur = &root;
  std::string walked;  // the dotted key of `cur`
  for (std::size_t s = 0; s < steps.size(); ++s) {
    const KeyStep& step = steps[s];
    const bool last = s + 1 == steps.size();
    toml::table* table = cur->as_table();
    if (!table) throw refuse("'" + walked + "' is not a table, it has no key '" + step.name + "'");
    const std::string name = walked.empty() ? step.name : walked + "." + step.name;
    toml::node* n = table->get(step.name);
    if (last && step.indices.empty()) {
      // A new key of an existing table is added; the solver's reader then accepts or refuses
      // it like any key of the file (naming this override).
      table->insert_or_assign(step.name, std::move(value));
      return;
    }
    if (!n) {
      throw refuse("the scene has no " + std::string(step.indices.empty() ? "table" : "array") +
                   " '" + name +
                   "' (an override sets or adds a key of an existing table; it does not create "
                   "tables or array entries: add them to the scene)");
    }
    walked = name;
    for (std::size_t j = 0; j < step.indices.size(); ++j) {
      toml::array* array = n->as_array();
      const std::size_t idx = step.indices[j];
      if (!array)
        throw refuse("'" + walked + "' is not an array, it has no entry [" + std::to_string(idx) +
                     "]");
      if (idx >= array->size()) {
        throw refuse("the scene has no '" + walked + "[" + std::to_string(idx) + "]' ('" + walked +
                     "' has " + std::to_string(array->size()) + " entries)");
      }
      walked.append(1, '[').append(std::to_string(idx)).append(1, ']');
      if (last && j + 1 == step.indices.size()) {
        array->replace(array->cbegin() + static_cast<std::ptrdiff_t>(idx), std::move(value));
        return;
      }
      n = array->get(idx);
    }
    cur = n;
  }
}

bool override_target_exists(const toml::table& root, const Override& o, const std::string& file) {
  const std::vector<KeyStep> steps = parse_key(o, file);
  const toml::node* cur = &root;
  for (std::size_t s = 0; s < steps.size(); ++s) {
    const toml::table* table = cur->as_table();
    if (!table) return false;
    if (s + 1 == steps.size() && steps[s].indices.empty()) return true;
    const toml::node* n = table->get(steps[s].name);
    if (!n) return false;
    for (const std::size_t idx : steps[s].indices) {
      const toml::array* array = n->as_array();
      if (!array || idx >= array->size()) return false;
      n = array->get(idx);
    }
    cur = n;
  }
  return true;
}

}  // namespace detail
}  // namespace demfem::scene
