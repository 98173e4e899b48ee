#pragma once
// Strict reading of TOML scene files. Every value is checked on the way in: its type, that
// it is finite, and its range; a key nobody read is an error. Every message names the file,
// the line and the full dotted key, so a user can fix a scene without reading code.

#include <array>
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <memory>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace toml {
inline namespace v3 {
class table;
class node;
}  // namespace v3
}  // namespace toml

namespace demfem::scene {

/// @brief Error in a scene file; what() names file, line and key.
class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// @brief An accepted interval for a number; open or closed at each end.
struct Range {
  double min = -1e308;
  double max = 1e308;
  bool min_open = false;
  bool max_open = false;

  static Range any() { return {}; }
  static Range positive() { return {0.0, 1e308, true, false}; }
  static Range non_negative() { return {0.0, 1e308, false, false}; }
  static Range closed(double lo, double hi) { return {lo, hi, false, false}; }
  static Range open_closed(double lo, double hi) { return {lo, hi, true, false}; }
  bool contains(double v) const;
  std::string describe() const;
};

/// @brief A scene key set from the command line (`demfem run --set KEY=VALUE`, passed on to
/// the solvers): KEY is a dotted scene key whose segments may carry array indices
/// (`dem.pairs[0].friction`, `dem.gravity[2]`), VALUE a TOML value (`0.3`, `"cuda"`, `true`,
/// `[0, 0, -9.81]`, `{ kind = "constant", diameter = 0.02 }`). docs/scenes.md, "Overriding keys".
struct Override {
  std::string key;
  std::string value;

  /// Splits "KEY=VALUE" at the first '='; throws SceneError naming the text when there is
  /// none or either side is empty.
  static Override parse(std::string_view assignment);
  /// "--set KEY=VALUE", as messages name it.
  std::string text() const { return "--set " + key + "=" + value; }
  /// Whether the key is `prefix` or lies below it ("dem.pairs" covers
  /// "dem.pairs[0].friction"; "dem.pair" does not).
  bool under(std::string_view prefix) const;
};

/// @brief One TOML table of a scene, with its file and dotted path, that tracks which keys
/// were read so that finish() can reject unknown ones.
class Table {
 public:
  Table(const toml::table* table, std::shared_ptr<const std::string> file, std::string path,
        std::shared_ptr<const std::vector<Override>> overrides = nullptr);

  bool has(std::string_view key) const;

  double number(std::string_view key, Range range = Range::any()) const;
  double number(std::string_view key, double fallback, Range range = Range::any()) const;
  std::int64_t integer(std::string_view key, std::int64_t lo, std::int64_t hi) const;
  std::int64_t integer(std::string_view key, std::int64_t fallback, std::int64_t lo,
                       std::int64_t hi) const;
  bool boolean(std::string_view key) const;
  bool boolean(std::string_view key, bool fallback) const;
  std::string string(std::string_view key) const;
  std::string string(std::string_view key, std::string_view fallback) const;
  /// A string that must be one of `choices`.
  std::string choice(std::string_view key, std::initializer_list<std::string_view> choices) const;
  std::string choice(std::string_view key, std::string_view fallback,
                     std::initializer_list<std::string_view> choices) const;
  std::array<double, 3> vec3(std::string_view key, Range range = Range::any()) const;
  std::array<double, 3> vec3(std::string_view key, std::array<double, 3> fallback,
                             Range range = Range::any()) const;
  /// An array of numbers; `size` 0 accepts any non-empty length.
  std::vector<double> numbers(std::string_view key, std::size_t size = 0,
                              Range range = Range::any()) const;
  /// An array of rows of numbers ([[t, f], [t, f], ...]); each row has `row_size` entries
  /// (0 = any non-empty length), at least one row.
  std::vector<std::vector<double>> number_rows(std::string_view key, std::size_t row_size = 0,
                                               Range range = Range::any()) const;
  /// A non-empty array of strings.
  std::vector<std::string> strings(std::string_view key) const;
  /// A path, resolved relative to the scene file's folder.
  std::filesystem::path path(std::string_view key) const;

  std::optional<Table> table(std::string_view key) const;
  Table required_table(std::string_view key) const;
  std::vector<Table> tables(std::string_view key) const;  ///< array of tables ([[key]])

  /// Marks a key as handled elsewhere (a section another process reads), so finish() accepts it.
  void skip(std::string_view key) const;

  /// Throws for any key of this table that was never read.
  void finish() const;

  /// "file:line:col: key 'a.b.c'" for messages about a key of this table.
  std::string where(std::string_view key) const;
  [[noreturn]] void fail(std::string_view key, const std::string& message) const;
  /// Throws "is required but missing" (+ " (" hint ")"), naming a present key that nothing
  /// has read and whose spelling is close to `key` (a misspelling of it), when there is one.
  [[noreturn]] void fail_missing(std::string_view key, const std::string& hint = {}) const;

