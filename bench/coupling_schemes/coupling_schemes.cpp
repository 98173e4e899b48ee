// bench/coupling_schemes: the evidence for choosing a coupling scheme (issue 13,
// docs/coupling.md "Choosing a scheme"). Real three-process runs (demfem_run with dem_server
// and fem_server) of the reference problems, for every scheme and coupling step dt_F:
//
//  * work-precision: wall time (the coupler's, timing.csv) and CPU time (of the run's processes)
//    against the error of a quantity of interest (problem a: the mid-span deflection of the
//    beam under the dropped slab; problem b: the centre deflection of the plate under the bed)
//    relative to a converged reference,
//    the same problem with implicit coupling at dt_F = dt_D (problem b: shown converged by the
//    run at 2 dt_D; problem a: at three dt_F = dt_D below the case's, halving, combined by
//    Richardson extrapolation, with the observed order and the extrapolation's own error
//    printed); plus the interface energy error, the iterations, stable or not;
//  * stability map (problem b): the largest stable dt_F of each scheme against the plate's
//    density (the structure-to-particle mass ratio);
//  * concurrency: the concurrent scheme's wall time per step against max(DEM, FEM) and the
//    sequential sum, on problem a with a finer FEM mesh so that both cost about the same;
//  * problem (c), the sheet CI case (cases/sheet_ci.toml, shortened by --sheet-end): every
//    scheme at the dt_F of --sheet-dts, the error of the mean deflection at the measurement
//    position against implicit IQN-ILS at dt_F = dt_D.
//
// Unstable (a measurable criterion): the run stops with a blow-up (exit status 3: a
// non-finite state, an overlap beyond the case's bound, a DEM step past half a radius of
// overlap), or the largest displacement of any interface node over the run exceeds twice the
// reference's (spurious energy makes the response grow), or the interface energy error
// |W_DEM - W_FEM| exceeds the largest interface work of the reference (the scheme creates
// more energy than the physics moves).
//
// Output: a table on stdout, JSON (--json FILE, one row per run) and, with --plots, the PNG
// figures drawn by tools/plot_coupling_schemes.py. Options: --parts LIST (work,stability,
// concurrency,sheet; default all), --repeat N (timed repetitions of each work-precision run,
// interleaved; default 3), --quick (fewer dt_F and densities), --work DIR (run folders),
// --schemes LIST and --dts LIST (of the work-precision part: scheme labels, dt_F; default all),
// --beam-dem-dts LIST (dt_D of problem a's grid, default 1e-6), --sheet-end S (s of flow
// of problem c, default 0.6), --sheet-dts LIST, --sheet-schemes LIST.
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_report.hpp"
#include "demfem/io/h5_file.hpp"

namespace fs = std::filesystem;
using demfem::bench::Report;

namespace {

const fs::path kSource = DEMFEM_SOURCE_DIR;
const fs::path kBin = fs::path(DEMFEM_BINARY_DIR) / "bin";

// ---- schemes ------------------------------------------------------------------------------

struct Scheme {
  std::string label;         // in the table and the plots
  std::string scheme;        // coupling.scheme
  bool force_averaging;      // coupling.force_averaging
  std::string acceleration;  // implicit only
};

const std::vector<Scheme> kSchemes = {
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

// ---- problems -----------------------------------------------------------------------------

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

// The implicit keys a case sets in [coupling]; an explicit variant must not carry them.
const std::set<std::string> kImplicitKeys = {"acceleration",
                                             "max_iterations",
                                             "displacement_tolerance",
                                             "force_tolerance",
                                             "displacement_abs_tolerance",
                                             "force_abs_tolerance",
                                             "on_nonconvergence",
                                             "initial_relaxation",
                                             "reuse_steps",
                                             "max_columns",
                                             "qr_filter"};

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + p.string());
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t");
  const auto b = s.find_last_not_of(" \t\r");
  return a == std::string::npos ? "" : s.substr(a, b - a + 1);
}

// The case with [coupling] rewritten for `sc`: scheme, force averaging and acceleration set;
// the case's implicit keys kept for an implicit variant (its tolerances are the case's, or
// `factor` times them), dropped for an explicit one. Written beside the run folder `dir`; the
// problems here refer to no file by a relative path.
fs::path scene_variant(const Problem& pb, const Scheme& sc, const fs::path& dir, double factor) {
  std::istringstream in(read_text(pb.scene));
  std::ostringstream out;
  std::string line;
  bool in_coupling = false;
  while (std::getline(in, line)) {
    const std::string t = trim(line);
    if (!t.empty() && t[0] == '[') {
      in_coupling = t == "[coupling]";
      out << line << '\n';
      if (in_coupling) {
        out << "scheme = \"" << sc.scheme << "\"\n";
        out << "force_averaging = " << (sc.force_averaging ? "true" : "false") << "\n";
        if (!sc.acceleration.empty()) out << "acceleration = \"" << sc.acceleration << "\"\n";
      }
      continue;
    }
    if (in_coupling) {
      const std::string key = trim(t.substr(0, t.find('=')));
      if (key == "scheme" || key == "force_averaging" || key == "acceleration") continue;
      if (kImplicitKeys.count(key)) {
        if (sc.scheme != "implicit") continue;
        if (factor != 1.0 && (key == "displacement_tolerance" || key == "force_tolerance")) {
          const double v = std::stod(t.substr(t.find('=') + 1));
          char buf[64];
          std::snprintf(buf, sizeof buf, "%s = %.3g\n", key.c_str(), v * factor);
          out << buf;
          continue;
        }
        if (key == "reuse_steps" && sc.acceleration != "iqn-ils") continue;
      }
    }
    out << line << '\n';
  }
  fs::create_directories(dir.parent_path());
  const fs::path p = dir.string() + ".toml";
  std::ofstream(p) << out.str();
  return p;
}

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

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

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::vector<std::vector<std::string>> read_csv(const fs::path& p) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(p);
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

