# Finding ROS 2 in a Python venv that holds the pip wheels (no system ROS 2), for
# cpp/CMakeLists.txt. Everything specific to the wheels is here; with a system ROS 2
# (colcon, ament_cmake) this file is not included and plain find_package() calls do the job.
#
# Input: CONTEXTROS_ROS_WHEELS, the venv (absolute). Output: the imported targets of rcl,
# rcutils, rmw and contextros_interfaces as find_package() gives them, repaired, and
# contextros_use_ros_wheels(<target>) to call on every executable that runs rcl.
#
# The pitfalls worked around (../shared/notes/cpp-on-wheels.md, each seen here):
#  1. The typesupport lookup reads the ament index from the *environment* at configure time.
#  2. The wheels' rmw_implementation is built for Fast DDS only.
#  3. `<pkg>__rosidl_generator_py` targets carry the wheel builder's include directories.
#  4. Fast DDS's exported targets name the builder's tinyxml2 and the system OpenSSL.
#  5. The wheels' libraries find their bundled dependencies (site-packages/ros_*.libs)
#     through an RPATH that is wrong once installed under <venv>/lib.
#  6. librcl NEEDs generator_py helpers whose relocations refer to libpython's symbols.
#  7. The exported link interfaces list about 60 libraries.
include_guard(GLOBAL)

if(NOT IS_ABSOLUTE "${CONTEXTROS_ROS_WHEELS}" OR NOT EXISTS "${CONTEXTROS_ROS_WHEELS}/bin/python")
  message(FATAL_ERROR
    "CONTEXTROS_ROS_WHEELS='${CONTEXTROS_ROS_WHEELS}' is not a venv with the ROS 2 wheels "
    "(expected <venv>/bin/python; `make venv` creates one)")
endif()
set(_wheels "${CONTEXTROS_ROS_WHEELS}")

# 1 and 2: set here rather than by the caller, so that ninja's automatic re-configure (which
# does not see the Makefile's environment) behaves like the first configure.
set(ENV{AMENT_PREFIX_PATH} "${_wheels}")
unset(ENV{RMW_IMPLEMENTATION})
list(PREPEND CMAKE_PREFIX_PATH "${_wheels}")
set(Python3_EXECUTABLE "${_wheels}/bin/python" CACHE FILEPATH "the venv's interpreter" FORCE)

# The venv's interpreter tells where its libpython and the wheels' bundled libraries are.
execute_process(
  COMMAND "${_wheels}/bin/python" -c [=[
import glob, os, site, sysconfig
libdir = sysconfig.get_config_var("LIBDIR")
library = os.path.join(libdir, sysconfig.get_config_var("LDLIBRARY"))
bundled = sorted(d for p in site.getsitepackages() for d in glob.glob(os.path.join(p, "ros_*.libs")))
print(library + "|" + ";".join(bundled), end="")
]=]
  OUTPUT_VARIABLE _probe
  RESULT_VARIABLE _probe_result)
if(NOT _probe_result EQUAL 0)
  message(FATAL_ERROR "contextros: cannot ask ${_wheels}/bin/python about its libraries")
endif()
string(REPLACE "|" ";" _probe "${_probe}")
list(POP_FRONT _probe _libpython)
# Cache (internal) variables: contextros_use_ros_wheels() is also called from a robot's own
# project that added cpp/ with add_subdirectory (a parent scope).
set(CONTEXTROS_LIBPYTHON "${_libpython}" CACHE INTERNAL "the venv's libpython")
set(CONTEXTROS_WHEEL_LIBRARY_DIRS "${_probe}" CACHE INTERNAL "the wheels' bundled libraries")
if(NOT EXISTS "${CONTEXTROS_LIBPYTHON}")
  message(FATAL_ERROR "contextros: the venv's Python has no shared libpython (${CONTEXTROS_LIBPYTHON}); "
    "rcl from the wheels needs it (pitfall 6 in docs/cpp.md)")
endif()

find_package(rcutils REQUIRED)
find_package(rmw REQUIRED)
find_package(rcl REQUIRED)
find_package(rosidl_typesupport_cpp REQUIRED)
find_package(contextros_interfaces REQUIRED)
# The messages of the example nodes (examples/cleaner/cpp).
find_package(sensor_msgs REQUIRED)
find_package(geometry_msgs REQUIRED)

# 3 and 4: repair every imported target now that find_package has made them.
function(_contextros_repair_wheel_targets)
  get_property(_targets DIRECTORY "${CMAKE_CURRENT_SOURCE_DIR}" PROPERTY IMPORTED_TARGETS)
  foreach(_target IN LISTS _targets)
    if(_target MATCHES "__rosidl_generator_py$")
      # C++ code never includes Python's headers: drop the builder's paths.
      set_property(TARGET ${_target} PROPERTY INTERFACE_INCLUDE_DIRECTORIES "")
    endif()
    get_property(_links TARGET ${_target} PROPERTY INTERFACE_LINK_LIBRARIES)
    if(_links)
      list(FILTER _links EXCLUDE REGEX "(^|/)libtinyxml2\\.so|tinyxml2::|OpenSSL::")
      set_property(TARGET ${_target} PROPERTY INTERFACE_LINK_LIBRARIES "${_links}")
    endif()
  endforeach()
endfunction()
_contextros_repair_wheel_targets()

# 5, 6 and 7, for every executable (or shared library) that uses rcl.
function(contextros_use_ros_wheels target)
  set(_options "LINKER:--as-needed" "LINKER:--disable-new-dtags")
  foreach(_dir IN LISTS CONTEXTROS_WHEEL_LIBRARY_DIRS)
    list(APPEND _options "LINKER:-rpath-link,${_dir}")
  endforeach()
  get_filename_component(_libpython_dir "${CONTEXTROS_LIBPYTHON}" DIRECTORY)
  # An RPATH (not RUNPATH: --disable-new-dtags) also serves the wheels' own libraries.
  set_target_properties(${target} PROPERTIES
    BUILD_RPATH "${CONTEXTROS_ROS_WHEELS}/lib;${CONTEXTROS_WHEEL_LIBRARY_DIRS};${_libpython_dir}"
    INSTALL_RPATH "${CONTEXTROS_ROS_WHEELS}/lib;${CONTEXTROS_WHEEL_LIBRARY_DIRS};${_libpython_dir}")
  target_link_options(${target} PRIVATE ${_options})
  # libpython is NEEDED by no object of ours, only by the wheels' helpers: keep it anyway.
  target_link_libraries(${target} PRIVATE
    "-Wl,--push-state,--no-as-needed" "${CONTEXTROS_LIBPYTHON}" "-Wl,--pop-state")
endfunction()
