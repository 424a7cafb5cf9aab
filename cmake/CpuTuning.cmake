# CPU tuning, kept out of the toolchain files: one toolchain serves every CPU
# of an architecture, and the CPU is a choice of the build (preset or -D).
#   MARKLOOP_CPU=cortex-a53|cortex-a72|cortex-a76|...  adds -mcpu=<cpu>
# Empty (the default) keeps the compiler's baseline for the architecture
# (Debian: armv8-a for arm64, armv7-a+vfpv3-d16 for armhf).
set(MARKLOOP_CPU "" CACHE STRING "Target CPU for -mcpu (empty: the architecture's baseline)")
if(MARKLOOP_CPU)
  if(NOT MARKLOOP_CPU MATCHES "^[a-z0-9.+-]+$")
    message(FATAL_ERROR "MARKLOOP_CPU='${MARKLOOP_CPU}' is not a CPU name (e.g. cortex-a72)")
  endif()
  include(CheckCXXCompilerFlag)
  check_cxx_compiler_flag(-mcpu=${MARKLOOP_CPU} markloop_cpu_flag_ok)
  if(NOT markloop_cpu_flag_ok)
    message(FATAL_ERROR "MARKLOOP_CPU='${MARKLOOP_CPU}': the compiler rejects -mcpu=${MARKLOOP_CPU}")
  endif()
  add_compile_options(-mcpu=${MARKLOOP_CPU})
endif()
