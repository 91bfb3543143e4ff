# Sanitizer and fuzzing builds (see docs/quality.md). CI builds both in one clang tree,
# build-asan/ (tools/ci-clang-tree.sh configures it for tools/ci-sanitizers.sh and
# tools/ci-fuzz-smoke.sh alike):
#
#   CC=clang CXX=clang++ cmake -B build-asan -DMAV_SANITIZE=address,undefined -DMAV_FUZZ=ON ...
#
# MAV_SANITIZE is a comma-separated -fsanitize= list. Every report stops the program
# (-fno-sanitize-recover=all), so a test that triggers one fails. Frame pointers are kept for
# readable stacks. The flags apply to every target of the build, ours and the tests. Both
# scripts use clang: its one runtime writes UBSan reports to UBSAN_OPTIONS=log_path like ASan's
# (GCC's libubsan next to libasan prints them to stderr only, so a report in a child process
# whose failure a test expects would go unseen), and it takes an ignore list for third-party
# headers (cmake/sanitize-ignorelist.txt).
#
# MAV_FUZZ (clang only) builds tests/fuzz, whose executables link libFuzzer's main
# (-fsanitize=fuzzer), with address,undefined unless MAV_SANITIZE says otherwise. Coverage
# feedback is added per library by mav_fuzz_coverage() (tests/fuzz/CMakeLists.txt lists which),
# not to every target: the unit and contract tests of the same tree then run the renderer's and
# the planners' loops without a coverage callback on every comparison.

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
endif()

# mav_fuzz_coverage(FULL|EDGES <target>...): libFuzzer's coverage instrumentation on these
# libraries. FULL is -fsanitize=fuzzer-no-link (edge counters and comparison tracing, for the
# code that parses the fuzzed bytes); EDGES only the edge counters (for the code a fuzzer
# reaches behind the parsers, e.g. the options' IsValid, at a fraction of the cost to the
# hot loops the other tests of the tree run).
function(mav_fuzz_coverage kind)
  if(kind STREQUAL "FULL")
    set(flags -fsanitize=fuzzer-no-link)
  elseif(kind STREQUAL "EDGES")
    set(flags -fsanitize-coverage=inline-8bit-counters,pc-table)
  else()
    message(FATAL_ERROR "mav_fuzz_coverage: FULL or EDGES, not '${kind}'")
  endif()
  foreach(target IN LISTS ARGN)
    target_compile_options(${target} PRIVATE ${flags})
  endforeach()
endfunction()

if(MAV_SANITIZE)
  add_compile_options(-fsanitize=${MAV_SANITIZE} -fno-omit-frame-pointer
                      -fno-sanitize-recover=all)
  add_link_options(-fsanitize=${MAV_SANITIZE})
  # Debug paths relative to the source root. With -g ccache hashes the compile directory unless
  # a prefix map covers it, so without this a fresh clone in another directory misses on every
  # object (CMakeLists.txt's ccache launcher).
  add_compile_options(-fdebug-prefix-map=${CMAKE_SOURCE_DIR}=.)
  if(CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    # Checks off inside a few third-party headers, each with its report and reason. Compilers
    # do not list the file as a dependency: its hash in the flags rebuilds what it changes.
    set(ignorelist ${CMAKE_SOURCE_DIR}/cmake/sanitize-ignorelist.txt)
    set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${ignorelist})
    file(MD5 ${ignorelist} ignorelist_md5)
    # The list's path relative to the directory the compiler runs in (the target's binary
    # directory with Makefiles, the build root with Ninja): ccache does not rewrite this flag's
    # path to a relative one, and an absolute path would miss in every new clone.
    if(CMAKE_GENERATOR MATCHES "Ninja")
      set(compile_dir ${CMAKE_BINARY_DIR})
    else()
      set(compile_dir "$<TARGET_PROPERTY:BINARY_DIR>")
    endif()
    if(CMAKE_VERSION VERSION_GREATER_EQUAL 3.24)
      set(ignorelist_arg "$<PATH:RELATIVE_PATH,${ignorelist},${compile_dir}>")
    else()
      set(ignorelist_arg ${ignorelist})
    endif()
    add_compile_options(-fsanitize-ignorelist=${ignorelist_arg}
                        -DMAV_SANITIZE_IGNORELIST=${ignorelist_md5})
  endif()
  message(STATUS "mav: -fsanitize=${MAV_SANITIZE} on every target")
endif()
