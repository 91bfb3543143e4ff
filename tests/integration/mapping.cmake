# The mapping service in the stack: mav-simulator and mav-mapping binaries over loopback gRPC +
# DDS; the map is checked against the simulator's ground-truth occupancy (libs/sim in process).
# Included from tests/integration/CMakeLists.txt: include(${CMAKE_CURRENT_LIST_DIR}/mapping.cmake)
mav_add_test(mapping_stack_test
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/mapping_stack_test.cc
  LIBS mav::transport mav::protos mav::sim mav::mapping mav::geometry ${OCTOMAP_LIBRARIES}
  LABELS integration TIMEOUT 150)
target_include_directories(mapping_stack_test SYSTEM PRIVATE ${OCTOMAP_INCLUDE_DIRS})
add_dependencies(mapping_stack_test mav-simulator mav-mapping)
