# ROS 2 from the pip wheels (no system ROS 2): finding it and repairing the wheels' defects.
# Used when ContextROS itself is built (cpp/CMakeLists.txt, the wheel's build, colcon over a
# venv) and, installed beside contextrosConfig.cmake, when a robot's project finds ContextROS.
# With a system ROS 2 none of this is used: plain find_package() calls do the job.
#
# Input: CONTEXTROS_ROS_WHEELS, the prefix the wheels installed into (a venv, or pip's build
# environment); CONTEXTROS_PYTHON, the interpreter that has them (default
# <prefix>/bin/python). Output: rcl, rcutils, rmw and rosidl_typesupport_cpp found and
# repaired; contextros_repair_wheel_targets() for packages found later;
# contextros_ros_wheels_link_interface(<target> <INTERFACE|PRIVATE>) for the link options a
# program that runs rcl needs.
#
# The pitfalls worked around (docs/cpp.md, each seen here):
#  1. The typesupport lookup reads the ament index from the *environment* at configure time.
#  2. The wheels' rmw_implementation is built for Fast DDS only.
#  3. `<pkg>__rosidl_generator_py` targets carry the wheel builder's include directories.
#  4. Fast DDS's exported targets name the builder's tinyxml2 and the system OpenSSL;
#     tracetools' (rclcpp's dependency) the system lttng-ust (the wheel bundles its own).
#  5. The wheels' libraries find their bundled dependencies (site-packages/ros_*.libs)
#     through an RPATH that is wrong once installed under <venv>/lib.
#  6. librcl NEEDs generator_py helpers whose relocations refer to libpython's symbols.
#  7. The exported link interfaces list about 60 libraries.
include_guard(GLOBAL)

# contextros_detect_ros_wheels(<out>): the first prefix of CMAKE_PREFIX_PATH or
# AMENT_PREFIX_PATH that holds the ROS 2 wheels (their bootstrapper package), else "".
function(contextros_detect_ros_wheels out)
  set(_prefixes ${CMAKE_PREFIX_PATH})
  if(DEFINED ENV{AMENT_PREFIX_PATH})
    string(REPLACE ":" ";" _ament "$ENV{AMENT_PREFIX_PATH}")
    list(APPEND _prefixes ${_ament})
  endif()
  foreach(_prefix IN LISTS _prefixes)
    file(GLOB _bootstrapper "${_prefix}/lib/python3*/site-packages/ros_wheels_bootstrapper")
    if(_bootstrapper)
      set(${out} "${_prefix}" PARENT_SCOPE)
      return()
    endif()
  endforeach()
  set(${out} "" PARENT_SCOPE)
endfunction()

# 3 and 4: repair the imported targets of this directory (call again after more
# find_package calls; it is also deferred to the end of the directory's configure).
# CONTEXTROS_GENERATOR_PY_INCLUDES: what replaces the builder's include directories of the
# generator_py targets; empty (C++ code never includes Python's headers) unless a project
# builds Python bindings itself (cpp/ros/rclcpp/wheels_project_include.cmake).
function(contextros_repair_wheel_targets)
  get_property(_targets DIRECTORY "${CMAKE_CURRENT_SOURCE_DIR}" PROPERTY IMPORTED_TARGETS)
  foreach(_target IN LISTS _targets)
    if(_target MATCHES "__rosidl_generator_py$")
      set_property(TARGET ${_target}
        PROPERTY INTERFACE_INCLUDE_DIRECTORIES "${CONTEXTROS_GENERATOR_PY_INCLUDES}")
    endif()
    get_property(_links TARGET ${_target} PROPERTY INTERFACE_LINK_LIBRARIES)
    if(_links)
      list(FILTER _links EXCLUDE REGEX "(^|/)libtinyxml2\\.so|tinyxml2::|OpenSSL::|^lttng-ust$")
      set_property(TARGET ${_target} PROPERTY INTERFACE_LINK_LIBRARIES "${_links}")
    endif()
  endforeach()
