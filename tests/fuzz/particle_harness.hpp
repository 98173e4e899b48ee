#pragma once
// The particle-file fuzz harnesses' common part (fuzz_csv.cpp, fuzz_h5.cpp): the particle
// files a scene loads ([dem.load]: CSV, particle snapshot, DEM state with or without its
// contact history) and a checkpoint's DEM state (DemSystem::restore). Any input must give loaded
// particles or a clean error (an exception derived from std::exception, as dem_server's main
// catches): a crash, a sanitizer report, a hang or an allocation beyond libFuzzer's limit is a
// finding.
//
// fuzz_csv gives its bytes to the CSV reader. fuzz_h5's first byte picks the target; the rest
// is either a raw HDF5 file's bytes or a recipe of mutations applied to a valid state or snapshot
// written at start-up (a bed of spheres and two rocks on a plane, run until it has contact
// history): resize a dataset, overwrite an element with fuzzed bits or a special value, delete a
// dataset. Raw bytes rarely get past HDF5's superblock check; the recipes reach the readers' own
// checks (row pointers, indices, sizes, shape tables), which is where forged files do harm.
#include <hdf5.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "../dem/core/dem_test_util.hpp"
#include "../dem/core/poly_test_util.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/placement/state_check.hpp"
#include "demfem/dem/scene/particle_source.hpp"
#include "demfem/io/h5_file.hpp"

namespace fuzz_particles {

namespace fs = std::filesystem;
using namespace demfem::dem;

// The bytes consumed by a recipe, zero once the input is used up.
struct Bytes {
  const std::uint8_t* p;
  std::size_t n;
  std::uint8_t u8() { return n ? (--n, *p++) : 0; }
  std::uint16_t u16() { return static_cast<std::uint16_t>(u8() | (u8() << 8)); }
  std::uint64_t u64() {
    std::uint64_t v = 0;
    for (int k = 0; k < 8; ++k) v |= std::uint64_t(u8()) << (8 * k);
    return v;
  }
};

inline DemSettings fuzz_settings() {
  auto s = test::two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, 1e-5, 0.02);
  s.gravity = {0, 0, -9.81};
  return s;
}

// The same scene for the file's writer and its readers (walls and materials must match for
// a state loaded with its history).
inline DemSystem fuzz_system() {
  DemSystem sys(fuzz_settings());
  sys.add_wall(test::plane_mesh(0.1, 2));
  return sys;
}

struct Paths {
  fs::path dir, state, snapshot, input;
  Paths() = default;
  Paths(Paths&& o) noexcept : dir(o.dir), state(o.state), snapshot(o.snapshot), input(o.input) {
    o.dir.clear();
  }
  ~Paths() {
    std::error_code ec;
    // The process's scratch folder (FUZZ_KEEP=1 keeps it, to look at the last input's files).
    if (!dir.empty() && !std::getenv("FUZZ_KEEP")) fs::remove_all(dir, ec);
  }
};

// Writes the seed state (group "dem") and a seed snapshot once per process.
inline const Paths& seeds() {
  static const Paths paths = [] {
    Paths p;
    p.dir = fs::temp_directory_path() / ("fuzz_particles_" + std::to_string(getpid()));
    fs::create_directories(p.dir);
    p.state = p.dir / "state.h5";
    p.snapshot = p.dir / "snapshot.h5";
    p.input = p.dir / "input.h5";
    DemSystem sys = fuzz_system();
    const auto cube = sys.add_shape(test::box_shape(0.004, 0.004, 0.004, 0.0005));
    std::vector<ParticleInit> init;
    for (int k = 0; k < 3; ++k)
      for (int j = 0; j < 3; ++j)
        for (int i = 0; i < 3; ++i)
          init.push_back(
              test::sphere({-0.006 + 0.0041 * i, -0.006 + 0.0041 * j, 0.0021 + 0.0041 * k}, 0.002,
                           {0, 0, -0.1}));
    init.push_back(test::poly(cube, {0.01, 0.0, 0.004}));
    init.push_back(test::poly(cube, {0.01, 0.0, 0.0095}));
    sys.add_particles(init);
    sys.advance(400);
    {
      demfem::io::H5File f(p.state, demfem::io::H5File::Mode::create);
      sys.save(f, "dem");
      f.close();
    }
    const auto& ps = sys.particles();
    const std::size_t n = ps.size();
    std::vector<double> pos, vel, radius(ps.radius.begin(), ps.radius.end());
    for (std::size_t i = 0; i < n; ++i) {
      pos.insert(pos.end(), {ps.px[i], ps.py[i], ps.pz[i]});
      vel.insert(vel.end(), {ps.vx[i], ps.vy[i], ps.vz[i]});
    }
    demfem::io::H5File f(p.snapshot, demfem::io::H5File::Mode::create);
    f.write("position", pos, {n, 3});
    f.write("velocity", vel, {n, 3});
    f.write("radius", radius);
    f.close();
    return p;
  }();
  return paths;
}

