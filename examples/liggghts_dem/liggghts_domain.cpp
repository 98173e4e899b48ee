#include "liggghts_domain.hpp"

// LIGGGHTS 3.8's headers include each other by their plain names (-I.../liggghts).
#include <atom.h>
#include <fix_contact_property_atom_wall.h>
#include <fix_mesh_surface.h>
#include <lammps.h>
#include <library.h>
#include <mesh_mover.h>
#include <modify.h>
#include <timer.h>
#include <tri_mesh.h>
#include <update.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>

#include "demfem/dem/physics/geometry.hpp"

namespace demfem::liggghts {

namespace fs = std::filesystem;
namespace phys = demfem::dem::phys;

/// LIGGGHTS lets only its mesh movers write a mesh's nodes and node velocities: the adapter
/// moves the coupling mesh through one that does nothing on its own.
class MeshNodeAccess : public LAMMPS_NS::MeshMover {
 public:
  MeshNodeAccess(LAMMPS_NS::LAMMPS* lammps, LAMMPS_NS::TriMesh* mesh)
      : LAMMPS_NS::MeshMover(lammps, mesh, nullptr) {}
  void post_create() override {}
  void pre_delete() override {}
  void initial_integrate(double, double, double) override {}
};

namespace {

/// LIGGGHTS recomputes a surface mesh's edges, normals and areas from its nodes in a run's
/// full set-up, which also rebuilds every neighbour list from scratch: in a small coupled run
/// that set-up, every coupling step, was 77 % of the DEM's time. The recomputation alone is
/// protected in SurfaceMesh; a derived class may name it (the class is never made).
struct SurfaceGeometry : LAMMPS_NS::TriMesh {
  static void recompute(LAMMPS_NS::TriMesh& mesh) {
    auto owned = &SurfaceGeometry::recalcLocalSurfProperties;  // collective: sums the area
    auto ghosts = &SurfaceGeometry::recalcGhostSurfProperties;
    (mesh.*owned)();
    (mesh.*ghosts)();
  }
};

/// The one reduction of a coupling step: the node forces and the kinetic energy are summed
/// over the ranks, the largest overlap (the last value) is the largest of theirs. The values
/// travel as one element of a contiguous type, so MPI hands the whole array to this function.
void sum_then_max(void* in, void* inout, int* count, MPI_Datatype* type) {
  int bytes = 0;
  MPI_Type_size(*type, &bytes);
  const std::size_t n = static_cast<std::size_t>(bytes) / sizeof(double);
  const auto* a = static_cast<const double*>(in);
  auto* b = static_cast<double*>(inout);
  for (int e = 0; e < *count; ++e, a += n, b += n) {
    for (std::size_t i = 0; i + 1 < n; ++i) b[i] += a[i];
    b[n - 1] = std::max(b[n - 1], a[n - 1]);
  }
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

std::uint64_t liggghts_seed(std::uint64_t run_seed) {
  // LIGGGHTS takes only primes above 10000 as seeds: the first prime from 100003 + 1000 s
  // on (primes lie closer than 1000 apart there, so each run.seed gets its own).
  auto is_prime = [](std::uint64_t n) {
    for (std::uint64_t d = 2; d * d <= n; ++d)
      if (n % d == 0) return false;
    return true;
  };
  std::uint64_t candidate = 100003 + 1000 * (run_seed % 1000000000);
  while (!is_prime(candidate)) ++candidate;
  return candidate;
}

void write_interface_stl(const InterfaceMesh& mesh, const fs::path& file) {
  const fs::path partial = file.string() + ".partial";
  {
    std::ofstream out(partial);
    char line[160];
    out << "solid demfem_interface\n";
    for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
      out << " facet normal 0 0 0\n  outer loop\n";
      for (int k = 0; k < 3; ++k) {
        const double* p = &mesh.reference_positions[3 * mesh.triangles[3 * t + k]];
        std::snprintf(line, sizeof line, "   vertex %.17g %.17g %.17g\n", p[0], p[1], p[2]);
        out << line;
      }
      out << "  endloop\n endfacet\n";
    }
    out << "endsolid demfem_interface\n";
    if (!out.flush()) throw std::runtime_error("cannot write " + partial.string());
  }
  fs::rename(partial, file);
}

LiggghtsDomain::LiggghtsDomain(MPI_Comm world, fs::path deck, std::string mesh_fix,
                               double dem_timestep, fs::path output_dir, std::uint64_t seed)
    : world_(world),
      deck_(std::move(deck)),
      output_dir_(std::move(output_dir)),
      mesh_fix_(std::move(mesh_fix)),
      seed_(seed),
      dem_timestep_(dem_timestep) {
  MPI_Comm_rank(world_, &rank_);
}

LiggghtsDomain::~LiggghtsDomain() {
  if (reduction_op_ != MPI_OP_NULL) MPI_Op_free(&reduction_op_);
  if (reduction_type_ != MPI_DATATYPE_NULL) MPI_Type_free(&reduction_type_);
  // After a read_restart LIGGGHTS 3.8 crashes in its own destructor (in deleting its Error
  // object): the instance is then left to the process's end, its files flushed.
  if (restored_)
    std::fflush(nullptr);
  else if (lammps_)
    lammps_close(lammps_);
}

void LiggghtsDomain::command(const std::string& line) {
  lammps_command(lammps_, const_cast<char*>(line.c_str()));
}

void LiggghtsDomain::set_timestep(double timestep) {
  if (timestep == timestep_) return;
  char line[64];
  std::snprintf(line, sizeof line, "timestep %.17g", timestep);
  command(line);
  timestep_ = timestep;
  set_up_ = false;
}

std::string LiggghtsDomain::attach(const InterfaceMesh& mesh, const fs::path& restart) {
  mesh_ = mesh;
  sums_.assign(3 * mesh_.node_count() + 2, 0.0);
  if (reduction_type_ == MPI_DATATYPE_NULL) {
    MPI_Type_contiguous(static_cast<int>(sums_.size()), MPI_DOUBLE, &reduction_type_);
    MPI_Type_commit(&reduction_type_);
    MPI_Op_create(&sum_then_max, 1, &reduction_op_);
  }
  const fs::path stl = output_dir_ / "demfem_interface.stl";
  const fs::path log = output_dir_ / "liggghts.log";
  const std::string restart_file = restart.empty() ? "none" : restart.string();
  const std::string resume = restart.empty() ? "0" : "1";
  if (lammps_) {
    // A restore: LIGGGHTS reads a restart file only into an empty simulation. `clear` empties
    // this one (a second LIGGGHTS instance in the same process crashes in 3.8: its style
    // tables are global); the variables stay and are set anew.
    node_access_.reset();
    tri_mesh_ = nullptr;
    contacts_ = nullptr;
    set_up_ = false;
    timestep_ = 0.0;
    command("clear");
    command("variable demfem_restart delete");
    command("variable demfem_resume delete");
    command("variable demfem_restart index " + restart_file);
    command("variable demfem_resume index " + resume);
  } else {
    if (rank_ == 0) {
      fs::create_directories(output_dir_);
      write_interface_stl(mesh_, stl);
    }
    MPI_Barrier(world_);
    // The deck reads the mesh as ${demfem_mesh}; LIGGGHTS's screen output goes to stdout (the
    // run's log), its own log file beside the run's output.
    // ${demfem_output} is the run's output folder (for the deck's own files),
    // ${demfem_seed} a seed for the deck's random commands that follows run.seed.
    const std::pair<const char*, std::string> variables[] = {
        {"demfem_mesh", stl.string()},
        {"demfem_restart", restart_file},
        {"demfem_resume", resume},
        {"demfem_output", output_dir_.string()},
        {"demfem_seed", std::to_string(liggghts_seed(seed_))}};
    std::vector<std::string> args = {"liggghts", "-log", log.string(), "-echo", "none"};
    for (const auto& [name, value] : variables) args.insert(args.end(), {"-var", name, value});
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    void* handle = nullptr;
    lammps_open(static_cast<int>(argv.size()), argv.data(), world_, &handle);
    lammps_ = static_cast<LAMMPS_NS::LAMMPS*>(handle);
  }
  lammps_file(lammps_, const_cast<char*>(deck_.c_str()));
  restored_ = restored_ || !restart.empty();
  std::string refusal = check_coupling_mesh();
  if (refusal.empty() && !restart.empty()) refusal = restore_adapter_state(restart);
  return refusal;
}

std::string LiggghtsDomain::check_coupling_mesh() {
  const std::string deck = deck_.string();
  const std::string add_line = "Add `fix " + mesh_fix_ +
                               " all mesh/surface file ${demfem_mesh} type T` (T: the wall's "
                               "material type) and list it in a fix wall/gran with "
                               "`store_force_contact_stress yes`";
  auto* fix = lammps_->modify->find_fix_id(mesh_fix_.c_str());
  if (!fix) {
    std::string found;
    for (int i = 0; i < lammps_->modify->nfix; ++i) {
      const std::string style = lammps_->modify->fix[i]->style;
      if (style.rfind("mesh/surface", 0) == 0)
        found += (found.empty() ? "" : ", ") + std::string(lammps_->modify->fix[i]->id) + " (" +
                 style + ")";
    }
    return "the LIGGGHTS deck " + deck + " has no fix '" + mesh_fix_ +
           "' (dem.external.mesh_fix), the coupling mesh; its mesh fixes: " +
           (found.empty() ? "none" : found) + ". " + add_line;
  }
  const std::string style = fix->style;
  if (style.rfind("mesh/surface", 0) != 0)
    return "fix '" + mesh_fix_ + "' of the LIGGGHTS deck " + deck + " is a " + style +
           ", not a mesh/surface. " + add_line;
  auto* surface = static_cast<LAMMPS_NS::FixMeshSurface*>(fix);
  contacts_ = surface->meshforceContactStress();
  if (!contacts_)
    return "the LIGGGHTS deck " + deck + ": no fix wall/gran stores the contacts with fix '" +
           mesh_fix_ + "': add `store_force_contact_stress yes` to the fix wall/gran that lists "
           "it (the adapter distributes each contact's force to the nodes from its contact point)";
  const auto* atom = lammps_->atom;
  if (!atom->sphere_flag || atom->superquadric_flag)
    return std::string("the LIGGGHTS deck ") + deck + " uses atom_style " + atom->atom_style +
           ": the adapter couples spheres only (atom_style granular or sphere); polyhedral "
           "particles couple with demfem's own DEM, dem_server (dem.backend = \"cpu\" or "
           "\"cuda\", [[dem.shapes]])";
  tri_mesh_ = surface->triMesh();
  // LIGGGHTS distributes a mesh's elements over the ranks when a run sets up: a run of no
  // steps (it computes the forces of the initial state) makes the element counts known.
  set_timestep(dem_timestep_);
  command("run 0 post no");
  set_up_ = true;
  positions_ = mesh_.reference_positions;
  held_velocities_.assign(positions_.size(), 0.0);
  node_access_ = std::make_unique<MeshNodeAccess>(lammps_, tri_mesh_);
  // The nodes' velocities, which the wall contact reads when the mesh has them (a conveyor
  // belt's surface_vel or a fix move/mesh of the deck would have made them already).
  if (!tri_mesh_->prop().getElementProperty<LAMMPS_NS::MultiVectorContainer<double, 3, 3>>("v"))
    tri_mesh_->prop().addElementProperty<LAMMPS_NS::MultiVectorContainer<double, 3, 3>>(
        "v", "comm_exchange_borders", "frame_invariant", "restart_no");
  const auto elements = static_cast<std::size_t>(tri_mesh_->sizeGlobal());
  if (elements != mesh_.triangle_count())
    return "fix '" + mesh_fix_ + "' of the LIGGGHTS deck " + deck + " has " +
           std::to_string(elements) + " triangles, demfem's interface " +
           std::to_string(mesh_.triangle_count()) +
           ": it must read the interface demfem writes, file ${demfem_mesh}, unscaled and "
           "unmoved";
  if (tri_mesh_->isMoving())
    return "fix '" + mesh_fix_ + "' of the LIGGGHTS deck " + deck +
           " is moved by the deck (fix move/mesh): the structure moves the coupling mesh; "
           "remove the deck's motion of it";
  // A mesh that moves, to LIGGGHTS: its particle-mesh neighbour lists then keep the whole
  // skin (a fixed mesh's keep half: only the particles move) and are rebuilt when a node has
  // moved more than skin/2 since the last build, as for a mesh of fix move/mesh.
  tri_mesh_->registerMove(false, true, false);
  tri_mesh_->storeNodePosRebuild();
  return {};
}

void LiggghtsDomain::run(std::int64_t steps) {
  // "pre no" skips LIGGGHTS's full set-up (every fix's init, neighbour lists from scratch)
  // between the runs of a coupled simulation, as if it were one long run; a run after a new
  // time step needs it (the integrators take the time step in their set-up).
  const auto start = std::chrono::steady_clock::now();
  const bool full = !set_up_;
  command("run " + std::to_string(steps) + (full ? " post no" : " pre no post no"));
  set_up_ = true;
  const double wall = seconds_since(start);
  const double loop = lammps_->timer->array[TIME_LOOP];
  times_.loop += loop;
  (full ? times_.set_up : times_.run_fixed) += wall - loop;
  times_.set_ups += full ? 1 : 0;
  ++times_.runs;
}

StepReport LiggghtsDomain::advance(double dt, std::int64_t substeps, bool average) {
  set_timestep(dt / static_cast<double>(substeps));
  std::fill(sums_.begin(), sums_.end(), 0.0);
  double overlap = 0.0;
  if (average) {
    for (std::int64_t s = 0; s < substeps; ++s) {
      run(1);
      const auto start = std::chrono::steady_clock::now();
      overlap = add_contact_forces(sums_);  // the last substep's overlap counts
      times_.gather += seconds_since(start);
    }
    for (std::size_t i = 0; i < 3 * mesh_.node_count(); ++i)
      sums_[i] /= static_cast<double>(substeps);
  } else {
    run(substeps);
    const auto start = std::chrono::steady_clock::now();
    overlap = add_contact_forces(sums_);
    times_.gather += seconds_since(start);
  }
  StepReport report;
  const auto start = std::chrono::steady_clock::now();
  reduce_onto_rank0(report, overlap);
  times_.gather += seconds_since(start);
  ++times_.steps;
  return report;
}

void LiggghtsDomain::reduce_onto_rank0(StepReport& report, double overlap) {
  const std::size_t n = 3 * mesh_.node_count();
  sums_[n] = local_kinetic_energy();
  sums_[n + 1] = overlap;
  std::vector<double> total(rank_ == 0 ? sums_.size() : 0);
  MPI_Reduce(sums_.data(), rank_ == 0 ? total.data() : nullptr, 1, reduction_type_, reduction_op_,
             0, world_);
  if (rank_ != 0) return;
  report.kinetic_energy = total[n];
  report.max_overlap = total[n + 1];
  total.resize(n);
  report.node_forces = std::move(total);
}

double LiggghtsDomain::add_contact_forces(std::vector<double>& sums) const {
  // demfem's own scheme (dem_server): each contact's force goes to the three nodes of its
  // triangle with the barycentric weights of the contact point. LIGGGHTS stores, per owned
  // particle and touched triangle (by element ID), the force on the particle and the vector
  // from its centre to the contact point (fix wall/gran ... store_force_contact_stress yes).
  // A contact on an edge shared by two triangles gets the same weights from either, so the
  // result does not depend on which triangle LIGGGHTS gave it (nor on the rank count).
  // The overlap of each contact (radius less the centre's distance to the triangle) is the
  // largest overlap with the interface: a particle that overlaps a triangle touches it.
  const auto* atom = lammps_->atom;
  const auto& x = positions_;
  double largest = 0.0;
  for (int i = 0; i < atom->nlocal; ++i) {
    const int contacts = contacts_->n_partner(i);
    if (contacts == 0) continue;
    const phys::Vec3 centre{atom->x[i][0], atom->x[i][1], atom->x[i][2]};
    for (int c = 0; c < contacts; ++c) {
      const int triangle = contacts_->partner(i, c);
      const double* data = contacts_->contacthistory(i, c);  // force (3), delta (3), v_wall (3)
      const phys::Vec3 point{centre.x + data[3], centre.y + data[4], centre.z + data[5]};
      const std::int32_t* t = &mesh_.triangles[3 * static_cast<std::size_t>(triangle)];
      phys::Vec3 v[3];
      for (int k = 0; k < 3; ++k) v[k] = {x[3 * t[k]], x[3 * t[k] + 1], x[3 * t[k] + 2]};
      const auto closest = phys::closest_point_triangle(point, v[0], v[1], v[2]);
      const double weight[3] = {closest.u, closest.v, closest.w};
      for (int k = 0; k < 3; ++k)
        for (int d = 0; d < 3; ++d) sums[3 * t[k] + d] -= weight[k] * data[d];
      const phys::Vec3 gap = centre - phys::closest_point_triangle(centre, v[0], v[1], v[2]).point;
      largest = std::max(largest, atom->radius[i] - std::sqrt(phys::dot(gap, gap)));
    }
  }
  return largest;
}

double LiggghtsDomain::local_kinetic_energy() const {
  const auto* atom = lammps_->atom;
  double energy = 0.0;
  for (int i = 0; i < atom->nlocal; ++i) {
    const double m = atom->rmass[i], r = atom->radius[i];
    const double* v = atom->v[i];
    const double* w = atom->omega[i];
    energy += 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) +
              0.2 * m * r * r * (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
  }
  return energy;
}

void LiggghtsDomain::move_mesh(const std::vector<double>& kinematics) {
  const auto start = std::chrono::steady_clock::now();
  const std::size_t n = 3 * mesh_.node_count();
  std::copy(kinematics.begin(), kinematics.begin() + static_cast<std::ptrdiff_t>(n),
            positions_.begin());
  const double* velocities = kinematics.data() + n;
  double*** nodes = node_access_->get_nodes();
  double*** node_velocities = node_access_->get_v();
  const int elements = tri_mesh_->sizeLocal() + tri_mesh_->sizeGhost();
  for (int e = 0; e < elements; ++e) {
    const std::int32_t* t = &mesh_.triangles[3 * static_cast<std::size_t>(tri_mesh_->id(e))];
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d) {
        nodes[e][k][d] = positions_[3 * t[k] + d];
        node_velocities[e][k][d] = velocities[3 * t[k] + d];
      }
  }
  // The elements' centres and bounding radii (contact search), edges, normals and areas. The
  // forces of the coming step's first half-step stay those of the last step, at the mesh's
  // old place: LIGGGHTS's own convention for moving meshes (fix move/mesh moves a mesh in the
  // step's first half, the forces follow). A set-up would recompute them at a cost of 1.2 ms
  // per coupling step on bench/liggghts_dem's bed (its mesh neighbour list from scratch).
  tri_mesh_->updateCenterRbound(0, elements);
  SurfaceGeometry::recompute(*tri_mesh_);
  held_velocities_.assign(velocities, velocities + n);
  times_.mesh_update += seconds_since(start);
}

}  // namespace demfem::liggghts
