# Helpers shared by every CMakeLists.txt of the project.

# mav_add_library(<name> SOURCES ... [PUBLIC_DEPS ...] [PRIVATE_DEPS ...])
# Creates the static library mav_<name> with the alias mav::<name>; public headers live in
# libs/<name>/include/mav/<name>/.
function(mav_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(mav_${name} STATIC ${ARG_SOURCES})
  add_library(mav::${name} ALIAS mav_${name})
  target_include_directories(mav_${name} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include)
  target_link_libraries(mav_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
endfunction()

# mav_add_test(<name> SOURCES ... [LIBS ...] [LABELS ...] [TIMEOUT s])
# One GoogleTest executable registered with CTest as one test (gtest handles the cases inside;
# per-case output is in the ctest log). Tests run from the build directory;
# tests/common/build_paths.h tells them where the trees are (bin/, tests/data/). Labels: unit,
# contract (both also run under the sanitizers), integration, load; add slow to a test that takes
# over ~40 s in the sanitizer pass (docs/quality.md, "CI time").
# SHARDS suffix=filter ...: instead of one ctest entry, one per shard (<name>_<suffix>, running
# the gtest cases --gtest_filter=filter), each under the per-test budget of docs/quality.md.
function(mav_add_test name)
  cmake_parse_arguments(ARG "" "TIMEOUT" "SOURCES;LIBS;LABELS;SHARDS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} mav::build_paths GTest::gtest GTest::gmock
                                        GTest::gtest_main Threads::Threads)
  # Test helpers shared across folders are included as "tests/common/<file>.h".
  target_include_directories(${name} PRIVATE ${CMAKE_SOURCE_DIR})
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/bin/tests)
  set(tests ${name})
  if(ARG_SHARDS)
    set(tests)
    foreach(shard ${ARG_SHARDS})
      string(REPLACE "=" ";" parts "${shard}")
      list(GET parts 0 suffix)
      list(GET parts 1 filter)
      add_test(NAME ${name}_${suffix} COMMAND ${name} --gtest_filter=${filter}
               WORKING_DIRECTORY ${CMAKE_BINARY_DIR})
      list(APPEND tests ${name}_${suffix})
    endforeach()
  else()
    add_test(NAME ${name} COMMAND ${name} WORKING_DIRECTORY ${CMAKE_BINARY_DIR})
  endif()
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  if(MAV_SANITIZE)
    # ASan + UBSan run the tests 2-5x slower (cmake/MavSanitize.cmake).
    math(EXPR ARG_TIMEOUT "${ARG_TIMEOUT} * 5")
  endif()
  set_tests_properties(${tests} PROPERTIES TIMEOUT ${ARG_TIMEOUT} LABELS "${ARG_LABELS}")
  # LABELS slow: over ~40 s in the sanitizer pass (docs/quality.md, "CI time"). ctest starts these
  # first, so on two cores the long tests overlap rather than one running alone at the end: a
  # fresh clone has no timing history (Testing/Temporary/CTestCostData.txt) to order them by.
  if("slow" IN_LIST ARG_LABELS)
    set_tests_properties(${tests} PROPERTIES COST 1000)
  endif()
  # LABELS load: the test saturates both cores on purpose (mav-load against a server), which
  # starves whatever runs beside it; a real-time flight beside one missed its 20 ms deadlines and
  # crashed on take-off. It runs alone.
  if("load" IN_LIST ARG_LABELS)
    set_tests_properties(${tests} PROPERTIES RUN_SERIAL TRUE)
  endif()
endfunction()

# mav_add_benchmark(<name> SOURCES ... [LIBS ...])
function(mav_add_benchmark name)
  cmake_parse_arguments(ARG "" "" "SOURCES;LIBS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} mav::build_paths benchmark::benchmark
                                        Threads::Threads)
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/bin/benchmarks)
endfunction()
