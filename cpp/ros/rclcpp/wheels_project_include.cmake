# Injected into each of rclcpp's dependency projects (-DCMAKE_PROJECT_INCLUDE=<this file>,
# build_prefix.sh) so that they build against the ROS 2 pip wheels unchanged: the defects
# cmake/ContextrosRosWheels.cmake repairs for ContextROS itself (docs/cpp.md), its imported
# targets' repair reused, its link settings applied to every target of a foreign project.
# Input: CONTEXTROS_ROS_WHEELS (the venv), Python3_EXECUTABLE (its interpreter).
cmake_minimum_required(VERSION 3.21)
include_guard(GLOBAL)
if(NOT IS_DIRECTORY "${CONTEXTROS_ROS_WHEELS}/share/rcl")
  message(FATAL_ERROR "pass -DCONTEXTROS_ROS_WHEELS=<a venv holding the ROS 2 wheels>")
endif()

# The typesupport lookup reads the ament index from the environment (also on ninja's own
# re-configure); the wheels' rmw_implementation knows Fast DDS only.
if(NOT ":$ENV{AMENT_PREFIX_PATH}:" MATCHES ":${CONTEXTROS_ROS_WHEELS}:")
  set(ENV{AMENT_PREFIX_PATH} "$ENV{AMENT_PREFIX_PATH}:${CONTEXTROS_ROS_WHEELS}")
endif()
unset(ENV{RMW_IMPLEMENTATION})

execute_process(
  COMMAND "${Python3_EXECUTABLE}" -c [=[
import glob, os, sys, sysconfig
import numpy
libpython = os.path.join(sysconfig.get_config_var("LIBDIR"), sysconfig.get_config_var("LDLIBRARY"))
includes = [sysconfig.get_paths()["include"], numpy.get_include()]
bundled = sorted(glob.glob(os.path.join(sys.argv[1], "lib", "python3*", "site-packages", "ros_*.libs")))
print(libpython + "|" + ";".join(includes) + "|" + ";".join(bundled), end="")
]=] "${CONTEXTROS_ROS_WHEELS}"
  OUTPUT_VARIABLE _probe RESULT_VARIABLE _probe_result)
if(NOT _probe_result EQUAL 0)
  message(FATAL_ERROR "cannot ask ${Python3_EXECUTABLE} about its libraries")
endif()
# "<libpython>|<include dirs>|<bundled library dirs>"
string(REGEX REPLACE "^([^|]*)\\|([^|]*)\\|(.*)$" "\\1" _libpython "${_probe}")
string(REGEX REPLACE "^([^|]*)\\|([^|]*)\\|(.*)$" "\\2" _python_includes "${_probe}")
string(REGEX REPLACE "^([^|]*)\\|([^|]*)\\|(.*)$" "\\3" _bundled "${_probe}")

# Link- and run-time search paths of every library and program: this prefix, every
# CMAKE_PREFIX_PATH entry, the venv, its bundled libraries and libpython's directory, as an
# RPATH (not a RUNPATH) so that the wheels' own libraries are served too. libpython on every
# link: librcl NEEDs generator_py helpers that refer to its symbols.
get_filename_component(_libpython_dir "${_libpython}" DIRECTORY)
set(_dirs "${CMAKE_INSTALL_PREFIX}/lib")
foreach(_prefix IN LISTS CMAKE_PREFIX_PATH)
  list(APPEND _dirs "${_prefix}/lib")
endforeach()
list(APPEND _dirs "${CONTEXTROS_ROS_WHEELS}/lib" ${_bundled} "${_libpython_dir}")
list(REMOVE_DUPLICATES _dirs)
set(_flags "-Wl,--disable-new-dtags")
foreach(_dir IN LISTS _dirs)
  string(APPEND _flags " -Wl,-rpath-link,${_dir}")
endforeach()
foreach(_kind IN ITEMS EXE SHARED MODULE)
  string(APPEND CMAKE_${_kind}_LINKER_FLAGS " ${_flags}")
endforeach()
string(APPEND CMAKE_CXX_STANDARD_LIBRARIES
  " -Wl,--push-state,--no-as-needed ${_libpython} -Wl,--pop-state")
set(CMAKE_BUILD_RPATH "${_dirs}")
set(CMAKE_INSTALL_RPATH "${_dirs}")

# The imported targets, once the project has found them all, repaired as ContextROS's own
# (these projects build Python bindings too: the generator_py targets get the real Python's
# include directories).
set(CONTEXTROS_GENERATOR_PY_INCLUDES "${_python_includes}")
include("${CMAKE_CURRENT_LIST_DIR}/../../cmake/ContextrosRosWheels.cmake")
cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL contextros_repair_wheel_targets)
