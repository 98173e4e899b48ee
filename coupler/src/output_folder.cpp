#include "demfem/coupling/output_folder.hpp"

#include <algorithm>
#include <cctype>
#include <stdexcept>
#include <system_error>

namespace fs = std::filesystem;

namespace demfem::coupling {

namespace {

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

bool starts_with(const std::string& s, const std::string& head) {
  return s.rfind(head, 0) == 0;
}

// "<stem>_NNNNNN.h5" (one or more digits), the numbered field files of the FEM and DEM.
bool numbered_h5(const std::string& name, const std::string& stem) {
  if (!starts_with(name, stem + "_") || !ends_with(name, ".h5")) return false;
  const std::string digits = name.substr(stem.size() + 1, name.size() - stem.size() - 4);
  return !digits.empty() && std::all_of(digits.begin(), digits.end(), [](char c) {
    return std::isdigit(static_cast<unsigned char>(c)) != 0;
  });
}

std::vector<fs::path> owned_files(const fs::path& dir) {
  std::vector<fs::path> files;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (!it->is_regular_file(ec)) continue;
    if (is_owned_output(it->path().filename().string())) files.push_back(it->path());
  }
  if (ec) throw std::runtime_error(dir.string() + ": cannot list the folder: " + ec.message());
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace

bool is_owned_output(const std::string& file_name) {
  std::string name = file_name;
  if (ends_with(name, ".part")) name.resize(name.size() - 5);
  static const char* const kNames[] = {
      "coupling.csv",  "coupling.h5",    "coupling.xdmf",    "timing.csv",  "beam_check.csv",
      "coupling.png",  "fem.xdmf",       "fem_series.csv",   "fem_mesh.h5", "particles.xdmf",
      "fem_modes.csv", "fem_modes.xdmf", "fem_modes_mesh.h5"};
  for (const char* n : kNames)
    if (name == n) return true;
  if (numbered_h5(name, "fem") || numbered_h5(name, "particles") ||
      numbered_h5(name, "fem_modes") || numbered_h5(name, "coupling"))
    return true;
  return starts_with(name, "sensor_") && ends_with(name, ".csv") && name.size() > 11;
}

std::vector<std::string> clear_owned_outputs(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& f : owned_files(dir)) {
    std::error_code ec;
    fs::remove(f, ec);
    if (ec)
      throw std::runtime_error(f.string() +
                               ": cannot remove (a file of an earlier run): " + ec.message());
    names.push_back(f.filename().string());
  }
  return names;
}

std::vector<std::string> copy_owned_outputs(const fs::path& from, const fs::path& to) {
  clear_owned_outputs(to);
  std::vector<std::string> names;
  for (const auto& f : owned_files(from)) {
    const std::string name = f.filename().string();
    if (ends_with(name, ".part")) continue;
    std::error_code ec;
    fs::copy_file(f, to / name, fs::copy_options::overwrite_existing, ec);
    if (ec) {
      throw std::runtime_error("cannot copy " + f.string() + " to " + (to / name).string() + ": " +
                               ec.message());
    }
    names.push_back(name);
  }
  return names;
}

}  // namespace demfem::coupling
