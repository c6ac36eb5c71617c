# Cross-compile fleetgw for 32-bit ARM Linux with hardware float (Debian armhf) on a Debian
# x86-64 host. Same scheme as aarch64-linux-gnu.cmake with the armhf packages
# (dpkg --add-architecture armhf; crossbuild-essential-armhf; the -dev libraries as :armhf;
# run with qemu-arm-static).
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(FLEETGW_CROSS_TRIPLE arm-linux-gnueabihf)
include(${CMAKE_CURRENT_LIST_DIR}/debian-multiarch.cmake)
