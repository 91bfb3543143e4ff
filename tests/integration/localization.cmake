# The localization service in the stack: mav-simulator and mav-localization binaries over
# loopback gRPC + DDS, poses compared with the simulator's ground truth.
# Included from tests/integration/CMakeLists.txt: include(${CMAKE_CURRENT_LIST_DIR}/localization.cmake)
mav_add_test(localization_stack_test
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/localization_stack_test.cc
  LIBS mav::transport mav::protos mav::dds_types mav::geometry
  LABELS integration TIMEOUT 120)
add_dependencies(localization_stack_test mav-simulator mav-localization)
