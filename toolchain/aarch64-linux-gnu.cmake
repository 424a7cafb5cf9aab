# Cross toolchain for 64-bit ARM Linux (Cortex-A53/A72/A76 class).
# Compilers: Debian package g++-aarch64-linux-gnu. Target libraries: the
# :arm64 packages (Debian multiarch) or a sysroot, see common-cross.cmake.
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(MARKLOOP_TARGET_TRIPLE aarch64-linux-gnu)
set(MARKLOOP_QEMU_USER qemu-aarch64)
include(${CMAKE_CURRENT_LIST_DIR}/common-cross.cmake)
