# contextros_add_layers(<target> <file.cpp.layers>...)
#
# Compiles C++ layer files with `contextros compile` at build time (again whenever a layer
# file changes) and adds the generated sources to <target>, which is linked to
# contextros::core. For `robot.cpp.layers` the generated files are robot.layers.cpp and
# robot.layers.hpp in <build dir>/contextros_layers/; the include path gets that directory
# (other sources `#include "robot.layers.hpp"`) and the layer file's own directory (the
# header part's includes). The layer file is named by its absolute path, so the generated
# `#line` directives name it absolutely too: compiler messages open from the build directory,
# where ninja and make run the compiler. A relative path is relative to
# CMAKE_CURRENT_SOURCE_DIR; a file that is not there stops the configure
# ("contextros_add_layers(<target>): no layer file <path>").
#
# It links <target> with the keyword signature (`target_link_libraries(<target> PRIVATE
# contextros::core)`): the target's own target_link_libraries calls must use keywords too
# (PRIVATE, PUBLIC or INTERFACE); CMake refuses to mix the two signatures on one target.
#
# CONTEXTROS_COMPILER: the command that runs the compiler (a list; default: the `contextros`
# program of the active virtual environment, of CMAKE_PREFIX_PATH or of PATH).

if(NOT CONTEXTROS_COMPILER)
  set(_contextros_hints)
  if(DEFINED ENV{VIRTUAL_ENV})
    list(APPEND _contextros_hints "$ENV{VIRTUAL_ENV}/bin")
  endif()
  foreach(_prefix IN LISTS CMAKE_PREFIX_PATH)
    list(APPEND _contextros_hints "${_prefix}/bin")
  endforeach()
  find_program(_contextros_program contextros HINTS ${_contextros_hints})
  if(_contextros_program)
    set(CONTEXTROS_COMPILER "${_contextros_program}" CACHE STRING
        "Command running the ContextROS layer compiler")
  endif()
endif()

function(contextros_add_layers target)
  if(NOT ARGN)
    message(FATAL_ERROR "contextros_add_layers(${target}): no layer files given")
  endif()
  if(NOT CONTEXTROS_COMPILER)
    message(FATAL_ERROR "contextros_add_layers: the `contextros` compiler was not found; "
                        "set CONTEXTROS_COMPILER (e.g. to <venv>/bin/contextros)")
  endif()
  # In this repository, the compiler's own sources: a change of the compiler regenerates too.
  set(compiler_sources)
  set(language_dir "${CMAKE_CURRENT_FUNCTION_LIST_DIR}/../../src/contextros/language")
  if(EXISTS "${language_dir}")
    file(GLOB_RECURSE compiler_sources CONFIGURE_DEPENDS "${language_dir}/*.py")
  endif()
  set(output_dir "${CMAKE_CURRENT_BINARY_DIR}/contextros_layers")
  file(MAKE_DIRECTORY "${output_dir}")
  foreach(file IN LISTS ARGN)
    get_filename_component(source "${file}" ABSOLUTE BASE_DIR "${CMAKE_CURRENT_SOURCE_DIR}")
    if(NOT EXISTS "${source}" OR IS_DIRECTORY "${source}")
      message(FATAL_ERROR "contextros_add_layers(${target}): no layer file ${file} "
                          "(looked for ${source})")
    endif()
    get_filename_component(source_dir "${source}" DIRECTORY)
    get_filename_component(name "${source}" NAME)
    string(REGEX REPLACE "(\\.cpp)?\\.layers$" "" stem "${name}")
    set(out_cpp "${output_dir}/${stem}.layers.cpp")
    set(out_hpp "${output_dir}/${stem}.layers.hpp")
    add_custom_command(
      OUTPUT "${out_cpp}" "${out_hpp}"
      COMMAND ${CONTEXTROS_COMPILER} compile --language cpp "${source}" -o "${out_cpp}"
      DEPENDS "${source}" ${compiler_sources}
      COMMENT "contextros compile ${name}"
      VERBATIM)
    target_sources(${target} PRIVATE "${out_cpp}" "${out_hpp}")
    target_include_directories(${target} PRIVATE "${output_dir}" "${source_dir}")
  endforeach()
  target_link_libraries(${target} PRIVATE contextros::core)
endfunction()
