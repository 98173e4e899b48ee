#include "demfem/coupling/local_solvers.hpp"

#include <omp.h>

#include <iostream>
#include <stdexcept>
#include <type_traits>

#include <toml++/toml.h>

#include "demfem/coupling/coupling_settings.hpp"
#include "demfem/coupling/solver_link.hpp"

#include "demfem/dem/dem_backend.hpp"
#include "demfem/dem/run/dem_run.hpp"
#include "demfem/fem/assembly.hpp"
#include "demfem/fem/fem_backend.hpp"
#include "demfem/fem/fem_output.hpp"
#include "demfem/fem/fem_scene.hpp"

namespace demfem::coupling {

namespace {

// Forwards every call to the adapter; owns the engine objects the adapter refers to. Built
// exactly as the servers build them (dem_server.cpp, fem_server.cpp) so that the in-process
// run and the three-process run compute the same thing.
class LocalDem final : public protocol::SolverBackend {
 public:
  LocalDem(const dem::DemScene& scene, const scene::RunSettings& run,
           const std::filesystem::path& out)
      : run_(scene, out, run.seed, run.output_interval, nullptr, true), backend_(run_) {}
  ~LocalDem() override {
    try {
      // The end state, as dem_server; not after a step was cancelled half-way (a stop signal):
      // dem_server writes none then either, and that state lies between two coupling steps.
      if (run_.system().step_count() > 0 && !cancelled_) run_.finish();
    } catch (const std::exception& e) {
      std::cerr << "dem: " << e.what() << "\n";
    }
  }
  std::string name() const override { return backend_.name() + " in process"; }
  std::optional<InterfaceMesh> published_mesh() override { return backend_.published_mesh(); }
  void on_mesh(const InterfaceMesh& m) override { backend_.on_mesh(m); }
  StepResult step(const StepCommand& c, InterfaceBuffers& b) override {
    try {
      return backend_.step(c, b);
    } catch (const dem::Cancelled&) {
      cancelled_ = true;
      throw;
    }
  }
  void write_checkpoint(const std::filesystem::path& f, std::int64_t s) override {
    backend_.write_checkpoint(f, s);
  }
  void restore_checkpoint(const std::filesystem::path& f, std::int64_t s) override {
    backend_.restore_checkpoint(f, s);
  }
  void set_cancel_flag(const std::atomic<bool>* flag) override { backend_.set_cancel_flag(flag); }
  bool supports_iteration() const override { return backend_.supports_iteration(); }
  void save_iteration_state() override { backend_.save_iteration_state(); }
  void restore_iteration_state() override { backend_.restore_iteration_state(); }
  void accept_step() override { backend_.accept_step(); }
  void drop_end_state() { cancelled_ = true; }

 private:
  dem::DemRun run_;
  dem::DemBackend backend_;
  bool cancelled_ = false;  // no end state: a step was cut, or the folder is not ours any more
};

template <class Solver>
class LocalFem final : public protocol::SolverBackend {
 public:
  LocalFem(Solver solver, const fem::FemScene& scene, const scene::RunSettings& run,
           const std::filesystem::path& out, bool resume)
      : solver_(std::move(solver)) {
    for (const auto& note : scene.notes) std::cerr << "fem: note: " << note << "\n";
    // The model checks fem_server makes before it attaches (a mechanism, missing clamps).
    if constexpr (std::is_same_v<Solver, fem::FemSolver>) {
      try {
        solver_.prepare(scene.analysis == fem::Analysis::static_analysis);
      } catch (const fem::FemModelError& e) {
        throw protocol::BackendError(protocol::ErrorKind::bad_input, e.what());
      }
    }
    if (scene.output.enabled) {
      output_ = std::make_unique<fem::FemOutput>(
          out, "fem", solver_.problem().mesh, scene.output,
          resume ? fem::OutputMode::resume : fem::OutputMode::replace);
    }
    const double interval =
        scene.output.interval > 0.0 ? scene.output.interval : run.output_interval;
    backend_ = std::make_unique<fem::StructureBackend<Solver>>(solver_, output_.get(), interval);
    if constexpr (std::is_same_v<Solver, fem::FemSolver>) {
      if (scene.monitor.enabled) {  // the full FEM only (read_fem_scene refuses it otherwise)
        monitor_ = std::make_unique<fem::FemMonitor>(out, scene.monitor, resume);
        backend_->set_monitor(monitor_.get());
      }
    }
    if (!resume) backend_->write_initial_output();  // reference state
  }
  ~LocalFem() override {
    if (!write_end_state_) return;
    try {
      backend_->write_final_output();  // the end state
    } catch (const std::exception& e) {
      std::cerr << "fem: " << e.what() << "\n";
    }
  }
  std::string name() const override { return backend_->name() + " in process"; }
  std::optional<InterfaceMesh> published_mesh() override { return backend_->published_mesh(); }
  void on_mesh(const InterfaceMesh& m) override { backend_->on_mesh(m); }
  StepResult step(const StepCommand& c, InterfaceBuffers& b) override {
    return backend_->step(c, b);
  }
  void write_checkpoint(const std::filesystem::path& f, std::int64_t s) override {
    backend_->write_checkpoint(f, s);
  }
  void restore_checkpoint(const std::filesystem::path& f, std::int64_t s) override {
    backend_->restore_checkpoint(f, s);
  }
  bool supports_iteration() const override { return backend_->supports_iteration(); }
  void save_iteration_state() override { backend_->save_iteration_state(); }
  void restore_iteration_state() override { backend_->restore_iteration_state(); }
  void accept_step() override { backend_->accept_step(); }
  void drop_end_state() { write_end_state_ = false; }