  const std::string& file() const { return *file_; }
  const std::string& dotted_path() const { return path_; }
  /// The --set overrides applied to the document this table belongs to, in order.
  const std::vector<Override>& overrides() const;

 private:
  const toml::node* get(std::string_view key) const;
  const toml::node& require(std::string_view key) const;
  std::string full_key(std::string_view key) const;
  double as_finite(std::string_view key, const toml::node& n, Range range) const;
  /// The override that set this key, or set a value containing it, or an element of it.
  const Override* override_of(const std::string& full) const;

  const toml::table* table_;
  std::shared_ptr<const std::string> file_;
  std::string path_;
  mutable std::shared_ptr<std::set<std::string, std::less<>>> used_;
  std::shared_ptr<const std::vector<Override>> overrides_;
  /// Every key a reader asked for, present or not: the known keys, for suggestions.
  mutable std::shared_ptr<std::set<std::string, std::less<>>> asked_;
};

/// @brief Edit distance of two keys (optimal string alignment: insertions, deletions,
/// substitutions and transpositions of neighbours each count 1; case is ignored).
std::size_t key_distance(std::string_view a, std::string_view b);

/// @brief Whether `written` is plausibly a misspelling of `known`: a distance of at most 1
/// for keys up to 5 characters, 2 up to 9, 3 beyond; keys of 1 or 2 characters only match
/// a written key that contains them (so that 'a' does not suggest 'b'); keys longer than 64
/// characters never match.
bool is_misspelling(std::string_view written, std::string_view known);

/// @brief A parsed scene file; keeps the TOML tree alive for its Tables.
class Document {
 public:
  /// Parses `file`, then applies `overrides` in order (a later one wins) before any table
  /// is read; throws SceneError naming the file and line on a syntax error or when the file
  /// cannot be read, and naming the override when one is malformed or names a table or array
  /// entry the scene does not have (an override may add a key to an existing table, never
  /// create a table). Messages about an overridden key say "(from --set KEY=VALUE)".
  static Document load(const std::filesystem::path& file,
                       const std::vector<Override>& overrides = {});
  static Document parse(std::string_view text, const std::string& name,
                        const std::vector<Override>& overrides = {});

  Table root() const;
  /// The scene as TOML in one canonical form (keys sorted, comments, layout and number
  /// spelling dropped, overrides applied): equal for two scenes with the same content.
  std::string canonical_text() const;
  const std::filesystem::path& file() const { return file_; }
  const std::vector<Override>& overrides() const { return *overrides_; }

 private:
  std::filesystem::path file_;
  std::shared_ptr<toml::table> tree_;
  std::shared_ptr<const std::vector<Override>> overrides_ =
      std::make_shared<const std::vector<Override>>();
};

/// @brief The [run] section every process reads: what the run is called, how long it runs
/// and where its output goes.
struct RunSettings {
  std::string name;                    ///< run.name (default: the scene file's stem)
  double end_time = 0.0;               ///< run.end_time, s, > 0
  std::string end_time_where;          ///< "file:line:col: key 'run.end_time'", for messages
  std::filesystem::path output_dir;    ///< run.output_dir (default "out/<name>", relative to
                                       ///< the current directory)
  std::uint64_t seed = 1;              ///< run.seed, for random insertion
  double output_interval = 0.0;        ///< run.output_interval, s (0 = only the end state)
  /// run.peer_timeout, s: a process whose heartbeat has not advanced for this long is hung.
  /// Long enough that a loaded machine (a heartbeat thread not scheduled for seconds: 3.8 s
  /// measured with ten compilers on two cores) does not end a healthy run; a dead pid is
  /// found within 0.1 s regardless.
  double peer_timeout = 10.0;
};

/// @brief Reads and checks [run] (required) of a scene; the other top-level sections are
/// left for their owners, and an unknown top-level section is an error.
RunSettings read_run_settings(const Document& scene);

/// @brief Largest step counts of a run (docs/coupling.md, "Time steps"): beyond them a run
/// would not end in any useful time, and an end_time or dt typed wrong by orders of magnitude
/// (1e300, 1e-20) is refused upfront instead of overflowing a counter or never ending.
inline constexpr double kMaxDemSteps = 1e12;  ///< DEM time steps of a run
inline constexpr double kMaxFemSteps = 1e9;   ///< FEM time steps (= coupling steps) of a run

/// @brief Refuses (SceneError naming run.end_time and the dt key, with the count and the
/// limit) a run whose run.end_time / dt steps exceed `limit`. `solver`: "DEM" or "FEM".
void check_step_count(const RunSettings& run, double dt, const std::string& dt_where, double limit,
                      const std::string& solver);

/// @brief Top-level sections a scene may have.
inline constexpr std::string_view kSceneSections[] = {"run", "dem", "fem", "coupling",
                                                      "checkpoint", "post"};

}  // namespace demfem::scene
