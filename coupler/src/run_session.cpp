#include "run_session.hpp"

#include <utility>

namespace demfem::coupling {

RunSession::RunSession(SolverLink& link_in, const CouplingSettings& settings_in,
                       const RunControl& control_in, const std::filesystem::path& output_dir_in,
                       RecoveryStats& stats_in, RunOutput& output_in, InterfaceMesh mesh)
    : link(link_in),
      settings(settings_in),
      control(control_in),
      output_dir(output_dir_in),
      stats(stats_in),
      output(output_in),
      n3(3 * mesh.node_count()),
      state(mesh.reference_positions),
      exchange(link_in, control_in, state, n3) {
  summary.mesh = std::move(mesh);
  summary.time = settings.start_time;  // a fresh run's; a resumed one's from its checkpoint
  scheme = make_coupling_scheme(SchemeContext{settings, exchange, state,
                                              summary.mesh.reference_positions, summary,
                                              [this](const std::string& m) { report(m); }});
}

void RunSession::write_end_state() const {
  output.write_end_state(interface_state(), scheme_name(settings.scheme), summary.steps,
                         summary.time);
}

}  // namespace demfem::coupling
