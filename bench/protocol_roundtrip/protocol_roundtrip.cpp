// Round trip of a Step -> StepDone exchange between the coupler (this process) and a solver
// (this program re-executed with --serve), for several interface sizes, with spinning and
// with blocking waits. The interface arrays are read in place, so the message cost should
// not grow with the node count; the "touch" rows add the solver writing 3n force values,
// which is the smallest real work a DEM does per step.
//
//   protocol_roundtrip [--json FILE] [--iterations N]

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "bench_report.hpp"
#include "demfem/protocol/protocol.hpp"

namespace proto = demfem::protocol;
using Clock = std::chrono::steady_clock;

namespace {

enum class Mode { spin, block, standard };
const char* mode_name(Mode m) {
  return m == Mode::spin ? "spin" : m == Mode::block ? "block" : "default";
}

// spin: busy-wait until the message comes; block: futex at once; default: the library's
// default policy (spin 20 us yielding the CPU every few us, then block).
proto::WaitPolicy policy(Mode mode) {
  proto::WaitPolicy p;
  if (mode == Mode::spin) {
    p.block = false;
    p.yield = false;  // pure busy-wait: the lowest latency, one core per waiting process
  } else if (mode == Mode::block) {
    p.block = true;
    p.spin = std::chrono::microseconds(0);
  }
  return p;
}

class BenchBackend : public proto::SolverBackend {
 public:
  std::size_t nodes = 0;
  bool touch = false;
  std::string name() const override { return "protocol_roundtrip solver"; }
  std::optional<demfem::InterfaceMesh> published_mesh() override {
    if (nodes == 0) return std::nullopt;
    demfem::InterfaceMesh mesh;
    mesh.reference_positions.assign(3 * nodes, 0.0);
    for (std::size_t i = 0; i + 2 < nodes; i += 3)
      mesh.triangles.insert(mesh.triangles.end(),
                            {static_cast<std::int32_t>(i), static_cast<std::int32_t>(i + 1),
                             static_cast<std::int32_t>(i + 2)});
    return mesh;
  }
  void on_mesh(const demfem::InterfaceMesh&) override {}
  proto::StepResult step(const proto::StepCommand& cmd, proto::InterfaceBuffers& b) override {
    proto::StepResult r;
    r.values[0] = static_cast<double>(cmd.step);
    if (touch && !b.empty()) {
      auto f = b.forces(cmd.buffer);
      const double v = static_cast<double>(cmd.step);
      std::fill(f.begin(), f.end(), v);
    }
    return r;
  }
  void write_checkpoint(const std::filesystem::path&, std::int64_t) override {}
  void restore_checkpoint(const std::filesystem::path&, std::int64_t) override {}
};

int serve_mode(int argc, char** argv) {
  BenchBackend backend;
  proto::ServeOptions options;
  options.role = proto::Role::fem;
  Mode mode = Mode::standard;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--serve" && i + 1 < argc)
      options.segment = argv[++i];
    else if (a == "--nodes" && i + 1 < argc)
      backend.nodes = std::stoul(argv[++i]);
    else if (a == "--spin")
      mode = Mode::spin;
    else if (a == "--block")
      mode = Mode::block;
    else if (a == "--touch")
      backend.touch = true;
  }
  options.wait = policy(mode);
  return proto::serve(backend, options);
}

struct Stats {
  double median_us;
  double p99_us;
  double mean_us;
};

Stats measure(std::size_t nodes, Mode mode, bool touch, int iterations) {
  proto::CouplerOptions options;
  options.wait = policy(mode);
  proto::CouplerSession session(options);
  std::vector<std::string> args = {"/proc/self/exe", "--serve", session.segment_name(), "--nodes",
                                   std::to_string(nodes)};
  if (mode == Mode::spin) args.emplace_back("--spin");
  if (mode == Mode::block) args.emplace_back("--block");
  if (touch) args.emplace_back("--touch");
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv("/proc/self/exe", argv.data());
    ::_exit(127);
  }
  session.expect(proto::Role::fem);
  session.wait_hello(proto::Role::fem, pid);
  session.exchange_mesh();
  const int warmup = std::max(100, iterations / 10);
  std::vector<double> samples;
  samples.reserve(static_cast<std::size_t>(iterations));
  for (int i = 0; i < warmup + iterations; ++i) {
    proto::StepCommand cmd;
    cmd.step = i;
    cmd.buffer = static_cast<std::uint32_t>(i % 2);
    const auto t0 = Clock::now();
    session.send_step(proto::Role::fem, cmd);
    session.wait_step_done(proto::Role::fem);
    const auto t1 = Clock::now();
    if (i >= warmup) samples.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
  }
  session.shutdown(proto::Role::fem);
  int status = 0;
  ::waitpid(pid, &status, 0);
  std::sort(samples.begin(), samples.end());
  Stats s{};
  s.median_us = samples[samples.size() / 2];
  s.p99_us = samples[std::min(samples.size() - 1, samples.size() * 99 / 100)];
  double sum = 0.0;
  for (double x : samples) sum += x;
  s.mean_us = sum / static_cast<double>(samples.size());
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    for (int i = 1; i < argc; ++i)
      if (std::strcmp(argv[i], "--serve") == 0) return serve_mode(argc, argv);
    int iterations = 20000;
    std::string json;
    CLI::App app{"Round trip of a Step -> StepDone exchange over the shared-memory protocol, "
                 "for several interface sizes, spinning and blocking waits"};
    app.add_option("--iterations", iterations, "round trips per configuration")
        ->check(CLI::Range(100, 100000000));
    app.add_option("--json", json, "write the results as JSON");
    CLI11_PARSE(app, argc, argv);

    demfem::bench::Report report("protocol_roundtrip", {"nodes", "wait", "solver work", "median_us",
                                                        "p99_us", "mean_us", "samples"});
    report.set_info("machine", demfem::bench::machine_description());
    report.set_info("commit", demfem::bench::git_commit());
    report.set_info("protocol_version", static_cast<long long>(proto::kProtocolVersion));
    report.set_info("iterations", static_cast<long long>(iterations));
    for (std::size_t nodes : {std::size_t{0}, std::size_t{1000}, std::size_t{100000}}) {
      for (Mode mode : {Mode::spin, Mode::block, Mode::standard}) {
        for (bool touch : {false, true}) {
          if (touch && (nodes == 0 || mode == Mode::standard)) continue;
          // Writing 3n forces for 10^5 nodes is ~2.4 MB per step: fewer samples suffice.
          const int n = touch && nodes >= 100000 ? std::max(100, iterations / 20) : iterations;
          const Stats s = measure(nodes, mode, touch, n);
          report.add_row({static_cast<long long>(nodes), std::string(mode_name(mode)),
                          std::string(touch ? "write 3n forces" : "none"), s.median_us, s.p99_us,
                          s.mean_us, static_cast<long long>(n)});
        }
      }
    }
    report.print();
    report.write_json(json);
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "protocol_roundtrip: " << e.what() << '\n';
    return 1;
  }
}
