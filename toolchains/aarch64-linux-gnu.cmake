# Cross-compile for Debian arm64 with g++-aarch64-linux-gnu (Debian 12); tests run under qemu-aarch64.
# Usage: cmake --preset aarch64-release   (or -DCMAKE_TOOLCHAIN_FILE=toolchains/aarch64-linux-gnu.cmake)
# Target libraries: the sysroot from `scripts/sysroot.sh arm64` (default build/sysroots/aarch64-linux-gnu,
# or PTDA_SYSROOT), else the host's multiarch arm64 packages. aarch64 always has NEON (Advanced SIMD).
set(PTDA_TARGET_TRIPLET aarch64-linux-gnu)
set(PTDA_TARGET_PROCESSOR aarch64)
set(PTDA_DEB_ARCH arm64)
set(PTDA_QEMU_USER qemu-aarch64)
include(${CMAKE_CURRENT_LIST_DIR}/ptda_cross_common.cmake)
