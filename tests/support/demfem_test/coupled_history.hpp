#pragma once
// An in-process coupled run (the same adapters the servers run) that records the interface
// displacement after every coupling step: for comparing FEM backends (tests/system/
// test_fem_backends.cpp, bench/fem_backends). Needs demfem::coupling_local.

#include <filesystem>
#include <string>
#include <vector>

#include "demfem/coupling/coupling_run.hpp"
#include "demfem/coupling/local_solvers.hpp"

namespace demfem::test {

struct CoupledHistory {
  std::vector<std::vector<double>> u;  ///< interface displacement (3n) after each step
  coupling::RunSummary summary;
};

/// Runs `scene` with the `--set` overrides `sets` in process, output into `out`.
inline CoupledHistory coupled_history(const std::string& scene,
                                      const std::vector<std::string>& sets,
                                      const std::filesystem::path& out) {
  std::vector<scene::Override> overrides;
  for (const auto& s : sets) overrides.push_back(scene::Override::parse(s));
  const auto doc = scene::Document::load(scene, overrides);
  const auto settings = coupling::read_coupling_settings(doc);
  coupling::LocalLink link(coupling::make_local_dem(doc, settings, out),
                           coupling::make_local_fem(doc, settings, out));
  coupling::CouplingRun run(link, settings, out);
  CoupledHistory h;
  std::vector<double> ref;
  run.set_observer([&](const coupling::StepDiagnostics&, const coupling::CouplingSettings&) {
    const auto x = link.buffers().positions(0);
    if (ref.empty()) ref = link.buffers().reference_mesh().reference_positions;
    std::vector<double> u(x.size());
    for (std::size_t k = 0; k < u.size(); ++k) u[k] = x[k] - ref[k];
    h.u.push_back(std::move(u));
  });
  h.summary = run.run();
  return h;
}

}  // namespace demfem::test