// The datasets of a file (full paths), in HDF5's visiting order.
inline std::vector<std::string> datasets(hid_t file) {
  std::vector<std::string> names;
  H5Ovisit(
      file, H5_INDEX_NAME, H5_ITER_INC,
      [](hid_t, const char* name, const H5O_info_t* info, void* out) -> herr_t {
        if (info->type == H5O_TYPE_DATASET)
          static_cast<std::vector<std::string>*>(out)->push_back(name);
        return 0;
      },
      &names);
  return names;
}

// Reads a dataset as raw bytes of its own type; false if it is not a 1-D or 2-D array of a
// fixed-size numeric type.
inline bool read_raw(hid_t file, const std::string& name, std::vector<std::uint8_t>& bytes,
                     hid_t& type, std::vector<hsize_t>& dims) {
  const hid_t d = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  if (d < 0) return false;
  const hid_t space = H5Dget_space(d);
  const int rank = H5Sget_simple_extent_ndims(space);
  bool ok = rank >= 1 && rank <= 2;
  if (ok) {
    dims.assign(static_cast<std::size_t>(rank), 0);
    H5Sget_simple_extent_dims(space, dims.data(), nullptr);
    type = H5Tget_native_type(H5Dget_type(d), H5T_DIR_ASCEND);
    hsize_t count = 1;
    for (const auto x : dims) count *= x;
    bytes.assign(count * H5Tget_size(type), 0);
    ok = H5Dread(d, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, bytes.data()) >= 0;
  }
  H5Sclose(space);
  H5Dclose(d);
  return ok;
}

