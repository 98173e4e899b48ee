// The scene of each run: the case with its [coupling] rewritten for a scheme.
#include "study.hpp"

#include "demfem/coupling/coupling_settings.hpp"

#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace demfem::bench::coupling_study {

namespace {

// The implicit keys a case sets in [coupling]; an explicit variant must not carry them.
const std::set<std::string> kImplicitKeys(demfem::coupling::kImplicitCouplingKeys.begin(),
                                          demfem::coupling::kImplicitCouplingKeys.end());

std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t");
  const auto b = s.find_last_not_of(" \t\r");
  return a == std::string::npos ? "" : s.substr(a, b - a + 1);
}

}  // namespace

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + p.string());
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// The case with [coupling] rewritten for `sc`: scheme, force averaging and acceleration set;
// the case's implicit keys kept for an implicit variant (its tolerances are the case's, or
// `factor` times them), dropped for an explicit one. Written beside the run folder `dir`; the
// problems here refer to no file by a relative path.
fs::path scene_variant(const Problem& pb, const Scheme& sc, const fs::path& dir, double factor) {
  std::istringstream in(read_text(pb.scene));
  std::ostringstream out;
  std::string line;
  bool in_coupling = false;
  while (std::getline(in, line)) {
    const std::string t = trim(line);
    if (!t.empty() && t[0] == '[') {
      in_coupling = t == "[coupling]";
      out << line << '\n';
      if (in_coupling) {
        out << "scheme = \"" << sc.scheme << "\"\n";
        out << "force_averaging = " << (sc.force_averaging ? "true" : "false") << "\n";
        if (!sc.acceleration.empty()) out << "acceleration = \"" << sc.acceleration << "\"\n";
      }
      continue;
    }
    if (in_coupling) {
      const std::string key = trim(t.substr(0, t.find('=')));
      if (key == "scheme" || key == "force_averaging" || key == "acceleration") continue;
      if (kImplicitKeys.count(key)) {
        if (sc.scheme != "implicit") continue;
        if (factor != 1.0 && (key == "displacement_tolerance" || key == "force_tolerance")) {
          const double v = std::stod(t.substr(t.find('=') + 1));
          char buf[64];
          std::snprintf(buf, sizeof buf, "%s = %.3g\n", key.c_str(), v * factor);
          out << buf;
          continue;
        }
        if (key == "reuse_steps" && sc.acceleration != "iqn-ils") continue;
      }
    }
    out << line << '\n';
  }
  fs::create_directories(dir.parent_path());
  const fs::path p = dir.string() + ".toml";
  std::ofstream(p) << out.str();
  return p;
}

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

}  // namespace demfem::bench::coupling_study
