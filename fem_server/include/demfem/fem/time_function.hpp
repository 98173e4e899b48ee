#pragma once
// Load amplitudes as functions of time: constant, piecewise-linear tables, sinusoids and the
// rail-seat load pattern of the sleeper case (thesis ch. 6, fig. 6.2). Each returns a
// TimeFunction (fem_problem.hpp); invalid parameters throw std::invalid_argument.

#include <utility>
#include <vector>

#include "demfem/fem/fem_problem.hpp"

namespace demfem::fem {

/// @brief f(t) = value.
TimeFunction constant_function(double value);

/// @brief Linear interpolation in a table of (t, f) points with strictly increasing t;
/// clamped outside (f(t) = first value before the first time, last value after the last).
TimeFunction piecewise_linear_function(std::vector<std::pair<double, double>> points);

/// @brief f(t) = mean + amplitude * sin(2 pi frequency t + phase); frequency in Hz, phase in
/// rad.
TimeFunction sinusoid_function(double mean, double amplitude, double frequency, double phase);

/// @brief The sleeper load pattern (thesis fig. 6.2, after Song et al. 2019): a linear ramp
/// from 0 to the peak, cycles between cycle_min and cycle_max, and the same ramp again.
///
/// The thesis gives the levels (0 -> 220 kN, cycles 4.4..44 kN at 2 Hz in the experiment,
/// the same ramp again), that its pattern is the experiment's accelerated 50 times and lasts
/// 0.12 s at time scale 1, and that the cyclic part is the reference time 0.03..0.09 s. From
/// these, in reference time tau = t / time_scale, with T_1 = T_r + T_u and T_2 = T_1 + T_c:
///   0 <= tau < T_r             F = F_peak * tau / T_r                       (first ramp)
///   T_r <= tau < T_1           F = F_peak + (F_min - F_peak)(tau - T_r) / T_u    (unloading)
///   T_1 <= tau < T_2           F = F_min + (F_max - F_min)(1 - cos(2 pi f (tau - T_1)))/2
///   T_2 <= tau < T_2 + T_r     F = F_peak * (tau - T_2) / T_r               (second ramp)
///   tau >= T_2 + T_r           F = F_peak (held);  tau < 0: F = 0
/// with T_r = 0.03 s, T_c = 0.06 s, f = 100 Hz (2 Hz x 50: six cycles), F_peak = 220 kN,
/// F_min = 4.4 kN, F_max = 44 kN, T_u = 0. The cycles start and end at F_min. The figure
/// itself is not in the text we have: by default the load drops from F_peak to F_min at once
/// when the cycles begin (T_u = 0, our reading), and from F_min to 0 when the second ramp
/// begins. A loading machine unloads at a finite rate: T_u > 0 inserts that unloading (the
/// pattern grows by T_u); a table reproduces any other shape.
struct SleeperLoadPattern {
  double peak_force = 220e3;       ///< N
  double cycle_min = 4.4e3;        ///< N
  double cycle_max = 44e3;         ///< N
  double ramp_duration = 0.03;     ///< s (reference time)
  double cycle_duration = 0.06;    ///< s (reference time)
  double cycle_frequency = 100.0;  ///< Hz (reference time)
  double unload_duration = 0.0;    ///< s (reference time): peak -> cycle_min; 0 = at once
  double time_scale = 1.0;         ///< stretch factor: 10 = ten times slower (thesis' choice)

  /// Total duration in simulated time, s.
  double duration() const {
    return time_scale * (2.0 * ramp_duration + unload_duration + cycle_duration);
  }
  /// Load at simulated time t, N.
  double operator()(double t) const;
};

/// @brief The sleeper pattern as a TimeFunction returning the force in N; checks its
/// parameters (durations, frequency and scale > 0, unload_duration >= 0,
/// 0 <= cycle_min <= cycle_max).
TimeFunction sleeper_load_function(const SleeperLoadPattern& pattern);

}  // namespace demfem::fem
