#include "demfem/io/checkpoint_file.hpp"

#include <stdexcept>
#include <string>

#include "demfem/io/atomic_file.hpp"

namespace demfem::io {

void write_checkpoint_file(const std::filesystem::path& file, std::int64_t step,
                           const std::function<void(H5File&)>& write) {
  {
    H5File h5(partial_path(file), H5File::Mode::create);
    h5.set_attribute("/", "step", step);
    write(h5);
    h5.close();
  }
  commit_partial(file);
}

H5File open_checkpoint_file(const std::filesystem::path& file, std::int64_t step) {
  H5File h5(file, H5File::Mode::read);
  const std::int64_t saved = h5.attribute_int64("/", "step");
  if (saved != step) {
    throw std::runtime_error(file.string() + ": checkpoint is of step " + std::to_string(saved) +
                             ", asked to restore step " + std::to_string(step));
  }
  return h5;
}

}  // namespace demfem::io
