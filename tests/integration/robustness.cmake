# The service binaries under bursts, kill -9 / restart and a busy port.
mav_add_test(robustness_test
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/robustness_test.cc
  LIBS mav::transport mav::protos
  LABELS integration TIMEOUT 120)
add_dependencies(robustness_test mav-simulator mav-localization mav-mapping)
