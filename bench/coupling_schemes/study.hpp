#pragma once
// bench/coupling_schemes (coupling_schemes.cpp says what it measures): what its parts share,
// the schemes and problems of the study, one demfem_run run and what is read from it, the
// errors and the stability criterion, the report's rows, the options.

#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "bench_report.hpp"
#include "median.hpp"

namespace demfem::bench::coupling_study {

namespace fs = std::filesystem;
using demfem::bench::Report;

inline const fs::path kSource = DEMFEM_SOURCE_DIR;
inline const fs::path kBin = fs::path(DEMFEM_BINARY_DIR) / "bin";

// ---- schemes and problems ---------------------------------------------------------------

struct Scheme {
  std::string label;         // in the table and the plots
  std::string scheme;        // coupling.scheme
  bool force_averaging;      // coupling.force_averaging
  std::string acceleration;  // implicit only
};

inline const std::vector<Scheme> kSchemes = {
    {"just_in_time", "just_in_time", false, ""},
    {"just_in_time+avg", "just_in_time", true, ""},
    {"predictive", "predictive", false, ""},
    {"predictive+avg", "predictive", true, ""},
    {"concurrent", "concurrent", false, ""},
    // The implicit ones give the FEM the last substep's force, the load at the step's end that
    // the Bossak step takes (with the mean force, eq. 3.8, problem a's error at dt_F = 1e-4 s
    // was 12 % instead of 10 %).
    {"implicit-aitken", "implicit", false, "aitken"},
    {"implicit-iqn", "implicit", false, "iqn-ils"},
};

struct Problem {
  std::string name;
  fs::path scene;
  std::array<double, 3> probe;  // the quantity of interest: u_z of the FEM node nearest to it
  double dem_dt;
  double end_time;
  double sample;                  // field output of the accuracy runs every max(dt_F, sample) s
  std::vector<double> dts;        // dt_F of the study
  std::vector<std::string> sets;  // --set overrides of every run of the problem
  // The reference by extrapolation (problem a): implicit IQN-ILS at dt_F = dt_D = each of these
  // (halving), combined by Richardson extrapolation; empty: the run at dt_F = dem_dt checked
  // by the one at 2 dem_dt.
  std::vector<double> reference_dts;
};

/// The problems of the work-precision and stability parts, from the options (--quick).
struct Problems {
  Problem beam;     // (a): the beam under the dropped slab
  Problem elastic;  // (a'): the same with elastic contacts
  Problem plate;    // (b): the plate under the bed
};
Problems study_problems(bool quick);

/// The case with [coupling] rewritten for `sc` (scene_variant.cpp).
fs::path scene_variant(const Problem& pb, const Scheme& sc, const fs::path& dir, double factor);
std::string read_text(const fs::path& p);
/// A number as %g.
std::string fmt(double v);

// ---- one run ------------------------------------------------------------------------------

struct RunResult {
  int exit = -1;
  double wall = NAN;  // s, the coupler's wall_total (timing.csv); NaN when not completed
  // s of CPU time (user + system) of the run's processes, the coupler and the solvers it
  // waited for: the work, less disturbed than the wall time by other jobs on a shared machine.
  double cpu = NAN;
  double end_time = 0.0;
  std::int64_t steps = 0, iterations = 0, max_iterations = 0, unconverged = 0;
  double max_displacement = 0.0;                // of any interface node over the run, m
  double max_energy_error = 0.0;                // |W_DEM - W_FEM|, J
  double max_work = 0.0;                        // |W_FEM|, J
  double dem_compute = 0.0, fem_compute = 0.0;  // s per step, medians
  double step_wall = 0.0;   // s per step, median of the step's wall time (solvers + coupler)
  double step_ratio = NAN;  // median over the steps of step wall / max(DEM, FEM compute)
  std::vector<double> times, probe;           // u_z at the probe node at the FEM outputs
  std::vector<double> step_times, step_umax;  // every step: time, largest |u| of any node
  std::string error_text;
};

std::vector<std::vector<std::string>> read_csv(const fs::path& p);
/// One demfem_run run of `scene` into `out` (case_run.cpp says what `fields` and the flags do).
RunResult run(const Problem& pb, const fs::path& scene, const fs::path& out,
              const std::vector<std::string>& sets, double dt, bool fields, bool overlapped = false,
              bool own_sessions = false);

// ---- errors, stability, rows ---------------------------------------------------------------

struct Stability {
  bool stable;
  std::string why;  // "", "blow-up", "growth", "energy", "failed"
};

Stability judge(const RunResult& r, const RunResult& ref);

struct Errors {
  double series = NAN;  // the probe's u_z over the run (relative_error)
  double peak = NAN;    // its largest |value| (peak_error)
};

Errors errors_of(const RunResult& r, const RunResult& ref, const Problem& pb);

/// The report's columns; add_row() writes one row of them.
extern const std::vector<std::string> kColumns;
void add_row(Report& rep, const std::string& part, const Problem& pb, const std::string& scheme,
             double dt, double density, const std::vector<double>& walls, const Errors& e,
             const RunResult& r, const Stability& s, const std::vector<double>& cpus = {});

// ---- options --------------------------------------------------------------------------------

struct Options {
  std::set<std::string> parts = {"work", "stability", "concurrency", "sheet"};
  std::set<std::string> problems = {"beam_drop", "beam_drop_elastic", "plate_bed"};
  int repeat = 3;
  bool quick = false;
  fs::path work = kSource / "out" / "bench" / "coupling_schemes_runs";
  double sheet_end = 0.6;                                    // s of flow (the case: 0.8)
  std::vector<double> sheet_dts = {1e-4, 2e-4, 5e-4, 1e-3};  // dt_F of problem (c)
  std::set<std::string> sheet_schemes;                       // empty: all
  // dt_D of problem (a)'s work-precision grid: the case's 1e-6 s (every dt_F of the grid) and
  // finer ones (dt_F from dt_D to 20 dt_D), for errors the case's dt_D cannot reach.
  std::vector<double> beam_dem_dts = {1e-6};
  std::set<std::string> schemes;  // of the work-precision part; empty: all
  std::set<double> dts;           // dt_F of the work-precision part; empty: all of its grid
  std::string json;
  bool help = false;  // --help: the usage only, nothing run
};

inline constexpr const char* kUsage =
    "Work-precision, stability and concurrency of the coupling schemes, with real demfem_run runs\n"
    "usage: coupling_schemes [--json FILE] [--parts work,stability,concurrency,sheet]\n"
    "  [--problems beam_drop,beam_drop_elastic,plate_bed] [--repeat N] [--quick] [--work DIR]\n"
    "  [--schemes LIST] [--dts LIST] [--beam-dem-dts LIST] [--sheet-end S] [--sheet-dts LIST]\n"
    "  [--sheet-schemes LIST]\n"
    "The header of bench/coupling_schemes/coupling_schemes.cpp says what each part does.\n";

Options parse(int argc, char** argv);

// ---- the references and the parts ----------------------------------------------------------

/// The converged reference: implicit IQN-ILS at dt_F = dt_D, tolerances 10 x tighter
/// (references.cpp); `check`: also at 2 dt_D, whose distance bounds its error.
RunResult reference(const Options& opt, Report& rep, const Problem& pb, const std::string& tag,
                    const std::vector<std::string>& sets, bool check = true);
/// Problem (a)'s reference by Richardson extrapolation over pb.reference_dts.
RunResult extrapolated_reference(const Options& opt, Report& rep, const Problem& pb);

void work_precision_part(const Options& opt, Report& rep, const Problems& problems);
void stability_part(const Options& opt, Report& rep, const Problems& problems);
void concurrency_part(const Options& opt, Report& rep, const Problems& problems);
void sheet_part(const Options& opt, Report& rep);

}  // namespace demfem::bench::coupling_study
