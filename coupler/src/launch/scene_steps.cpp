#include "launch/scene_steps.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "demfem/coupling/coupling_settings.hpp"
#include "demfem/dem/scene/dem_scene.hpp"
#include "demfem/dem/scene/particle_source.hpp"
#include "demfem/interface/exit_status.hpp"
#include "launch/supervisor.hpp"

namespace demfem::coupling {

namespace fs = std::filesystem;
using scene::SceneError;

namespace {

#ifndef DEMFEM_TOOLS_DIR
#define DEMFEM_TOOLS_DIR "tools"
#endif

// Prepare scenes nest at most this deep (the chain's length, below): a longer chain of
// distinct scenes is more likely a mistake than a bed.
constexpr std::size_t kMaxPrepareDepth = 8;
// The enclosing prepare runs, outermost first, one line each: "pid<TAB>scene<TAB>state", the
// demfem_run that waits, its scene and the state it waits for (absolute paths). A run refuses
// a [dem.load] scene already in the chain (a cycle), and a state an enclosing run is making
// (its lock is held by that run, which waits for this one: a deadlock).
constexpr const char* kChainVariable = "DEMFEM_PREPARE_CHAIN";

struct ChainLink {
  long pid = 0;
  std::string scene, state;
};

std::vector<ChainLink> read_chain() {
  std::vector<ChainLink> chain;
  const char* text = std::getenv(kChainVariable);
  std::string rest = text ? text : "";
  while (!rest.empty()) {
    const auto end = rest.find('\n');
    const std::string line = rest.substr(0, end);
    rest = end == std::string::npos ? "" : rest.substr(end + 1);
    const auto a = line.find('\t'), b = a == std::string::npos ? a : line.find('\t', a + 1);
    if (b == std::string::npos) continue;
    chain.push_back(
        {std::atol(line.substr(0, a).c_str()), line.substr(a + 1, b - a - 1), line.substr(b + 1)});
  }
  return chain;
}

std::string absolute_text(const fs::path& p) {
  std::error_code ec;
  const fs::path a = fs::weakly_canonical(fs::absolute(p), ec);
  return (ec ? fs::absolute(p) : a).string();
}

// Takes the prepare lock of a state's folder: waits while another run prepares it (the kernel
// drops a lock when its holder ends in any way), writes this run into the file, and returns
// the descriptor; -1 with a message when it cannot be taken, when its holder is a run of this
// chain (which waits for this one: it would never be released), or on a stop signal (then
// `stopped` is the signal's status, 128 + N).
int take_prepare_lock(const fs::path& lock, const std::vector<ChainLink>& chain,
                      const std::string& scene, int& stopped) {
  const int fd = ::open(lock.c_str(), O_CREAT | O_RDWR | O_CLOEXEC, 0644);
  if (fd < 0) {
    std::fprintf(stderr, "demfem run: cannot open the lock %s\n", lock.c_str());
    return -1;
  }
  SignalGuard signals;  // a stop signal ends the wait
  bool told = false;
  for (;;) {
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0) break;
    if (errno != EWOULDBLOCK && errno != EINTR) {
      std::fprintf(stderr, "demfem run: cannot lock %s\n", lock.c_str());
      ::close(fd);
      return -1;
    }
    char buf[512] = {};
    const ssize_t got = ::pread(fd, buf, sizeof buf - 1, 0);
    const std::string holder = got > 0 ? std::string(buf, static_cast<std::size_t>(got)) : "";
    const long pid = std::atol(holder.c_str());
    for (const auto& l : chain)
      if (pid > 0 && l.pid == pid) {
        std::fprintf(stderr,
                     "demfem run: %s is held by process %ld, a run of this [dem.load] chain "
                     "(%s) that waits for this one: it would never be released\n",
                     lock.c_str(), pid, l.scene.c_str());
        ::close(fd);
        return -1;
      }
    if (!told) {
      std::printf("demfem run: waiting for %s (held by %s) to be released\n", lock.c_str(),
                  holder.empty() ? "another run" : holder.c_str());
      std::fflush(stdout);
      told = true;
    }
    if (SignalGuard::stop_flag().load()) {
      stopped = 128 + SignalGuard::signal_number();
      ::close(fd);
      return -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  const std::string me = std::to_string(::getpid()) + " (demfem run " + scene + ")";
  if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, me.data(), me.size(), 0) < 0) {
    // the holder line is for the waiting runs' messages only: the lock is held all the same
  }
  return fd;
}

std::string python() {
  const char* p = std::getenv("DEMFEM_PYTHON");
  return p && *p ? p : "/usr/bin/python3";
}

std::string substitute(std::string s, const fs::path& output, const fs::path& scene,
                       const fs::path& bin) {
  const std::pair<const char*, std::string> keys[] = {
      {"{output}", output.string()}, {"{scene}", scene.string()}, {"{bin}", bin.string()}};
  for (const auto& [key, value] : keys)
    for (auto at = s.find(key); at != std::string::npos; at = s.find(key, at + value.size()))
      s.replace(at, std::string(key).size(), value);
  return s;
}

// Runs a child to its end; a stop request (Ctrl-C) is forwarded by SignalGuard, and with
// `checkpoint_requests` (a prepare scene's demfem_run) so is a checkpoint request (SIGUSR1/2).
int run_child(const std::string& label, const fs::path& exe, const std::vector<std::string>& args,
              bool checkpoint_requests) {
  // A stop signal (Ctrl-C, SIGTERM, a sweep or Slurm stopping the run) goes on to the child,
  // whose pid the handler knows from start(): a prepare run or a post step must not outlive
  // its launcher (it did, running its scene to the end, segments and all). A child that has
  // not ended 10 s after the signal is killed.
  SignalGuard signals;
  SolverProcess p(label, exe, args);
  p.start();
  for (;;) {
    if (auto c = p.wait_for(std::chrono::milliseconds(500))) {
      return SignalGuard::stop_flag().load() ? 128 + SignalGuard::signal_number() : *c;
    }
    if (SignalGuard::stop_flag().load()) {
      p.stop(std::chrono::seconds(10));
      return 128 + SignalGuard::signal_number();
    }
    if (const int sig = SignalGuard::take_checkpoint_request(); sig != 0 && checkpoint_requests)
      p.signal(sig);
  }
}

// demfem_run on the prepare scene of `src`, with its overrides and `extra` arguments, one
// prepare level deeper: `link` (this run's line) added to kChainVariable, restored afterwards.
// 1 when it cannot be started.
int run_prepare_child(const std::string& label, const dem::ParticleSource& src,
                      const fs::path& bin_dir, const std::string& link,
                      std::vector<std::string> extra) {
  std::vector<std::string> args = {"--bin-dir", bin_dir.string(), src.prepare_scene.string()};
  for (const auto& o : src.prepare_overrides)
    args.insert(args.end(), {"--set", o.key + "=" + o.value});
  args.insert(args.end(), extra.begin(), extra.end());
  const char* chain_before = std::getenv(kChainVariable);
  const std::string chain_saved = chain_before ? chain_before : "";
  ::setenv(kChainVariable, (chain_saved + link).c_str(), 1);
  int code = 1;
  try {
    code = run_child(label, bin_dir / "demfem_run", args, true);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "demfem run: %s\n", e.what());
  }
  if (chain_before)
    ::setenv(kChainVariable, chain_saved.c_str(), 1);
  else
    ::unsetenv(kChainVariable);
  return code;
}

}  // namespace

