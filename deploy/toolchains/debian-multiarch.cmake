# Shared part of the Debian multiarch cross toolchains: set CMAKE_SYSTEM_PROCESSOR and
# FLEETGW_CROSS_TRIPLE (e.g. aarch64-linux-gnu), then include this file.
if(NOT FLEETGW_CROSS_TRIPLE)
  message(FATAL_ERROR "set FLEETGW_CROSS_TRIPLE before including debian-multiarch.cmake")
endif()
set(CMAKE_C_COMPILER ${FLEETGW_CROSS_TRIPLE}-gcc)
set(CMAKE_CXX_COMPILER ${FLEETGW_CROSS_TRIPLE}-g++)
set(CMAKE_LIBRARY_ARCHITECTURE ${FLEETGW_CROSS_TRIPLE})

# Target files only from the target's directories; programs (protoc) from the host.
set(CMAKE_FIND_ROOT_PATH /usr/${FLEETGW_CROSS_TRIPLE} /)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

# pkg-config: the target's .pc files and the architecture-independent ones, never the host's.
set(ENV{PKG_CONFIG_LIBDIR} /usr/lib/${FLEETGW_CROSS_TRIPLE}/pkgconfig:/usr/share/pkgconfig)
set(ENV{PKG_CONFIG_PATH} "")

# binfmt_misc may not be mounted (containers, CI): run target programs (gtest discovery, tests,
# benchmarks) through qemu explicitly. No -L: the binaries find their libraries through the
# multiarch paths, and -L /usr/<triple> makes threaded programs spin forever under qemu 7.2.
if(CMAKE_SYSTEM_PROCESSOR STREQUAL "aarch64")
  set(_fleetgw_qemu qemu-aarch64-static)
else()
  set(_fleetgw_qemu qemu-arm-static)
endif()
find_program(FLEETGW_QEMU ${_fleetgw_qemu})
if(FLEETGW_QEMU)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${FLEETGW_QEMU})
endif()
