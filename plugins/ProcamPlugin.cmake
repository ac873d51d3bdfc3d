# SPDX-License-Identifier: MIT
# procam_add_plugin(): one call builds a decoder plugin from its folder.
#
#   procam_add_plugin(NAME <name>
#     CORE     <srcs...>   # the algorithm: static library procam_<prefix>_core
#     SOURCES  <srcs...>   # the ABI glue: MODULE procam-<name>.so
#     [TESTS   <srcs...>]  # one GoogleTest binary procam_<prefix>_<file stem> per source
#     [PREFIX  <prefix>]   # short name for targets (default: <name> with '-' -> '_')
#     [CORE_LIBS <libs...>]  # extra PUBLIC libraries of the core
#     [TEST_LIBS <libs...>]) # extra libraries of every test
#
# What it makes:
#   - procam_<prefix>_core: STATIC, position-independent, hidden visibility
#     (linked into a module, it exports nothing), include dir src/, links the
#     plugin SDK (procam::plugin_sdk) publicly and the warning set privately.
#   - <name>: the MODULE procam-<name>.so in ${PROCAM_PLUGIN_OUTPUT_DIR}, hidden
#     visibility so only the two ABI symbols (PROCAM_DEFINE_PLUGIN) are exported;
#     installed to lib/procam/plugins.
#   - one test binary per TESTS source, linked to the core (label "unit"); its
#     ctest names start with "procam_<prefix>_<stem>." (ctest -R procam_<prefix>).
#   - registration: the global property PROCAM_PLUGINS lists every plugin and
#     the custom target `procam_plugins` depends on all of them (wired up in
#     plugins/CMakeLists.txt), so suites that run every plugin depend on
#     `procam_plugins` and nobody edits add_dependencies lists.
# The core is a real static library even when CORE lists one file, so unit
# tests call the algorithm without the ABI.

function(procam_add_plugin)
  cmake_parse_arguments(P "" "NAME;PREFIX" "CORE;SOURCES;TESTS;CORE_LIBS;TEST_LIBS" ${ARGN})
  if(NOT P_NAME)
    message(FATAL_ERROR "procam_add_plugin: NAME is required")
  endif()
  if(NOT P_NAME MATCHES "^[a-z0-9][a-z0-9-]*$")
    message(FATAL_ERROR "procam_add_plugin: NAME '${P_NAME}' must be lower-case letters, digits and '-'")
  endif()
  if(NOT P_CORE OR NOT P_SOURCES)
    message(FATAL_ERROR "procam_add_plugin(${P_NAME}): CORE and SOURCES are both required")
  endif()
  if(P_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "procam_add_plugin(${P_NAME}): unknown arguments ${P_UNPARSED_ARGUMENTS}")
  endif()
  if(NOT P_PREFIX)
    string(REPLACE "-" "_" P_PREFIX "${P_NAME}")
  endif()
  set(core procam_${P_PREFIX}_core)

  add_library(${core} STATIC ${P_CORE})
  target_include_directories(${core} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/src)
  target_link_libraries(${core} PUBLIC procam::plugin_sdk ${P_CORE_LIBS} PRIVATE procam_warnings)
  set_target_properties(${core} PROPERTIES
    CXX_VISIBILITY_PRESET hidden VISIBILITY_INLINES_HIDDEN ON POSITION_INDEPENDENT_CODE ON)

  add_library(${P_NAME} MODULE ${P_SOURCES})
  target_link_libraries(${P_NAME} PRIVATE ${core} procam::plugin_sdk procam_warnings)
  set_target_properties(${P_NAME} PROPERTIES
    PREFIX "procam-" OUTPUT_NAME ${P_NAME}
    LIBRARY_OUTPUT_DIRECTORY ${PROCAM_PLUGIN_OUTPUT_DIR}
    CXX_VISIBILITY_PRESET hidden VISIBILITY_INLINES_HIDDEN ON)
  install(TARGETS ${P_NAME} LIBRARY DESTINATION lib/procam/plugins)
  set_property(GLOBAL APPEND PROPERTY PROCAM_PLUGINS ${P_NAME})

  foreach(src IN LISTS P_TESTS)
    get_filename_component(stem ${src} NAME_WE)
    procam_add_test(procam_${P_PREFIX}_${stem} SOURCES ${src} LIBS ${core} ${P_TEST_LIBS}
      TEST_PREFIX procam_${P_PREFIX}_${stem}.)
  endforeach()
endfunction()