inline void write_raw(hid_t file, const std::string& name, const std::vector<std::uint8_t>& bytes,
                      hid_t type, const std::vector<hsize_t>& dims) {
  H5Ldelete(file, name.c_str(), H5P_DEFAULT);
  const hid_t space = H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
  const hid_t d =
      H5Dcreate2(file, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (d >= 0) {
    if (!bytes.empty()) H5Dwrite(d, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, bytes.data());
    H5Dclose(d);
  }
  H5Sclose(space);
}

// Values that readers of counts, indices and sizes tend to trip on.
inline std::uint64_t special_value(std::uint8_t which, std::size_t width, bool floating) {
  if (floating) {
    const double v[] = {0.0,
                        -1.0,
                        1e300,
                        -1e300,
                        std::numeric_limits<double>::quiet_NaN(),
                        std::numeric_limits<double>::infinity(),
                        1e-300,
                        4294967296.0};
    double x = v[which % 8];
    std::uint64_t bits;
    std::memcpy(&bits, &x, 8);
    return width == 8 ? bits : 0;
  }
  const std::uint64_t v[] = {
      0,      ~0ull, 1, 0x7fffffffffffffffull, 0x8000000000000000ull, 0xffffffffull, 0x7fffffffull,
      1000000};
  return v[which % 8];
}

// Applies a recipe to a copy of `seed` and returns the copy's path.
inline const fs::path& mutated(const fs::path& seed, Bytes& in) {
  const auto& out = seeds().input;
  fs::copy_file(seed, out, fs::copy_options::overwrite_existing);
  const hid_t file = H5Fopen(out.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  if (file < 0) return out;
  const auto names = datasets(file);
  const int ops = 1 + in.u8() % 6;
  for (int k = 0; k < ops && !names.empty(); ++k) {
    const std::string& name = names[in.u8() % names.size()];
    std::vector<std::uint8_t> bytes;
    std::vector<hsize_t> dims;
    hid_t type = -1;
    if (!read_raw(file, name, bytes, type, dims)) continue;
    const std::size_t width = H5Tget_size(type);
    const bool floating = H5Tget_class(type) == H5T_FLOAT;
    const std::size_t count = width ? bytes.size() / width : 0;
    const std::uint8_t op = in.u8() % 5;
    if (op == 0) {  // another length (first dimension), new entries fuzzed
      const std::size_t rows = in.u16() % 512, row = dims.size() > 1 ? dims[1] : 1;
      dims[0] = rows;
      const std::size_t old = bytes.size();
      bytes.resize(rows * row * width);
      for (std::size_t b = old; b < bytes.size(); ++b) bytes[b] = in.u8();
    } else if (op == 1 && count) {  // one element's bits
      const std::size_t at = in.u16() % count;
      const std::uint64_t v = in.u64();
      std::memcpy(bytes.data() + at * width, &v, std::min<std::size_t>(width, 8));
    } else if (op == 2 && count) {  // one element set to a special value
      const std::size_t at = in.u16() % count;
      const std::uint64_t v = special_value(in.u8(), width, floating);
      std::memcpy(bytes.data() + at * width, &v, std::min<std::size_t>(width, 8));
    } else if (op == 3 && count) {  // one element moved by a small amount (off by one)
      const std::size_t at = in.u16() % count;
      const int delta = static_cast<int>(in.u8() % 5) - 2;
      if (floating && width == 8) {
        double x;
        std::memcpy(&x, bytes.data() + at * 8, 8);
        x = x * (1.0 + 0.5 * delta);
        std::memcpy(bytes.data() + at * 8, &x, 8);
      } else if (width == 8) {  // unsigned: wraps at the ends instead of overflowing
        std::uint64_t x;
        std::memcpy(&x, bytes.data() + at * 8, 8);
        x += static_cast<std::uint64_t>(static_cast<std::int64_t>(delta));
        std::memcpy(bytes.data() + at * 8, &x, 8);
      } else if (width == 4) {
        std::uint32_t x;
        std::memcpy(&x, bytes.data() + at * 4, 4);
        x += static_cast<std::uint32_t>(delta);
        std::memcpy(bytes.data() + at * 4, &x, 4);
      } else {
        bytes[at * width] = static_cast<std::uint8_t>(bytes[at * width] + delta);
      }
    } else if (op == 4) {
      H5Ldelete(file, name.c_str(), H5P_DEFAULT);
      H5Tclose(type);
      continue;
    }
    write_raw(file, name, bytes, type, dims);
    H5Tclose(type);
  }
  H5Fclose(file);
  return out;
}

inline const fs::path& raw_file(Bytes& in, const char* name) {
  static fs::path path;
  path = seeds().dir / name;
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(in.p), static_cast<std::streamsize>(in.n));
  return path;
}

inline void load(const fs::path& file, ParticleSource::Format format, bool history) {
  ParticleSource s;
  s.file = file;
  s.format = format;
  s.history = history;
  s.keep_time = history;
  s.material = history ? -1 : 0;
  s.where = "fuzz: key 'dem.load.file'";
  s.outside = ParticleSource::Outside::keep;
  s.max_overlap = 1.0;
  DemSystem sys = fuzz_system();
  const WallMesh walls[] = {test::plane_mesh(0.1, 2)};
  load_particles(s, sys, walls, nullptr);
  sys.advance(3);
}

enum class Target { csv, raw_snapshot, raw_state, snapshot, state, state_history, checkpoint };

// Loads one input as `target`; a clean error is any std::exception (as dem_server's main).
inline void run(Target target, Bytes in) {
  static const bool quiet = [] {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // HDF5's own error stack print
    (void)seeds();
    return true;
  }();
  (void)quiet;
  try {
    switch (target) {
      case Target::csv:
        load(raw_file(in, "input.csv"), ParticleSource::Format::csv, false);
        break;
      case Target::raw_snapshot:
        load(raw_file(in, "raw.h5"), ParticleSource::Format::snapshot, false);
        break;
      case Target::raw_state:
        load(raw_file(in, "raw.h5"), ParticleSource::Format::state, true);
        break;
      case Target::snapshot:
        load(mutated(seeds().snapshot, in), ParticleSource::Format::snapshot, false);
        break;
      case Target::state:
        load(mutated(seeds().state, in), ParticleSource::Format::state, false);
        break;
      case Target::state_history:
        load(mutated(seeds().state, in), ParticleSource::Format::state, true);
        break;
      case Target::checkpoint: {
        const auto& file = mutated(seeds().state, in);
        DemSystem sys = fuzz_system();
        demfem::io::H5File f(file, demfem::io::H5File::Mode::read);
        sys.restore(f, "dem");  // as DemRun::restore (dem_server resuming a checkpoint)
        check_particle_state(sys.particles(), file.string() + ":/dem");
        sys.advance(3);
        break;
      }
    }
  } catch (const std::exception& e) {
    if (std::getenv("FUZZ_VERBOSE")) std::fprintf(stderr, "clean error: %s\n", e.what());
    return;
  }
  if (std::getenv("FUZZ_VERBOSE")) std::fprintf(stderr, "loaded\n");
}

}  // namespace fuzz_particles
