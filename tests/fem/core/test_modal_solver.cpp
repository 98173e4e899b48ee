// ModalSolver (the modal-reduced backend's engine) against FemSolver: with every mode it is
// the full FEM to round-off (the same Bossak step per mode); its static correction makes the
// static solution exact for any number of modes; the dynamic error falls with the mode count
// and the correction; save/restore continue bitwise, and a full FEM state projects onto the
// modes.
#include <catch2/catch.hpp>

#include <cstdio>
#include <filesystem>

#include "demfem/fem/modal_solver.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem_test/temp_dir.hpp"
#include "fem_test_util.hpp"

using namespace demfem::fem;

namespace {

/// A 0.4 m steel cantilever, 4 x 1 x 1 hex8 (48 free DOF), its whole exterior coupled, with
/// gravity, a pressure with a time-varying amplitude, Rayleigh damping and Bossak alpha -0.1.
FemProblem small_cantilever() {
  auto p =
      test::make_problem(box_mesh_hex({0, 0, 0}, {0.4, 0.05, 0.05}, {4, 1, 1}), 210e9, 0.3, 7800);
  test::clamp(p, "xmin");
  p.gravity = {0, 0, -9.81};
  PressureLoad q;
  q.faces = p.mesh.surfaces.at("zmax");
  q.magnitude = 2e4;
  q.amplitude = [](double t) { return std::sin(2000.0 * t); };
  p.pressures.push_back(q);
  p.damping.mass_factor = 5.0;
  p.damping.stiffness_factor = 2e-6;
  return p;
}

/// A 0.3 m x 0.1 m steel plate strip (MITC4, 6 x 2), clamped at x = 0: both offset surfaces
/// are coupled (moments of the offset forces).
FemProblem small_plate() {
  auto p =
      test::make_problem(plate_mesh_quad({0, 0, 0}, 0.3, 0.1, {6, 2}), 210e9, 0.3, 7800, 0.004);
  test::clamp(p, "xmin");
  p.damping.stiffness_factor = 1e-5;
  return p;
}

/// Interface forces that change every step (a moving, growing push on the first nodes).
std::vector<double> forces_at(std::size_t n3, int step) {
  std::vector<double> f(n3, 0.0);
  for (std::size_t i = 0; i < n3; ++i)
    f[i] = 50.0 * std::sin(0.3 * static_cast<double>(i) + 0.2 * step) * (1.0 + 0.05 * step) *
           (i % 3 == 2 ? 2.0 : 1.0);
  return f;
}

double max_abs_diff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, std::abs(a[i] - b[i]));
  return d;
}
double max_abs(const std::vector<double>& a) {
  double d = 0;
  for (double x : a) d = std::max(d, std::abs(x));
  return d;
}

struct Kinematics {
  std::vector<double> x, v, a;
  explicit Kinematics(std::size_t n3) : x(n3), v(n3), a(n3) {}
};

template <class Solver>
Kinematics interface_state(const Solver& s) {
  Kinematics k(3 * s.interface_mesh().node_count());
  s.interface_kinematics(k.x, k.v, k.a);
  for (std::size_t i = 0; i < k.x.size(); ++i) k.x[i] -= s.interface_mesh().reference_positions[i];
  return k;
}

}  // namespace

