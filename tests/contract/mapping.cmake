# mav.v1.Mapping: every RPC with good and bad input (in-process channel, a real loopback port,
# health, a deadline), the pose matcher and the DDS sample checks. Keyframes rendered by libs/sim.
# Included from tests/contract/CMakeLists.txt: include(${CMAKE_CURRENT_LIST_DIR}/mapping.cmake)
mav_add_test(mapping_contract_test
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/mapping_contract_test.cc
  LIBS mav::mapping_service mav::sim ${OCTOMAP_LIBRARIES}
  LABELS contract slow TIMEOUT 120)
target_include_directories(mapping_contract_test SYSTEM PRIVATE ${OCTOMAP_INCLUDE_DIRS})
