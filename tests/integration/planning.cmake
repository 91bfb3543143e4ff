# The planning service from outside: clients/python/plan.py (Debian's python3-grpcio) against the
# mav-planning binary. Included from tests/integration/CMakeLists.txt.
find_program(MAV_PYTHON3 python3 PATHS /usr/bin NO_DEFAULT_PATH)
if(NOT MAV_PYTHON3)
  find_program(MAV_PYTHON3 python3)
endif()
mav_add_test(planning_python_test
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/planning_python_test.cc
  LIBS mav::transport mav::common
  LABELS integration TIMEOUT 120)
target_compile_definitions(planning_python_test PRIVATE MAV_PYTHON3="${MAV_PYTHON3}")
add_dependencies(planning_python_test mav-planning mav_python_stubs)
