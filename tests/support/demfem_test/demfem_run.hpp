#pragma once
// demfem_run from the build tree as a user runs it, in a folder of its own (the scenes'
// run.output_dir is relative to it), for the system tests of the cases.

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "demfem_test/launch.hpp"

namespace demfem::test {

inline const std::filesystem::path kBin = std::filesystem::path(DEMFEM_BINARY_DIR) / "bin";
inline const std::filesystem::path kCases = std::filesystem::path(DEMFEM_SOURCE_DIR) / "cases";

/// demfem_run ARGS in `dir`, with the build's solvers; waits and returns its output.
inline Ended run_demfem(const std::filesystem::path& dir, const std::vector<std::string>& args) {
  std::vector<std::string> argv = {(kBin / "demfem_run").string(), "--bin-dir", kBin.string()};
  argv.insert(argv.end(), args.begin(), args.end());
  return wait_for(launch(dir, argv));
}

/// The cases' [[post]] plots need matplotlib in Debian's python3.
inline bool have_matplotlib() {
  return std::system("/usr/bin/python3 -c 'import matplotlib' >/dev/null 2>&1") == 0;
}

}  // namespace demfem::test
