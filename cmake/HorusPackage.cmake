# Installation of horus and its CMake package: `cmake --install build --prefix P` gives
#   P/include/horus/...                 runtime headers
#   P/lib/libhorus_runtime.a            horus::runtime
#   P/lib/cmake/horus/                  horusConfig.cmake, targets, HorusGenerate.cmake
#   P/include/horus/msg/..., P/lib/libhorus_msgs.a, P/lib/python3.X/dist-packages/horus/msg
#                                       the standard messages (horus::msgs)
#   P/share/horus/{generator,templates,schemas}   the generator package, its templates, the schemas
#   P/share/horus/python/_horus_gen_support_v1.py the support module copied into Python outputs
#   P/include/horus/bridge/..., P/lib/libhorus_bridge_core.a   horus::bridge_core
#   P/include/horus/dds_bridge.hpp, P/include/horus/dds/..., P/lib/libhorus_dds.a,
#   P/share/horus/dds/register_network_bridge.cpp
#                                       horus::dds, the DDS bridge (built with Cyclone DDS only)
#   P/include/horus/live_view.hpp, P/include/horus/view/..., P/lib/libhorus_view{,_codecs}.a,
#   P/share/horus/view/register_scheduler_view.cpp
#                                       horus::view, the live view (built with Cap'n Proto only)
#   P/bin/horus-gen                     the generator's command (configured from cmake/horus-gen.in
#                                       with where the three above are, relative to it)
# so that user projects do find_package(horus CONFIG) and call horus_generate().
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(HORUS_INSTALL_CMAKEDIR "${CMAKE_INSTALL_LIBDIR}/cmake/horus")
set(HORUS_INSTALL_GENERATORDIR "${CMAKE_INSTALL_DATADIR}/horus/generator")
set(HORUS_INSTALL_SCHEMADIR "${CMAKE_INSTALL_DATADIR}/horus/schemas")
set(HORUS_INSTALL_TEMPLATEDIR "${CMAKE_INSTALL_DATADIR}/horus/templates")
set(HORUS_INSTALL_SUPPORTDIR "${CMAKE_INSTALL_DATADIR}/horus/python")
set(HORUS_INSTALL_GEN "${CMAKE_INSTALL_BINDIR}/horus-gen")

set_target_properties(horus_headers PROPERTIES EXPORT_NAME headers)
set_target_properties(horus_summary PROPERTIES EXPORT_NAME summary)
set_target_properties(horus_runtime PROPERTIES EXPORT_NAME runtime)
set(horus_exported horus_headers horus_summary horus_runtime)
# The standard message library (schemas/), installed by its horus_generate() into the export set
# horusTargets: exported as horus::msgs, which users link and name in DEPENDS to use its types in
# their own schemas.
set(HORUS_MSGS_PYTHON OFF)
if(TARGET horus_msgs)
  set_target_properties(horus_msgs PROPERTIES EXPORT_NAME msgs)
  get_target_property(horus_msgs_python horus_msgs HORUS_PYTHON_DIR)
  if(horus_msgs_python)
    set(HORUS_MSGS_PYTHON ON)
  endif()
  # The tensor pool and its types (runtime/src/pool) build on the standard messages.
  set_target_properties(horus_pool PROPERTIES EXPORT_NAME pool)
  list(APPEND horus_exported horus_pool)
endif()
# The bridges' shared core, and the DDS bridge (which carries pool-backed topics, so it needs the
# pool): a user's C++ program whose scheduler calls network() links horus::dds. The package
# config then finds Cyclone DDS (HORUS_DDS_INSTALLED).
set_target_properties(horus_bridge_core PROPERTIES EXPORT_NAME bridge_core)
list(APPEND horus_exported horus_bridge_core)
install(DIRECTORY bridges/core/include/horus DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}")
set(HORUS_DDS_INSTALLED OFF)
if(TARGET horus_dds AND TARGET horus_pool)
  set(HORUS_DDS_INSTALLED ON)
  set_target_properties(horus_dds PROPERTIES EXPORT_NAME dds)
  list(APPEND horus_exported horus_dds)
  install(DIRECTORY bridges/dds/include/horus DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}")
  install(FILES bridges/dds/src/register_network_bridge.cpp
          DESTINATION "${CMAKE_INSTALL_DATADIR}/horus/dds")
