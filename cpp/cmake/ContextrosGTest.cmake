# GoogleTest for the C++ tests, as the target `contextros_gtest` (gtest + gtest_main):
# from find_package(GTest) when the machine has one, else built from the sources of the
# ros-gtest-vendor wheel (<prefix>/src/gtest_vendor, searched in CMAKE_PREFIX_PATH and the
# active virtual environment), or from CONTEXTROS_GTEST_SOURCE_DIR.
if(TARGET contextros_gtest)
  return()
endif()

set(_contextros_gtest_hints)
foreach(_prefix IN LISTS CMAKE_PREFIX_PATH)
  list(APPEND _contextros_gtest_hints "${_prefix}/src/gtest_vendor")
endforeach()
if(DEFINED ENV{VIRTUAL_ENV})
  list(APPEND _contextros_gtest_hints "$ENV{VIRTUAL_ENV}/src/gtest_vendor")
endif()
find_path(CONTEXTROS_GTEST_SOURCE_DIR NAMES src/gtest-all.cc include/gtest/gtest.h
  HINTS ${_contextros_gtest_hints} NO_DEFAULT_PATH
  DOC "GoogleTest sources (the ros-gtest-vendor wheel's <venv>/src/gtest_vendor)")

if(CONTEXTROS_GTEST_SOURCE_DIR)
  find_package(Threads REQUIRED)
  add_library(contextros_gtest STATIC
    ${CONTEXTROS_GTEST_SOURCE_DIR}/src/gtest-all.cc
    ${CONTEXTROS_GTEST_SOURCE_DIR}/src/gtest_main.cc)
  target_include_directories(contextros_gtest SYSTEM PUBLIC ${CONTEXTROS_GTEST_SOURCE_DIR}/include)
  target_include_directories(contextros_gtest PRIVATE ${CONTEXTROS_GTEST_SOURCE_DIR})
  target_link_libraries(contextros_gtest PUBLIC Threads::Threads)
else()
  find_package(GTest QUIET)
  if(TARGET GTest::gtest_main)
    add_library(contextros_gtest INTERFACE)
    target_link_libraries(contextros_gtest INTERFACE GTest::gtest GTest::gtest_main)
  endif()
endif()
