#include "demfem/fem/fem_monitor.hpp"

#include <cmath>
#include <fstream>
#include <limits>

#include "demfem/fem/fem_solver.hpp"
#include "demfem/io/atomic_file.hpp"
#include "demfem/io/csv_writer.hpp"
#include "demfem/io/h5_file.hpp"

namespace demfem::fem {

using scene::Range;
using scene::Table;

namespace {

// Times within this fraction of a step of a target count as reaching it.
constexpr double kTimeSlack = 1e-9;

std::vector<std::string> columns(const FemMonitorSettings& s) {
  std::vector<std::string> c{"time"};
  for (const auto& p : s.probes)
    for (const char* d : {"_ux", "_uy", "_uz"}) c.push_back(p.name + d);
  for (const char* f : {"force_x", "force_y", "force_z"}) c.emplace_back(f);
  return c;
}

// Times (first column) of an existing series, to cut it back to a restored time.
std::vector<double> read_times(const std::filesystem::path& csv) {
  // Complete rows only: a row cut by a kill is dropped by the resume as well.
  std::vector<double> t;
  for (const auto& line : io::read_csv_rows(csv))
    if (!line.empty()) t.push_back(std::strtod(line.c_str(), nullptr));
  return t;
}

}  // namespace

FemMonitorSettings read_fem_monitor(const Table& m, const Mesh& mesh) {
  FemMonitorSettings s;
  s.enabled = true;
  s.interval = m.number("interval", 0.0, Range::non_negative());
  for (const Table& p : m.tables("probes")) {
    FemProbe probe;
    probe.name = p.string("name");
    if (probe.name.empty() || probe.name.find_first_of(" ,/\t\"") != std::string::npos)
      p.fail("name",
             "must be non-empty without spaces, commas, quotes or slashes (it names "
             "CSV columns)");
    for (const auto& other : s.probes)
      if (other.name == probe.name) p.fail("name", "\"" + probe.name + "\" is used twice");
    probe.point = p.vec3("point");
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t n = 0; n < mesh.nodes.size(); ++n) {
      double d2 = 0;
      for (int k = 0; k < 3; ++k)
        d2 += (mesh.nodes[n][k] - probe.point[k]) * (mesh.nodes[n][k] - probe.point[k]);
      if (d2 < best) best = d2, probe.node = static_cast<std::int32_t>(n);
    }
    if (probe.node < 0) p.fail("point", "the mesh has no nodes");
    probe.distance = std::sqrt(best);
    p.finish();
    s.probes.push_back(probe);
  }
  if (m.has("mean_window")) {
    const auto w = m.numbers("mean_window", 2, Range::non_negative());
    if (!(w[1] > w[0])) m.fail("mean_window", "must be [start, end] with end > start (s)");
    s.mean = true;
    s.mean_start = w[0];
    s.mean_end = w[1];
  }
  m.finish();
  return s;
}

FemMonitor::FemMonitor(std::filesystem::path dir, FemMonitorSettings settings, bool resume)
    : dir_(std::move(dir)), settings_(std::move(settings)) {
  std::filesystem::create_directories(dir_);
  if (resume && std::filesystem::exists(csv_path())) {
    times_ = read_times(csv_path());
    csv_ = std::make_unique<io::CsvWriter>(io::CsvWriter::resume(csv_path(), times_.size()));
  } else {
    csv_ = std::make_unique<io::CsvWriter>(csv_path(), columns(settings_));
    if (!resume) std::filesystem::remove(mean_path());  // an earlier run's
  }
}

FemMonitor::~FemMonitor() = default;