// `cpu`: set to the CPU time (user + system) of the child and of the children it waited for.
int spawn_and_wait(const std::vector<std::string>& args, const fs::path& log,
                   double* cpu = nullptr) {
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      ::dup2(fd, 1);
      ::dup2(fd, 2);
      ::close(fd);
    }
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(argv[0], argv.data());
    std::_Exit(127);
  }
  int st = 0;
  struct rusage ru {};
  ::wait4(pid, &st, 0, &ru);
  if (cpu)
    *cpu = static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
           1e-6 * static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
  return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

// `fields`: an accuracy run, with the FEM's field output at every max(dt_F, pb.sample) (the
// probe is read from it); otherwise a timing run, whose FEM writes only its first and last
// state, so that the wall time is the coupling's.
RunResult run(const Problem& pb, const fs::path& scene, const fs::path& out,
              const std::vector<std::string>& sets, double dt, bool fields, bool overlapped = false,
              bool own_sessions = false) {
  fs::remove_all(out);
  fs::create_directories(out.parent_path());
  std::vector<std::string> args = {(kBin / "demfem_run").string(),
                                   "--bin-dir",
                                   kBin.string(),
                                   scene.string(),
                                   "--output-dir",
                                   out.string(),
                                   "--quiet"};
  if (own_sessions) args.push_back("--solver-sessions");
  for (const auto& s : pb.sets) args.insert(args.end(), {"--set", s});
  for (const auto& s : sets) args.insert(args.end(), {"--set", s});
  args.insert(args.end(), {"--set", "fem.dt=" + fmt(dt)});
  args.insert(args.end(),
              {"--set", "run.output_interval=" + fmt(fields ? std::max(dt, pb.sample) : 0.0)});
  const fs::path log = out.string() + ".log";
  RunResult r;
  r.exit = spawn_and_wait(args, log, &r.cpu);
  // This machine is shared: a run that failed otherwise than by the scheme (a solver starved
  // of CPU for longer than the 2 s peer timeout, "heartbeat stale") is run again, twice at most.
  for (int retry = 0; retry < 2 && r.exit != 0 && r.exit != 3 &&
                      read_text(log).find("heartbeat stale") != std::string::npos;
       ++retry) {
    std::fprintf(stderr, "# %s: a solver was starved of CPU (heartbeat stale); run again\n",
                 out.filename().c_str());
    fs::remove_all(out);
    r.exit = spawn_and_wait(args, log, &r.cpu);
  }
  if (r.exit != 0) {
    const std::string text = read_text(log);
    const auto at = text.rfind("demfem run:");
    r.error_text = at == std::string::npos ? text : text.substr(at, 300);
  }
  const auto rows = read_csv(out / "coupling.csv");
  if (rows.size() > 1) {
    std::map<std::string, std::size_t> c;
    for (std::size_t k = 0; k < rows[0].size(); ++k) c[rows[0][k]] = k;
    std::vector<double> dem, fem, wall, ratio;
    for (std::size_t i = 1; i < rows.size(); ++i) {
      const auto& row = rows[i];
      auto v = [&](const char* name) { return std::stod(row.at(c.at(name))); };
      r.end_time = v("time");
      r.steps = static_cast<std::int64_t>(v("step")) + 1;
      const auto it = static_cast<std::int64_t>(v("iterations"));
      r.iterations += it;
      r.max_iterations = std::max(r.max_iterations, it);
      if (v("converged") == 0.0) ++r.unconverged;
      r.max_displacement = std::max(r.max_displacement, std::abs(v("fem_max_displacement")));
      r.max_energy_error = std::max(r.max_energy_error, std::abs(v("energy_error")));
      r.max_work = std::max(r.max_work, std::abs(v("work_fem")));
      r.step_times.push_back(v("time"));
      r.step_umax.push_back(v("fem_max_displacement"));
      dem.push_back(v("wall_dem_compute"));
      fem.push_back(v("wall_fem_compute"));
      // In the concurrent scheme both solvers are sent their step at once and wall_dem,
      // wall_fem count from there: the step took the longer of the two plus the coupler's own
      // time; otherwise the sum of all three.
      const double solvers =
          overlapped ? std::max(v("wall_dem"), v("wall_fem")) : v("wall_dem") + v("wall_fem");
      wall.push_back(solvers + v("wall_coupling"));
      ratio.push_back(wall.back() / std::max(v("wall_dem_compute"), v("wall_fem_compute")));
    }
    r.dem_compute = median(dem);
    r.fem_compute = median(fem);
    r.step_wall = median(wall);
    r.step_ratio = median(ratio);
  }
  const auto timing = read_csv(out / "timing.csv");
  if (r.exit == 0 && timing.size() == 2) r.wall = std::stod(timing[1][2]);
  if (r.exit != 0) r.cpu = NAN;
  // The probe: the FEM node nearest to pb.probe, u_z at every field output.
  if (fs::exists(out / "fem_mesh.h5") && fs::exists(out / "fem_series.csv")) {
    std::vector<std::size_t> dims;
    const auto nodes = demfem::io::H5File(out / "fem_mesh.h5", demfem::io::H5File::Mode::read)
                           .read_doubles("nodes", &dims);
    std::size_t best = 0;
    double best_d = INFINITY;
    for (std::size_t i = 0; 3 * i + 2 < nodes.size(); ++i) {
      double d = 0.0;
      for (int k = 0; k < 3; ++k) d += std::pow(nodes[3 * i + k] - pb.probe[k], 2);
      if (d < best_d) best_d = d, best = i;
    }
    const auto series = read_csv(out / "fem_series.csv");
    for (std::size_t i = 1; i < series.size(); ++i) {
      char name[32];
      std::snprintf(name, sizeof name, "fem_%06zu.h5", i - 1);
      if (!fs::exists(out / name)) break;
      const auto u = demfem::io::H5File(out / name, demfem::io::H5File::Mode::read)
                         .read_doubles("displacement");
      r.times.push_back(std::stod(series[i][0]));
      r.probe.push_back(u.at(3 * best + 2));
    }
  }
  return r;
}

