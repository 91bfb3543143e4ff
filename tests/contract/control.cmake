# The closed loop's contracts: mav.v1.Control (every RPC with good and bad input, deadlines, the
# plan_id path against a fake Planning service, the failsafes) and mav.v1.Simulator's flight mode
# (every flight RPC, the lock-step wait and its timeout, stale and malformed commands, a flight
# scored exactly as eval::FlyTask scores it).
# Included from tests/contract/CMakeLists.txt: include(${CMAKE_CURRENT_LIST_DIR}/control.cmake)
mav_add_test(control_contract_test
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/control_contract_test.cc
  LIBS mav::control_service mav::sim mav::eval
  LABELS contract TIMEOUT 120)
mav_add_test(simulator_flight_contract_test
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/simulator_flight_contract_test.cc
  LIBS mav::simulator_service mav::sim mav::eval mav::control
  LABELS contract TIMEOUT 120)
