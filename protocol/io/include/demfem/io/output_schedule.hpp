#pragma once
// When field output (particle snapshots, FEM steps) is taken and which time it is written
// with, shared by the DEM and FEM writers so that both files of a coupled run carry the same
// time values and ParaView's animation shows one frame per output, not two.
//
// Output k of an interval is due at the nominal time k * interval. A solver can only write
// the state at the end of one of its steps (dem.dt alone, the coupling step when coupled),
// so output k takes the state at the step end nearest to its nominal time (a tie goes to the
// later one): the state time differs from the nominal time by at most half a step, and not
// at all when the interval is a whole number of steps. The file is labelled with the nominal
// time, rounded to 15 significant digits so that 3 x 0.1 is written as 0.3; the state time is
// recorded beside it. Solvers pass the clock as (step count) x dt, a product, never a running
// sum of dt whose rounding grows with the step count.

#include <cstdint>
#include <string>

namespace demfem::io {

/// @brief `t` rounded to 15 significant decimal digits: the number a user wrote, when `t` is
/// a product such as 3 * 0.1 or 2500 * 2e-6 that carries binary rounding.
double decimal_time(double t);

/// @brief Shortest decimal text that reads back as exactly `t` (for XDMF Time values: "0.3",
/// not "0.29999999999999999").
std::string format_time(double t);

/// @brief The nominal output times k * interval (k = 0, 1, ...) and which of them are taken.
class OutputSchedule {
 public:
  /// `interval` > 0 s; 0 (or less) = no output between the start and the end state.
  explicit OutputSchedule(double interval = 0.0) : interval_(interval > 0.0 ? interval : 0.0) {}

  double interval() const { return interval_; }
  bool active() const { return interval_ > 0.0; }

  /// Nominal time of output k: decimal_time(k * interval).
  double nominal(std::int64_t k) const;

  /// Whether the state at time `t` (the end of a step of length `step`, s) takes an output
  /// not taken yet: nominal(next()) lies before the middle of the following step.
  bool due(double t, double step) const;

  /// Takes every output that the state at `t` is the nearest step end of; returns the label
  /// of the state: the latest of those nominal times, or label(t, step) when none.
  double take(double t, double step);

  /// Label of a state that is not (or not only) a scheduled output, e.g. the initial or the
  /// end state: the nominal time within half a step of `t` when there is one, else
  /// decimal_time(t).
  double label(double t, double step) const;

  /// Index of the next output not yet taken.
  std::int64_t next() const { return next_; }
  /// Restores the index saved with a checkpoint.
  void set_next(std::int64_t k) { next_ = k; }
  /// Marks every output whose nominal time is at or before `t` (+ 1e-9 interval) as taken
  /// (for states restored from files that lack the saved index).
  void skip_to_after(double t);

 private:
  /// Index of the nominal time nearest to t.
  std::int64_t nearest(double t) const;
  double interval_ = 0.0;
  std::int64_t next_ = 0;
};

}  // namespace demfem::io
