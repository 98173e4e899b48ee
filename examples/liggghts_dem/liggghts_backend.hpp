#pragma once
// LiggghtsBackend: the DEM side of demfem's protocol for LIGGGHTS, on MPI rank 0.
//
// Rank 0 serves the protocol (serve(), Role::dem) and turns each message into an order that
// it broadcasts to the other ranks, which wait in serve_other_rank(); then every rank does the
// same LIGGGHTS work (LiggghtsDomain), so that LIGGGHTS's collective commands line up. When
// serve() returns (Shutdown, an error, a stop signal, a dead coupler) rank 0 sends `quit`.

#include <mpi.h>

#include "demfem/protocol/protocol.hpp"
#include "liggghts_domain.hpp"

namespace demfem::liggghts {

/// What rank 0 asks the other ranks to do next.
enum class RankOrder : int { attach = 1, step = 2, quit = 3 };

class LiggghtsBackend : public protocol::SolverBackend {
 public:
  LiggghtsBackend(MPI_Comm world, LiggghtsDomain& domain);

  std::string name() const override;
  std::optional<InterfaceMesh> published_mesh() override { return std::nullopt; }
  void on_mesh(const InterfaceMesh& mesh) override;
  protocol::StepResult step(const protocol::StepCommand& cmd,
                            protocol::InterfaceBuffers& buffers) override;
  void write_checkpoint(const std::filesystem::path& file, std::int64_t step) override;
  void restore_checkpoint(const std::filesystem::path& file, std::int64_t step) override;

  /// Tells the other ranks to leave serve_other_rank(): call once, after serve().
  void release_other_ranks();

 private:
  MPI_Comm world_;
  int ranks_ = 1;
  LiggghtsDomain& domain_;
};

/// The loop of ranks 1..N-1: follows rank 0's orders until `quit`.
void serve_other_rank(MPI_Comm world, LiggghtsDomain& domain);

}  // namespace demfem::liggghts
