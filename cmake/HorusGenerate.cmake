# horus_generate(): turn .hmsg/.hsrv/.haction/.hnode schema files into a library target of generated code.
#
#   horus_generate(TARGET my_msgs
#                  [PACKAGE my_robot.msg]          # package of files that declare none
#                  FILES motor.hmsg pose.hmsg ...   # also .hsrv services, .haction actions, .hnode nodes
#                  [INCLUDE_DIRS dir...]           # extra import roots (-I)
#                  [LANGUAGES cpp python jsonschema idl] # default: cpp
#                  [DEPENDS other_msgs...]         # targets made by horus_generate()
#                  [INSTALL | NO_INSTALL]
#                  [EXPORT export_set])            # install(TARGETS ... EXPORT export_set)
#
# With `cpp` in LANGUAGES, makes the static library `my_msgs` (position-independent; linking
# horus::headers and the DEPENDS targets) whose include directory is the generated C++ folder:
#   target_link_libraries(app PRIVATE my_msgs)      then  #include <my_robot/msg/motor.hpp>
# The headers declare; the library defines what the headers leave out to stay quick to include
# (log_summary(), the layout checks), so a program that uses the types links the target. Helpers
# too big to be inline: declare them in the #[cpp_mixin] fragment and add the .cpp that defines
# them with target_sources(my_msgs PRIVATE ...). Python only: an INTERFACE library.
# With .hnode files among FILES, the node base classes derive from horus::Node and hold topics:
# the library then links horus::runtime too (and its Python classes need the `horus` package).
# With `python` in LANGUAGES the Python package folder (put it on sys.path) is the target property
# HORUS_PYTHON_DIR and the variable <TARGET>_PYTHON_DIR; with `cpp`, the generated C++ folder is
# the target property HORUS_CPP_DIR; with `jsonschema` (a JSON Schema per message, as the recording
# export to Foxglove writes messages), the folder of `<package path>/<Name>.schema.json` is the
# target property HORUS_JSONSCHEMA_DIR (installed under share/horus/jsonschema); with `idl` (OMG IDL
# in ROS 2's naming, for DDS: `<package path>/<Name>.idl`), the include root of the IDL files (idlc's
# -I) is the target property HORUS_IDL_DIR and the variable <TARGET>_IDL_DIR (installed under
# share/horus/idl). HORUS_SCHEMA_DIRS holds the folders that horus-gen searches
# for imports and qualified names (-I), here and in every target that DEPENDS on this one: the
# folders of FILES, the root above them when they sit in their package's folder
# (schemas/ for schemas/my_robot/msg/motor.hmsg in my_robot.msg), INCLUDE_DIRS, and the folders
# of the DEPENDS targets.
#
# Installation (default INSTALL; set HORUS_GENERATE_INSTALL to OFF to change the default): the C++
# headers go to <prefix>/${CMAKE_INSTALL_INCLUDEDIR}, the library to
# <prefix>/${CMAKE_INSTALL_LIBDIR}/lib<TARGET>.a, the Python packages to
# <prefix>/${HORUS_PYTHON_INSTALL_DIR} (lib/python3.X/dist-packages: on the path of Debian's
# /usr/bin/python3 for the default prefix /usr/local). `EXPORT set` adds the target to the export
# set `set`, so that the project's own install(EXPORT set ...) makes it an imported target for
# its users (the DEPENDS targets must be exported too); without it, consumers of the installation
# link lib<TARGET>.a and horus::headers themselves and add the include folder.
#
# Inputs: HORUS_GEN_EXECUTABLE (the horus-gen script; set by find_package(horus) or by the horus
# build itself), HORUS_PYTHON (the interpreter that runs it, default /usr/bin/python3) and, when
# set, HORUS_WARNINGS (compile options for the generated sources; horus's own build sets it).

include_guard(GLOBAL)
if(CMAKE_VERSION VERSION_LESS 3.20)
  message(FATAL_ERROR "horus_generate() needs CMake 3.20 or newer (DEPFILE with every generator); "
                      "this is CMake ${CMAKE_VERSION}")
endif()
include(GNUInstallDirs)

set(HORUS_PYTHON "/usr/bin/python3" CACHE FILEPATH "Python interpreter with python3-jinja2")

# The generator's path is remembered globally so that horus_generate() works in every directory,
# not only in the one that ran find_package(horus).
if(NOT HORUS_GEN_EXECUTABLE)
  message(FATAL_ERROR "HorusGenerate.cmake: set HORUS_GEN_EXECUTABLE before including it "
                      "(user projects get both from find_package(horus CONFIG))")