endif()
# The live view (built with Cap'n Proto only): a user's C++ program whose scheduler calls view()
# links horus::view. The package config then finds Cap'n Proto (HORUS_VIEW_INSTALLED).
set(HORUS_VIEW_INSTALLED OFF)
if(TARGET horus_view AND TARGET horus_pool)
  set(HORUS_VIEW_INSTALLED ON)
  set_target_properties(horus_view PROPERTIES EXPORT_NAME view)
  set_target_properties(horus_view_codecs PROPERTIES EXPORT_NAME view_codecs)
  list(APPEND horus_exported horus_view horus_view_codecs)
  install(DIRECTORY bridges/view/include/horus DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}")
  install(FILES bridges/view/src/register_scheduler_view.cpp
          DESTINATION "${CMAKE_INSTALL_DATADIR}/horus/view")
endif()
install(TARGETS ${horus_exported} EXPORT horusTargets ARCHIVE DESTINATION "${CMAKE_INSTALL_LIBDIR}")
install(DIRECTORY runtime/include/horus DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}")
install(EXPORT horusTargets NAMESPACE horus:: DESTINATION "${HORUS_INSTALL_CMAKEDIR}")

install(DIRECTORY generator/horus_gen DESTINATION "${HORUS_INSTALL_GENERATORDIR}"
        PATTERN __pycache__ EXCLUDE)
install(FILES runtime/python/_horus_gen_support_v1.py DESTINATION "${HORUS_INSTALL_SUPPORTDIR}")
install(DIRECTORY templates/ DESTINATION "${HORUS_INSTALL_TEMPLATEDIR}"
        PATTERN README.md EXCLUDE)
install(DIRECTORY schemas/ DESTINATION "${HORUS_INSTALL_SCHEMADIR}" PATTERN README.md EXCLUDE)

file(RELATIVE_PATH HORUS_GEN_PACKAGE_FROM_BIN "/${CMAKE_INSTALL_BINDIR}" "/${HORUS_INSTALL_GENERATORDIR}")
file(RELATIVE_PATH HORUS_TEMPLATES_FROM_BIN "/${CMAKE_INSTALL_BINDIR}" "/${HORUS_INSTALL_TEMPLATEDIR}")
file(RELATIVE_PATH HORUS_SUPPORT_FROM_BIN "/${CMAKE_INSTALL_BINDIR}"
     "/${HORUS_INSTALL_SUPPORTDIR}/_horus_gen_support_v1.py")
configure_file(cmake/horus-gen.in "${PROJECT_BINARY_DIR}/package/horus-gen" @ONLY)
install(PROGRAMS "${PROJECT_BINARY_DIR}/package/horus-gen" DESTINATION "${CMAKE_INSTALL_BINDIR}")

configure_package_config_file(cmake/horusConfig.cmake.in
  "${PROJECT_BINARY_DIR}/package/horusConfig.cmake"
  INSTALL_DESTINATION "${HORUS_INSTALL_CMAKEDIR}"
  PATH_VARS HORUS_INSTALL_GEN HORUS_INSTALL_SCHEMADIR HORUS_PYTHON_INSTALL_DIR)
# 0.x: a new minor version may break users, so only the same minor version is compatible.
write_basic_package_version_file("${PROJECT_BINARY_DIR}/package/horusConfigVersion.cmake"
  COMPATIBILITY SameMinorVersion)
install(FILES
  "${PROJECT_BINARY_DIR}/package/horusConfig.cmake"
  "${PROJECT_BINARY_DIR}/package/horusConfigVersion.cmake"
  cmake/HorusGenerate.cmake
  cmake/HorusCheck.cmake
  DESTINATION "${HORUS_INSTALL_CMAKEDIR}")

# Inside this build, find_package(horus) (as the examples, written as user projects, call it)
# finds this stand-in, which only adds what the build has not already defined.
set(HORUS_IN_TREE_PACKAGE_DIR "${PROJECT_BINARY_DIR}/package/in-tree")
file(CONFIGURE OUTPUT "${HORUS_IN_TREE_PACKAGE_DIR}/horusConfig.cmake" CONTENT
  "# horus inside its own build: the targets and horus_generate() are already defined.\n\
set(HORUS_SCHEMA_DIR \"${PROJECT_SOURCE_DIR}/schemas\")\n")
file(COPY "${PROJECT_BINARY_DIR}/package/horusConfigVersion.cmake"
     DESTINATION "${HORUS_IN_TREE_PACKAGE_DIR}")

# Message libraries of horus's own tests and examples are not part of the installation.
set(HORUS_GENERATE_INSTALL OFF)
