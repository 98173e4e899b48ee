#include "demfem/io/h5_file.hpp"

#include <hdf5.h>

#include <cerrno>
#include <cstring>
#include <mutex>

namespace demfem::io {

namespace {

// HDF5 prints its own error stack by default; our exceptions carry the context instead.
// H5dont_atexit: HDF5 1.10 leaves a file whose H5Fclose failed (a full disk while it writes its
// metadata) half-closed in its table of open files, and its exit handler then closes it again
// and crashes (SIGSEGV after the run's clean error message). Every file is closed by its
// H5File; at exit there is nothing left for the library to flush.
void silence_hdf5() {
  static std::once_flag once;
  std::call_once(once, [] {
    H5dont_atexit();
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  });
}

template <typename T>
hid_t native_type();
template <>
hid_t native_type<double>() { return H5T_NATIVE_DOUBLE; }
template <>
hid_t native_type<std::int64_t>() { return H5T_NATIVE_INT64; }
template <>
hid_t native_type<std::uint8_t>() { return H5T_NATIVE_UINT8; }

// errno values that say why a file operation failed (others, left over from HDF5's own
// probing, say nothing about it).
bool telling_errno(int err) {
  switch (err) {
    case EACCES:
    case EPERM:
    case EROFS:
    case ENOSPC:
    case EDQUOT:
    case EFBIG:
    case EIO:
    case EISDIR:
    case ENOTDIR:
    case EMFILE:
    case ENFILE:
    case ENOMEM:
    case ENAMETOOLONG:
    case ENOENT:
      return true;
    default:
      return false;
  }
}

struct Handle {
  hid_t id;
  herr_t (*close)(hid_t);
  ~Handle() {
    if (id >= 0) close(id);
  }
};

template <typename T>
void write_dataset(hid_t file, const std::string& name, std::span<const T> data,
                   std::vector<std::size_t> dims, const auto& fail) {
  if (dims.empty()) dims = {data.size()};
  std::size_t total = 1;
  for (auto d : dims) total *= d;
  if (total != data.size()) fail("dataset '" + name + "': dims do not match the data size");
  std::vector<hsize_t> hd(dims.begin(), dims.end());
  Handle space{H5Screate_simple(static_cast<int>(hd.size()), hd.data(), nullptr), H5Sclose};
  Handle lcpl{H5Pcreate(H5P_LINK_CREATE), H5Pclose};
  H5Pset_create_intermediate_group(lcpl.id, 1);
  Handle set{H5Dcreate2(file, name.c_str(), native_type<T>(), space.id, lcpl.id, H5P_DEFAULT,
                        H5P_DEFAULT),
             H5Dclose};
  if (set.id < 0) fail("cannot create dataset '" + name + "'");
  if (!data.empty() &&
      H5Dwrite(set.id, native_type<T>(), H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()) < 0) {
    fail("cannot write dataset '" + name + "'");
  }
}

template <typename T>
std::vector<T> read_dataset(hid_t file, const std::string& name, std::vector<std::size_t>* dims,
                            const auto& fail) {
  if (H5Lexists(file, name.c_str(), H5P_DEFAULT) <= 0) fail("no dataset '" + name + "'");
  Handle set{H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose};
  if (set.id < 0) fail("cannot open dataset '" + name + "'");
  Handle space{H5Dget_space(set.id), H5Sclose};
  const int rank = H5Sget_simple_extent_ndims(space.id);
  if (rank < 0) fail("dataset '" + name + "' has no simple shape");
  std::vector<hsize_t> hd(static_cast<std::size_t>(rank));
  H5Sget_simple_extent_dims(space.id, hd.data(), nullptr);
  std::size_t total = 1;
  for (auto d : hd) total *= d;
  if (dims) dims->assign(hd.begin(), hd.end());
  std::vector<T> out(total);
  if (total > 0 &&
      H5Dread(set.id, native_type<T>(), H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0) {
    fail("cannot read dataset '" + name + "' (truncated or corrupt file?)");
  }
  return out;
}

}  // namespace

H5File::H5File(const std::filesystem::path& path, Mode mode) : path_(path) {
  silence_hdf5();
  hid_t id = -1;
  errno = 0;
  switch (mode) {
    case Mode::read:
      if (!std::filesystem::exists(path)) fail("file does not exist");
      id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
      break;
    case Mode::create:
      id = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
      break;
    case Mode::append:
      id = std::filesystem::exists(path) ? H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT)
                                         : H5Fcreate(path.c_str(), H5F_ACC_EXCL, H5P_DEFAULT,
                                                     H5P_DEFAULT);
      break;
  }
  if (id < 0) {
    const int err = errno;
    const bool creating = mode == Mode::create || !std::filesystem::exists(path);
    if (telling_errno(err)) fail_io(creating ? "cannot create" : "cannot open", err);
    fail(creating ? "cannot create (the folder does not exist or is not writable?)"
                  : "cannot open (not an HDF5 file, or truncated)");
  }
  id_ = id;
}

H5File::~H5File() {
  close_quietly();
}

H5File::H5File(H5File&& other) noexcept : path_(std::move(other.path_)), id_(other.id_) {
  other.id_ = -1;
}

H5File& H5File::operator=(H5File&& other) noexcept {
  if (this != &other) {
    close_quietly();
    path_ = std::move(other.path_);
    id_ = other.id_;
    other.id_ = -1;
  }
  return *this;
}

void H5File::fail(const std::string& what) const {
  throw H5Error(path_.string() + ": " + what);
}

void H5File::fail_io(const std::string& what, int err) const {
  if (!telling_errno(err)) fail(what);
  std::string hint;
  if (err == ENOSPC || err == EDQUOT || err == EFBIG) {
    hint = "; free space (or choose another output folder) and run again";
  } else if (err == EACCES || err == EPERM || err == EROFS) {
    hint = "; the folder is not writable";
  }
  fail(what + ": " + std::strerror(err) + hint);
}

void H5File::close() {
  if (id_ < 0) return;
  errno = 0;
  const herr_t rc = H5Fclose(id_);
  const int err = errno;
  id_ = -1;
  if (rc < 0) fail_io("cannot write the file's end (it is incomplete)", err);
}

void H5File::close_quietly() noexcept {
  if (id_ >= 0) {
    H5Fclose(id_);
    id_ = -1;
  }
}

bool H5File::has_attribute(const std::string& object, const std::string& name) const {
  if (!exists(object)) return false;
  return H5Aexists_by_name(id_, object.c_str(), name.c_str(), H5P_DEFAULT) > 0;
}

void H5File::flush() {
  if (id_ >= 0) H5Fflush(id_, H5F_SCOPE_GLOBAL);
}

void H5File::create_group(const std::string& name) {
  if (exists(name)) return;
  Handle lcpl{H5Pcreate(H5P_LINK_CREATE), H5Pclose};
  H5Pset_create_intermediate_group(lcpl.id, 1);
  Handle g{H5Gcreate2(id_, name.c_str(), lcpl.id, H5P_DEFAULT, H5P_DEFAULT), H5Gclose};
  if (g.id < 0) fail("cannot create group '" + name + "'");
}

bool H5File::exists(const std::string& name) const {
  if (name == "/" || name.empty()) return true;
  // Check each prefix: H5Lexists fails on a missing intermediate group.
  std::size_t pos = 0;
  while (true) {
    pos = name.find('/', pos + 1);
    const std::string prefix = name.substr(0, pos);
    if (!prefix.empty() && prefix != "/" && H5Lexists(id_, prefix.c_str(), H5P_DEFAULT) <= 0) {
      return false;
    }
    if (pos == std::string::npos) return true;
  }
}

void H5File::write(const std::string& name, std::span<const double> data,
                   std::vector<std::size_t> dims) {
  errno = 0;
  write_dataset(id_, name, data, std::move(dims),
                [this](const std::string& m) { fail_io(m, errno); });
}
void H5File::write(const std::string& name, std::span<const std::int64_t> data,
                   std::vector<std::size_t> dims) {
  errno = 0;
  write_dataset(id_, name, data, std::move(dims),
                [this](const std::string& m) { fail_io(m, errno); });
}
void H5File::write(const std::string& name, std::span<const std::uint8_t> data,
                   std::vector<std::size_t> dims) {
  errno = 0;
  write_dataset(id_, name, data, std::move(dims),
                [this](const std::string& m) { fail_io(m, errno); });
}

std::vector<double> H5File::read_doubles(const std::string& name,
                                         std::vector<std::size_t>* dims) const {
  return read_dataset<double>(id_, name, dims, [this](const std::string& m) { fail(m); });
}
std::vector<std::int64_t> H5File::read_int64(const std::string& name,
                                             std::vector<std::size_t>* dims) const {
  return read_dataset<std::int64_t>(id_, name, dims, [this](const std::string& m) { fail(m); });
}
std::vector<std::uint8_t> H5File::read_uint8(const std::string& name) const {
  return read_dataset<std::uint8_t>(id_, name, nullptr, [this](const std::string& m) { fail(m); });
}

namespace {

template <typename T>
void put_attribute(hid_t file, const std::string& object, const std::string& name, hid_t type,
                   const T* value, const auto& fail) {
  Handle obj{H5Oopen(file, object.c_str(), H5P_DEFAULT), H5Oclose};
  if (obj.id < 0) fail("no object '" + object + "' for attribute '" + name + "'");
  if (H5Aexists(obj.id, name.c_str()) > 0) H5Adelete(obj.id, name.c_str());
  Handle space{H5Screate(H5S_SCALAR), H5Sclose};
  Handle attr{H5Acreate2(obj.id, name.c_str(), type, space.id, H5P_DEFAULT, H5P_DEFAULT),
              H5Aclose};
  if (attr.id < 0 || H5Awrite(attr.id, type, value) < 0) {
    fail("cannot write attribute '" + name + "' on '" + object + "'");
  }
}

Handle open_attribute(hid_t file, const std::string& object, const std::string& name,
                      const auto& fail) {
  Handle obj{H5Oopen(file, object.c_str(), H5P_DEFAULT), H5Oclose};
  if (obj.id < 0 || H5Aexists(obj.id, name.c_str()) <= 0) {
    fail("no attribute '" + name + "' on '" + object + "'");
  }
  return Handle{H5Aopen(obj.id, name.c_str(), H5P_DEFAULT), H5Aclose};
}

}  // namespace

void H5File::set_attribute(const std::string& object, const std::string& name, double value) {
  put_attribute(id_, object, name, H5T_NATIVE_DOUBLE, &value,
                [this](const std::string& m) { fail(m); });
}
void H5File::set_attribute(const std::string& object, const std::string& name,
                           std::int64_t value) {
  put_attribute(id_, object, name, H5T_NATIVE_INT64, &value,
                [this](const std::string& m) { fail(m); });
}
void H5File::set_attribute(const std::string& object, const std::string& name,
                           const std::string& value) {
  Handle type{H5Tcopy(H5T_C_S1), H5Tclose};
  H5Tset_size(type.id, value.size() + 1);
  put_attribute(id_, object, name, type.id, value.c_str(),
                [this](const std::string& m) { fail(m); });
}

double H5File::attribute_double(const std::string& object, const std::string& name) const {
  Handle a = open_attribute(id_, object, name, [this](const std::string& m) { fail(m); });
  double v = 0.0;
  if (H5Aread(a.id, H5T_NATIVE_DOUBLE, &v) < 0) fail("cannot read attribute '" + name + "'");
  return v;
}

std::int64_t H5File::attribute_int64(const std::string& object, const std::string& name) const {
  Handle a = open_attribute(id_, object, name, [this](const std::string& m) { fail(m); });
  std::int64_t v = 0;
  if (H5Aread(a.id, H5T_NATIVE_INT64, &v) < 0) fail("cannot read attribute '" + name + "'");
  return v;
}

std::string H5File::attribute_string(const std::string& object, const std::string& name) const {
  Handle a = open_attribute(id_, object, name, [this](const std::string& m) { fail(m); });
  Handle type{H5Aget_type(a.id), H5Tclose};
  const std::size_t size = H5Tget_size(type.id);
  std::string v(size, '\0');
  Handle mem{H5Tcopy(H5T_C_S1), H5Tclose};
  H5Tset_size(mem.id, size);
  if (H5Aread(a.id, mem.id, v.data()) < 0) fail("cannot read attribute '" + name + "'");
  v.resize(v.find('\0') == std::string::npos ? v.size() : v.find('\0'));
  return v;
}

}  // namespace demfem::io
