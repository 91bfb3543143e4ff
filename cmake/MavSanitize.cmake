# Sanitizer and fuzzing builds, each in its own build directory (see docs/quality.md):
#
#   CC=clang CXX=clang++ cmake -B build-asan -DMAV_SANITIZE=address,undefined ...
#                                                            (tools/ci-sanitizers.sh)
#   CC=clang CXX=clang++ cmake -B build-fuzz -DMAV_FUZZ=ON ... (tools/ci-fuzz-smoke.sh)
#
# MAV_SANITIZE is a comma-separated -fsanitize= list. Every report stops the program
# (-fno-sanitize-recover=all), so a test that triggers one fails. Frame pointers are kept for
# readable stacks. The flags apply to every target of the build, ours and the tests. Both
# scripts use clang: its one runtime writes UBSan reports to UBSAN_OPTIONS=log_path like ASan's
# (GCC's libubsan next to libasan prints them to stderr only, so a report in a child process
# whose failure a test expects would go unseen), and it takes an ignore list for third-party
# headers (cmake/sanitize-ignorelist.txt).
#
# MAV_FUZZ (clang only) instruments every target for libFuzzer's coverage feedback
# (-fsanitize=fuzzer-no-link, with address,undefined unless MAV_SANITIZE says otherwise) and
# builds tests/fuzz; the fuzz executables link libFuzzer's main (-fsanitize=fuzzer).

set(MAV_SANITIZE "" CACHE STRING
    "Comma-separated sanitizers for every target, e.g. address,undefined (empty: none)")
option(MAV_FUZZ "Build the libFuzzer targets in tests/fuzz (clang only)" OFF)

if(MAV_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "MAV_FUZZ needs clang (libFuzzer): CC=clang CXX=clang++ cmake ...")
  endif()
  if(NOT MAV_SANITIZE)
    set(MAV_SANITIZE "address,undefined" CACHE STRING "" FORCE)
  endif()
  add_compile_options(-fsanitize=fuzzer-no-link)
endif()

if(MAV_SANITIZE)
  add_compile_options(-fsanitize=${MAV_SANITIZE} -fno-omit-frame-pointer
                      -fno-sanitize-recover=all)
  add_link_options(-fsanitize=${MAV_SANITIZE})
  if(CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    # Checks off inside a few third-party headers, each with its report and reason. Compilers
    # do not list the file as a dependency: its hash in the flags rebuilds what it changes.
    set(ignorelist ${CMAKE_SOURCE_DIR}/cmake/sanitize-ignorelist.txt)
    set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${ignorelist})
    file(MD5 ${ignorelist} ignorelist_md5)
    add_compile_options(-fsanitize-ignorelist=${ignorelist}
                        -DMAV_SANITIZE_IGNORELIST=${ignorelist_md5})
  endif()
  message(STATUS "mav: -fsanitize=${MAV_SANITIZE} on every target")
endif()
