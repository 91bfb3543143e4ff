# The closed loop in the stack: mav-simulator (flight mode, lock-step) and mav-control as separate
# processes over loopback DDS + gRPC; t3_1 hovered inside the contest's limits, then a hand-made
# leg flown without collision; t4_3's first leg planned by mav-planning (a third process) on
# maps/power_plant.bt and flown through SetTrajectory{plan}; in real time, a killed controller's
# stale commands stop the motors.
# Included from tests/integration/CMakeLists.txt: include(${CMAKE_CURRENT_LIST_DIR}/control.cmake)
mav_add_test(control_stack_test
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/control_stack_test.cc
  LIBS mav::control_service mav::transport mav::protos mav::dds_types
  LABELS integration TIMEOUT 120)
add_dependencies(control_stack_test mav-simulator mav-control mav-planning)
