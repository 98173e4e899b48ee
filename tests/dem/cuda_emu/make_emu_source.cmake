# cmake -DIN=dem_cuda.cu -DOUT=dem_cuda_emu.cpp -P make_emu_source.cmake
# Turns each kernel launch `kernel<<<grid, block, shmem, stream>>>(args)` of the CUDA backend
# into `EMU_LAUNCH(grid, block, shmem, stream, kernel, args)` for the runtime test double
# (cuda_runtime.h next to this file). Nothing else of the source changes.
file(READ "${IN}" src)
string(REGEX REPLACE "([A-Za-z_0-9]+(<[a-z]+>)?)<<<([^;]*)>>>\\(" "EMU_LAUNCH(\\3, \\1, " src "${src}")
string(FIND "${src}" "<<<" left)
if(NOT left EQUAL -1)
  message(FATAL_ERROR "make_emu_source: a kernel launch in ${IN} was not converted")
endif()
file(WRITE "${OUT}" "// Generated from ${IN} by make_emu_source.cmake; do not edit.\n${src}")
