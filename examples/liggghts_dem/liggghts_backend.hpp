#pragma once
// LiggghtsBackend: the DEM side of demfem's protocol for LIGGGHTS, on MPI rank 0.
//
// Rank 0 serves the protocol (serve(), Role::dem) and turns each message into an order that
// it broadcasts to the other ranks, which wait in serve_other_rank(); then every rank does the
// same LIGGGHTS work (LiggghtsDomain), so that LIGGGHTS's collective commands line up.
// Checkpoints are LIGGGHTS restart files, which the deck reads when ${demfem_restart} names one
// (docs/liggghts.md). When
// serve() returns (Shutdown, an error, a stop signal, a dead coupler) rank 0 sends `quit`.

#include <mpi.h>

#include "demfem/protocol/protocol.hpp"
#include "liggghts_domain.hpp"

namespace demfem::liggghts {

/// What rank 0 asks the other ranks to do next.
enum class RankOrder : int { attach = 1, step = 2, quit = 3, checkpoint = 4 };

class LiggghtsBackend : public protocol::SolverBackend {
 public:
  /// `steps_per_coupling_step`: n_D = fem.dt / dem.dt, by which a restored LIGGGHTS step
  /// counter is checked against the checkpoint's coupling step; `resume`: the process was
  /// started with --resume (LIGGGHTS then waits for the checkpoint to start from).
  LiggghtsBackend(MPI_Comm world, LiggghtsDomain& domain, std::int64_t steps_per_coupling_step,
                  bool resume);

  std::string name() const override;
  std::optional<InterfaceMesh> published_mesh() override { return std::nullopt; }
  void on_mesh(const InterfaceMesh& mesh) override;
  protocol::StepResult step(const protocol::StepCommand& cmd,
                            protocol::InterfaceBuffers& buffers) override;
  void write_checkpoint(const std::filesystem::path& file, std::int64_t step) override;
  void restore_checkpoint(const std::filesystem::path& file, std::int64_t step) override;

  /// Tells the other ranks to leave serve_other_rank(): call once, after serve().
  void release_other_ranks();

  /// What rank 0 is doing, for the note on LIGGGHTS's own exit (liggghts_dem.cpp): the
  /// coupling step in progress (-1 outside step()) and its time, s.
  std::int64_t step_in_progress() const { return step_in_progress_; }
  double time_in_progress() const { return time_in_progress_; }

  /// Writes where the coupling steps' wall time went (StepTimes, rank 0's) as JSON to
  /// `file` and one line to stdout; bench/liggghts_dem reads the file.
  void write_times(const std::filesystem::path& file) const;

 private:
  MPI_Comm world_;
  int ranks_ = 1;
  LiggghtsDomain& domain_;
  std::int64_t steps_per_coupling_step_;
  bool resume_;
  InterfaceMesh mesh_;
  std::int64_t step_in_progress_ = -1;
  double time_in_progress_ = 0.0;
  std::vector<double> kinematics_;  ///< node positions, then velocities (3 n each)
  /// Each coupling step's times (the first kKeptStepTimes), for their medians.
  static constexpr std::size_t kKeptStepTimes = 1000000;
  std::vector<StepTimes> step_times_;

  /// Every rank opens LIGGGHTS on the mesh and runs the deck, from `restart` when not empty.
  void attach_everywhere(const std::string& restart);
};

/// The loop of ranks 1..N-1: follows rank 0's orders until `quit`.
void serve_other_rank(MPI_Comm world, LiggghtsDomain& domain);

}  // namespace demfem::liggghts
