// The command line of bench/coupling_schemes.
#include "study.hpp"

#include <algorithm>
#include <sstream>
#include <stdexcept>

namespace demfem::bench::coupling_study {

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    // The value as a comma-separated list, of words or of numbers.
    auto words = [&]() {
      std::vector<std::string> v;
      std::stringstream s(next());
      std::string p;
      while (std::getline(s, p, ',')) v.push_back(p);
      return v;
    };
    auto numbers = [&]() {
      std::vector<double> v;
      for (const auto& w : words()) v.push_back(std::stod(w));
      return v;
    };
    auto word_set = [&]() {
      const auto v = words();
      return std::set<std::string>(v.begin(), v.end());
    };
    if (a == "--help" || a == "-h") {
      o.help = true;
    } else if (a == "--json") {
      o.json = next();
    } else if (a == "--parts") {
      o.parts = word_set();
    } else if (a == "--problems") {
      o.problems = word_set();
    } else if (a == "--repeat") {
      o.repeat = std::max(1, std::stoi(next()));
    } else if (a == "--quick") {
      o.quick = true;
    } else if (a == "--work") {
      o.work = next();
    } else if (a == "--sheet-end") {
      o.sheet_end = std::stod(next());
    } else if (a == "--sheet-dts") {
      o.sheet_dts = numbers();
    } else if (a == "--dts") {
      const auto v = numbers();
      o.dts = {v.begin(), v.end()};
    } else if (a == "--schemes") {
      o.schemes = word_set();
    } else if (a == "--beam-dem-dts") {
      o.beam_dem_dts = numbers();
    } else if (a == "--sheet-schemes") {
      o.sheet_schemes = word_set();
    } else {
      throw std::invalid_argument("unknown option " + a + "\n" + kUsage);
    }
  }
  return o;
}

}  // namespace demfem::bench::coupling_study
