// The converged references the errors of the study are measured against.
#include "study.hpp"

#include <cstdio>
#include <map>
#include <stdexcept>

namespace demfem::bench::coupling_study {

// The converged reference: implicit IQN-ILS at dt_F = dt_D with tolerances 10 x tighter;
// its distance to the one at 2 dt_D bounds its own error.
RunResult reference(const Options& opt, Report& rep, const Problem& pb, const std::string& tag,
                    const std::vector<std::string>& sets, bool check) {
  const Scheme& iqn = kSchemes.back();
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
  // One table row per reference run; the one at 2 dt_D carries its distance to the first.
  auto add_reference_row = [&](const RunResult& r, double dt, double err_series,
                               double err_peak) {
    rep.add_row({"reference",
                 pb.name,
                 std::string("implicit-iqn (") + tag + ")",
                 dt,
                 pb.dem_dt,
                 NAN,
                 1LL,
                 r.wall,
                 r.wall,
                 err_series,
                 err_peak,
                 r.max_energy_error,
                 r.max_work,
                 static_cast<double>(r.iterations) / static_cast<double>(r.steps),
                 static_cast<long long>(r.max_iterations),
                 static_cast<long long>(r.unconverged),
                 r.max_displacement,
                 0LL,
                 1LL,
                 std::string(""),
                 r.dem_compute,
                 r.fem_compute,
                 r.step_wall,
                 r.cpu,
                 r.cpu});
  };
  add_reference_row(refs[0], pb.dem_dt, 0.0, 0.0);
  add_reference_row(refs[1], 2 * pb.dem_dt, self.series, self.peak);
  return refs[0];
}

// The reference of problem (a): implicit IQN-ILS (tolerances 10 x tighter) at dt_F = dt_D =
// h_1 > h_2 > h_3 (each half the one before), field output every pb.sample; at every output
// time the Richardson extrapolation that removes the error terms of order 1 and 2,
// w* = (8 w_3 - 6 w_2 + w_1) / 3. The observed order, log2 of the ratio of the largest
// differences |w_1 - w_2| / |w_2 - w_3|, and the extrapolation's own error, estimated by its
// distance to the first-order extrapolation 2 w_3 - w_2 from the two finest runs, are printed
// and recorded (rows "reference": each run's distance to w*; the extrapolation's row has
// its error estimate). The returned result is the finest run with w* in place of its probe.
RunResult extrapolated_reference(const Options& opt, Report& rep, const Problem& pb) {
  const Scheme& iqn = kSchemes.back();
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
}

}  // namespace demfem::bench::coupling_study