 private:
  bool write_end_state_ = true;
  Solver solver_;
  std::unique_ptr<fem::FemOutput> output_;
  std::unique_ptr<fem::FemMonitor> monitor_;
  std::unique_ptr<fem::StructureBackend<Solver>> backend_;
};

}  // namespace

SolverSections check_solver_sections(const scene::Document& scene, std::uint64_t seed) {
  SolverSections out;
  const scene::Table root = scene.root();
  const auto fem = root.table("fem");
  // With fem.backend = "external" and no fem.mesh, [fem] belongs to the outside program
  // (demfem reads only backend, command, dt and analysis: coupling_settings.cpp); with a mesh
  // it is also a demfem structure (for the beam check, or to resume with another backend).
  const bool external_only = names_external_backend(fem) && !fem->has("mesh");
  if (fem && !external_only) {
    const fem::FemScene fs = fem::read_fem_scene(*fem);
    out.fem_nodes = fs.problem.mesh.nodes.size();
    out.fem_elements = fs.problem.mesh.elements.size();
    if (fs.backend != fem::FemBackendKind::external)
      out.fem_interface_nodes = fem::build_interface(fs.problem).mesh.node_count();
  }
  // With dem.backend = "external", [dem] belongs to the outside program as [fem] does to an
  // external FEM: demfem reads only backend, command, dt and settle_time (coupling_settings);
  // dem_server's keys (particles, materials, output, sensors) are neither checked nor applied.
  const auto dem_table = root.table("dem");
  if (names_external_backend(dem_table)) {
    out.dem_backend = "external";
    // The scene with its overrides, as TOML: the keys [dem] holds (the reader lists none).
    const toml::table tree = toml::parse(scene.canonical_text());
    if (const toml::table* dem = tree["dem"].as_table()) {
      for (const auto& [key, value] : *dem) {
        const std::string k(key.str());
        if (k != "backend" && k != "command" && k != "dt" && k != "settle_time" && k != "external")
          out.dem_unapplied_keys.push_back(k);
      }
    }
    return out;
  }
  if (auto dem = dem_table) {
    const dem::DemScene ds = dem::read_dem_scene(*dem);
    // The DEM adapter needs it only when the mesh arrives; say so before anything starts.
    if (fem && ds.interface_material < 0) {
      throw scene::SceneError(
          dem->where("interface_material") +
          ": a coupled scene needs it: the [[dem.materials]] name of the structure's surface");
    }
    out.dem_backend = dem::dem_backend_name(ds.settings.backend);
    out.dem_threads = ds.settings.threads > 0 ? ds.settings.threads : omp_get_max_threads();
    const auto setup = dem::DemRun::setup(ds, seed);
    out.dem_setup_particles = setup->setup_particles();
    out.dem_start_time = setup->system().time();
    if (ds.load && ds.load->keep_time) out.dem_start_where = dem->table("load")->where("keep_time");
  }
  return out;
}

void drop_end_state(protocol::SolverBackend* backend) {
  if (auto* dem = dynamic_cast<LocalDem*>(backend)) dem->drop_end_state();
  if (auto* fem = dynamic_cast<LocalFem<fem::FemSolver>*>(backend)) fem->drop_end_state();
  if (auto* fem = dynamic_cast<LocalFem<fem::ModalSolver>*>(backend)) fem->drop_end_state();
  if (auto* fem = dynamic_cast<LocalFem<fem::RigidSolver>*>(backend)) fem->drop_end_state();
}

std::unique_ptr<protocol::SolverBackend> make_local_dem(const scene::Document& scene,
                                                        const CouplingSettings& settings,
                                                        const std::filesystem::path& out) {
  const auto dem = scene.root().table("dem");
  if (!dem) return nullptr;
  return std::make_unique<LocalDem>(dem::read_dem_scene(*dem), settings.run, out);
}

std::unique_ptr<protocol::SolverBackend> make_local_fem(const scene::Document& scene,
                                                        const CouplingSettings& settings,
                                                        const std::filesystem::path& out,
                                                        bool resume) {
  const auto fem = scene.root().table("fem");
  if (!fem) return nullptr;
  fem::FemScene fs = fem::read_fem_scene(*fem);
  // A model the reduced backends refuse at set-up (a rigid reference point too far out, more
  // modes than DOFs) is bad input, as fem_server reports it (exit status 2).
  auto reduced = [&](auto make) -> std::unique_ptr<protocol::SolverBackend> {
    try {
      return make();
    } catch (const fem::FemModelError& e) {
      throw protocol::BackendError(protocol::ErrorKind::bad_input, e.what());
    } catch (const std::invalid_argument& e) {
      throw protocol::BackendError(protocol::ErrorKind::bad_input, e.what());
    }
  };
  switch (fs.backend) {
    case fem::FemBackendKind::modal:
      return reduced([&] {
        fem::ModalSolver solver(std::move(fs.problem), fs.modal);
        return std::make_unique<LocalFem<fem::ModalSolver>>(std::move(solver), fs, settings.run,
                                                            out, resume);
      });
    case fem::FemBackendKind::rigid:
      return reduced([&] {
        fem::RigidSolver solver(std::move(fs.problem), fs.rigid);
        return std::make_unique<LocalFem<fem::RigidSolver>>(std::move(solver), fs, settings.run,
                                                            out, resume);
      });
    case fem::FemBackendKind::external:
      throw scene::SceneError(fem->where("backend") +
                              ": \"external\" runs the program of fem.command in its own "
                              "process; --in-process runs only demfem's own backends (fem, "
                              "modal, rigid)");
    case fem::FemBackendKind::fem:
      break;
  }
  fem::FemSolver solver(std::move(fs.problem));
  return std::make_unique<LocalFem<fem::FemSolver>>(std::move(solver), fs, settings.run, out,
                                                    resume);
}

}  // namespace demfem::coupling
