# Cross-compile fleetgw for 64-bit ARM Linux (Debian arm64) on a Debian x86-64 host.
#
# Needs: dpkg --add-architecture arm64; apt-get install crossbuild-essential-arm64 and the
# project's -dev libraries as :arm64 (see tests/deploy/arm64-cross.sh for the exact list);
# qemu-user-static to run the results. Debian's multiarch layout puts the target's libraries in
# /usr/lib/aarch64-linux-gnu next to the host's, so no sysroot is needed: CMAKE_LIBRARY_ARCHITECTURE
# steers find_library/find_package there, and pkg-config is pointed at the arm64 .pc files only
# (otherwise FindOpenSSL and pkg_check_modules happily return the host's x86-64 libraries).
# Build-time tools (protoc) stay the host's: CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER. Debian
# ships protoc and libprotobuf:arm64 from the same source version, so generated code matches.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(FLEETGW_CROSS_TRIPLE aarch64-linux-gnu)
include(${CMAKE_CURRENT_LIST_DIR}/debian-multiarch.cmake)
