# Installs demfem::protocol into a temporary prefix, builds tests/protocol/outside_solver
# against it with find_package(demfemProtocol), and runs it (it attaches as a FEM solver).
# cmake -DBUILD_DIR=<demfem build> -DSOURCE_DIR=<demfem source> -DWORK_DIR=<scratch> -P install_check.cmake
file(REMOVE_RECURSE ${WORK_DIR})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR}/protocol/ipc --prefix ${WORK_DIR}/prefix
  RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "install of demfem::protocol failed (${rc})")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -S ${SOURCE_DIR}/tests/protocol/outside_solver
  -B ${WORK_DIR}/build -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "configuring the outside solver failed:\n${out}\n${err}")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} --build ${WORK_DIR}/build
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "building the outside solver failed:\n${out}\n${err}")
endif()
execute_process(COMMAND ${WORK_DIR}/build/outside_solver RESULT_VARIABLE rc
  OUTPUT_VARIABLE out ERROR_VARIABLE err)
file(REMOVE_RECURSE ${WORK_DIR})
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "outside_solver failed (${rc}):\n${out}\n${err}")
endif()
message(STATUS "${out}")
