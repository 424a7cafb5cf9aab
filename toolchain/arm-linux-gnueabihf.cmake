# Cross toolchain for 32-bit ARM Linux, hard-float ABI (Debian armhf:
# ARMv7-A, VFPv3-D16, Thumb-2 by default).
# Compilers: Debian package g++-arm-linux-gnueabihf. Target libraries: a
# sysroot or the :armhf packages (Debian multiarch), see common-cross.cmake.
set(CMAKE_SYSTEM_PROCESSOR armv7l)
set(MARKLOOP_TARGET_TRIPLE arm-linux-gnueabihf)
set(MARKLOOP_QEMU_USER qemu-arm)
include(${CMAKE_CURRENT_LIST_DIR}/common-cross.cmake)