// The probe's largest |w| over the run's field outputs against the reference's (the peak
// deflection under the impact, or under the bed's dynamic load).
double peak_error(const RunResult& r, const RunResult& ref) {
  double a = 0.0, b = 0.0;
  for (double v : r.probe) a = std::max(a, std::abs(v));
  for (double v : ref.probe) b = std::max(b, std::abs(v));
  return b > 0.0 ? std::abs(a - b) / b : NAN;
}

// The probe's u_z: the largest |w - w_ref| over the run's field outputs (which the reference
// has too: its outputs are every pb.sample, the run's every max(dt_F, pb.sample)), over the
// largest |w_ref|.
double relative_error(const RunResult& r, const RunResult& ref, double sample) {
  std::map<long, double> at;
  for (std::size_t i = 0; i < ref.times.size(); ++i)
    at[std::lround(ref.times[i] / sample)] = ref.probe[i];
  double err = 0.0, scale = 0.0;
  std::size_t matched = 0;
  for (double w : ref.probe) scale = std::max(scale, std::abs(w));
  for (std::size_t i = 0; i < r.times.size(); ++i) {
    const double k = r.times[i] / sample;
    if (std::abs(k - std::round(k)) > 1e-6) continue;
    const auto it = at.find(std::lround(k));
    if (it == at.end()) continue;
    err = std::max(err, std::abs(r.probe[i] - it->second));
    ++matched;
  }
  if (matched < 2 || scale == 0.0) return NAN;
  return err / scale;
}

struct Stability {
  bool stable;
  std::string why;  // "", "blow-up", "growth", "energy", "failed"
};

Stability judge(const RunResult& r, const RunResult& ref) {
  // An implicit step that did not converge stops the run with status 3 as well (the case's
  // on_nonconvergence = "stop"): told apart by the CSV's last row.
  if (r.exit == 3 && r.unconverged > 0) return {false, "no convergence"};
  if (r.exit == 3) return {false, "blow-up"};
  if (r.exit != 0) return {false, "failed"};
  if (r.max_displacement > 2.0 * ref.max_displacement) return {false, "growth"};
  if (r.max_energy_error > ref.max_work) return {false, "energy"};
  return {true, ""};
}

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

constexpr const char* kUsage =
    "usage: coupling_schemes [--json FILE] [--parts work,stability,concurrency,sheet]\n"
    "  [--problems beam_drop,beam_drop_elastic,plate_bed] [--repeat N] [--quick] [--work DIR]\n"
    "  [--schemes LIST] [--dts LIST] [--beam-dem-dts LIST] [--sheet-end S] [--sheet-dts LIST]\n"
    "  [--sheet-schemes LIST]\n"
    "Work-precision, stability and concurrency of the coupling schemes (real demfem_run runs;\n"
    "the header of bench/coupling_schemes/coupling_schemes.cpp says what each part does).\n";

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    // The value as a comma-separated list, of words or of numbers.
    auto words = [&]() {
      std::vector<std::string> v;
      std::stringstream s(next());
      std::string p;
      while (std::getline(s, p, ',')) v.push_back(p);
      return v;
    };
    auto numbers = [&]() {
      std::vector<double> v;
      for (const auto& w : words()) v.push_back(std::stod(w));
      return v;
    };
    auto word_set = [&]() {
      const auto v = words();
      return std::set<std::string>(v.begin(), v.end());
    };
    if (a == "--help" || a == "-h") {
      o.help = true;
    } else if (a == "--json") {
      o.json = next();
    } else if (a == "--parts") {
      o.parts = word_set();
    } else if (a == "--problems") {
      o.problems = word_set();
    } else if (a == "--repeat") {
      o.repeat = std::max(1, std::stoi(next()));
    } else if (a == "--quick") {
      o.quick = true;
    } else if (a == "--work") {
      o.work = next();
    } else if (a == "--sheet-end") {
      o.sheet_end = std::stod(next());
    } else if (a == "--sheet-dts") {
      o.sheet_dts = numbers();
    } else if (a == "--dts") {
      const auto v = numbers();
      o.dts = {v.begin(), v.end()};
    } else if (a == "--schemes") {
      o.schemes = word_set();
    } else if (a == "--beam-dem-dts") {
      o.beam_dem_dts = numbers();
    } else if (a == "--sheet-schemes") {
      o.sheet_schemes = word_set();
    } else {
      throw std::invalid_argument("unknown option " + a + "\n" + kUsage);
    }
  }
  return o;
}

const std::vector<std::string> kColumns = {"part",
                                           "problem",
                                           "scheme",
                                           "dt",
                                           "dem_dt",
                                           "density",
                                           "runs",
                                           "wall_median",
                                           "wall_best",
                                           "error",
                                           "peak_error",
                                           "energy_error",
                                           "work",
                                           "iterations_mean",
                                           "iterations_max",
                                           "unconverged",
                                           "max_displacement",
                                           "exit",
                                           "stable",
                                           "why",
                                           "dem_compute",
                                           "fem_compute",
                                           "step_wall",
                                           "cpu_median",
                                           "cpu_best"};

struct Errors {
  double series = NAN;  // the probe's u_z over the run (relative_error)
  double peak = NAN;    // its largest |value| (peak_error)
};

Errors errors_of(const RunResult& r, const RunResult& ref, const Problem& pb) {
  if (r.exit != 0) return {};
  return {relative_error(r, ref, pb.sample), peak_error(r, ref)};
}