endfunction()

# 5, 6 and 7: what a program (or shared library) that runs rcl needs at link time, as
# <scope> (INTERFACE: for whoever links <target>) link options and libraries of <target>.
function(contextros_ros_wheels_link_interface target scope)
  set(_dirs "${CONTEXTROS_WHEELS_PREFIX}/lib" ${CONTEXTROS_WHEEL_LIBRARY_DIRS})
  get_filename_component(_libpython_dir "${CONTEXTROS_LIBPYTHON}" DIRECTORY)
  list(APPEND _dirs "${_libpython_dir}")
  set(_options "LINKER:--as-needed" "LINKER:--disable-new-dtags")
  foreach(_dir IN LISTS _dirs)
    list(APPEND _options "LINKER:-rpath-link,${_dir}")
    if(scope STREQUAL "INTERFACE")
      # An RPATH (not RUNPATH: --disable-new-dtags) also serves the wheels' own libraries.
      list(APPEND _options "LINKER:-rpath,${_dir}")
    endif()
  endforeach()
  if(NOT scope STREQUAL "INTERFACE")
    # <target> itself: these paths while in the build tree, its INSTALL_RPATH once installed.
    set_property(TARGET ${target} APPEND PROPERTY BUILD_RPATH ${_dirs})
  endif()
  # libpython is NEEDED by no object of ours, only by the wheels' helpers: keep it anyway.
  set(_libraries "-Wl,--push-state,--no-as-needed" "${CONTEXTROS_LIBPYTHON}" "-Wl,--pop-state")
  get_target_property(_imported ${target} IMPORTED)
  if(scope STREQUAL "INTERFACE" AND NOT _imported)
    # These paths are this build's: an installed target gets the consumer's own
    # (contextrosConfig.cmake calls this on the imported target).
    list(TRANSFORM _options PREPEND "$<BUILD_INTERFACE:")
    list(TRANSFORM _options APPEND ">")
    list(TRANSFORM _libraries PREPEND "$<BUILD_INTERFACE:")
    list(TRANSFORM _libraries APPEND ">")
  endif()
  target_link_options(${target} ${scope} ${_options})
  target_link_libraries(${target} ${scope} ${_libraries})
endfunction()

