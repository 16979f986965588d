# Shared part of the Debian 12 cross toolchain files (aarch64-linux-gnu.cmake, arm-linux-gnueabihf.cmake).
# The including file sets PTDA_TARGET_TRIPLET, PTDA_TARGET_PROCESSOR, PTDA_DEB_ARCH and PTDA_QEMU_USER.
#
# Two ways to find the target libraries (docs/cross-build.md):
#   sysroot   - PTDA_SYSROOT (cache variable or environment variable), else the default
#               <source>/build/sysroots/<triplet> when it exists (scripts/sysroot.sh makes it from
#               the Debian .debs without touching the host). This is what scripts/cross_test.sh uses.
#   multiarch - PTDA_SYSROOT=none, or no sysroot made: the -dev packages installed into the host as
#               <pkg>:<arch> (apt-get install libspdlog-dev:arm64 ...), found under /usr/lib/<triplet>.
#               Only works when the mirror's target and host versions of every Multi-Arch: same library
#               agree.
#
# Facts checked with the Debian 12 cross compilers (g++-aarch64-linux-gnu, g++-arm-linux-gnueabihf
# 12.2.0-14cross1): with --sysroot=S the driver searches S/usr/include/<triplet>, S/usr/include,
# S/{,usr/}lib/<triplet> and lets ld resolve the absolute paths of S's libc.so linker script inside S;
# but its own /usr/<triplet>/{include,lib} (libc6-dev-<arch>-cross: glibc 2.36 headers, crt*.o,
# libc.so) come first. So libc is compiled and linked against the cross package's glibc 2.36 and run
# under qemu-user against the sysroot's glibc 2.36 (same ABI); every other library comes from S.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR ${PTDA_TARGET_PROCESSOR})
set(CMAKE_C_COMPILER ${PTDA_TARGET_TRIPLET}-gcc)
set(CMAKE_CXX_COMPILER ${PTDA_TARGET_TRIPLET}-g++)
set(CMAKE_LIBRARY_ARCHITECTURE ${PTDA_TARGET_TRIPLET})  # find_package looks in lib/<triplet>/cmake

# try_compile() projects re-read this file without the main project's cache: pass the choice on.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES PTDA_SYSROOT PTDA_ARMHF_NEON)

if((NOT DEFINED PTDA_SYSROOT OR PTDA_SYSROOT STREQUAL "") AND NOT "$ENV{PTDA_SYSROOT}" STREQUAL "")
  set(PTDA_SYSROOT "$ENV{PTDA_SYSROOT}")
endif()
get_filename_component(_ptda_default_sysroot "${CMAKE_CURRENT_LIST_DIR}/../build/sysroots/${PTDA_TARGET_TRIPLET}"
                       ABSOLUTE)
if(NOT DEFINED PTDA_SYSROOT OR PTDA_SYSROOT STREQUAL "")
  if(EXISTS "${_ptda_default_sysroot}/.complete")
    set(PTDA_SYSROOT "${_ptda_default_sysroot}")
  else()
    set(PTDA_SYSROOT none)
  endif()
endif()
set(PTDA_SYSROOT "${PTDA_SYSROOT}" CACHE STRING
    "Target sysroot (scripts/sysroot.sh), or 'none': the host's multiarch /usr/lib/${PTDA_TARGET_TRIPLET}")

# The host's programs (pkg-config, qemu, the compiler) and the target's headers, libraries and packages.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

if(NOT PTDA_SYSROOT STREQUAL "none")
  if(NOT EXISTS "${PTDA_SYSROOT}/usr/lib/${PTDA_TARGET_TRIPLET}")
    message(FATAL_ERROR "PTDA_SYSROOT=${PTDA_SYSROOT} has no usr/lib/${PTDA_TARGET_TRIPLET}: "
                        "run scripts/sysroot.sh ${PTDA_DEB_ARCH}")
  endif()
  set(CMAKE_SYSROOT "${PTDA_SYSROOT}")
  # The host pkgconf reads only the sysroot's .pc files and prefixes their paths with the sysroot.
  set(ENV{PKG_CONFIG_LIBDIR}
      "${PTDA_SYSROOT}/usr/lib/${PTDA_TARGET_TRIPLET}/pkgconfig:${PTDA_SYSROOT}/usr/share/pkgconfig:${PTDA_SYSROOT}/usr/lib/pkgconfig")
  set(ENV{PKG_CONFIG_SYSROOT_DIR} "${PTDA_SYSROOT}")
  set(ENV{PKG_CONFIG_PATH} "")
  set(_ptda_qemu_prefix "${PTDA_SYSROOT}")
else()
  # Multiarch: pkgconf:<arch> installs the <triplet>-pkg-config wrapper; without it the host pkgconf
  # is pointed at the target's .pc directories.
  find_program(_ptda_cross_pkg_config ${PTDA_TARGET_TRIPLET}-pkg-config)
  if(_ptda_cross_pkg_config)
    set(PKG_CONFIG_EXECUTABLE ${_ptda_cross_pkg_config} CACHE FILEPATH "pkg-config for the target")
  else()
    set(ENV{PKG_CONFIG_LIBDIR} "/usr/lib/${PTDA_TARGET_TRIPLET}/pkgconfig:/usr/share/pkgconfig")
  endif()
  # libc6-<arch>-cross puts the dynamic loader and libc under /usr/<triplet>; the other libraries are
  # found by qemu-user in the host's /usr/lib/<triplet> (qemu falls back to host paths).
  set(_ptda_qemu_prefix "/usr/${PTDA_TARGET_TRIPLET}")
endif()

# ctest (and gtest discovery at test time) run target binaries through qemu-user.
find_program(PTDA_QEMU_USER_EXECUTABLE ${PTDA_QEMU_USER})
if(NOT PTDA_QEMU_USER_EXECUTABLE)
  set(PTDA_QEMU_USER_EXECUTABLE ${PTDA_QEMU_USER})  # tests fail with "not found" until qemu-user is installed
endif()
set(CMAKE_CROSSCOMPILING_EMULATOR "${PTDA_QEMU_USER_EXECUTABLE};-L;${_ptda_qemu_prefix}")

# CPack's default is the build host's `dpkg --print-architecture`.
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE ${PTDA_DEB_ARCH} CACHE STRING "Debian architecture of the .deb")
