// DemRun's state in files: the end state a run writes for later runs ([dem.output] state),
// and the checkpoint of the system with the run's own counters (particle ids, sensor rows and
// schedules, mass-flow counters, snapshot counts, the output schedule, insertion repeats).

#include <algorithm>
#include <filesystem>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "demfem/dem/placement/state_check.hpp"
#include "demfem/dem/run/dem_output.hpp"
#include "demfem/dem/run/dem_run.hpp"
#include "demfem/dem/run/wall_output.hpp"
#include "demfem/dem/scene/particle_source.hpp"
#include "demfem/dem/sensors/sensors.hpp"
#include "demfem/io/checkpoint_file.hpp"
#include "demfem/io/h5_file.hpp"

namespace demfem::dem {

void DemRun::write_state() const {
  if (!scene_.output_state || output_dir_.empty()) return;
  std::filesystem::create_directories(output_dir_);
  const auto file = output_dir_ / kStateFileName;
  io::write_checkpoint_file(file, system_->step_count(), [&](io::H5File& h5) {
    save(h5, "dem");
    h5.set_attribute("/", "scene_file", scene_.file);
    h5.set_attribute("/", "scene_hash", scene_text_hash(scene_.file, scene_.overrides));
    h5.set_attribute("/", "time", system_->time());
    h5.set_attribute("/", "count", static_cast<std::int64_t>(system_->particle_count()));
  });
}

void DemRun::save(io::H5File& file, const std::string& group) const {
  system_->save(file, group);
  const std::string g = group + "_tools";
  file.create_group(g);
  file.write(g + "/ids", std::span<const std::int64_t>(ids_));
  // Before the first advance() (deferred output) no row has been written yet.
  const auto rows =
      sensors_ ? sensors_->rows() : std::vector<std::size_t>(scene_.sensors.size(), 0);
  std::vector<std::int64_t> r(rows.begin(), rows.end());
  r.push_back(0);  // never empty
  file.write(g + "/sensor_rows", std::span<const std::int64_t>(r));
  // The sensors' schedule, so that a restored run samples at the same step ends.
  std::vector<double> sched = sensors_ ? sensors_->schedule() : std::vector<double>{};
  sched.push_back(0.0);  // never empty
  file.write(g + "/sensor_schedule", std::span<const double>(sched));
  // Mass-flow counters: the cumulative mass and the side of every particle id.
  if (sensors_) {
    const auto states = sensors_->counter_states();
    for (std::size_t i = 0; i < states.size(); ++i) {
      if (!states[i].present) continue;
      std::vector<std::uint8_t> sides;
      for (std::int8_t v : states[i].sides) sides.push_back(static_cast<std::uint8_t>(v + 1));
      sides.push_back(1);  // never empty
      const std::string name = g + "/mass_flow_" + std::to_string(i);
      file.write(name + "_sides", std::span<const std::uint8_t>(sides), {sides.size()});
      file.set_attribute(g, "mass_flow_" + std::to_string(i) + "_cumulative", states[i].cumulative);
    }
  }
  file.set_attribute(g, "next_id", next_id_);
  file.set_attribute(g, "setup_particles", static_cast<std::int64_t>(setup_particles_));
  file.set_attribute(g, "snapshots", static_cast<std::int64_t>(output_ ? output_->count() : 0));
  file.set_attribute(g, "wall_snapshots",
                     static_cast<std::int64_t>(wall_output_ ? wall_output_->count() : 0));
  // The output schedule: the next output index and the step of the last snapshot, so that a
  // restored run takes the same states with the same labels.
  const std::vector<std::int64_t> sched_out{schedule_.next(), last_snapshot_step_, chunk_steps_};
  file.write(g + "/output_schedule", std::span<const std::int64_t>(sched_out));
  std::vector<std::int64_t> reps = repeats_;
  reps.push_back(0);  // never empty
  file.write(g + "/insert_repeats", std::span<const std::int64_t>(reps));
}

void DemRun::restore(const io::H5File& file, const std::string& group) {
  held_back_ = false;  // a held-back step is not part of the restored state
  const std::string g = group + "_tools";
  // The scene must be the one the checkpoint was taken with, as far as the particles go: a
  // changed lattice or insertion would be silently replaced by the checkpoint's particles.
  if (file.exists(g) && file.has_attribute(g, "setup_particles")) {
    const auto saved = file.attribute_int64(g, "setup_particles");
    if (saved != static_cast<std::int64_t>(setup_particles_)) {
      throw std::runtime_error(
          file.path().string() + ": the checkpoint's scene made " + std::to_string(saved) +
          " particles at set-up, this scene (" + scene_.file + ") makes " +
          std::to_string(setup_particles_) +
          " ([[dem.lattice]], [[dem.insert]] or run.seed changed); its state cannot be "
          "continued with this scene: resume with the scene it was taken with, or start afresh");
    }
  }
  system_->restore(file, group);
  check_particle_state(system_->particles(), file.path().string() + ":/" + group);
  ids_ = file.read_int64(g + "/ids");
  if (ids_.size() != system_->particle_count()) {
    throw std::runtime_error(file.path().string() + ": " + g + "/ids has " +
                             std::to_string(ids_.size()) + " entries for " +
                             std::to_string(system_->particle_count()) + " particles");
  }
  next_id_ = file.attribute_int64(g, "next_id");
  if (!sensors_) start_output(true);
  auto r = file.read_int64(g + "/sensor_rows");
  r.pop_back();
  if (r.size() != scene_.sensors.size()) {
    throw std::runtime_error(file.path().string() + ": " + g + " has " + std::to_string(r.size()) +
                             " sensor series, the scene " + std::to_string(scene_.sensors.size()));
  }
  std::vector<std::size_t> rows(r.begin(), r.end());
  std::vector<double> sched;
  if (file.exists(g + "/sensor_schedule")) {  // absent in checkpoints of older versions
    sched = file.read_doubles(g + "/sensor_schedule");
    sched.pop_back();
  }
  if (sched.size() == 2 * rows.size() && !rows.empty()) {
    sensors_->resume(rows, system_->time(), sched);
  } else {
    sensors_->resume(rows, system_->time());
  }
  {
    auto states = sensors_->counter_states();
    for (std::size_t i = 0; i < states.size(); ++i) {
      const std::string name = g + "/mass_flow_" + std::to_string(i);
      if (!states[i].present || !file.exists(name + "_sides")) continue;
      auto sides = file.read_uint8(name + "_sides");
      sides.pop_back();
      states[i].sides.clear();
      for (std::uint8_t v : sides) states[i].sides.push_back(static_cast<std::int8_t>(v) - 1);
      states[i].cumulative =
          file.attribute_double(g, "mass_flow_" + std::to_string(i) + "_cumulative");
    }
    sensors_->restore_counter_states(states);
  }
  if (output_) output_->resume(static_cast<std::size_t>(file.attribute_int64(g, "snapshots")));
  // A state saved before walls were written has no count: their series starts again.
  if (wall_output_)
    wall_output_->resume(file.has_attribute(g, "wall_snapshots")
                             ? static_cast<std::size_t>(file.attribute_int64(g, "wall_snapshots"))
                             : 0);
  if (file.exists(g + "/output_schedule")) {
    const auto o = file.read_int64(g + "/output_schedule");
    if (o.size() != 3)
      throw std::runtime_error(file.path().string() + ": " + g +
                               "/output_schedule must have 3 entries");
    schedule_.set_next(o[0]);
    last_snapshot_step_ = o[1];
    chunk_steps_ = std::max<std::int64_t>(o[2], 1);
  } else {  // a checkpoint of an older version: outputs up to the restored time were taken
    schedule_.skip_to_after(output_clock());
    last_snapshot_step_ = -1;
  }
  auto reps = file.read_int64(g + "/insert_repeats");
  reps.pop_back();
  if (reps.size() != repeats_.size()) {
    throw std::runtime_error(file.path().string() + ": " + g + " has " +
                             std::to_string(reps.size()) + " insertion counters, the scene " +
                             std::to_string(repeats_.size()));
  }
  repeats_ = reps;
  set_next_freeze();  // the freezings up to the restored time were done (the mask is state)
}

}  // namespace demfem::dem
