# Cross toolchain for 64-bit ARM Linux (Cortex-A53/A72/A76 class).
# The sysroot comes from the user: -DCMAKE_SYSROOT=... or MARKLOOP_SYSROOT in
# the environment; without one, Debian's multiarch layout is used (compilers
# from g++-aarch64-linux-gnu, libraries from the :arm64 packages).
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(MARKLOOP_TARGET_TRIPLE aarch64-linux-gnu)

include(${CMAKE_CURRENT_LIST_DIR}/common-cross.cmake)
