# horus_check(): run horus-check (tools/check) on a target's sources as a build step.
#
#   horus_check(TARGET my_robot                   # an executable or library target
#               [LAYOUT_TARGETS aarch64-linux-gnu armv7-linux-gnueabihf ...]  # --target each
#               [ALL_NODES])                      # lint tick() of every node (--all-nodes)
#
# After the target is built, horus-check reads ${CMAKE_BINARY_DIR}/compile_commands.json (so
# CMAKE_EXPORT_COMPILE_COMMANDS must be ON) for the target's C++ sources and for the generated
# sources of the horus_generate() libraries it links (their _nodes.cpp holds the declared topic
# lists of .hnode nodes). A finding fails the build, like a compiler error would; the findings
# are printed compiler-style.
# HORUS_CHECK_EXECUTABLE names the tool: the build tree's horus-check in this project,
# find_package(horus CONFIG) sets the installed one.

function(horus_check)
  cmake_parse_arguments(ARG "ALL_NODES" "TARGET" "LAYOUT_TARGETS" ${ARGN})
  if(NOT ARG_TARGET OR ARG_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "horus_check(TARGET name [LAYOUT_TARGETS triple...] [ALL_NODES]): "
                        "unexpected arguments '${ARG_UNPARSED_ARGUMENTS}'")
  endif()
  if(NOT TARGET ${ARG_TARGET})
    message(FATAL_ERROR "horus_check(): '${ARG_TARGET}' is not a target")
  endif()
  if(NOT CMAKE_EXPORT_COMPILE_COMMANDS)
    message(FATAL_ERROR "horus_check(): set CMAKE_EXPORT_COMPILE_COMMANDS ON (horus-check reads "
                        "compile_commands.json)")
  endif()
  if(NOT HORUS_CHECK_EXECUTABLE)
    message(FATAL_ERROR "horus_check(): HORUS_CHECK_EXECUTABLE is not set (horus-check is built "
                        "only where Debian's libclang-cpp14-dev is installed)")
  endif()

  set(files)
  _horus_check_sources(${ARG_TARGET} files)
  get_target_property(libraries ${ARG_TARGET} LINK_LIBRARIES)
  foreach(library IN LISTS libraries)
    if(TARGET ${library})
      get_target_property(generated_dir ${library} HORUS_CPP_DIR)
      if(generated_dir)
        _horus_check_sources(${library} files)
      endif()
    endif()
  endforeach()
  if(NOT files)
    message(FATAL_ERROR "horus_check(): target '${ARG_TARGET}' has no C++ sources to check")
  endif()

  set(options)
  foreach(triple IN LISTS ARG_LAYOUT_TARGETS)
    list(APPEND options "--target=${triple}")
  endforeach()
  if(ARG_ALL_NODES)
    list(APPEND options --all-nodes)
  endif()
  add_custom_command(TARGET ${ARG_TARGET} POST_BUILD
    COMMAND ${HORUS_CHECK_EXECUTABLE} -p "${CMAKE_BINARY_DIR}" ${options} ${files}
    COMMENT "horus-check ${ARG_TARGET}"
    VERBATIM)
endfunction()

# Appends the absolute paths of `target`'s C++ sources to the list `out`.
function(_horus_check_sources target out)
  get_target_property(sources ${target} SOURCES)
  get_target_property(source_dir ${target} SOURCE_DIR)
  get_target_property(binary_dir ${target} BINARY_DIR)
  set(found ${${out}})
  foreach(source IN LISTS sources)
    if(source MATCHES "^\\$<" OR NOT source MATCHES "\\.(cpp|cc|cxx|c\\+\\+)$")
      continue()
    endif()
    if(NOT IS_ABSOLUTE "${source}")
      if(EXISTS "${source_dir}/${source}")
        set(source "${source_dir}/${source}")
      else()
        set(source "${binary_dir}/${source}")
      endif()
    endif()
    list(APPEND found "${source}")
  endforeach()
  set(${out} ${found} PARENT_SCOPE)
endfunction()
