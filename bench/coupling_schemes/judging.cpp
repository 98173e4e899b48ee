// The errors of a run against its reference, the stability criterion, the report's rows.
#include "study.hpp"

#include <algorithm>
#include <map>

namespace demfem::bench::coupling_study {

namespace {

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

}  // namespace

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

Errors errors_of(const RunResult& r, const RunResult& ref, const Problem& pb) {
  if (r.exit != 0) return {};
  return {relative_error(r, ref, pb.sample), peak_error(r, ref)};
}

void add_row(Report& rep, const std::string& part, const Problem& pb, const std::string& scheme,
             double dt, double density, const std::vector<double>& walls, const Errors& e,
             const RunResult& r, const Stability& s, const std::vector<double>& cpus) {
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

}  // namespace demfem::bench::coupling_study
