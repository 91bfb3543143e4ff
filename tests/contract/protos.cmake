# The generated contract code: protobuf round trip, the documented RPCs of every service, and a
# DDS StereoFrame through an in-process writer/reader (CRC-32 and the rig_id key).
# Included from tests/contract/CMakeLists.txt: include(${CMAKE_CURRENT_LIST_DIR}/protos.cmake)
find_package(ZLIB REQUIRED)
mav_add_test(protos_test SOURCES ${CMAKE_CURRENT_LIST_DIR}/protos_test.cc
             LIBS mav::protos mav::dds_types ZLIB::ZLIB LABELS contract TIMEOUT 60)
