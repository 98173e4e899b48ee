#include "liggghts_backend.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

namespace demfem::liggghts {

namespace {

// An order travels as five doubles: the order, then its arguments (a step: dt, substeps,
// 1 for force averaging, 1 when the node positions and velocities follow; attach: the node
// and triangle counts, followed by the mesh).
using OrderMessage = std::array<double, 5>;

// How long a waiting rank polls for the next order, yielding the core between polls, before
// it sleeps between them: a coupling step's FEM part and the coupler's work take about this
// long, and a rank that sleeps wakes 0.1 ms late or more on a loaded machine (measured:
// 110 us of each 2-rank coupling step of bench/liggghts_dem went to rank 0 waiting for it).
constexpr auto kPollBeforeSleep = std::chrono::milliseconds(2);

OrderMessage broadcast_order(MPI_Comm world, OrderMessage message) {
  MPI_Request request;
  MPI_Ibcast(message.data(), static_cast<int>(message.size()), MPI_DOUBLE, 0, world, &request);
  // The other ranks wait here while rank 0 waits for the coupler, often for the whole FEM
  // step: a blocking MPI_Bcast would spin a core that the FEM and the coupler need for as
  // long as the wait lasts (a checkpoint, a slow FEM step, a recovery).
  const auto start = std::chrono::steady_clock::now();
  for (int done = 0;;) {
    MPI_Test(&request, &done, MPI_STATUS_IGNORE);
    if (done) return message;
    if (std::chrono::steady_clock::now() - start < kPollBeforeSleep)
      std::this_thread::yield();
    else
      std::this_thread::sleep_for(std::chrono::microseconds(50));
  }
}

double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void broadcast_values(MPI_Comm world, std::vector<double>& values) {
  MPI_Bcast(values.data(), static_cast<int>(values.size()), MPI_DOUBLE, 0, world);
}

std::filesystem::path broadcast_path(MPI_Comm world, std::string text) {
  MPI_Bcast(text.data(), static_cast<int>(text.size()), MPI_CHAR, 0, world);
  return text;
}

void broadcast_mesh(MPI_Comm world, InterfaceMesh& mesh) {
  MPI_Bcast(mesh.reference_positions.data(), static_cast<int>(mesh.reference_positions.size()),
            MPI_DOUBLE, 0, world);
  MPI_Bcast(mesh.triangles.data(), static_cast<int>(mesh.triangles.size()), MPI_INT32_T, 0,
            world);
}

}  // namespace

LiggghtsBackend::LiggghtsBackend(MPI_Comm world, LiggghtsDomain& domain,
                                 std::int64_t steps_per_coupling_step, bool resume)
    : world_(world), domain_(domain), steps_per_coupling_step_(steps_per_coupling_step),
      resume_(resume) {
  MPI_Comm_size(world_, &ranks_);
}

std::string LiggghtsBackend::name() const {
  return "liggghts_dem (LIGGGHTS-PUBLIC 3.8, " + std::to_string(ranks_) + " MPI rank" +
         (ranks_ == 1 ? "" : "s") + ")";
}

void LiggghtsBackend::on_mesh(const InterfaceMesh& mesh) {
  mesh_ = mesh;
  // A restarted process (--resume) is sent its checkpoint next: LIGGGHTS then starts from
  // that checkpoint's restart file, once, instead of running the deck afresh and clearing it.
  if (!resume_) attach_everywhere({});
}

void LiggghtsBackend::attach_everywhere(const std::string& restart) {
  broadcast_order(world_, {static_cast<double>(RankOrder::attach),
                           static_cast<double>(mesh_.node_count()),
                           static_cast<double>(mesh_.triangle_count()),
                           static_cast<double>(restart.size()), 0.0});
  broadcast_mesh(world_, mesh_);
  const std::string refusal = domain_.attach(mesh_, broadcast_path(world_, restart));
  if (!refusal.empty()) throw protocol::BackendError(protocol::ErrorKind::bad_input, refusal);
}

protocol::StepResult LiggghtsBackend::step(const protocol::StepCommand& cmd,
                                           protocol::InterfaceBuffers& buffers) {
  if (!domain_.attached()) attach_everywhere({});  // resumed, but sent no checkpoint
  step_in_progress_ = cmd.step;
  time_in_progress_ = cmd.time;
  StepTimes& times = domain_.times();
  const StepTimes before = times;
  const bool average = cmd.force_mode == ForceMode::average;
  const bool kinematics = (cmd.flags & protocol::kStepSetKinematics) != 0;
  auto start = std::chrono::steady_clock::now();
  broadcast_order(world_, {static_cast<double>(RankOrder::step), cmd.dt,
                           static_cast<double>(cmd.substeps), average ? 1.0 : 0.0,
                           kinematics ? 1.0 : 0.0});
  times.broadcast += seconds_since(start);
  if (kinematics) {
    // The mesh stays at the step's start within the step (dem_server moves it on as
    // x + v t + a t^2 / 2), with the node velocities for the contact law: positions and
    // velocities travel to the other ranks in one message.
    start = std::chrono::steady_clock::now();
    const auto x = buffers.positions(cmd.buffer), v = buffers.velocities(cmd.buffer);
    kinematics_.resize(x.size() + v.size());
    std::copy(x.begin(), x.end(), kinematics_.begin());
    std::copy(v.begin(), v.end(), kinematics_.begin() + static_cast<std::ptrdiff_t>(x.size()));
    times.protocol_io += seconds_since(start);
    start = std::chrono::steady_clock::now();
    broadcast_values(world_, kinematics_);
    times.broadcast += seconds_since(start);
    domain_.move_mesh(kinematics_);
  }
  const StepReport report = domain_.advance(cmd.dt, cmd.substeps, average);
  start = std::chrono::steady_clock::now();
  std::copy(report.node_forces.begin(), report.node_forces.end(),
            buffers.forces(cmd.buffer).begin());
  const auto& held = domain_.mesh_positions();
  std::copy(held.begin(), held.end(), buffers.dem_positions(cmd.buffer).begin());
  times.protocol_io += seconds_since(start);
  if (step_times_.size() < kKeptStepTimes) step_times_.push_back(times - before);
  step_in_progress_ = -1;
  protocol::StepResult result;
  result.values[0] = report.max_overlap;
  result.values[1] = report.kinetic_energy;
  result.values[2] = report.max_overlap;
  return result;
}

void LiggghtsBackend::write_checkpoint(const std::filesystem::path& file, std::int64_t step) {
  (void)step;
  if (!domain_.attached()) attach_everywhere({});
  const std::string path = file.string();
  broadcast_order(world_, {static_cast<double>(RankOrder::checkpoint),
                           static_cast<double>(path.size()), 0.0, 0.0, 0.0});
  domain_.write_restart(broadcast_path(world_, path));
}

void LiggghtsBackend::restore_checkpoint(const std::filesystem::path& file, std::int64_t step) {
  const std::string path = file.string();
  if (ranks_ > 1)
    throw protocol::BackendError(
        protocol::ErrorKind::bad_input,
        "cannot restore " + path + " on " + std::to_string(ranks_) +
            " MPI ranks: LIGGGHTS 3.8's read_restart corrupts its memory on more than one rank "
            "(it aborts in AtomVecSphere::unpack_restart); resume on one rank (--resume with "
            "dem.command = [\".../liggghts_dem\"]: the restart file does not depend on the rank "
            "count), then continue on more from its next checkpoint");
  attach_everywhere(path);
  const std::int64_t expected = step * steps_per_coupling_step_;
  if (domain_.dem_steps() != expected)
    throw protocol::BackendError(
        protocol::ErrorKind::bad_input,
        "checkpoint " + path + " holds LIGGGHTS step " + std::to_string(domain_.dem_steps()) +
            ", not that of coupling step " + std::to_string(step) + " (" +
            std::to_string(expected) + " = " + std::to_string(step) + " x n_D " +
            std::to_string(steps_per_coupling_step_) + "): a deck that does not read_restart "
            "${demfem_restart} when ${demfem_resume} is 1 starts afresh instead (docs/liggghts.md)");
}

void LiggghtsBackend::write_times(const std::filesystem::path& file) const {
  // Totals over the run, and the median coupling step of each part: a machine shared with
  // other work stalls a process now and then, which a total counts in full.
  const StepTimes& t = domain_.times();
  const auto parts = t.parts();
  std::vector<double> medians;
  for (std::size_t k = 0; k < parts.size(); ++k) {
    std::vector<double> values;
    for (const auto& s : step_times_) values.push_back(s.parts()[k].second);
    medians.push_back(median(values));
  }
  std::FILE* out = std::fopen(file.c_str(), "w");
  if (!out) return;
  std::fprintf(out, "{\"ranks\": %d, \"steps\": %lld, \"runs\": %lld, \"set_ups\": %lld,\n", ranks_,
               static_cast<long long>(t.steps), static_cast<long long>(t.runs),
               static_cast<long long>(t.set_ups));
  for (const char* kind : {"seconds", "median_step_seconds"}) {
    const bool total = kind[0] == 's';
    std::fprintf(out, " \"%s\": {", kind);
    for (std::size_t k = 0; k < parts.size(); ++k)
      std::fprintf(out, "%s\"%s\": %.9g", k ? ", " : "", parts[k].first,
                   total ? parts[k].second : medians[k]);
    std::fprintf(out, "},\n");
  }
  std::fprintf(out, " \"liggghts\": %.9g, \"adapter\": %.9g}\n", t.liggghts(), t.adapter());
  std::fclose(out);
  if (t.steps > 0)
    std::printf(
        "liggghts_dem: %lld coupling steps: LIGGGHTS %.4g s (loop %.4g, run commands "
        "%.4g, %lld set-ups %.4g), adapter %.4g s (%.2f %%): mesh update %.4g, gather "
        "%.4g, broadcast %.4g, protocol I/O %.4g\n",
        static_cast<long long>(t.steps), t.liggghts(), t.loop, t.run_fixed,
        static_cast<long long>(t.set_ups), t.set_up, t.adapter(),
        100.0 * t.adapter() / (t.adapter() + t.liggghts()), t.mesh_update, t.gather, t.broadcast,
        t.protocol_io);
}

void LiggghtsBackend::release_other_ranks() {
  broadcast_order(world_, {static_cast<double>(RankOrder::quit), 0.0, 0.0, 0.0, 0.0});
}

void serve_other_rank(MPI_Comm world, LiggghtsDomain& domain) {
  std::vector<double> kinematics;  // node positions, then velocities (3 n each)
  for (;;) {
    const OrderMessage order = broadcast_order(world, {});
    switch (static_cast<RankOrder>(static_cast<int>(order[0]))) {
      case RankOrder::attach: {
        InterfaceMesh mesh;
        mesh.reference_positions.resize(3 * static_cast<std::size_t>(order[1]));
        mesh.triangles.resize(3 * static_cast<std::size_t>(order[2]));
        broadcast_mesh(world, mesh);
        // rank 0 reports a refusal; this rank waits for quit
        domain.attach(mesh, broadcast_path(world, std::string(static_cast<std::size_t>(order[3]), ' ')));
        break;
      }
      case RankOrder::step:
        if (order[4] != 0.0) {
          kinematics.resize(6 * domain.mesh().node_count());
          broadcast_values(world, kinematics);
          domain.move_mesh(kinematics);
        }
        domain.advance(order[1], static_cast<std::int64_t>(order[2]), order[3] != 0.0);
        break;
      case RankOrder::checkpoint:
        domain.write_restart(
            broadcast_path(world, std::string(static_cast<std::size_t>(order[1]), ' ')));
        break;
      case RankOrder::quit:
        return;
    }
  }
}

}  // namespace demfem::liggghts
