# Included by contextros_interfaces's CMakeLists.txt: works around a defect of the pip ROS 2 wheels.
# Their exported `<pkg>::<pkg>__rosidl_generator_py` targets carry include directories of the
# wheel builder's interpreter (/opt/python/cp3xx-.../include), which do not exist here, so
# generation fails with "includes non-existent path". At the end of configure (deferred, so
# every find_package has run) point them at this interpreter's Python and NumPy headers.
cmake_minimum_required(VERSION 3.21)

function(contextros_fix_generator_py_includes)
  execute_process(
    COMMAND "${Python3_EXECUTABLE}" -c
      "import sysconfig, numpy; print(sysconfig.get_paths()['include'] + ';' + numpy.get_include(), end='')"
    OUTPUT_VARIABLE _contextros_py_includes
    RESULT_VARIABLE _contextros_py_result)
  if(NOT _contextros_py_result EQUAL 0)
    message(FATAL_ERROR "contextros: cannot ask ${Python3_EXECUTABLE} for its include dirs")
  endif()
  get_property(_targets DIRECTORY "${CMAKE_SOURCE_DIR}" PROPERTY IMPORTED_TARGETS)
  foreach(_target IN LISTS _targets)
    if(_target MATCHES "__rosidl_generator_py$")
      set_property(TARGET ${_target} PROPERTY INTERFACE_INCLUDE_DIRECTORIES "${_contextros_py_includes}")
    endif()
  endforeach()
endfunction()

cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL contextros_fix_generator_py_includes)