fs::path tools_directory() {
  const char* d = std::getenv("DEMFEM_TOOLS_DIR");
  return d && *d ? fs::path(d) : fs::path(DEMFEM_TOOLS_DIR);
}

std::vector<PostStep> read_post_steps(const scene::Document& doc, const fs::path& bin_dir) {
  std::vector<PostStep> steps;
  const scene::Table root = doc.root();
  if (!root.has("post")) return steps;
  for (const auto& t : root.tables("post")) {
    PostStep s;
    s.tool = t.string("tool");
    s.where = t.where("tool");
    if (s.tool.empty() || s.tool.find('/') != std::string::npos || s.tool[0] == '.')
      t.fail("tool",
             "must be the bare name of a script in tools/ or a program of the build "
             "(no folders)");
    const fs::path script = tools_directory() / s.tool;
    const fs::path program = bin_dir / s.tool;
    if (fs::is_regular_file(script)) {
      s.executable = script;
      s.python = script.extension() == ".py";
    } else if (fs::is_regular_file(program)) {
      s.executable = program;
    } else {
      t.fail("tool", "\"" + s.tool + "\" is neither a script in " + tools_directory().string() +
                         " nor a program in " + bin_dir.string());
    }
    if (t.has("args")) s.args = t.strings("args");
    t.finish();
    steps.push_back(std::move(s));
  }
  return steps;
}

int run_post_steps(const std::vector<PostStep>& steps, const fs::path& output_dir,
                   const fs::path& scene_file, const fs::path& bin_dir) {
  for (const auto& s : steps) {
    std::vector<std::string> args;
    for (const auto& a : s.args) args.push_back(substitute(a, output_dir, scene_file, bin_dir));
    fs::path exe = s.executable;
    if (s.python) {
      args.insert(args.begin(), s.executable.string());
      exe = python();
    }
    std::string line = exe.string();
    for (const auto& a : args) line += " " + a;
    std::printf("demfem run: post: %s\n", line.c_str());
    std::fflush(stdout);
    int code = 0;
    try {
      code = run_child("post step " + s.tool, exe, args, false);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "demfem run: post step %s (%s): %s\n", s.tool.c_str(), s.where.c_str(),
                   e.what());
      return kExitFailed;
    }
    if (code != 0) {
      std::fprintf(stderr,
                   "demfem run: post step %s (%s) failed with status %d; the run's own output "
                   "in %s is complete\n",
                   s.tool.c_str(), s.where.c_str(), code, output_dir.c_str());
      return kExitFailed;
    }
  }
  return 0;
}