void add_row(Report& rep, const std::string& part, const Problem& pb, const std::string& scheme,
             double dt, double density, const std::vector<double>& walls, const Errors& e,
             const RunResult& r, const Stability& s, const std::vector<double>& cpus = {}) {
  std::vector<double> ok, ok_cpu;
  for (double w : walls)
    if (std::isfinite(w)) ok.push_back(w);
  for (double c : cpus)
    if (std::isfinite(c)) ok_cpu.push_back(c);
  const double best = ok.empty() ? NAN : *std::min_element(ok.begin(), ok.end());
  rep.add_row({part,
               pb.name,
               scheme,
               dt,
               pb.dem_dt,
               density,
               static_cast<long long>(walls.size()),
               median(ok),
               best,
               e.series,
               e.peak,
               r.max_energy_error,
               r.max_work,
               r.steps > 0 ? static_cast<double>(r.iterations) / static_cast<double>(r.steps) : NAN,
               static_cast<long long>(r.max_iterations),
               static_cast<long long>(r.unconverged),
               r.max_displacement,
               static_cast<long long>(r.exit),
               static_cast<long long>(s.stable ? 1 : 0),
               s.why,
               r.dem_compute,
               r.fem_compute,
               r.step_wall,
               median(ok_cpu),
               ok_cpu.empty() ? NAN : *std::min_element(ok_cpu.begin(), ok_cpu.end())});
}

}  // namespace

