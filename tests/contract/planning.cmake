# mav.v1.Planning: every RPC with good and bad input (in-process channel, a real loopback port,
# health), deadlines, the limits, plans during a rebuild, a map from a (fake) mapping service.
# Included from tests/contract/CMakeLists.txt: include(${CMAKE_CURRENT_LIST_DIR}/planning.cmake)
mav_add_test(planning_contract_test
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/planning_contract_test.cc
  LIBS mav::planning_service mav::dataset
  LABELS contract slow TIMEOUT 180)