void FemMonitor::sample(const FemSolver& solver, std::span<const double> forces) {
  const double t = solver.time();
  const double dt = started_ ? t - last_time_ : 0.0;
  const double slack = kTimeSlack * std::max(1.0, std::abs(t));
  if (!started_ || settings_.interval == 0.0 || t >= next_ - slack) {
    const auto u = solver.displacements();
    std::vector<double> row{t};
    for (const auto& p : settings_.probes)
      for (int k = 0; k < 3; ++k) row.push_back(u[3 * std::size_t(p.node) + k]);
    double f[3] = {0, 0, 0};
    for (std::size_t i = 0; i + 2 < forces.size(); i += 3)
      for (int k = 0; k < 3; ++k) f[k] += forces[i + k];
    row.insert(row.end(), {f[0], f[1], f[2]});
    csv_->row(row);
    csv_->flush();
    times_.push_back(t);
    // The next multiple of the interval after t (multiples, so that a restored run samples
    // at the same times).
    if (settings_.interval > 0.0)
      next_ = settings_.interval * (std::floor(t / settings_.interval + 1e-9) + 1.0);
  }
  // The window (start, end]: each step whose end lies in it counts with its dt.
  if (settings_.mean && !mean_written_ && dt > 0.0 && t > settings_.mean_start + slack &&
      t <= settings_.mean_end + slack) {
    const auto u = solver.displacements();
    if (sum_u_.empty()) sum_u_.assign(u.size(), 0.0), sum_force_.assign(forces.size(), 0.0);
    for (std::size_t i = 0; i < u.size(); ++i) sum_u_[i] += dt * u[i];
    for (std::size_t i = 0; i < forces.size(); ++i) sum_force_[i] += dt * forces[i];
    weight_ += dt;
    ++steps_;
    if (t >= settings_.mean_end - slack) {
      write_mean(solver);
      mean_written_ = true;
    }
  }
  started_ = true;
  last_time_ = t;
}

void FemMonitor::write_mean(const FemSolver& solver) const {
  std::vector<double> f(sum_force_.size()), u(sum_u_.size());
  for (std::size_t i = 0; i < f.size(); ++i) f[i] = sum_force_[i] / weight_;
  for (std::size_t i = 0; i < u.size(); ++i) u[i] = sum_u_[i] / weight_;
  {
    io::H5File h5(io::partial_path(mean_path()), io::H5File::Mode::create);
    h5.write("interface_force", f, {f.size() / 3, 3});
    h5.write("displacement", u, {u.size() / 3, 3});
    const auto& nodes = solver.interface_mesh_nodes();
    std::vector<std::int64_t> n(nodes.begin(), nodes.end());
    h5.write("interface_mesh_nodes", n);
    h5.set_attribute("/", "start", settings_.mean_start);
    h5.set_attribute("/", "end", settings_.mean_end);
    h5.set_attribute("/", "duration", weight_);
    h5.set_attribute("/", "steps", steps_);
    h5.close();
  }
  io::commit_partial(mean_path());
}

void FemMonitor::save(io::H5File& file, const std::string& group) const {
  file.create_group(group);
  file.set_attribute(group, "next", next_);
  file.set_attribute(group, "last_time", last_time_);
  file.set_attribute(group, "started", std::int64_t(started_));
  file.set_attribute(group, "weight", weight_);
  file.set_attribute(group, "steps", steps_);
  file.set_attribute(group, "mean_written", std::int64_t(mean_written_));
  std::vector<double> f = sum_force_, u = sum_u_;
  f.push_back(0.0), u.push_back(0.0);  // never empty
  file.write(group + "/sum_force", f);
  file.write(group + "/sum_u", u);
}

void FemMonitor::restore(const io::H5File& file, const std::string& group, double time) {
  if (file.exists(group)) {
    next_ = file.attribute_double(group, "next");
    last_time_ = file.attribute_double(group, "last_time");
    started_ = file.attribute_int64(group, "started") != 0;
    weight_ = file.attribute_double(group, "weight");
    steps_ = file.attribute_int64(group, "steps");
    mean_written_ = file.attribute_int64(group, "mean_written") != 0;
    sum_force_ = file.read_doubles(group + "/sum_force");
    sum_u_ = file.read_doubles(group + "/sum_u");
    sum_force_.pop_back(), sum_u_.pop_back();
  }
  std::size_t keep = 0;
  const double slack = kTimeSlack * std::max(1.0, std::abs(time));
  while (keep < times_.size() && times_[keep] <= time + slack) ++keep;
  times_.resize(keep);
  csv_.reset();
  csv_ = std::make_unique<io::CsvWriter>(io::CsvWriter::resume(csv_path(), keep));
  csv_->flush();
}

}  // namespace demfem::fem