int run_prepare_scenes(const scene::Document& doc, const fs::path& bin_dir, bool quiet,
                       bool in_process, bool check_only) {
  const auto dem = doc.root().table("dem");
  // An external DEM's [dem] is the program's own (a [dem.load] there is not dem_server's).
  if (!dem || names_external_backend(dem)) return 0;
  const dem::DemScene ds = dem::read_dem_scene(*dem);
  if (!ds.load || ds.load->prepare_scene.empty()) return 0;
  const dem::ParticleSource& src = *ds.load;
  if (dem::state_is_current(src.file, src.prepare_scene, src.prepare_overrides)) return 0;

  // A cycle: this scene (or one of the runs that wait for it) is the one it loads, or the
  // state it needs is being made by one of them. Refused before anything waits for anything.
  const std::vector<ChainLink> chain = read_chain();
  const std::string self = absolute_text(doc.file()), prepare = absolute_text(src.prepare_scene),
                    state = absolute_text(src.file);
  std::string path;
  bool cycle = prepare == self;
  for (const auto& l : chain) {
    path += l.scene + " -> ";
    cycle = cycle || l.scene == prepare || l.state == state;
  }
  if (cycle) {
    std::fprintf(stderr,
                 "demfem run: %s: [dem.load] scenes load each other: %s%s -> %s (state %s); a "
                 "scene cannot start from its own end state, nor from a state that a scene "
                 "waiting for it makes\n",
                 src.where.c_str(), path.c_str(), self.c_str(), prepare.c_str(), state.c_str());
    return kExitBadInput;
  }
  const std::string link = std::to_string(::getpid()) + "\t" + self + "\t" + state + "\n";
  if (chain.size() >= kMaxPrepareDepth) {
    std::fprintf(stderr,
                 "demfem run: %s: prepare scenes nest more than %d deep (a scene that prepares "
                 "itself?)\n",
                 src.where.c_str(), static_cast<int>(kMaxPrepareDepth));
    return kExitBadInput;
  }
  if (check_only) {  // its scene is checked as a run of it would check it, nothing is made
    const int code = run_prepare_child("prepare check", src, bin_dir, link, {"--check"});
    if (code != 0)
      std::fprintf(stderr, "demfem run: the prepare scene %s does not pass --check (status %d)\n",
                   src.prepare_scene.c_str(), code);
    return code == 0 ? 0 : (code == kExitBadInput ? kExitBadInput : kExitFailed);
  }
  // One run prepares; another one that needs the same state waits for it and then finds
  // it current.
  fs::create_directories(src.file.parent_path().empty() ? fs::path(".") : src.file.parent_path());
  const fs::path lock = src.file.parent_path() / ".prepare.lock";
  int stopped = 0;
  const int fd = take_prepare_lock(lock, chain, self, stopped);
  if (fd < 0) return stopped != 0 ? stopped : kExitFailed;
  int code = 0;
  if (!dem::state_is_current(src.file, src.prepare_scene, src.prepare_overrides)) {
    std::string with = src.prepare_overrides.empty() ? "" : " with";
    for (const auto& o : src.prepare_overrides) with.append(" ").append(o.text());
    std::printf("demfem run: %s needs the end state of %s%s (%s %s): running that scene first\n",
                doc.file().c_str(), src.prepare_scene.c_str(), with.c_str(), src.file.c_str(),
                fs::exists(src.file) ? "was made by another version of it" : "does not exist");
    std::fflush(stdout);
    std::vector<std::string> extra;
    if (quiet) extra.push_back("--quiet");
    if (in_process) extra.push_back("--in-process");
    code = run_prepare_child("prepare run", src, bin_dir, link, extra);
    if (code != 0) {
      std::fprintf(stderr, "demfem run: the prepare scene %s ended with status %d\n",
                   src.prepare_scene.c_str(), code);
    } else if (!dem::state_is_current(src.file, src.prepare_scene, src.prepare_overrides)) {
      std::fprintf(stderr, "demfem run: the prepare scene %s ended without writing %s\n",
                   src.prepare_scene.c_str(), src.file.c_str());
      code = kExitFailed;
    }
  }
  ::flock(fd, LOCK_UN);
  ::close(fd);
  // bad input and a blow-up keep their status (a sweep does not retry them: the same steps
  // blow up again), and so does a stop signal (128 + N); any other failure is kExitFailed
  const bool kept = code == kExitBadInput || code == kExitBlowUp || code > 128;
  return kept ? code : (code != 0 ? kExitFailed : 0);
}

}  // namespace demfem::coupling
