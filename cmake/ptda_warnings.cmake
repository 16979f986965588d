# One interface target carries the project's warning and sanitizer flags; every ptda target links it.
add_library(ptda_options INTERFACE)
target_compile_options(ptda_options INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Woverloaded-virtual
  -Wimplicit-fallthrough -Wformat=2 -Wundef)
if(CMAKE_SYSTEM_PROCESSOR MATCHES "^arm")
  # armhf: GCC's "parameter passing for argument of type ... changed in GCC 7.1" notes (hundreds, on
  # std::vector code) concern linking with code built by GCC < 7, which Debian 12 has none of.
  target_compile_options(ptda_options INTERFACE -Wno-psabi)
endif()
if(PTDA_WERROR)
  target_compile_options(ptda_options INTERFACE -Werror)
endif()
if(PTDA_SANITIZE)
  target_compile_options(ptda_options INTERFACE -fsanitize=${PTDA_SANITIZE} -fno-omit-frame-pointer -fno-sanitize-recover=all)
  target_link_options(ptda_options INTERFACE -fsanitize=${PTDA_SANITIZE})
endif()

# ptda_add_test(NAME name SOURCES a.cpp b.cpp LIBS lib...) builds one gtest binary and registers its tests.
function(ptda_add_test)
  cmake_parse_arguments(T "" "NAME;LABEL" "SOURCES;LIBS" ${ARGN})
  add_executable(${T_NAME} ${T_SOURCES})
  target_link_libraries(${T_NAME} PRIVATE ${T_LIBS} ptda_options GTest::gtest GTest::gtest_main)
  # The test files themselves get line tables only (-g1) and, on the host, -O1: with gtest's macros
  # they are two thirds of the build's compile time, and -O2 -g costs them 1.5-2x -O1 -g1 (5 test
  # files, docs/benchmarks.md "CI time"). The libraries they test keep the build type's flags.
  # Cross builds keep -O2: on arm64 GCC forms fused multiply-adds only from -O2, and a test body's
  # reference arithmetic should round as the library's does.
  target_compile_options(${T_NAME} PRIVATE $<$<CONFIG:RelWithDebInfo>:-g1>)
  if(NOT CMAKE_CROSSCOMPILING)
    target_compile_options(${T_NAME} PRIVATE $<$<CONFIG:RelWithDebInfo>:-O1>)
  endif()
  target_compile_definitions(${T_NAME} PRIVATE
    PTDA_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
    PTDA_SHARED_DIR="${PROJECT_SOURCE_DIR}/../shared")
  # PRE_TEST: the test list is read when ctest runs, so a cross build never runs target binaries at
  # build time (ctest lists and runs them through CMAKE_CROSSCOMPILING_EMULATOR, qemu-user).
  set(discovery_timeout_s 60)
  if(CMAKE_CROSSCOMPILING)
    set(discovery_timeout_s 300)  # qemu-user start-up on a loaded machine
  endif()
  gtest_discover_tests(${T_NAME} DISCOVERY_MODE PRE_TEST DISCOVERY_TIMEOUT ${discovery_timeout_s}
    PROPERTIES ENVIRONMENT "PTDA_TEST_TMP=${CMAKE_BINARY_DIR}/test-tmp" LABELS "${T_LABEL}")
  if(T_LABEL)
    if(NOT TARGET tests_${T_LABEL})
      add_custom_target(tests_${T_LABEL})
    endif()
    add_dependencies(tests_${T_LABEL} ${T_NAME})
  endif()
endfunction()
