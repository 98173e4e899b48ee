// LiggghtsDomain's checkpoints: LIGGGHTS's restart file (particles, contact histories, the
// fixes' states) and, beside it, the adapter's state that the restart file lacks:
//
//  * the coupling mesh as the adapter held it in the last step (node positions and
//    velocities): LIGGGHTS's restart file keeps no mesh nodes, and the deck reads the
//    undeformed interface;
//  * every particle's force and torque of the last step. The next step's first half-step
//    uses them (velocity Verlet). A run's set-up, which a restored LIGGGHTS needs, recomputes
//    them at the full-step velocities, while the step computed them at the half-step ones:
//    with damped contacts they differ (4e-4 of the interface force one step after a restore,
//    measured on beam_spheres_ci), so the stored ones replace the set-up's.
//
// File (native byte order, doubles): node count n, particle count m, 3 n positions (m),
// 3 n velocities (m/s), then per particle its tag, force (3, N) and torque (3, N m).
#include <atom.h>
#include <lammps.h>
#include <update.h>

#include <fstream>
#include <stdexcept>
#include <unordered_map>

#include "liggghts_domain.hpp"

namespace demfem::liggghts {

namespace fs = std::filesystem;

namespace {
constexpr std::size_t kValuesPerParticle = 7;  // tag, force, torque
}

fs::path adapter_state_file(const fs::path& restart) {
  return restart.string() + ".adapter";
}

void LiggghtsDomain::write_restart(const fs::path& file) {
  // The adapter's state first: a checkpoint whose restart file is whole has it too.
  write_adapter_state(adapter_state_file(file));
  const fs::path partial = file.string() + ".partial";
  command("write_restart " + partial.string());
  MPI_Barrier(world_);
  if (rank_ == 0) fs::rename(partial, file);
  MPI_Barrier(world_);
}

void LiggghtsDomain::write_adapter_state(const fs::path& file) {
  const auto* atom = lammps_->atom;
  std::vector<double> mine;
  mine.reserve(kValuesPerParticle * static_cast<std::size_t>(atom->nlocal));
  for (int i = 0; i < atom->nlocal; ++i) {
    mine.push_back(static_cast<double>(atom->tag[i]));
    for (int d = 0; d < 3; ++d) mine.push_back(atom->f[i][d]);
    for (int d = 0; d < 3; ++d) mine.push_back(atom->torque[i][d]);
  }
  int ranks = 1;
  MPI_Comm_size(world_, &ranks);
  const int count = static_cast<int>(mine.size());
  std::vector<int> counts(static_cast<std::size_t>(ranks)), offsets(counts.size(), 0);
  MPI_Gather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, world_);
  std::vector<double> particles;
  if (rank_ == 0) {
    for (std::size_t r = 1; r < counts.size(); ++r) offsets[r] = offsets[r - 1] + counts[r - 1];
    particles.resize(static_cast<std::size_t>(offsets.back() + counts.back()));
  }
  MPI_Gatherv(mine.data(), count, MPI_DOUBLE, particles.data(), counts.data(), offsets.data(),
              MPI_DOUBLE, 0, world_);
  if (rank_ != 0) return;
  const fs::path partial = file.string() + ".partial";
  {
    std::ofstream out(partial, std::ios::binary);
    const double header[2] = {static_cast<double>(mesh_.node_count()),
                              static_cast<double>(particles.size() / kValuesPerParticle)};
    auto write = [&](const double* data, std::size_t n) {
      out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(n * 8));
    };
    write(header, 2);
    write(positions_.data(), positions_.size());
    write(held_velocities_.data(), held_velocities_.size());
    write(particles.data(), particles.size());
    if (!out.flush()) throw std::runtime_error("cannot write " + partial.string());
  }
  fs::rename(partial, file);
}

std::string LiggghtsDomain::restore_adapter_state(const fs::path& restart) {
  const fs::path file = adapter_state_file(restart);
  std::ifstream in(file, std::ios::binary);
  std::vector<double> values((in ? fs::file_size(file) : 0) / sizeof(double));
  in.read(reinterpret_cast<char*>(values.data()),
          static_cast<std::streamsize>(values.size() * sizeof(double)));
  const std::size_t n = 3 * mesh_.node_count();
  const std::size_t particles = values.size() >= 2 ? static_cast<std::size_t>(values[1]) : 0;
  if (!in || values.size() < 2 || values[0] != static_cast<double>(mesh_.node_count()) ||
      values.size() != 2 + 2 * n + kValuesPerParticle * particles)
    return "checkpoint " + restart.string() + ": the adapter's state " + file.string() +
           " (written with the restart file) is missing, cut short or not of this interface (" +
           std::to_string(mesh_.node_count()) + " nodes)";
  // The mesh where it was held, then a set-up there (neighbour and contact lists).
  move_mesh(std::vector<double>(values.begin() + 2, values.begin() + 2 + 2 * n));
  command("run 0 post no");
  // The last step's forces and torques in place of the set-up's.
  const auto* atom = lammps_->atom;
  std::unordered_map<int, int> local;
  for (int i = 0; i < atom->nlocal; ++i) local.emplace(atom->tag[i], i);
  long long applied = 0;
  for (std::size_t p = 0; p < particles; ++p) {
    const double* record = &values[2 + 2 * n + kValuesPerParticle * p];
    const auto found = local.find(static_cast<int>(record[0]));
    if (found == local.end()) continue;
    for (int d = 0; d < 3; ++d) {
      atom->f[found->second][d] = record[1 + d];
      atom->torque[found->second][d] = record[4 + d];
    }
    ++applied;
  }
  long long total = 0;
  MPI_Allreduce(&applied, &total, 1, MPI_LONG_LONG, MPI_SUM, world_);
  if (total != static_cast<long long>(particles) || total != static_cast<long long>(atom->natoms))
    return "checkpoint " + restart.string() + ": the adapter's state holds " +
           std::to_string(particles) + " particles, LIGGGHTS's restart file " +
           std::to_string(static_cast<long long>(atom->natoms)) + " (" + std::to_string(total) +
           " matched by tag)";
  return {};
}

std::int64_t LiggghtsDomain::dem_steps() const {
  return static_cast<std::int64_t>(lammps_->update->ntimestep);
}

}  // namespace demfem::liggghts