endif()
set_property(GLOBAL PROPERTY HORUS_GEN_EXECUTABLE "${HORUS_GEN_EXECUTABLE}")

if(NOT DEFINED HORUS_PYTHON_INSTALL_DIR)
  execute_process(
    COMMAND "${HORUS_PYTHON}" -c
            "import sys; print(f'lib/python{sys.version_info[0]}.{sys.version_info[1]}/dist-packages')"
    OUTPUT_VARIABLE _horus_python_dir
    OUTPUT_STRIP_TRAILING_WHITESPACE
    RESULT_VARIABLE _horus_python_rc)
  if(NOT _horus_python_rc EQUAL 0)
    set(_horus_python_dir "lib/python3/dist-packages")
  endif()
  set(HORUS_PYTHON_INSTALL_DIR "${_horus_python_dir}" CACHE STRING
      "Where horus_generate() installs Python packages, relative to the install prefix")
endif()

option(HORUS_GENERATE_INSTALL "horus_generate() installs the generated code by default" ON)

# Policies recorded with the function below, whatever the calling project asks for: CMP0116 makes
# the Ninja generator rewrite the generator's depfile paths relative to the build tree.
cmake_policy(PUSH)
cmake_policy(VERSION 3.20...3.25)

# Fails configuration once, with a clear message, when the interpreter cannot run horus-gen.
function(_horus_check_python)
  get_property(checked GLOBAL PROPERTY _HORUS_PYTHON_CHECKED)
  if(checked)
    return()
  endif()
  execute_process(COMMAND "${HORUS_PYTHON}" -c "import jinja2"
                  RESULT_VARIABLE rc OUTPUT_QUIET ERROR_QUIET)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR
      "horus_generate: '${HORUS_PYTHON}' cannot import jinja2, which horus-gen needs.\n"
      "Install it with: sudo apt-get install python3-jinja2 "
      "(or set HORUS_PYTHON to an interpreter that has it)")
  endif()
  set_property(GLOBAL PROPERTY _HORUS_PYTHON_CHECKED TRUE)
endfunction()

