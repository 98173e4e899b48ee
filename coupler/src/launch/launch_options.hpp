#pragma once
// The command line of `demfem run` (coupler/app/demfem_run.cpp parses it with CLI11), as the
// launcher's parts read it.

#include <string>
#include <vector>

namespace demfem::coupling::launch {

/// @brief The options of one `demfem run`.
struct LaunchOptions {
  std::string scene;
  std::string bin_dir;
  std::string output_dir;
  bool quiet = false;
  bool in_process = false;
  bool no_post = false;
  int wait_spin_us = 0;
  bool solver_sessions = false;
  bool resume = false;
  std::string resume_from;        ///< empty: the latest valid checkpoint
  std::string debug_kill;         ///< ROLE:STEP[:always], fault injection for tests
  std::vector<std::string> sets;  ///< --set KEY=VALUE, passed on to the solvers
  bool check = false;             ///< --check: read and check the scene, start nothing
  double hello_timeout = 300.0;   ///< s: a started solver that has not said Hello is killed
  bool hello_timeout_given = false;
  std::string fem_backend;  ///< --fem-backend: overrides fem.backend ("" = the scene's)
  std::string dem_backend;  ///< --dem-backend: overrides dem.backend ("" = the scene's)
};

}  // namespace demfem::coupling::launch
