# Shared by the cross toolchain files; expects CMAKE_SYSTEM_PROCESSOR and
# MARKLOOP_TARGET_TRIPLE. Compilers are found by target triple on PATH; no
# machine's absolute paths are baked in. CPU tuning flags belong in presets.
set(CMAKE_C_COMPILER ${MARKLOOP_TARGET_TRIPLE}-gcc)
set(CMAKE_CXX_COMPILER ${MARKLOOP_TARGET_TRIPLE}-g++)

if(NOT CMAKE_SYSROOT AND DEFINED ENV{MARKLOOP_SYSROOT})
  set(CMAKE_SYSROOT $ENV{MARKLOOP_SYSROOT})
endif()
if(NOT CMAKE_SYSROOT)
  # Debian multiarch: target libraries live under /usr/lib/<triple>.
  set(CMAKE_LIBRARY_ARCHITECTURE ${MARKLOOP_TARGET_TRIPLE})
  list(APPEND CMAKE_FIND_ROOT_PATH /usr/${MARKLOOP_TARGET_TRIPLE})
endif()

# Programs run on the host; libraries and headers come from the target only
# (architecture-independent headers such as Eigen's are shared via /usr).
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
if(NOT CMAKE_SYSROOT)
  list(APPEND CMAKE_FIND_ROOT_PATH /)
endif()
