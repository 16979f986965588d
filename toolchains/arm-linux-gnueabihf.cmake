# Cross-compile for Debian armhf (32-bit ARMv7, hard float) with g++-arm-linux-gnueabihf (Debian 12);
# tests run under qemu-arm.
# Usage: cmake --preset armhf-release | armhf-neon-release
# Target libraries: the sysroot from `scripts/sysroot.sh armhf` (default build/sysroots/arm-linux-gnueabihf,
# or PTDA_SYSROOT), else the host's multiarch armhf packages.
#
# Debian's armhf baseline is -march=armv7-a+fp (VFPv3-D16, Thumb-2) with no NEON, so Eigen and the
# compiled code stay scalar. PTDA_ARMHF_NEON=ON adds -mfpu=neon-vfpv4 (Cortex-A7/A15 and later): faster,
# but the binaries then fault with SIGILL on the non-NEON ARMv7 parts Debian armhf also supports.
# The flag goes into the initial CMAKE_<LANG>_FLAGS, so it is fixed when a build directory is first
# configured: use a separate directory (the armhf-neon-release preset) rather than toggling it.
set(PTDA_TARGET_TRIPLET arm-linux-gnueabihf)
set(PTDA_TARGET_PROCESSOR arm)
set(PTDA_DEB_ARCH armhf)
set(PTDA_QEMU_USER qemu-arm)
include(${CMAKE_CURRENT_LIST_DIR}/ptda_cross_common.cmake)

option(PTDA_ARMHF_NEON "armhf: compile for NEON (-mfpu=neon-vfpv4); the result needs a NEON-capable ARMv7" OFF)
if(PTDA_ARMHF_NEON AND NOT CMAKE_CXX_FLAGS_INIT MATCHES "-mfpu=neon-vfpv4")  # this file is read more than once
  string(APPEND CMAKE_C_FLAGS_INIT " -mfpu=neon-vfpv4")
  string(APPEND CMAKE_CXX_FLAGS_INIT " -mfpu=neon-vfpv4")
endif()
# CMAKE_<LANG>_FLAGS keep their first value: catch a build directory switched after the fact.
if(DEFINED CACHE{CMAKE_CXX_FLAGS})
  string(FIND "${CMAKE_CXX_FLAGS}" "-mfpu=neon-vfpv4" _ptda_neon_at)
  if(PTDA_ARMHF_NEON AND _ptda_neon_at EQUAL -1 OR NOT PTDA_ARMHF_NEON AND NOT _ptda_neon_at EQUAL -1)
    message(FATAL_ERROR "PTDA_ARMHF_NEON=${PTDA_ARMHF_NEON} disagrees with CMAKE_CXX_FLAGS='${CMAKE_CXX_FLAGS}' "
                        "of this build directory: configure a fresh one (cmake --fresh, or another binary dir)")
  endif()
endif()
