# CHOLMOD (SuiteSparse) for the FEM's sparse Cholesky factorisation. Optional at build
# time: without it the FEM falls back to Eigen's SimplicialLDLT. Note the licence: CHOLMOD's
# supernodal module is GPL-2.0+, so a binary linked with it is distributed under the GPL.
option(DEMFEM_CHOLMOD "Use SuiteSparse CHOLMOD for sparse factorisation when found" ON)
set(DEMFEM_HAVE_CHOLMOD OFF)
if(DEMFEM_CHOLMOD)
  find_path(CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse)
  find_library(CHOLMOD_LIBRARY cholmod)
  find_library(SUITESPARSECONFIG_LIBRARY suitesparseconfig)
  if(CHOLMOD_INCLUDE_DIR AND CHOLMOD_LIBRARY AND SUITESPARSECONFIG_LIBRARY)
    add_library(demfem_cholmod INTERFACE)
    target_include_directories(demfem_cholmod SYSTEM INTERFACE ${CHOLMOD_INCLUDE_DIR})
    target_link_libraries(demfem_cholmod INTERFACE ${CHOLMOD_LIBRARY} ${SUITESPARSECONFIG_LIBRARY})
    target_compile_definitions(demfem_cholmod INTERFACE DEMFEM_HAVE_CHOLMOD=1)
    add_library(demfem::cholmod ALIAS demfem_cholmod)
    set(DEMFEM_HAVE_CHOLMOD ON)
  endif()
endif()
message(STATUS "demfem: CHOLMOD ${DEMFEM_HAVE_CHOLMOD}")
