// One demfem_run run of the study and what is read from its output.
#include "study.hpp"

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>

#include "demfem/io/csv_writer.hpp"
#include "demfem/io/h5_file.hpp"

namespace demfem::bench::coupling_study {

namespace {

// `cpu`: set to the CPU time (user + system) of the child and of the children it waited for.
int spawn_and_wait(const std::vector<std::string>& args, const fs::path& log,
                   double* cpu = nullptr) {
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      ::dup2(fd, 1);
      ::dup2(fd, 2);
      ::close(fd);
    }
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(argv[0], argv.data());
    std::_Exit(127);
  }
  int st = 0;
  struct rusage ru {};
  ::wait4(pid, &st, 0, &ru);
  if (cpu)
    *cpu = static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
           1e-6 * static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
  return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

}  // namespace

std::vector<std::vector<std::string>> read_csv(const fs::path& p) {
  return io::read_csv_cells(p);
}

// `fields`: an accuracy run, with the FEM's field output at every max(dt_F, pb.sample) (the
// probe is read from it); otherwise a timing run, whose FEM writes only its first and last
// state, so that the wall time is the coupling's.
RunResult run(const Problem& pb, const fs::path& scene, const fs::path& out,
              const std::vector<std::string>& sets, double dt, bool fields, bool overlapped,
              bool own_sessions) {
  fs::remove_all(out);
  fs::create_directories(out.parent_path());
  std::vector<std::string> args = {(kBin / "demfem_run").string(),
                                   "--bin-dir",
                                   kBin.string(),
                                   scene.string(),
                                   "--output-dir",
                                   out.string(),
                                   "--quiet"};
  if (own_sessions) args.push_back("--solver-sessions");
  for (const auto& s : pb.sets) args.insert(args.end(), {"--set", s});
  for (const auto& s : sets) args.insert(args.end(), {"--set", s});
  args.insert(args.end(), {"--set", "fem.dt=" + fmt(dt)});
  args.insert(args.end(),
              {"--set", "run.output_interval=" + fmt(fields ? std::max(dt, pb.sample) : 0.0)});
  const fs::path log = out.string() + ".log";
  RunResult r;
  r.exit = spawn_and_wait(args, log, &r.cpu);
  // This machine is shared: a run that failed otherwise than by the scheme (a solver starved
  // of CPU for longer than the 2 s peer timeout, "heartbeat stale") is run again, twice at most.
  for (int retry = 0; retry < 2 && r.exit != 0 && r.exit != 3 &&
                      read_text(log).find("heartbeat stale") != std::string::npos;
       ++retry) {
    std::fprintf(stderr, "# %s: a solver was starved of CPU (heartbeat stale); run again\n",
                 out.filename().c_str());
    fs::remove_all(out);
    r.exit = spawn_and_wait(args, log, &r.cpu);
  }
  if (r.exit != 0) {
    const std::string text = read_text(log);
    const auto at = text.rfind("demfem run:");
    r.error_text = at == std::string::npos ? text : text.substr(at, 300);
  }
  const auto rows = read_csv(out / "coupling.csv");
  if (rows.size() > 1) {
    std::map<std::string, std::size_t> c;
    for (std::size_t k = 0; k < rows[0].size(); ++k) c[rows[0][k]] = k;
    std::vector<double> dem, fem, wall, ratio;
    for (std::size_t i = 1; i < rows.size(); ++i) {
      const auto& row = rows[i];
      auto v = [&](const char* name) { return std::stod(row.at(c.at(name))); };
      r.end_time = v("time");
      r.steps = static_cast<std::int64_t>(v("step")) + 1;
      const auto it = static_cast<std::int64_t>(v("iterations"));
      r.iterations += it;
      r.max_iterations = std::max(r.max_iterations, it);
      if (v("converged") == 0.0) ++r.unconverged;
      r.max_displacement = std::max(r.max_displacement, std::abs(v("fem_max_displacement")));
      r.max_energy_error = std::max(r.max_energy_error, std::abs(v("energy_error")));
      r.max_work = std::max(r.max_work, std::abs(v("work_fem")));
      r.step_times.push_back(v("time"));
      r.step_umax.push_back(v("fem_max_displacement"));
      dem.push_back(v("wall_dem_compute"));
      fem.push_back(v("wall_fem_compute"));
      // In the concurrent scheme both solvers are sent their step at once and wall_dem,
      // wall_fem count from there: the step took the longer of the two plus the coupler's own
      // time; otherwise the sum of all three.
      const double solvers =
          overlapped ? std::max(v("wall_dem"), v("wall_fem")) : v("wall_dem") + v("wall_fem");
      wall.push_back(solvers + v("wall_coupling"));
      ratio.push_back(wall.back() / std::max(v("wall_dem_compute"), v("wall_fem_compute")));
    }
    r.dem_compute = median(dem);
    r.fem_compute = median(fem);
    r.step_wall = median(wall);
    r.step_ratio = median(ratio);
  }
  const auto timing = read_csv(out / "timing.csv");
  if (r.exit == 0 && timing.size() == 2) r.wall = std::stod(timing[1][2]);
  if (r.exit != 0) r.cpu = NAN;
  // The probe: the FEM node nearest to pb.probe, u_z at every field output.
  if (fs::exists(out / "fem_mesh.h5") && fs::exists(out / "fem_series.csv")) {
    std::vector<std::size_t> dims;
    const auto nodes = demfem::io::H5File(out / "fem_mesh.h5", demfem::io::H5File::Mode::read)
                           .read_doubles("nodes", &dims);
    std::size_t best = 0;
    double best_d = INFINITY;
    for (std::size_t i = 0; 3 * i + 2 < nodes.size(); ++i) {
      double d = 0.0;
      for (int k = 0; k < 3; ++k) d += std::pow(nodes[3 * i + k] - pb.probe[k], 2);
      if (d < best_d) best_d = d, best = i;
    }
    const auto series = read_csv(out / "fem_series.csv");
    for (std::size_t i = 1; i < series.size(); ++i) {
      char name[32];
      std::snprintf(name, sizeof name, "fem_%06zu.h5", i - 1);
      if (!fs::exists(out / name)) break;
      const auto u = demfem::io::H5File(out / name, demfem::io::H5File::Mode::read)
                         .read_doubles("displacement");
      r.times.push_back(std::stod(series[i][0]));
      r.probe.push_back(u.at(3 * best + 2));
    }
  }
  return r;
}

}  // namespace demfem::bench::coupling_study