function(horus_generate)
  cmake_parse_arguments(PARSE_ARGV 0 ARG "INSTALL;NO_INSTALL" "TARGET;PACKAGE;EXPORT"
                        "FILES;INCLUDE_DIRS;LANGUAGES;DEPENDS")
  set(where "horus_generate(${ARG_TARGET})")
  if(ARG_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "${where}: unknown arguments: ${ARG_UNPARSED_ARGUMENTS}")
  endif()
  if(NOT ARG_TARGET)
    message(FATAL_ERROR "horus_generate: TARGET <name> is required")
  endif()
  if(TARGET "${ARG_TARGET}")
    message(FATAL_ERROR "${where}: a target named '${ARG_TARGET}' already exists")
  endif()
  if(NOT ARG_FILES)
    message(FATAL_ERROR "${where}: FILES <schema files...> is required")
  endif()
  if(ARG_INSTALL AND ARG_NO_INSTALL)
    message(FATAL_ERROR "${where}: INSTALL and NO_INSTALL exclude each other")
  endif()
  if(ARG_EXPORT AND ARG_NO_INSTALL)
    message(FATAL_ERROR "${where}: EXPORT names an export set of the installation; "
                        "it cannot go with NO_INSTALL")
  endif()
  if(NOT ARG_LANGUAGES)
    set(ARG_LANGUAGES cpp)
  endif()
  foreach(lang IN LISTS ARG_LANGUAGES)
    if(NOT lang MATCHES "^(cpp|python|jsonschema|idl)$")
      message(FATAL_ERROR "${where}: unknown language '${lang}' (expected cpp, python, jsonschema or idl)")
    endif()
  endforeach()
  list(REMOVE_DUPLICATES ARG_LANGUAGES)

  set(generator "${HORUS_GEN_EXECUTABLE}")
  if(NOT generator)
    get_property(generator GLOBAL PROPERTY HORUS_GEN_EXECUTABLE)
  endif()
  if(NOT EXISTS "${generator}")
    message(FATAL_ERROR "${where}: the generator '${generator}' does not exist")
  endif()
  _horus_check_python()

  # Schema files, and the folders that imports and qualified names are resolved in (in order of
  # precedence; see HORUS_SCHEMA_DIRS above).
  set(files "")
  set(own_dirs "")
  set(has_nodes FALSE)
  string(REPLACE "." "/" package_path "${ARG_PACKAGE}")
  foreach(file IN LISTS ARG_FILES)
    get_filename_component(path "${file}" ABSOLUTE BASE_DIR "${CMAKE_CURRENT_SOURCE_DIR}")
    if(NOT EXISTS "${path}" OR IS_DIRECTORY "${path}")
      set(hint "")
      if(file MATCHES "^[A-Z_]+$")
        set(hint "; is '${file}' a misspelled keyword?")
      endif()
      message(FATAL_ERROR "${where}: schema file '${file}' not found (looked for ${path})${hint}")
    endif()
    list(APPEND files "${path}")
    if(path MATCHES "\\.hnode$")
      set(has_nodes TRUE)
    endif()
    get_filename_component(dir "${path}" DIRECTORY)
    list(APPEND own_dirs "${dir}")
    if(package_path AND dir MATCHES "^(.+)/${package_path}$")
      list(APPEND own_dirs "${CMAKE_MATCH_1}")
    endif()
  endforeach()
  foreach(dir IN LISTS ARG_INCLUDE_DIRS)
    get_filename_component(path "${dir}" ABSOLUTE BASE_DIR "${CMAKE_CURRENT_SOURCE_DIR}")
    if(NOT IS_DIRECTORY "${path}")
      message(FATAL_ERROR "${where}: include directory '${dir}' not found (looked for ${path})")
    endif()
    list(APPEND own_dirs "${path}")
  endforeach()
  list(REMOVE_DUPLICATES files)
  set(search_dirs ${own_dirs})
  foreach(dep IN LISTS ARG_DEPENDS)
    if(NOT TARGET "${dep}")
      message(FATAL_ERROR "${where}: DEPENDS '${dep}' is not a target (define it first)")
    endif()
    get_target_property(dep_dirs "${dep}" HORUS_SCHEMA_DIRS)
    if(NOT dep_dirs)
      message(FATAL_ERROR "${where}: DEPENDS '${dep}' was not made by horus_generate()")
    endif()
    list(APPEND search_dirs ${dep_dirs})
  endforeach()
  list(REMOVE_DUPLICATES search_dirs)

  set(out "${CMAKE_CURRENT_BINARY_DIR}/horus_gen/${ARG_TARGET}")
  set(stamp "${CMAKE_CURRENT_BINARY_DIR}/horus_gen/${ARG_TARGET}.stamp")
  set(depfile "${CMAKE_CURRENT_BINARY_DIR}/horus_gen/${ARG_TARGET}.d")
  list(JOIN ARG_LANGUAGES "," lang_list)
  set(options --lang "${lang_list}" --out "${out}")
  foreach(dir IN LISTS search_dirs)
    list(APPEND options -I "${dir}")
  endforeach()
  if(ARG_PACKAGE)
    list(APPEND options --package "${ARG_PACKAGE}")
  endif()

  # Ninja must know every generated file as an output of the generation step: only then does it
  # re-check (restat) them after the step ran and rebuild exactly the objects whose headers
  # changed. The list is taken at configure time; editing a schema re-runs configuration so that
  # added or renamed types are listed.
  execute_process(
    COMMAND "${HORUS_PYTHON}" "${generator}" list-outputs ${options} ${files}
    RESULT_VARIABLE rc
    OUTPUT_VARIABLE listed
    ERROR_VARIABLE errors)
  set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${files})
  if(NOT rc EQUAL 0)
    # Printed as is, so that editors still find the `path:line:col: error:` lines.
    message(NOTICE "${errors}")
    message(FATAL_ERROR "${where}: horus-gen rejected the schemas (errors above)")
  endif()
  string(REGEX REPLACE "\n+$" "" listed "${listed}")
  string(REPLACE "\n" ";" outputs "${listed}")
  if(NOT outputs)
    message(FATAL_ERROR "${where}: horus-gen lists no output for ${ARG_FILES}")
  endif()

  # The stamp is the step's one declared output: it is touched on every successful run, while the
  # generator rewrites only the files whose content changed, so a comment-only edit regenerates
  # and then recompiles nothing. The depfile names everything the generator read (imported
  # schemas, mixins, templates, its own sources), so a change to any of them, and nothing else,
  # re-runs it.
  list(LENGTH files file_count)
  add_custom_command(
    OUTPUT "${stamp}"
    BYPRODUCTS ${outputs}
    COMMAND "${HORUS_PYTHON}" "${generator}" generate ${options}
            --depfile "${depfile}" --stamp "${stamp}" ${files}
    DEPENDS ${files} "${generator}"
    DEPFILE "${depfile}"
    COMMENT "horus-gen: generating ${ARG_TARGET} from ${file_count} schema file(s)"
    VERBATIM)
  # Part of `all`: a Python-only library has no C++ consumer to pull it in, and installation
  # needs the files.
  add_custom_target(${ARG_TARGET}_generate ALL DEPENDS "${stamp}")

  # C++: a static library of the generated source (one per package: log_summary() and the
  # layout checks, compiled once here instead of in every file that includes the headers),
  # position-independent so that it can go into shared libraries and Python extensions too.
  # Python only: an INTERFACE target that carries the properties below.
  if("cpp" IN_LIST ARG_LANGUAGES)
    set(sources ${outputs})
    list(FILTER sources INCLUDE REGEX "\\.cpp$")
    add_library(${ARG_TARGET} STATIC ${sources})
    set_target_properties(${ARG_TARGET} PROPERTIES POSITION_INDEPENDENT_CODE ON)
    # Inside horus's own build, the generated code meets the project's warning flags (CI: -Werror).
    if(HORUS_WARNINGS)
      target_compile_options(${ARG_TARGET} PRIVATE ${HORUS_WARNINGS})
    endif()
    target_link_libraries(${ARG_TARGET} PUBLIC horus::headers ${ARG_DEPENDS})
    if(has_nodes)
      target_link_libraries(${ARG_TARGET} PUBLIC horus::runtime)
    endif()
    target_include_directories(${ARG_TARGET} PUBLIC
      "$<BUILD_INTERFACE:${out}/cpp>"
      "$<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>")
    set_target_properties(${ARG_TARGET} PROPERTIES HORUS_CPP_DIR "${out}/cpp")
  else()
    add_library(${ARG_TARGET} INTERFACE)
    target_link_libraries(${ARG_TARGET} INTERFACE horus::headers ${ARG_DEPENDS})
  endif()
  add_dependencies(${ARG_TARGET} ${ARG_TARGET}_generate)
  set_target_properties(${ARG_TARGET} PROPERTIES HORUS_SCHEMA_DIRS "${search_dirs}")
  if("python" IN_LIST ARG_LANGUAGES)
    set_target_properties(${ARG_TARGET} PROPERTIES HORUS_PYTHON_DIR "${out}/python")
    set(${ARG_TARGET}_PYTHON_DIR "${out}/python" PARENT_SCOPE)
  endif()
  if("jsonschema" IN_LIST ARG_LANGUAGES)
    set_target_properties(${ARG_TARGET} PROPERTIES HORUS_JSONSCHEMA_DIR "${out}/jsonschema")
  endif()
  if("idl" IN_LIST ARG_LANGUAGES)
    set_target_properties(${ARG_TARGET} PROPERTIES HORUS_IDL_DIR "${out}/idl")
    set(${ARG_TARGET}_IDL_DIR "${out}/idl" PARENT_SCOPE)
  endif()

  set(install ${HORUS_GENERATE_INSTALL})
  if(ARG_INSTALL)
    set(install ON)
  elseif(ARG_NO_INSTALL)
    set(install OFF)
  endif()
  if(install)
    # The library (an archive, or for Python only the target itself when it is exported).
    if(ARG_EXPORT)
      install(TARGETS ${ARG_TARGET} EXPORT ${ARG_EXPORT}
              ARCHIVE DESTINATION "${CMAKE_INSTALL_LIBDIR}")
    elseif("cpp" IN_LIST ARG_LANGUAGES)
      install(TARGETS ${ARG_TARGET} ARCHIVE DESTINATION "${CMAKE_INSTALL_LIBDIR}")
    endif()
    # File by file from the listed outputs, so a stale file left in the build folder by a removed
    # type is never installed; the generated sources are compiled into the archive, not installed.
    foreach(output IN LISTS outputs)
      file(RELATIVE_PATH relative "${out}" "${output}")
      get_filename_component(subdir "${relative}" DIRECTORY)
      if(output MATCHES "\\.cpp$")
        continue()
      elseif(subdir MATCHES "^cpp(/|$)")
        string(REGEX REPLACE "^cpp/?" "" subdir "${subdir}")
        install(FILES "${output}" DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}/${subdir}")
      elseif(subdir MATCHES "^python(/|$)")
        string(REGEX REPLACE "^python/?" "" subdir "${subdir}")
        install(FILES "${output}" DESTINATION "${HORUS_PYTHON_INSTALL_DIR}/${subdir}")
      elseif(subdir MATCHES "^(jsonschema|idl)(/|$)")
        install(FILES "${output}" DESTINATION "${CMAKE_INSTALL_DATADIR}/horus/${subdir}")
      endif()
    endforeach()
  endif()
endfunction()

cmake_policy(POP)
