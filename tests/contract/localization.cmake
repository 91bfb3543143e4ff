# mav.v1.Localization: every RPC with good and bad input (in-process channel, a real loopback
# port, health), the calibration sources (inline, EuRoC sensor.yaml, a simulator service), the
# input queue, and the DDS sample conversions.
# Included from tests/contract/CMakeLists.txt: include(${CMAKE_CURRENT_LIST_DIR}/localization.cmake)
mav_add_test(localization_contract_test
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/localization_contract_test.cc
  LIBS mav::localization_service mav::simulator_service mav::sim mav::dataset
  LABELS contract TIMEOUT 120)
