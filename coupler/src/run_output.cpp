#include "run_output.hpp"

#include <utility>

namespace demfem::coupling {

RunOutput::RunOutput(std::filesystem::path dir, bool resume, double output_interval)
    : dir_(std::move(dir)), schedule_(output_interval), resume_(resume) {
  if (!resume_) csv_.emplace(dir_ / "coupling.csv", coupling_columns());
}

void RunOutput::open_interface_series(const InterfaceMesh& mesh) {
  if (mesh.node_count() > 0) series_.emplace(dir_, mesh, resume_);
}

void RunOutput::write_row(const StepDiagnostics& d) {
  // Rows reach the disk at least every kFlushInterval of wall time (and at every end of the
  // run, normal or not): a flush per step would cost a system call per step.
  constexpr auto kFlushInterval = std::chrono::milliseconds(500);
  const auto r = row_of(d);
  csv_->row(r);
  ++rows_;
  if (const auto now = Clock::now(); now - last_flush_ >= kFlushInterval) {
    csv_->flush();
    last_flush_ = now;
  }
}

void RunOutput::flush() {
  if (csv_) csv_->flush();
}

void RunOutput::continue_rows(std::int64_t rows) {
  rows_ = rows;
  csv_.reset();
  csv_.emplace(dir_ / "coupling.csv", static_cast<std::size_t>(rows_));
}

void RunOutput::write_interface(const InterfaceState& state, double label, double time,
                                std::int64_t steps) {
  if (!series_) return;
  series_->write(state, label, time);
  last_output_step_ = steps;
}

void RunOutput::write_interface_if_due(const InterfaceState& state, double time, double coupling_dt,
                                       std::int64_t steps) {
  if (schedule_.due(time, coupling_dt))
    write_interface(state, schedule_.take(time, coupling_dt), time, steps);
}

void RunOutput::write_initial_interface(const InterfaceState& state, double time,
                                        double coupling_dt) {
  write_interface(state, schedule_.label(time, coupling_dt), time, 0);
  schedule_.skip_to_after(time);
}

void RunOutput::write_final_interface(const InterfaceState& state, double time, double coupling_dt,
                                      std::int64_t steps) {
  if (last_output_step_ != steps)
    write_interface(state, schedule_.label(time, coupling_dt), time, steps);
}

void RunOutput::restore_interface(std::optional<std::int64_t> next_output,
                                  std::int64_t last_output_step, double time, std::int64_t steps) {
  // The interface series: the outputs taken so far, and none of states after the checkpoint.
  if (next_output) {
    schedule_.set_next(*next_output);
    last_output_step_ = last_output_step;
  } else {
    schedule_.skip_to_after(time);
    last_output_step_ = -1;
  }
  if (series_) {
    series_->rollback(time);
    if (series_->last_state_time() == time) last_output_step_ = steps;
  }
}

void RunOutput::write_end_state(const InterfaceState& state, const std::string& scheme,
                                std::int64_t steps, double time) const {
  write_coupling_h5(dir_, state, scheme, steps, time);
}

}  // namespace demfem::coupling
