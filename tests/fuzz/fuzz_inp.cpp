// libFuzzer harness for the Abaqus .inp reader: any bytes give a model or an InpError.
#include <cstddef>
#include <cstdint>
#include <string>

#include "demfem/fem/inp_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    // No *INCLUDE: the fuzzer must not read files (and results must not depend on them).
    demfem::fem::InpOptions options;
    options.allow_include = false;
    options.c3d8r_as = demfem::fem::SolidFormulation::incompatible_modes;
    (void)demfem::fem::parse_inp(text, "fuzz.inp", options);
  } catch (const demfem::fem::InpError&) {
  }
  return 0;
}