TEST_CASE("modal solver with every mode equals the full FEM (solid and shell, damping, loads)",
          "[fem][modal_backend]") {
  for (FemProblem p : {small_cantilever(), small_plate()}) {
    FemSolver full(p);
    ModalSettings ms;
    ms.modes = static_cast<int>(full.free_dof_count());
    ModalSolver modal(p, ms);
    const std::size_t n3 = 3 * full.interface_mesh().node_count();
    REQUIRE(modal.interface_mesh().reference_positions ==
            full.interface_mesh().reference_positions);
    double worst_x = 0, worst_v = 0, scale_x = 0, scale_v = 0;
    for (int step = 0; step < 60; ++step) {
      const auto f = forces_at(n3, step);
      full.set_interface_forces(f);
      modal.set_interface_forces(f);
      full.advance(1e-4);
      modal.advance(1e-4);
      const auto a = interface_state(full), b = interface_state(modal);
      worst_x = std::max(worst_x, max_abs_diff(a.x, b.x));
      worst_v = std::max(worst_v, max_abs_diff(a.v, b.v));
      scale_x = std::max(scale_x, max_abs(a.x));
      scale_v = std::max(scale_v, max_abs(a.v));
    }
    std::printf(
        "every mode (%d): interface displacement differs by %.2e of %.2e m, velocity by "
        "%.2e of %.2e m/s after 60 steps\n",
        modal.mode_count(), worst_x, scale_x, worst_v, scale_v);
    // Round-off only: the solid agrees to ~1e-11; the shell's eigenbasis (rotational inertia
    // t^2 / 12 of the translational, drilling penalty) amplifies round-off to ~1e-8. A
    // wrong mode, damping or step would show at 1e-3 or more.
    CHECK(worst_x < 1e-7 * scale_x);
    CHECK(worst_v < 1e-7 * scale_v);
    CHECK(max_abs_diff(full.displacements(), modal.displacements()) <
          1e-7 * max_abs(full.displacements()));
    CHECK(modal.kinetic_energy() == Approx(full.kinetic_energy()).epsilon(1e-8));
    CHECK(modal.strain_energy() == Approx(full.strain_energy()).epsilon(1e-8));
  }
}

TEST_CASE("modal solver: the static correction makes the static solution exact for any N",
          "[fem][modal_backend]") {
  for (FemProblem p : {small_cantilever(), small_plate()}) {
    FemSolver full(p);
    const std::size_t n3 = 3 * full.interface_mesh().node_count();
    const auto f = forces_at(n3, 3);
    full.set_interface_forces(f);
    full.solve_static();
    for (int n : {1, 3, 10}) {
      ModalSettings ms;
      ms.modes = n;
      ModalSolver modal(p, ms);
      modal.set_interface_forces(f);
      modal.solve_static();
      const auto a = interface_state(full), b = interface_state(modal);
      CHECK(max_abs_diff(a.x, b.x) < 1e-10 * max_abs(a.x));
      CHECK(max_abs_diff(full.displacements(), modal.displacements()) <
            1e-10 * max_abs(full.displacements()));
      CHECK(modal.strain_energy() == Approx(full.strain_energy()).epsilon(1e-9));
      ms.static_correction = false;
      ModalSolver truncated(p, ms);
      truncated.set_interface_forces(f);
      truncated.solve_static();
      std::printf(
          "static, %d modes: interface error %.2e with the correction, %.2e without "
          "(of %.2e m)\n",
          n, max_abs_diff(a.x, b.x), max_abs_diff(a.x, interface_state(truncated).x), max_abs(a.x));
    }
  }
}

