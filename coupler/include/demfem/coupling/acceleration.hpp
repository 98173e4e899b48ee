#pragma once
// Acceleration of the fixed-point iteration of an implicit coupling step (docs/coupling.md,
// "Implicit coupling"). One coupling step ("time window" in preCICE's words) iterates
// x^{k+1} = A(x^k, H(x^k)) until the residual r^k = H(x^k) - x^k is small, where H maps the
// interface displacement the DEM is given to the displacement the FEM answers with. The
// accelerators here follow preCICE's: constant under-relaxation, Aitken's dynamic relaxation
// (the factor carried from step to step) and the interface quasi-Newton method IQN-ILS
// (Degroote et al. 2009): a least-squares model of the inverse Jacobian from the differences
// of residuals (V) and of outputs (W), solved by a QR decomposition of V whose nearly linearly
// dependent columns are dropped (preCICE's QR2 filter), with the columns of the last R steps
// reused.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

namespace demfem::io {
class H5File;
}

namespace demfem::coupling {

/// @brief [coupling].acceleration.
enum class AccelerationKind : std::uint8_t {
  constant,  ///< x^{k+1} = x^k + omega_0 r^k
  aitken,    ///< omega^k from the last two residuals (Irons-Tuck / Kuettler-Wall)
  iqn_ils,   ///< interface quasi-Newton, inverse least squares
};

/// @brief "constant", "aitken", "iqn-ils".
const char* acceleration_name(AccelerationKind kind);

struct AccelerationSettings {
  AccelerationKind kind = AccelerationKind::iqn_ils;
  /// omega_0 in (0, 1]: the constant factor; Aitken's first factor of a step is
  /// min(omega_0, |omega of the last step|) with that one's sign; IQN-ILS relaxes with it
  /// while it has no column.
  double initial_relaxation = 0.5;
  /// IQN-ILS: the columns of the last `reuse_steps` coupling steps are kept for the later ones
  /// (0: only the previous step's, for the first iteration of a step, as preCICE does).
  std::int64_t reuse_steps = 8;
  /// IQN-ILS: most columns in the least-squares system (the oldest are dropped first).
  std::int64_t max_columns = 100;
  /// IQN-ILS: a column whose part orthogonal to the newer ones is below qr_filter times its
  /// norm is dropped (preCICE's QR2 filter); 0 = no filter.
  double qr_filter = 1e-2;
};

/// @brief One accelerator, over vectors of a fixed size (3 x interface nodes).
class Acceleration {
 public:
  virtual ~Acceleration() = default;
  /// Iteration k of the current step: from x^k and x_tilde^k = H(x^k), the next input
  /// x^{k+1}. The three spans have size(); x_next may alias neither input.
  virtual void next(std::span<const double> x, std::span<const double> x_tilde,
                    std::span<double> x_next) = 0;
  /// The step ends with its last iteration's x^k, x_tilde^k (converged, or accepted without):
  /// keeps what later steps reuse; the next call of next() is iteration 0 of a new step.
  virtual void end_step(std::span<const double> x, std::span<const double> x_tilde) = 0;
  /// The history later steps use (between steps only): a checkpoint's coupler.h5 holds it so
  /// that a resumed or recovered run iterates exactly as the uninterrupted one.
  virtual void save(io::H5File& file, const std::string& group) const = 0;
  /// Throws std::runtime_error (naming the file) for a history of another kind or size.
  virtual void load(const io::H5File& file, const std::string& group) = 0;
  /// The relaxation factor of the last next() (IQN-ILS: 0 after a quasi-Newton update).
  virtual double last_relaxation() const = 0;
  /// Columns the last next() used (IQN-ILS; 0 for the others).
  virtual std::size_t last_columns() const { return 0; }
  std::size_t size() const { return size_; }

 protected:
  explicit Acceleration(std::size_t size) : size_(size) {}
  std::size_t size_;
};

std::unique_ptr<Acceleration> make_acceleration(const AccelerationSettings& settings,
                                                std::size_t size);

/// @brief ||now - before||_2 / ||now||_2: preCICE's relative convergence measure (0 when both
/// norms are 0, infinity when only ||now|| is). `change` receives ||now - before||_2.
double relative_change(std::span<const double> now, std::span<const double> before,
                       double* change = nullptr);

}  // namespace demfem::coupling