int main(int argc, char** argv) try {
  const Options opt = parse(argc, argv);
  if (opt.help) {
    std::fputs(kUsage, stdout);
    return 0;
  }
  Report rep("coupling_schemes", kColumns);
  rep.set_info("repeat", static_cast<long long>(opt.repeat));
  rep.set_info("quick", static_cast<long long>(opt.quick ? 1 : 0));
  rep.set_info("criterion",
               std::string("unstable: exit 3 (blow-up), or max interface displacement > 2 x "
                           "reference, or max |W_DEM - W_FEM| > max |W_FEM| of the reference"));
  fs::create_directories(opt.work);

  // Problem (a): the beam under the dropped slab; mid-span deflection every 1 ms.
  Problem beam{
      "beam_drop",
      kSource / "cases" / "beam_drop.toml",
      {0.5, 0.05, 0.0},
      1e-6,
      0.01,
      1e-4,
      opt.quick ? std::vector<double>{1e-5, 1e-4, 1e-3}
                : std::vector<double>{1e-6, 2e-6, 5e-6, 1e-5, 2e-5, 5e-5, 1e-4, 2e-4, 5e-4, 1e-3},
      {},
      // dt_F = dt_D = 5e-7, 2.5e-7, 1.25e-7 s (docs/coupling.md, "Work-precision": the
      // deflection converges at order 1 to 2 in dt, the extrapolation to about 2e-5).
      {5e-7, 2.5e-7, 1.25e-7}};
  // Problem (a'): the same with elastic contacts (restitution 1, no dashpot). The dashpot of
  // the damped contacts makes the deflection converge irregularly, at orders 0.4 to 1.2 in
  // dt_F and dt_D (its force grows as overlap^(1/4) from the contact's start and takes the
  // mesh velocity of the step's mean), so no extrapolation pins it below about 3e-5; the
  // elastic slab converges at order 2 (docs/coupling.md, "Work-precision"), which resolves
  // the 1e-4 target. Its DEM error at dt_D = 1e-6 s is about 1e-5.
  Problem elastic = beam;
  elastic.name = "beam_drop_elastic";
  elastic.sets = {"dem.pairs[0].restitution=1.0", "dem.pairs[1].restitution=1.0"};
  elastic.reference_dts = {1e-6, 5e-7, 2.5e-7};
  // Problem (b): the plate under the bed; centre deflection every 1 ms.
  Problem plate{"plate_bed",
                kSource / "cases" / "plate_bed.toml",
                {0.1, 0.1, 0.0},
                5e-6,
                0.03,
                1e-4,
                opt.quick ? std::vector<double>{1e-5, 1e-4, 1e-3}
                          : std::vector<double>{5e-6, 1e-5, 2e-5, 5e-5, 1e-4, 2e-4, 5e-4, 1e-3},
                {},
                {}};

  const Scheme& iqn = kSchemes.back();
  // The converged reference: implicit IQN-ILS at dt_F = dt_D with tolerances 10 x tighter;
  // its distance to the one at 2 dt_D bounds its own error.
  auto reference = [&](const Problem& pb, const std::string& tag,
                       const std::vector<std::string>& sets, bool check = true) {
    std::vector<RunResult> refs;
    for (double dt : {pb.dem_dt, 2 * pb.dem_dt}) {
      if (!check && dt != pb.dem_dt) break;
      const fs::path dir = opt.work / (pb.name + "_" + tag + "_reference_" + fmt(dt));
      const fs::path scene = scene_variant(pb, iqn, dir, 0.1);
      refs.push_back(run(pb, scene, dir, sets, dt, true));
      fs::remove(scene);
      if (refs.back().exit != 0)
        throw std::runtime_error(pb.name + " reference at dt_F = " + fmt(dt) +
                                 " failed: " + refs.back().error_text);
    }
    if (refs.size() == 1) {
      std::printf("# %s %s reference: dt_F = %g s, %lld steps, %.3g iterations per step\n",
                  pb.name.c_str(), tag.c_str(), pb.dem_dt, static_cast<long long>(refs[0].steps),
                  static_cast<double>(refs[0].iterations) / static_cast<double>(refs[0].steps));
      return refs[0];
    }
    const Errors self = errors_of(refs[1], refs[0], pb);
    std::printf(
        "# %s %s reference: dt_F = %g s, %lld steps, %.3g iterations per step; "
        "the run at %g s differs by %.3g (deflection over the run), %.3g (peak)\n",
        pb.name.c_str(), tag.c_str(), pb.dem_dt, static_cast<long long>(refs[0].steps),
        static_cast<double>(refs[0].iterations) / static_cast<double>(refs[0].steps), 2 * pb.dem_dt,
        self.series, self.peak);
    std::fflush(stdout);
    rep.add_row({"reference",
                 pb.name,
                 std::string("implicit-iqn (") + tag + ")",
                 pb.dem_dt,
                 pb.dem_dt,
                 NAN,
                 1LL,
                 refs[0].wall,
                 refs[0].wall,
                 0.0,
                 0.0,
                 refs[0].max_energy_error,
                 refs[0].max_work,
                 static_cast<double>(refs[0].iterations) / static_cast<double>(refs[0].steps),
                 static_cast<long long>(refs[0].max_iterations),
                 static_cast<long long>(refs[0].unconverged),
                 refs[0].max_displacement,
                 0LL,
                 1LL,
                 std::string(""),
                 refs[0].dem_compute,
                 refs[0].fem_compute,
                 refs[0].step_wall,
                 refs[0].cpu,
                 refs[0].cpu});
    rep.add_row({"reference",
                 pb.name,
                 std::string("implicit-iqn (") + tag + ")",
                 2 * pb.dem_dt,
                 pb.dem_dt,
                 NAN,
                 1LL,
                 refs[1].wall,
                 refs[1].wall,
                 self.series,
                 self.peak,
                 refs[1].max_energy_error,
                 refs[1].max_work,
                 static_cast<double>(refs[1].iterations) / static_cast<double>(refs[1].steps),
                 static_cast<long long>(refs[1].max_iterations),
                 static_cast<long long>(refs[1].unconverged),
                 refs[1].max_displacement,
                 0LL,
                 1LL,
                 std::string(""),
                 refs[1].dem_compute,
                 refs[1].fem_compute,
                 refs[1].step_wall,
                 refs[1].cpu,
                 refs[1].cpu});
    return refs[0];
  };

  // The reference of problem (a): implicit IQN-ILS (tolerances 10 x tighter) at dt_F = dt_D =
  // h_1 > h_2 > h_3 (each half the one before), field output every pb.sample; at every output
  // time the Richardson extrapolation that removes the error terms of order 1 and 2,
  // w* = (8 w_3 - 6 w_2 + w_1) / 3. The observed order, log2 of the ratio of the largest
  // differences |w_1 - w_2| / |w_2 - w_3|, and the extrapolation's own error, estimated by its
  // distance to the first-order extrapolation 2 w_3 - w_2 from the two finest runs, are printed
  // and recorded (rows "reference": each run's distance to w*; the extrapolation's row has
  // its error estimate). The returned result is the finest run with w* in place of its probe.
  auto extrapolated_reference = [&](const Problem& pb) {
    if (pb.reference_dts.size() != 3) throw std::runtime_error(pb.name + ": three reference dt");
    std::vector<RunResult> refs;
    for (double h : pb.reference_dts) {
      const fs::path dir = opt.work / (pb.name + "_reference_" + fmt(h));
      const fs::path scene = scene_variant(pb, iqn, dir, 0.1);
      refs.push_back(run(pb, scene, dir, {"dem.dt=" + fmt(h)}, h, true));
      fs::remove(scene);
      if (refs.back().exit != 0)
        throw std::runtime_error(pb.name + " reference at dt_F = dt_D = " + fmt(h) +
                                 " failed: " + refs.back().error_text);
    }
    // The three series at the common output times.
    std::vector<std::map<long, double>> at(3);
    for (int k = 0; k < 3; ++k)
      for (std::size_t i = 0; i < refs[k].times.size(); ++i)
        at[k][std::lround(refs[k].times[i] / pb.sample)] = refs[k].probe[i];
    RunResult out = refs[2];
    out.times.clear();
    out.probe.clear();
    std::vector<double> first_order;
    double d12 = 0.0, d23 = 0.0, scale = 0.0;
    for (const auto& [key, w3] : at[2]) {
      if (!at[0].count(key) || !at[1].count(key)) continue;
      const double w1 = at[0][key], w2 = at[1][key];
      out.times.push_back(static_cast<double>(key) * pb.sample);
      out.probe.push_back((8.0 * w3 - 6.0 * w2 + w1) / 3.0);
      first_order.push_back(2.0 * w3 - w2);
      d12 = std::max(d12, std::abs(w1 - w2));
      d23 = std::max(d23, std::abs(w2 - w3));
      scale = std::max(scale, std::abs(out.probe.back()));
    }
    double self = 0.0;
    for (std::size_t i = 0; i < out.probe.size(); ++i)
      self = std::max(self, std::abs(out.probe[i] - first_order[i]));
    self /= scale;
    const double order = std::log2(d12 / d23);
    std::printf(
        "# %s reference: implicit-iqn at dt_F = dt_D = %g, %g, %g s (%.3g, %.3g, %.3g iterations "
        "per step), Richardson-extrapolated (orders 1 and 2); observed order %.2f (largest "
        "differences %.3g, %.3g of the largest deflection); the extrapolation's error, by its "
        "distance to the first-order one: %.3g\n",
        pb.name.c_str(), pb.reference_dts[0], pb.reference_dts[1], pb.reference_dts[2],
        static_cast<double>(refs[0].iterations) / static_cast<double>(refs[0].steps),
        static_cast<double>(refs[1].iterations) / static_cast<double>(refs[1].steps),
        static_cast<double>(refs[2].iterations) / static_cast<double>(refs[2].steps), order,
        d12 / scale, d23 / scale, self);
    std::fflush(stdout);
    rep.set_info(pb.name + "_reference_observed_order", order);
    rep.set_info(pb.name + "_reference_error_estimate", self);
    for (int k = 0; k < 3; ++k) {
      Problem level = pb;
      level.dem_dt = pb.reference_dts[k];
      add_row(rep, "reference", level, "implicit-iqn (reference run)", level.dem_dt, NAN,
              {refs[k].wall}, errors_of(refs[k], out, pb), refs[k], {true, ""});
    }
    Problem level = pb;
    level.dem_dt = 0.0;  // the limit dt -> 0
    add_row(rep, "reference", level, "extrapolated", 0.0, NAN, {}, {self, NAN}, out, {true, ""});
    return out;
  };

  // ---- work-precision ---------------------------------------------------------------------
  if (opt.parts.count("work")) {
    // Problem (a) at each dt_D of --beam-dem-dts (the case's with its whole dt_F grid, a finer
    // one from dt_F = dt_D to 20 dt_D), then problem (b).
    std::vector<Problem> grid;
    for (double d : opt.beam_dem_dts) {
      Problem level = beam;
      if (d != beam.dem_dt) {
        level.dem_dt = d;
        level.sets.push_back("dem.dt=" + fmt(d));
        level.dts = {d, 2 * d, 4 * d, 8 * d, 20 * d};
      }
      grid.push_back(level);
    }
    grid.push_back(elastic);
    grid.push_back(plate);
    for (auto& pb : grid) {
      if (opt.dts.empty()) continue;
      std::vector<double> kept;
      for (double dt : pb.dts)
        for (double want : opt.dts)
          if (std::abs(dt - want) <= 1e-9 * want) kept.push_back(dt);
      pb.dts = kept;
    }
    std::map<std::string, RunResult> extrapolated;  // by problem
    for (const Problem* pb = grid.data(); pb != grid.data() + grid.size(); ++pb) {
      if (!opt.problems.count(pb->name)) continue;
      if (!pb->reference_dts.empty() && !extrapolated.count(pb->name))
        extrapolated[pb->name] = extrapolated_reference(*pb);
      const RunResult ref =
          pb->reference_dts.empty() ? reference(*pb, "work", {}) : extrapolated[pb->name];
      // Run folders of a dt_D other than the case's are named by it.
      const std::string tag =
          pb->name +
          (pb->dem_dt != beam.dem_dt && pb->name == beam.name ? "_D" + fmt(pb->dem_dt) : "");
      struct Cell {
        RunResult first;
        std::vector<double> walls, cpus;
      };
      std::map<std::pair<std::size_t, std::size_t>, Cell> cells;
      // Interleaved: every (scheme, dt) once, then again, so that the load of the machine
      // (shared with other jobs) falls on all variants alike.
      auto chosen = [&](std::size_t s) {
        return opt.schemes.empty() || opt.schemes.count(kSchemes[s].label);
      };
      for (int r = 0; r < opt.repeat; ++r) {
        for (std::size_t s = 0; s < kSchemes.size(); ++s) {
          if (!chosen(s)) continue;
          for (std::size_t k = 0; k < pb->dts.size(); ++k) {
            auto& cell = cells[{s, k}];
            const double dt = pb->dts[k];
            const fs::path dir = opt.work / (tag + "_" + kSchemes[s].label + "_" + fmt(dt));
            const fs::path scene = scene_variant(*pb, kSchemes[s], dir, 1.0);
            // First the accuracy run (field output for the probe), then timed runs without
            // field output; an unstable variant is not timed.
            const bool conc = kSchemes[s].scheme == "concurrent";
            if (r == 0) cell.first = run(*pb, scene, dir.string() + "_fields", {}, dt, true, conc);
            if (cell.first.exit == 0) {
              const RunResult timed = run(*pb, scene, dir, {}, dt, false, conc);
              cell.walls.push_back(timed.wall);
              cell.cpus.push_back(timed.cpu);
            }
            fs::remove(scene);
          }
        }
      }
      for (std::size_t s = 0; s < kSchemes.size(); ++s) {
        if (!chosen(s)) continue;
        for (std::size_t k = 0; k < pb->dts.size(); ++k) {
          const auto& cell = cells[{s, k}];
          const Stability st = judge(cell.first, ref);
          add_row(rep, "work", *pb, kSchemes[s].label, pb->dts[k], NAN, cell.walls,
                  errors_of(cell.first, ref, *pb), cell.first, st, cell.cpus);
        }
      }
      rep.write_json(opt.json);  // the rows so far: a later part that fails keeps them
    }
  }

  // ---- stability map (problem b: the plate's density) --------------------------------------
  if (opt.parts.count("stability")) {
    const std::vector<double> factors =
        opt.quick ? std::vector<double>{1, 10} : std::vector<double>{1, 3, 10, 30, 100};
    for (double f : factors) {
      const double density = 2700.0 * f;
      const std::vector<std::string> sets = {"fem.materials[0].density=" + fmt(density)};
      RunResult ref;
      try {
        ref = reference(plate, "rho" + fmt(density), sets, false);
      } catch (const std::exception& e) {
        // Recorded, not fatal: the other densities are still measured.
        std::printf("# stability at plate density %g: %s; density skipped\n", density, e.what());
        rep.set_info("stability_failed_reference_" + fmt(density), std::string(e.what()));
        continue;
      }
      for (const Scheme& sc : kSchemes) {
        // From the largest dt_F down to the first stable one: the largest stable dt_F (smaller
        // ones are not run; the work-precision part has them at the case's density).
        std::vector<double> dts = plate.dts;
        std::reverse(dts.begin(), dts.end());
        for (double dt : dts) {
          const fs::path dir =
              opt.work / (plate.name + "_stab_" + fmt(density) + "_" + sc.label + "_" + fmt(dt));
          const fs::path scene = scene_variant(plate, sc, dir, 1.0);
          const RunResult res = run(plate, scene, dir, sets, dt, false, sc.scheme == "concurrent");
          fs::remove(scene);
          const Stability st = judge(res, ref);
          add_row(rep, "stability", plate, sc.label, dt, density, {res.wall},
                  errors_of(res, ref, plate), res, st);
          if (st.stable) break;
        }
      }
      rep.write_json(opt.json);  // the rows so far
    }
  }

  // ---- concurrency: problem a with a FEM that costs about what the DEM costs ---------------
  if (opt.parts.count("concurrency")) {
    Problem balanced = beam;
    balanced.name = "beam_drop_balanced";
    // 60 x 6 x 6 hex8 (2160 elements): a FEM step of about the DEM's 300 substeps of 160
    // spheres at dt_F = 3e-4 s, about 10 ms each here (the table shows both, measured).
    balanced.sets.push_back("fem.mesh.box.cells=[60,6,6]");
    const double dt = 3e-4;
    // The reference of this finer mesh at dt_F = 1e-5 s: the errors compared here
    // (3e-4 s) are of order 0.1, the reference's at 1e-5 s below 1e-2 (the work-precision
    // part).
    balanced.dem_dt = 1e-5;
    balanced.reference_dts.clear();
    const RunResult ref = reference(balanced, "balanced", {}, false);
    // Each scheme as demfem_run starts the solvers by default (in its own session) and with
    // --solver-sessions (each in a session of its own: a CPU share each under autogroup).
    struct Variant {
      std::string label;
      const Scheme* scheme;
      bool sessions;
    };
    const std::vector<Variant> variants = {{"sequential", &kSchemes[0], false},
                                           {"concurrent", &kSchemes[4], false},
                                           {"sequential, solver sessions", &kSchemes[0], true},
                                           {"concurrent, solver sessions", &kSchemes[4], true}};
    // The first run of each has field output (for the error); the timed ones after it not.
    std::map<std::string, std::vector<RunResult>> runs;
    std::map<std::string, RunResult> accuracy;
    const int repeats = std::max(opt.repeat, 7);
    for (int r = -1; r < repeats; ++r) {  // interleaved
      for (const auto& v : variants) {
        if (r < 0 && v.sessions) continue;  // the same numbers as without
        const fs::path dir = opt.work / ("balanced_" + std::to_string(&v - &variants[0]) + "_" +
                                         std::to_string(r + 1));
        const fs::path scene = scene_variant(balanced, *v.scheme, dir, 1.0);
        RunResult res =
            run(balanced, scene, dir, {}, dt, r < 0, v.scheme->scheme == "concurrent", v.sessions);
        fs::remove(scene);
        if (r < 0) {
          accuracy[v.label] = std::move(res);
        } else {
          runs[v.label].push_back(std::move(res));
        }
      }
    }
    // Per run: the median over its steps of the step's wall time and of each solver's own
    // compute time (StepDone); over the runs: their median and their best.
    auto stat = [&](const std::string& label, double RunResult::*field) {
      std::vector<double> v;
      for (const auto& x : runs[label])
        if (x.exit == 0) v.push_back(x.*field);
      return std::make_pair(median(v), v.empty() ? NAN : *std::min_element(v.begin(), v.end()));
    };
    for (const std::string suffix : {"", ", solver sessions"}) {
      const auto seq_step = stat("sequential" + suffix, &RunResult::step_wall);
      const auto seq_dem = stat("sequential" + suffix, &RunResult::dem_compute);
      const auto seq_fem = stat("sequential" + suffix, &RunResult::fem_compute);
      const auto con_step = stat("concurrent" + suffix, &RunResult::step_wall);
      const auto con_ratio = stat("concurrent" + suffix, &RunResult::step_ratio);
      const double max_med = std::max(seq_dem.first, seq_fem.first);
      const double max_best = std::max(seq_dem.second, seq_fem.second);
      std::printf(
          "# concurrency%s (beam_drop, FEM 60 x 6 x 6 hex8, dt_F = %g s, %d runs of each, "
          "interleaved): per step, median (best) over the runs of their medians:\n"
          "#   sequential (just-in-time): step %.3g ms (%.3g), DEM %.3g ms (%.3g), FEM "
          "%.3g ms (%.3g)\n"
          "#   concurrent: step %.3g ms (%.3g) = %.3f (%.3f) x max(DEM, FEM) of the sequential "
          "runs, %.3f (%.3f) x their step; in the same run, step / max(DEM, FEM): %.3f "
          "(%.3f)\n",
          suffix.c_str(), dt, repeats, 1e3 * seq_step.first, 1e3 * seq_step.second,
          1e3 * seq_dem.first, 1e3 * seq_dem.second, 1e3 * seq_fem.first, 1e3 * seq_fem.second,
          1e3 * con_step.first, 1e3 * con_step.second, con_step.first / max_med,
          con_step.second / max_best, con_step.first / seq_step.first,
          con_step.second / seq_step.second, con_ratio.first, con_ratio.second);
      const std::string key = suffix.empty() ? "" : "_sessions";
      rep.set_info("concurrency" + key + "_step_over_max_median", con_step.first / max_med);
      rep.set_info("concurrency" + key + "_step_over_max_best", con_step.second / max_best);
      rep.set_info("concurrency" + key + "_step_over_sequential_median",
                   con_step.first / seq_step.first);
      rep.set_info("concurrency" + key + "_same_run_ratio_median", con_ratio.first);
    }
    for (const auto& v : variants) {
      const auto& rs = runs[v.label];
      std::vector<double> walls;
      for (const auto& x : rs) walls.push_back(x.wall);
      const RunResult& acc =
          accuracy[v.scheme->scheme == "concurrent" ? "concurrent" : "sequential"];
      RunResult shown = rs.front();  // the timed run's compute times, the accuracy run's rest
      shown.max_energy_error = acc.max_energy_error;
      shown.max_displacement = acc.max_displacement;
      add_row(rep, "concurrency", balanced, v.label, dt, NAN, walls, errors_of(acc, ref, balanced),
              shown, judge(acc, ref));
    }
  }

  // ---- problem (c): the sheet CI case -----------------------------------------------------
  // cases/sheet_ci.toml as it is (its geometry and fill are named by paths relative to it, so
  // the scheme goes in by --set, not by a rewritten copy), cut to opt.sheet_end s of flow. The
  // quantity of interest is the deflection of the measurement position (probe "lmp" of
  // fem_monitor.csv, every FEM step): its mean over the last 0.1 s (the grains reach the
  // sheet at about 0.26 s; a granular flow's details are chaotic, its mean load less so) and
  // its largest |value|, against implicit IQN-ILS at dt_F = dt_D = 2e-5 s.
  if (opt.parts.count("sheet")) {
    Problem sheet{
        "sheet_ci",
        kSource / "cases" / "sheet_ci.toml",
        {0.28, 0.05, 0.0},
        2e-5,
        opt.sheet_end,
        1e-4,
        opt.sheet_dts,
        {"run.end_time=" + fmt(opt.sheet_end),
         "fem.monitor.mean_window=[" + fmt(opt.sheet_end - 0.1) + "," + fmt(opt.sheet_end) + "]"},
        {}};
    auto scheme_sets = [](const Scheme& sc) {
      std::vector<std::string> v = {
          "coupling.scheme=\"" + sc.scheme + "\"",
          std::string("coupling.force_averaging=") + (sc.force_averaging ? "true" : "false")};
      if (sc.scheme == "implicit") {
        // The tolerances of problem (b) (plate_bed.toml); before the grains arrive the sheet
        // carries no force.
        for (const std::string& s : {"coupling.acceleration=\"" + sc.acceleration + "\"",
                                     std::string("coupling.displacement_tolerance=1e-3"),
                                     std::string("coupling.force_tolerance=1e-2"),
                                     std::string("coupling.force_abs_tolerance=1e-6"),
                                     std::string("coupling.displacement_abs_tolerance=1e-12"),
                                     std::string("coupling.max_iterations=50")})
          v.push_back(s);
      }
      return v;
    };
    struct SheetResult {
      RunResult run;
      double mean = NAN, peak = 0.0;  // lmp u_z: mean over the last 0.1 s, largest |u_z|
    };
    auto sheet_run = [&](const Scheme& sc, double dt, const std::string& tag) {
      const fs::path dir = opt.work / ("sheet_ci_" + sc.label + "_" + fmt(dt) + tag);
      auto sets = scheme_sets(sc);
      sets.push_back("coupling.diagnostics_interval=1");  // every step's iterations counted
      SheetResult r;
      r.run = run(sheet, sheet.scene, dir, sets, dt, false, sc.scheme == "concurrent");
      const auto rows = read_csv(dir / "fem_monitor.csv");
      if (rows.size() > 1) {
        std::size_t col = 0;
        for (std::size_t k = 0; k < rows[0].size(); ++k)
          if (rows[0][k] == "lmp_uz") col = k;
        double sum = 0.0;
        std::size_t n = 0;
        for (std::size_t i = 1; i < rows.size(); ++i) {
          if (col == 0 || rows[i].size() <= col) continue;
          const double t = std::stod(rows[i][0]), w = std::stod(rows[i][col]);
          r.peak = std::max(r.peak, std::abs(w));
          if (t >= opt.sheet_end - 0.1 - 1e-9) sum += w, ++n;
        }
        if (n > 0) r.mean = sum / static_cast<double>(n);
      }
      return r;
    };
    const SheetResult ref = sheet_run(kSchemes.back(), sheet.dem_dt, "_reference");
    if (ref.run.exit != 0)
      throw std::runtime_error("sheet_ci reference failed: " + ref.run.error_text);
    std::printf(
        "# sheet_ci reference: implicit-iqn, dt_F = %g s, %.3g s of flow, %lld steps, %.3g "
        "iterations per step, wall %.1f s; lmp deflection: mean over the last 0.1 s %.4g m, "
        "largest %.4g m\n",
        sheet.dem_dt, opt.sheet_end, static_cast<long long>(ref.run.steps),
        static_cast<double>(ref.run.iterations) / static_cast<double>(ref.run.steps), ref.run.wall,
        ref.mean, ref.peak);
    std::fflush(stdout);
    add_row(rep, "reference", sheet, "implicit-iqn (sheet)", sheet.dem_dt, NAN, {ref.run.wall},
            {0.0, 0.0}, ref.run, {true, ""});
    for (double dt : sheet.dts) {  // interleaved over the schemes
      for (const Scheme& sc : kSchemes) {
        if (!opt.sheet_schemes.empty() && !opt.sheet_schemes.count(sc.label)) continue;
        const SheetResult r = sheet_run(sc, dt, "");
        const Stability st = judge(r.run, ref.run);
        Errors e;
        if (r.run.exit == 0 && std::isfinite(r.mean) && ref.mean != 0.0)
          e = {std::abs(r.mean - ref.mean) / std::abs(ref.mean),
               std::abs(r.peak - ref.peak) / ref.peak};
        add_row(rep, "sheet", sheet, sc.label, dt, NAN, {r.run.wall}, e, r.run, st);
        rep.write_json(opt.json);  // the rows so far: a long study cut short keeps them
        std::printf(
            "# sheet_ci %-18s dt_F %-7g exit %d %s wall %.1f s, mean-deflection error "
            "%.3g, peak error %.3g, iterations/step %.3g\n",
            sc.label.c_str(), dt, r.run.exit, st.stable ? "stable" : st.why.c_str(), r.run.wall,
            e.series, e.peak,
            r.run.steps ? static_cast<double>(r.run.iterations) / static_cast<double>(r.run.steps)
                        : NAN);
        std::fflush(stdout);
      }
    }
  }

  rep.print();
  rep.write_json(opt.json);
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "coupling_schemes: %s\n", e.what());
  return 1;
}
