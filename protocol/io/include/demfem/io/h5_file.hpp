#pragma once
// A small RAII layer over the HDF5 C API: what the solvers need for results, checkpoints and
// restarts (whole datasets of double / int64 / uint8, groups, scalar attributes). Errors
// throw H5Error naming the file and the dataset.

#include <cstdint>
#include <filesystem>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace demfem::io {

/// @brief HDF5 failure; what() names the file and object.
class H5Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// @brief An open HDF5 file.
class H5File {
 public:
  enum class Mode { read, create, append };
  H5File(const std::filesystem::path& path, Mode mode);
  ~H5File();
  H5File(H5File&& other) noexcept;
  H5File& operator=(H5File&& other) noexcept;
  H5File(const H5File&) = delete;
  H5File& operator=(const H5File&) = delete;

  /// Creates the group and any missing parents ("a/b/c").
  void create_group(const std::string& name);
  bool exists(const std::string& name) const;

  /// Writes a whole dataset (replacing none: the name must be new). `dims` empty = 1-D.
  void write(const std::string& name, std::span<const double> data,
             std::vector<std::size_t> dims = {});
  void write(const std::string& name, std::span<const std::int64_t> data,
             std::vector<std::size_t> dims = {});
  void write(const std::string& name, std::span<const std::uint8_t> data,
             std::vector<std::size_t> dims = {});

  std::vector<double> read_doubles(const std::string& name,
                                   std::vector<std::size_t>* dims = nullptr) const;
  std::vector<std::int64_t> read_int64(const std::string& name,
                                       std::vector<std::size_t>* dims = nullptr) const;
  std::vector<std::uint8_t> read_uint8(const std::string& name) const;

  /// Scalar attributes on an object ("/" for the file).
  void set_attribute(const std::string& object, const std::string& name, double value);
  void set_attribute(const std::string& object, const std::string& name, std::int64_t value);
  void set_attribute(const std::string& object, const std::string& name, const std::string& value);
  double attribute_double(const std::string& object, const std::string& name) const;
  std::int64_t attribute_int64(const std::string& object, const std::string& name) const;
  std::string attribute_string(const std::string& object, const std::string& name) const;
  bool has_attribute(const std::string& object, const std::string& name) const;

  void flush();
  /// Closes the file, writing what HDF5 still holds; throws H5Error with the system's reason
  /// (e.g. "No space left on device") when that fails (the destructor closes silently).
  void close();
  const std::filesystem::path& path() const { return path_; }

 private:
  [[noreturn]] void fail(const std::string& what) const;
  /// fail() with the system's reason appended when errno holds one (a full disk, a
  /// permission, an I/O error), so that such a failure is not taken for a corrupt file.
  [[noreturn]] void fail_io(const std::string& what, int err) const;
  void close_quietly() noexcept;
  std::filesystem::path path_;
  std::int64_t id_ = -1;
};

}  // namespace demfem::io
