# SPDX-License-Identifier: MIT
# ctest procam_sim_only_build (label "build"): a configure with every device
# backend OFF (PROCAM_WITH_ARAVIS/GLFW/LIBCAMERA, as on a machine without
# their packages) must configure and build procam_hw and procamd, with no
# backend library built. With -DFULL=ON it also builds the conformance suite
# (and so every plugin) and runs the null plugin's cases there: 698 s on 2
# shared cores, too slow for every `make test`, so ctest runs the short form.
# Run as: cmake -DSOURCE_DIR=.. -DWORK_DIR=.. -DBUILD_TYPE=..
#   [-DLAUNCHER=ccache] [-DGENERATOR=..] [-DFULL=ON] -P sim_only_build.cmake
# Times each step and prints it; fails with the step's output.
foreach(v SOURCE_DIR WORK_DIR BUILD_TYPE)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "sim_only_build.cmake: -D${v}=... is required")
  endif()
endforeach()
set(args -S ${SOURCE_DIR} -B ${WORK_DIR} -DCMAKE_BUILD_TYPE=${BUILD_TYPE}
    -DPROCAM_WITH_ARAVIS=OFF -DPROCAM_WITH_GLFW=OFF -DPROCAM_WITH_LIBCAMERA=OFF
    -DPROCAM_BUILD_BENCHMARKS=OFF)
if(GENERATOR)
  list(APPEND args -G ${GENERATOR})
endif()
if(LAUNCHER)
  list(APPEND args -DCMAKE_C_COMPILER_LAUNCHER=${LAUNCHER} -DCMAKE_CXX_COMPILER_LAUNCHER=${LAUNCHER})
endif()

function(step name)
  string(TIMESTAMP t0 "%s")
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
  string(TIMESTAMP t1 "%s")
  math(EXPR dt "${t1} - ${t0}")
  message(STATUS "${name}: ${dt} s")
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${name} failed (${rc}):\n${out}")
  endif()
  set(step_output "${out}" PARENT_SCOPE)
endfunction()

step("configure (all device backends OFF)" ${CMAKE_COMMAND} ${args})
if(NOT step_output MATCHES "hw backends: sim, aravis=0, glfw\\+screencam=0, libcamera=0")
  message(FATAL_ERROR "configure did not turn the backends off:\n${step_output}")
endif()
set(targets procam_hw procamd)
if(FULL)
  list(APPEND targets procam_conformance_test)
endif()
step("build ${targets}" ${CMAKE_COMMAND} --build ${WORK_DIR} -j2 --target ${targets})
foreach(lib libprocam_aravis.a libprocam_glfw.a libprocam_libcamera.a)
  file(GLOB_RECURSE found ${WORK_DIR}/hw/${lib})
  if(found)
    message(FATAL_ERROR "a backend was built although it is OFF: ${found}")
  endif()
endforeach()
if(FULL)
  step("conformance of the null plugin in the sim-only build"
       ${WORK_DIR}/tests/conformance/procam_conformance_test --gtest_filter=*null*)
  if(NOT step_output MATCHES "PASSED")
    message(FATAL_ERROR "no conformance case ran:\n${step_output}")
  endif()
endif()