TEST_CASE(
    "modal solver: the dynamic error falls with the mode count, and the correction "
    "lowers it",
    "[fem][modal_backend]") {
  // A longer cantilever (0.8 m, 16 x 1 x 1, 192 free DOF) pushed at its tip by a force that
  // rises over 2 ms and is then held; 200 steps of 1e-4 s.
  auto p =
      test::make_problem(box_mesh_hex({0, 0, 0}, {0.8, 0.05, 0.05}, {16, 1, 1}), 210e9, 0.3, 7800);
  test::clamp(p, "xmin");
  p.damping.stiffness_factor = 1e-5;
  p.bossak.alpha = -0.1;
  FemSolver full(p);
  const std::size_t n3 = 3 * full.interface_mesh().node_count();
  std::vector<double> f(n3, 0.0);
  for (std::size_t i = 0; i < n3 / 3; ++i)
    if (full.interface_mesh().reference_positions[3 * i] > 0.799) f[3 * i + 2] = -200.0;
  auto history = [&](auto& solver) {
    std::vector<double> out;
    for (int step = 0; step < 200; ++step) {
      std::vector<double> g = f;
      for (double& x : g) x *= std::min(1.0, step / 20.0);
      solver.set_interface_forces(g);
      solver.advance(1e-4);
      const auto k = interface_state(solver);
      out.insert(out.end(), k.x.begin(), k.x.end());
    }
    return out;
  };
  const auto ref = history(full);
  double previous = INFINITY;
  for (int n : {2, 4, 8, 16}) {
    ModalSettings ms;
    ms.modes = n;
    ModalSolver with(p, ms);
    ms.static_correction = false;
    ModalSolver without(p, ms);
    const double e_with = max_abs_diff(ref, history(with)) / max_abs(ref);
    const double e_without = max_abs_diff(ref, history(without)) / max_abs(ref);
    std::printf(
        "%2d modes: max interface error %.2e (relative) with the correction, %.2e "
        "without\n",
        n, e_with, e_without);
    CHECK(e_with < e_without);
    CHECK(e_with < previous);
    previous = e_with;
  }
  CHECK(previous < 1e-3);
}

TEST_CASE("modal solver: save and restore continue bitwise; a full FEM state is projected",
          "[fem][modal_backend]") {
  demfem::test::TempDir dir("modal_restore");
  const FemProblem p = small_cantilever();
  ModalSettings ms;
  ms.modes = 12;
  ModalSolver a(p, ms), b(p, ms);
  const std::size_t n3 = 3 * a.interface_mesh().node_count();
  for (int step = 0; step < 10; ++step) {
    a.set_interface_forces(forces_at(n3, step));
    a.advance(1e-4);
  }
  {
    demfem::io::H5File h5(dir.path / "m.h5", demfem::io::H5File::Mode::create);
    a.save(h5, "fem");
  }
  b.restore(demfem::io::H5File(dir.path / "m.h5", demfem::io::H5File::Mode::read), "fem");
  CHECK(b.restore_report().empty());
  for (int step = 10; step < 20; ++step) {
    a.set_interface_forces(forces_at(n3, step));
    b.set_interface_forces(forces_at(n3, step));
    a.advance(1e-4);
    b.advance(1e-4);
  }
  CHECK(interface_state(a).x == interface_state(b).x);
  CHECK(interface_state(a).a == interface_state(b).a);

  // The full FEM's checkpoint, taken by a modal solver with every mode: an exact projection.
  FemSolver full(p);
  for (int step = 0; step < 10; ++step) {
    full.set_interface_forces(forces_at(n3, step));
    full.advance(1e-4);
  }
  {
    demfem::io::H5File h5(dir.path / "f.h5", demfem::io::H5File::Mode::create);
    full.save(h5, "fem");
  }
  ms.modes = static_cast<int>(full.free_dof_count());
  ModalSolver all(p, ms);
  all.restore(demfem::io::H5File(dir.path / "f.h5", demfem::io::H5File::Mode::read), "fem");
  std::printf("projection with every mode: %s\n", all.restore_report().c_str());
  CHECK(!all.restore_report().empty());
  CHECK(max_abs_diff(interface_state(all).x, interface_state(full).x) <
        1e-9 * max_abs(interface_state(full).x));
  CHECK(all.time() == full.time());
  CHECK(all.step_count() == full.step_count());
  // ... and a FemSolver restores the modal solver's checkpoint (the reconstructed full state).
  {
    demfem::io::H5File h5(dir.path / "m2.h5", demfem::io::H5File::Mode::create);
    all.save(h5, "fem");
  }
  FemSolver back(p);
  back.restore(demfem::io::H5File(dir.path / "m2.h5", demfem::io::H5File::Mode::read), "fem");
  CHECK(max_abs_diff(back.displacements(), full.displacements()) <
        1e-9 * max_abs(full.displacements()));
}
