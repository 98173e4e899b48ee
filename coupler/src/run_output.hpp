#pragma once
// What a coupling run writes as it goes (docs/coupling.md, "Output"): coupling.csv, one row of
// diagnostics per step (flushed at least every half second of wall time), the interface series
// coupling_NNNNNN.h5 + coupling.xdmf at the run's output times, and coupling.h5, the interface
// at the end. A checkpoint records how far each got (rows, next output) so that a restored run
// cuts them back to it. Private to the coupling library.

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include "coupling_series.hpp"
#include "demfem/io/output_schedule.hpp"
#include "interface_output.hpp"

namespace demfem::coupling {

/// @brief The CSV series, the interface series and their output schedule of one run.
class RunOutput {
 public:
  /// A fresh run starts coupling.csv in `dir` now (a resumed run continues it at restore()).
  RunOutput(std::filesystem::path dir, bool resume, double output_interval);

  /// The interface series for `mesh` (none for a mesh without nodes).
  void open_interface_series(const InterfaceMesh& mesh);

  /// Appends the row of `d` to coupling.csv.
  void write_row(const StepDiagnostics& d);
  /// Puts the rows written so far on disk (nothing before the first row of a resumed run).
  void flush();
  /// coupling.csv cut back to its first `rows` rows and continued (a checkpoint restored).
  void continue_rows(std::int64_t rows);
  std::int64_t rows() const { return rows_; }

  /// The interface series output `label` of `state` at `time`, after `steps` steps.
  void write_interface(const InterfaceState& state, double label, double time, std::int64_t steps);
  /// An output is due after the step that ended at `time`: written with its label.
  void write_interface_if_due(const InterfaceState& state, double time, double coupling_dt,
                              std::int64_t steps);
  /// The reference state as output 0 of a fresh run, whose clock starts at `time`.
  void write_initial_interface(const InterfaceState& state, double time, double coupling_dt);
  /// The end state as the last output of the series, unless the last output is of this step.
  void write_final_interface(const InterfaceState& state, double time, double coupling_dt,
                             std::int64_t steps);
  /// The schedule and the series back to the state of a checkpoint of `steps` steps at `time`:
  /// `next_output` / `last_output_step` as recorded there, or absent (checkpoints of older
  /// versions: the outputs up to its time were taken).
  void restore_interface(std::optional<std::int64_t> next_output, std::int64_t last_output_step,
                         double time, std::int64_t steps);
  /// coupling.h5: `state` after `steps` steps at `time` under `scheme`.
  void write_end_state(const InterfaceState& state, const std::string& scheme, std::int64_t steps,
                       double time) const;
  std::int64_t next_output() const { return schedule_.next(); }
  std::int64_t last_output_step() const { return last_output_step_; }

 private:
  using Clock = std::chrono::steady_clock;
  std::filesystem::path dir_;
  std::optional<SeriesFile> csv_;
  std::int64_t rows_ = 0;
  Clock::time_point last_flush_ = Clock::now();
  std::optional<InterfaceSeries> series_;
  io::OutputSchedule schedule_;
  std::int64_t last_output_step_ = -1;  // steps of the last series output
  bool resume_;
};

}  // namespace demfem::coupling
