# One small helper for every target in the tree, so that each folder's
# CMakeLists.txt is a short, explicit list of sources and dependencies.
#
#   reenact_add_library(NAME reenact_x SRCS a.cc b.cc
#                       PUBLIC_DEPS ... PRIVATE_DEPS ...)
#   reenact_add_executable(NAME reenact SRCS main.cc DEPS ...)
#   reenact_add_test(NAME x_test SRCS x_test.cc DEPS ... [PRE_TEST] [LABELS l])
#   reenact_add_benchmark(NAME x_bench SRCS x_bench.cc DEPS ...)
include_guard(GLOBAL)

function(reenact_add_library)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(${ARG_NAME} STATIC ${ARG_SRCS})
  target_include_directories(${ARG_NAME} PUBLIC ${PROJECT_SOURCE_DIR})
  target_link_libraries(${ARG_NAME} PUBLIC ${ARG_PUBLIC_DEPS}
                                    PRIVATE ${ARG_PRIVATE_DEPS})
  target_compile_options(${ARG_NAME} PRIVATE ${REENACT_WARNING_FLAGS})
endfunction()

function(reenact_add_executable)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;DEPS" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SRCS})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_DEPS})
  target_compile_options(${ARG_NAME} PRIVATE ${REENACT_WARNING_FLAGS})
  set_target_properties(${ARG_NAME} PROPERTIES
                        RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/bin)
endfunction()

# Tests see the shared test data through REENACT_TEST_DATA_DIR (see
# common/testing/test_data.h). PRE_TEST defers test discovery to test time,
# for binaries that need a display or a device to list their tests.
function(reenact_add_test)
  if(NOT REENACT_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "PRE_TEST" "NAME;TIMEOUT" "SRCS;DEPS;LABELS" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SRCS})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_DEPS} reenact_testing
                        GTest::gtest GTest::gmock GTest::gtest_main)
  target_compile_options(${ARG_NAME} PRIVATE ${REENACT_WARNING_FLAGS})
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 600)
  endif()
  set(mode POST_BUILD)
  if(ARG_PRE_TEST)
    set(mode PRE_TEST)
  endif()
  gtest_discover_tests(${ARG_NAME} DISCOVERY_MODE ${mode}
                       WORKING_DIRECTORY ${PROJECT_SOURCE_DIR}
                       PROPERTIES TIMEOUT ${ARG_TIMEOUT} LABELS "${ARG_LABELS}"
                       DISCOVERY_TIMEOUT 60)
endfunction()

function(reenact_add_benchmark)
  if(NOT REENACT_BUILD_BENCHMARKS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "NAME" "SRCS;DEPS" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SRCS})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_DEPS} benchmark::benchmark)
  target_compile_options(${ARG_NAME} PRIVATE ${REENACT_WARNING_FLAGS})
  set_target_properties(${ARG_NAME} PROPERTIES
                        RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/bench)
endfunction()
