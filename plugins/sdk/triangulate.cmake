# SPDX-License-Identifier: MIT
# Fast column-plane triangulation of the plugin SDK (procam/sdk/triangulate.hpp):
# a small static library plugins link, its test and its benchmark. Included
# from plugins/CMakeLists.txt.
set(_sdk_dir ${CMAKE_CURRENT_LIST_DIR})

add_library(procam_sdk_triangulate STATIC ${_sdk_dir}/src/triangulate.cpp)
add_library(procam::sdk_triangulate ALIAS procam_sdk_triangulate)
target_link_libraries(procam_sdk_triangulate
  PUBLIC procam::plugin_sdk Threads::Threads
  PRIVATE procam_warnings)
# The row kernel is written branch-free for the vectoriser, which -O2
# (RelWithDebInfo) does not run with a useful cost model; enable it here. The
# AVX2 twin is a __attribute__((target("avx2"))) function chosen at run time.
target_compile_options(procam_sdk_triangulate PRIVATE
  $<$<NOT:$<CONFIG:Debug>>:-ftree-vectorize -fvect-cost-model=dynamic>)
# Linked into plugin modules with hidden visibility: export nothing from here.
set_target_properties(procam_sdk_triangulate PROPERTIES
  CXX_VISIBILITY_PRESET hidden VISIBILITY_INLINES_HIDDEN ON POSITION_INDEPENDENT_CODE ON)

procam_add_test(procam_sdk_triangulate_test SOURCES ${_sdk_dir}/src/triangulate_test.cpp
  LIBS procam_sdk_triangulate)

if(PROCAM_BUILD_BENCHMARKS)
  add_executable(procam_sdk_triangulate_bench ${_sdk_dir}/src/triangulate_bench.cpp)
  target_link_libraries(procam_sdk_triangulate_bench
    PRIVATE procam_sdk_triangulate benchmark::benchmark procam_warnings)
endif()
