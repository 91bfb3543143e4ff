# cmake -DIN_DIR=... -DOUT_DIR=... -DNAME=... -P MavIdlcCopy.cmake
# Copies idlc's <NAME>.c and <NAME>.h from IN_DIR to OUT_DIR with the comment lines that name
# the output and the .idl by their absolute paths ("File name: /path/to/build/...",
# "Source: /path/to/clone/protos/dds/<NAME>.idl") reduced to the file names, so the generated
# files are the same in every clone (protos/CMakeLists.txt says why).
foreach(suffix .c .h)
  file(READ ${IN_DIR}/${NAME}${suffix} text)
  string(REGEX REPLACE "  (File name|Source): [^\n]*/([^/\n]+)" "  \\1: \\2" text "${text}")
  file(WRITE ${OUT_DIR}/${NAME}${suffix} "${text}")
endforeach()