# contextros_find_ros_wheels(): finds rcl, rcutils, rmw and rosidl_typesupport_cpp in the
# wheels of CONTEXTROS_ROS_WHEELS and repairs them (a macro: what it finds and sets is the
# caller's).
macro(contextros_find_ros_wheels)
  if(NOT IS_ABSOLUTE "${CONTEXTROS_ROS_WHEELS}" OR NOT EXISTS "${CONTEXTROS_ROS_WHEELS}/share/rcl")
    message(FATAL_ERROR
      "CONTEXTROS_ROS_WHEELS='${CONTEXTROS_ROS_WHEELS}' does not hold the ROS 2 wheels "
      "(no share/rcl there; `pip install 'contextros[ros]'` into that venv installs them)")
  endif()
  set(_wheels "${CONTEXTROS_ROS_WHEELS}")
  if(NOT CONTEXTROS_PYTHON)
    if(EXISTS "${_wheels}/bin/python")
      set(CONTEXTROS_PYTHON "${_wheels}/bin/python")
    elseif(Python3_EXECUTABLE)
      set(CONTEXTROS_PYTHON "${Python3_EXECUTABLE}")
    else()
      message(FATAL_ERROR "contextros: no Python interpreter for the wheels in ${_wheels} "
        "(set CONTEXTROS_PYTHON)")
    endif()
  endif()

  # 1 and 2: set here rather than by the caller, so that ninja's automatic re-configure (which
  # does not see the caller's environment) behaves like the first configure.
  # (Kept: prefixes a colcon workspace put there, e.g. contextros_interfaces's install.)
  if("$ENV{AMENT_PREFIX_PATH}" STREQUAL "")
    set(ENV{AMENT_PREFIX_PATH} "${_wheels}")
  elseif(NOT ":$ENV{AMENT_PREFIX_PATH}:" MATCHES ":${_wheels}:")
    set(ENV{AMENT_PREFIX_PATH} "$ENV{AMENT_PREFIX_PATH}:${_wheels}")
  endif()
  unset(ENV{RMW_IMPLEMENTATION})
  list(APPEND CMAKE_PREFIX_PATH "${_wheels}")
  set(Python3_EXECUTABLE "${CONTEXTROS_PYTHON}" CACHE FILEPATH "the interpreter of the ROS wheels")

  # Where the interpreter's libpython is and where the wheels bundle their own libraries.
  execute_process(
    COMMAND "${CONTEXTROS_PYTHON}" -c [=[
import glob, os, sys, sysconfig
libdir = sysconfig.get_config_var("LIBDIR")
library = os.path.join(libdir, sysconfig.get_config_var("LDLIBRARY"))
bundled = sorted(glob.glob(os.path.join(sys.argv[1], "lib", "python3*", "site-packages", "ros_*.libs")))
print(library + "|" + ";".join(bundled), end="")
  ]=] "${_wheels}"
    OUTPUT_VARIABLE _probe
    RESULT_VARIABLE _probe_result)
  if(NOT _probe_result EQUAL 0)
    message(FATAL_ERROR "contextros: cannot ask ${CONTEXTROS_PYTHON} about its libraries")
  endif()
  string(REPLACE "|" ";" _probe "${_probe}")
  list(POP_FRONT _probe _libpython)
  # Cache (internal) variables: the functions below are also called from other directories.
  set(CONTEXTROS_LIBPYTHON "${_libpython}" CACHE INTERNAL "the wheels' interpreter's libpython")
  set(CONTEXTROS_WHEEL_LIBRARY_DIRS "${_probe}" CACHE INTERNAL "the wheels' bundled libraries")
  set(CONTEXTROS_WHEELS_PREFIX "${_wheels}" CACHE INTERNAL "the prefix of the ROS wheels")
  if(NOT EXISTS "${CONTEXTROS_LIBPYTHON}")
    message(FATAL_ERROR "contextros: ${CONTEXTROS_PYTHON} has no shared libpython "
      "(${CONTEXTROS_LIBPYTHON}); rcl from the wheels needs it (pitfall 6 in docs/cpp.md)")
  endif()

  find_package(rcutils REQUIRED)
  find_package(rmw REQUIRED)
  find_package(rcl REQUIRED)
  find_package(rosidl_typesupport_cpp REQUIRED)
  contextros_repair_wheel_targets()
  cmake_language(DEFER DIRECTORY "${CMAKE_CURRENT_SOURCE_DIR}" CALL contextros_repair_wheel_targets)
endmacro()

# Removed names keep a stub for one release that says what replaces them
# (tests/cli/test_public_surface.py keeps the list).
# contextros_use_ros_wheels(<target>): removed in 0.1.0, goes in 0.2.0. Linking
# contextros::ros now brings what it added; a program that runs rcl without contextros::ros
# calls contextros_ros_wheels_link_interface(<target> PRIVATE), as this stub does.
function(contextros_use_ros_wheels target)
  message(DEPRECATION
    "contextros_use_ros_wheels() was removed in ContextROS 0.1.0 and goes in 0.2.0: "
    "target_link_libraries(${target} PRIVATE contextros::ros) brings what it added; a "
    "program that runs rcl without contextros::ros calls "
    "contextros_ros_wheels_link_interface(${target} PRIVATE) (docs/cpp.md)")
  if(CONTEXTROS_ROS_WHEELS AND TARGET ${target})
    contextros_ros_wheels_link_interface(${target} PRIVATE)
  endif()
endfunction()
