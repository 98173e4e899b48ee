#include "schemes/implicit_scheme.hpp"

#include <algorithm>
#include <sstream>

#include "run_text.hpp"

namespace demfem::coupling {

ImplicitScheme::ImplicitScheme(const SchemeContext& context) : CouplingScheme(context) {
  const CouplingSettings& s = settings();
  SolverLink& link = exchange().link();
  for (Role role : {Role::dem, Role::fem}) {
    if (link.supports_iteration(role)) continue;
    throw scene::SceneError(s.scene_file.string() +
                            ": coupling.scheme = \"implicit\" iterates every coupling step, "
                            "which needs solvers that can go back to a step's start; the " +
                            role_label(role) + " solver '" + link.name(role) +
                            "' cannot (its Hello does not announce the capability "
                            "'iteration', docs/protocol.md): choose an explicit scheme");
  }
  const std::size_t n3 = interface_values();
  accel_ = make_acceleration(s.implicit.acceleration, n3);
  for (auto* v : {&u_in_, &u_out_, &u_next_, &force_before_, &fem_vel_, &fem_acc_}) v->resize(n3);
}

std::string ImplicitScheme::take_stop_reason() {
  std::string why = std::move(stop_reason_);
  stop_reason_.clear();
  return why;
}

void ImplicitScheme::save_history(io::H5File& file) const {
  accel_->save(file, "acceleration");
}

void ImplicitScheme::load_history(const io::H5File& file) {
  accel_->load(file, "acceleration");
}

// docs/coupling.md: iteration k gives the DEM the displacement u^k (its mesh moves linearly in
// time from the accepted P_i to X + u^k, eq. 3.5-3.7 with the iterate for P_i+1), the DEM's
// forces F^k drive the FEM step, whose displacement u~^k = H(u^k) closes the loop. u^0 is the
// FEM's own extrapolation P_i + dt V_i + dt^2/2 A_i; later ones come from the accelerator.
// Both solvers keep the step's start in memory and go back to it for every new iteration
// (kStepIterate, kStepRedo); the last iteration's states are the accepted ones.
void ImplicitScheme::advance(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d) {
  const ImplicitSettings& im = settings().implicit;
  const double dt = settings().coupling_dt;
  const std::vector<double>& ref = ctx_.reference_positions;
  SchemeState& st = state();
  const std::size_t n3 = interface_values();
  for (std::size_t k = 0; k < n3; ++k)
    u_in_[k] =
        st.positions[k] + dt * st.velocities[k] + 0.5 * dt * dt * st.accelerations[k] - ref[k];
  force_before_ = st.dem_force_prev;  // F^{-1}: the last step's (preCICE's first measure)
  st.dem_start = st.positions;
  dem_cmd.flags |= protocol::kStepSetKinematics | protocol::kStepIterate;
  fem_cmd.flags |= protocol::kStepIterate;
  std::int64_t it = 0;
  bool converged = false;
  for (;;) {
    if (it > 0) {
      dem_cmd.flags |= protocol::kStepRedo;
      fem_cmd.flags |= protocol::kStepRedo;
    }
    iterate(dem_cmd, fem_cmd, d);
    double abs_u = 0.0, abs_f = 0.0;
    d.residual_displacement = relative_change(u_out_, u_in_, &abs_u);
    d.residual_force = relative_change(st.dem_force, force_before_, &abs_f);
    ++it;
    converged = (d.residual_displacement <= im.displacement_tolerance ||
                 abs_u <= im.displacement_abs_tolerance) &&
                (d.residual_force <= im.force_tolerance || abs_f <= im.force_abs_tolerance);
    if (converged || it >= im.max_iterations) break;
    force_before_ = st.dem_force;
    accel_->next(u_in_, u_out_, u_next_);
    u_in_.swap(u_next_);
  }
  accel_->end_step(u_in_, u_out_);
  st.velocities = fem_vel_;
  st.accelerations = fem_acc_;
  d.iterations = it;
  d.converged = converged;
  RunSummary& sum = ctx_.summary;
  sum.iterations += it;
  sum.max_iterations = std::max(sum.max_iterations, it);
  if (!converged) not_converged(it, d);
}

void ImplicitScheme::iterate(StepCommand& dem_cmd, StepCommand& fem_cmd, StepDiagnostics& d) {
  const double dt = settings().coupling_dt;
  const std::vector<double>& ref = ctx_.reference_positions;
  SchemeState& st = state();
  InterfaceBuffers& buf = buffers();
  constexpr std::uint32_t b = kSharedBuffer;
  const std::size_t n3 = interface_values();
  std::ranges::copy(st.positions, buf.positions(b).begin());
  auto v = buf.velocities(b);
  for (std::size_t k = 0; k < n3; ++k) v[k] = (ref[k] + u_in_[k] - st.positions[k]) / dt;
  std::ranges::fill(buf.accelerations(b), 0.0);
  exchange().dem_step(dem_cmd, d);
  st.fem_force = st.dem_force;  // the FEM reads them in the buffer, where the DEM left them
  exchange().fem_step(fem_cmd, d);
  std::ranges::copy(buf.positions(b), st.next_positions.begin());
  std::ranges::copy(buf.velocities(b), fem_vel_.begin());
  std::ranges::copy(buf.accelerations(b), fem_acc_.begin());
  for (std::size_t k = 0; k < n3; ++k) u_out_[k] = st.next_positions[k] - ref[k];
}

void ImplicitScheme::not_converged(std::int64_t it, const StepDiagnostics& d) {
  const ImplicitSettings& im = settings().implicit;
  std::ostringstream m;
  m << "coupling step " << d.step << " (t = " << format_number(d.time) << " s) did not converge in "
    << it << " iterations (coupling.max_iterations): relative residuals "
    << format_number(d.residual_displacement)
    << " (displacement, coupling.displacement_tolerance = "
    << format_number(im.displacement_tolerance) << ") and " << format_number(d.residual_force)
    << " (force, coupling.force_tolerance = " << format_number(im.force_tolerance) << ")";
  if (im.on_nonconvergence == NonConvergence::stop) {
    stop_reason_ = m.str() +
                   "; coupling.on_nonconvergence = \"stop\" (raise max_iterations, lower the "
                   "coupling step, or set \"accept\" to go on with a warning)";
    return;
  }
  // Counted in the summary and marked in coupling.csv (converged = 0); the first few are also
  // reported, not every one of a long run.
  constexpr std::int64_t kReported = 5;
  RunSummary& sum = ctx_.summary;
  if (++sum.unconverged_steps <= kReported && ctx_.report) {
    ctx_.report("warning: " + m.str() + "; accepted (coupling.on_nonconvergence = \"accept\")" +
                (sum.unconverged_steps == kReported
                     ? "; further unconverged steps are counted, not reported"
                     : ""));
  }
}

}  // namespace demfem::coupling
