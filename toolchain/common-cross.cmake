# Shared by the cross toolchain files; expects MARKLOOP_TARGET_TRIPLE (GNU
# triple, e.g. aarch64-linux-gnu), CMAKE_SYSTEM_PROCESSOR and
# MARKLOOP_QEMU_USER (name of the qemu-user program for the target).
#
# Compilers are found by target triple on PATH; no machine's absolute paths
# are baked in. CPU tuning is not the toolchain's business: the project's
# MARKLOOP_CPU cache variable (cmake/CpuTuning.cmake) adds -mcpu.
#
# Where target libraries come from, in this order:
#   1. a sysroot given by the user: -DCMAKE_SYSROOT=DIR or $MARKLOOP_SYSROOT
#      (toolchain/debian-sysroot.sh builds one from Debian packages);
#   2. otherwise Debian's multiarch layout on the build machine: the :arm64 /
#      :armhf packages in /usr/lib/<triple>, architecture-independent headers
#      and CMake configs in /usr/include and /usr/share.
# MARKLOOP_TARGET_ROOTS adds further roots with the same layout (unpacked
# Debian packages that cannot be co-installed, such as libcatch2-dev, whose
# static libraries live in /usr/lib without an architecture directory).
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_C_COMPILER ${MARKLOOP_TARGET_TRIPLE}-gcc)
set(CMAKE_CXX_COMPILER ${MARKLOOP_TARGET_TRIPLE}-g++)
# Debian libraries live in lib/<triple>, also inside a Debian-made sysroot.
set(CMAKE_LIBRARY_ARCHITECTURE ${MARKLOOP_TARGET_TRIPLE})

# try_compile projects load this file again: hand them the same inputs.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES MARKLOOP_TARGET_ROOTS)

if(NOT CMAKE_SYSROOT AND DEFINED ENV{MARKLOOP_SYSROOT})
  set(CMAKE_SYSROOT $ENV{MARKLOOP_SYSROOT})
endif()

# Extra roots are searched as install prefixes (<root>/usr), so that the
# hiding of the build machine's /usr/lib below does not hide them too.
foreach(root IN LISTS MARKLOOP_TARGET_ROOTS)
  if(NOT IS_DIRECTORY ${root}/usr)
    message(FATAL_ERROR "MARKLOOP_TARGET_ROOTS: ${root}/usr does not exist "
      "(create it with toolchain/debian-sysroot.sh, or run .ci/setup for this preset)")
  endif()
  list(APPEND CMAKE_PREFIX_PATH ${root}/usr)
endforeach()

set(CMAKE_FIND_ROOT_PATH)

if(CMAKE_SYSROOT)
  if(NOT IS_DIRECTORY ${CMAKE_SYSROOT})
    message(FATAL_ERROR "CMAKE_SYSROOT ${CMAKE_SYSROOT} does not exist "
      "(create it with toolchain/debian-sysroot.sh, or run .ci/setup for this preset)")
  endif()
  list(APPEND CMAKE_FIND_ROOT_PATH ${CMAKE_SYSROOT})
  set(ENV{PKG_CONFIG_SYSROOT_DIR} ${CMAKE_SYSROOT})
  set(ENV{PKG_CONFIG_LIBDIR}
    "${CMAKE_SYSROOT}/usr/lib/${MARKLOOP_TARGET_TRIPLE}/pkgconfig:${CMAKE_SYSROOT}/usr/share/pkgconfig")
  set(markloop_emulator_prefix ${CMAKE_SYSROOT})
else()
  # Multiarch: the build machine's root holds the target's libraries next to
  # its own. The cross runtime (libc6-dev-<arch>-cross) is in /usr/<triple>.
  list(APPEND CMAKE_FIND_ROOT_PATH /usr/${MARKLOOP_TARGET_TRIPLE} /)
  set(ENV{PKG_CONFIG_LIBDIR}
    "/usr/lib/${MARKLOOP_TARGET_TRIPLE}/pkgconfig:/usr/share/pkgconfig")
  # Never pick up the build machine's own libraries or package configs: hide
  # every library directory that is not the target's (CMake applies these
  # paths under every find root). Debian puts
  # architecture-dependent files only under lib/<triple> and lib/ (the latter
  # is not multiarch-aware, e.g. libcatch2-dev), and architecture-independent
  # CMake configs under share/ (e.g. Eigen), which stay visible.
  set(hidden_lib_dirs)
  foreach(prefix /usr /usr/local "")
    list(APPEND hidden_lib_dirs ${prefix}/lib ${prefix}/lib64 ${prefix}/lib32 ${prefix}/libx32)
    file(GLOB other_arch_dirs LIST_DIRECTORIES true ${prefix}/lib/*-linux-gnu*)
    list(REMOVE_ITEM other_arch_dirs ${prefix}/lib/${MARKLOOP_TARGET_TRIPLE})
    list(APPEND hidden_lib_dirs ${other_arch_dirs})
  endforeach()
  set(hidden)
  foreach(dir IN LISTS hidden_lib_dirs)
    list(APPEND hidden ${dir})
    # find_package() ignores a config file only when its own directory is
    # listed, so list every package directory under the hidden ones.
    file(GLOB package_dirs LIST_DIRECTORIES true ${dir}/cmake/* ${dir}/cmake)
    list(APPEND hidden ${package_dirs})
  endforeach()
  list(APPEND CMAKE_SYSTEM_IGNORE_PATH ${hidden})
  set(markloop_emulator_prefix /)
endif()

# Programs (code generators, python) run on the build machine; libraries,
# headers and package configs come from the target roots only.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

# Test binaries run under qemu-user so that ctest works unchanged; -L points
# the target's dynamic loader at the root holding the target's libraries.
find_program(MARKLOOP_QEMU_USER_PROGRAM ${MARKLOOP_QEMU_USER})
if(MARKLOOP_QEMU_USER_PROGRAM)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${MARKLOOP_QEMU_USER_PROGRAM} -L ${markloop_emulator_prefix})
endif()
