#include "liggghts_domain.hpp"

// LIGGGHTS 3.8's headers include each other by their plain names (-I.../liggghts).
#include <atom.h>
#include <fix_contact_property_atom_wall.h>
#include <fix_mesh_surface.h>
#include <lammps.h>
#include <mesh_mover.h>
#include <library.h>
#include <modify.h>
#include <tri_mesh.h>
#include <update.h>

#include <algorithm>
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
                               double dem_timestep, fs::path output_dir)
    : world_(world), deck_(std::move(deck)), output_dir_(std::move(output_dir)),
      mesh_fix_(std::move(mesh_fix)), dem_timestep_(dem_timestep) {
  MPI_Comm_rank(world_, &rank_);
}

LiggghtsDomain::~LiggghtsDomain() {
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
    std::vector<std::string> args = {"liggghts",      "-log",         log.string(),
                                     "-echo",         "none",         "-var",
                                     "demfem_mesh",   stl.string(),   "-var",
                                     "demfem_restart", restart_file,  "-var",
                                     "demfem_resume", resume};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    void* handle = nullptr;
    lammps_open(static_cast<int>(argv.size()), argv.data(), world_, &handle);
    lammps_ = static_cast<LAMMPS_NS::LAMMPS*>(handle);
  }
  lammps_file(lammps_, const_cast<char*>(deck_.c_str()));
  restored_ = restored_ || !restart.empty();
  return check_coupling_mesh();
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
  return {};
}

StepReport LiggghtsDomain::advance(double dt, std::int64_t substeps, bool average) {
  set_timestep(dt / static_cast<double>(substeps));
  std::vector<double> local(3 * mesh_.node_count(), 0.0);
  // "pre no" skips LIGGGHTS's set-up (neighbour lists from scratch) between the runs of a
  // coupled simulation; a run after a new time step needs it (the integrators take the time
  // step in their set-up).
  auto run = [&](std::int64_t steps) {
    command("run " + std::to_string(steps) + (set_up_ ? " pre no post no" : " post no"));
    set_up_ = true;
  };
  if (average) {
    for (std::int64_t s = 0; s < substeps; ++s) {
      run(1);
      add_contact_forces(local);
    }
    for (double& f : local) f /= static_cast<double>(substeps);
  } else {
    run(substeps);
    add_contact_forces(local);
  }
  StepReport report;
  if (rank_ == 0) report.node_forces.assign(local.size(), 0.0);
  MPI_Reduce(local.data(), rank_ == 0 ? report.node_forces.data() : nullptr,
             static_cast<int>(local.size()), MPI_DOUBLE, MPI_SUM, 0, world_);
  const double energy = local_kinetic_energy();
  const double overlap = local_max_overlap();
  MPI_Reduce(&energy, &report.kinetic_energy, 1, MPI_DOUBLE, MPI_SUM, 0, world_);
  MPI_Reduce(&overlap, &report.max_overlap, 1, MPI_DOUBLE, MPI_MAX, 0, world_);
  return report;
}

void LiggghtsDomain::add_contact_forces(std::vector<double>& node_forces) const {
  // demfem's own scheme (dem_server): each contact's force goes to the three nodes of its
  // triangle with the barycentric weights of the contact point. LIGGGHTS stores, per owned
  // particle and touched triangle (by element ID), the force on the particle and the vector
  // from its centre to the contact point (fix wall/gran ... store_force_contact_stress yes).
  // A contact on an edge shared by two triangles gets the same weights from either, so the
  // result does not depend on which triangle LIGGGHTS gave it (nor on the rank count).
  const auto* atom = lammps_->atom;
  const auto& x = positions_;
  for (int i = 0; i < atom->nlocal; ++i) {
    for (int c = 0; c < contacts_->n_partner(i); ++c) {
      const int triangle = contacts_->partner(i, c);
      const double* data = contacts_->contacthistory(i, c);  // force (3), delta (3), v_wall (3)
      const phys::Vec3 point{atom->x[i][0] + data[3], atom->x[i][1] + data[4],
                             atom->x[i][2] + data[5]};
      const std::int32_t* t = &mesh_.triangles[3 * static_cast<std::size_t>(triangle)];
      phys::Vec3 v[3];
      for (int k = 0; k < 3; ++k) v[k] = {x[3 * t[k]], x[3 * t[k] + 1], x[3 * t[k] + 2]};
      const auto closest = phys::closest_point_triangle(point, v[0], v[1], v[2]);
      const double weight[3] = {closest.u, closest.v, closest.w};
      for (int k = 0; k < 3; ++k)
        for (int d = 0; d < 3; ++d) node_forces[3 * t[k] + d] -= weight[k] * data[d];
    }
  }
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

double LiggghtsDomain::local_max_overlap() const {
  // Every owned particle against every interface triangle whose box it reaches: O(particles x
  // triangles) per coupling step, which is what bench/ measures against the step's cost.
  const auto* atom = lammps_->atom;
  const auto& x = positions_;
  double largest = 0.0;
  for (int i = 0; i < atom->nlocal; ++i) {
    const phys::Vec3 p{atom->x[i][0], atom->x[i][1], atom->x[i][2]};
    const double r = atom->radius[i];
    for (std::size_t t = 0; t < mesh_.triangle_count(); ++t) {
      phys::Vec3 v[3];
      for (int k = 0; k < 3; ++k) {
        const double* q = &x[3 * mesh_.triangles[3 * t + k]];
        v[k] = {q[0], q[1], q[2]};
      }
      const auto outside = [&](double pc, double a, double b, double c) {
        return pc + r < std::min({a, b, c}) || pc - r > std::max({a, b, c});
      };
      if (outside(p.x, v[0].x, v[1].x, v[2].x) || outside(p.y, v[0].y, v[1].y, v[2].y) ||
          outside(p.z, v[0].z, v[1].z, v[2].z))
        continue;
      const phys::Vec3 d = p - phys::closest_point_triangle(p, v[0], v[1], v[2]).point;
      largest = std::max(largest, r - std::sqrt(phys::dot(d, d)));
    }
  }
  return largest;
}

void LiggghtsDomain::write_restart(const fs::path& file) {
  const fs::path partial = file.string() + ".partial";
  command("write_restart " + partial.string());
  MPI_Barrier(world_);
  if (rank_ == 0) fs::rename(partial, file);
  MPI_Barrier(world_);
}

std::int64_t LiggghtsDomain::dem_steps() const {
  return static_cast<std::int64_t>(lammps_->update->ntimestep);
}

void LiggghtsDomain::move_mesh(const std::vector<double>& positions,
                               const std::vector<double>& velocities) {
  positions_ = positions;
  double*** nodes = node_access_->get_nodes();
  double*** node_velocities = node_access_->get_v();
  const int elements = tri_mesh_->sizeLocal() + tri_mesh_->sizeGhost();
  for (int e = 0; e < elements; ++e) {
    const std::int32_t* t = &mesh_.triangles[3 * static_cast<std::size_t>(tri_mesh_->id(e))];
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d) {
        nodes[e][k][d] = positions[3 * t[k] + d];
        node_velocities[e][k][d] = velocities[3 * t[k] + d];
      }
  }
  // The elements' centres and bounding radii (contact search) now; their edges and normals
  // when the next run sets up (LIGGGHTS recomputes them from the nodes then).
  tri_mesh_->updateCenterRbound(0, elements);
  set_up_ = false;
}

}  // namespace demfem::liggghts
