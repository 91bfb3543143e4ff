# A mission through the services: mav-simulator, mav-localization, mav-planning and mav-control
# as separate processes, driven by mavctl mission run, against the in-process driver; and a
# localization killed and restarted mid-mission. Included from tests/integration/CMakeLists.txt.
mav_add_test(mission_stack_test
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/mission_stack_test.cc
  LIBS mav::mission_sim mav::transport mav::protos
  LABELS integration slow TIMEOUT 600
  SHARDS "agreement=*InProcess*" "fault=*Killed*")
add_dependencies(mission_stack_test mavctl mav-simulator mav-localization mav-planning mav-control)
