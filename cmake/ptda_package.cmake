# Debian packages (CPack DEB), included by the root CMakeLists.txt. docs/packaging.md explains the
# split, the layout, the maintainer scripts and how to build for amd64, arm64 and armhf.
#
#   ptdad        (arch)  the daemon, its systemd unit, sysusers/tmpfiles/udev files, /etc/ptda/ptda.toml
#   ptda-tools   (arch)  the offline tool `ptda`
#   ptda-common  (all)   scenarios, example configurations, documentation (both depend on it)
#
# The binaries' install() rules live next to their targets (cli/, daemon/: COMPONENT tools/daemon);
# everything else is installed here. Build, then package:
#   cmake --build <dir> --target ptda ptdad && (cd <dir> && cpack -G DEB)   -> <dir>/packages/*.deb

# ---- Target architecture ------------------------------------------------------------------------
# CPack defaults to `dpkg --print-architecture` of the build host, which is wrong when cross-building:
# derive the Debian architecture from the target (toolchain) instead.
# The toolchain files (toolchains/*.cmake) set PTDA_DEB_ARCH; otherwise, or as a cross-check, it is
# derived from CMAKE_SYSTEM_PROCESSOR (and, for 32-bit ARM, the multiarch triplet: armhf vs armel).
string(TOLOWER "${CMAKE_SYSTEM_PROCESSOR}" _ptda_proc)
set(_ptda_triplet "${CMAKE_LIBRARY_ARCHITECTURE} ${CMAKE_CXX_COMPILER_TARGET} ${CMAKE_CXX_COMPILER}")
set(_ptda_derived_arch "")
if(_ptda_proc MATCHES "^(x86_64|amd64)$")
  set(_ptda_derived_arch amd64)
elseif(_ptda_proc MATCHES "^(aarch64|arm64)$")
  set(_ptda_derived_arch arm64)
elseif(_ptda_proc MATCHES "^arm")
  if(_ptda_triplet MATCHES "gnueabihf|armhf")
    set(_ptda_derived_arch armhf)
  else()
    set(_ptda_derived_arch armel)
  endif()
elseif(_ptda_proc MATCHES "^i[3-6]86$")
  set(_ptda_derived_arch i386)
elseif(_ptda_proc MATCHES "^riscv64$")
  set(_ptda_derived_arch riscv64)
endif()
set(PTDA_DEB_ARCH "" CACHE STRING "Debian architecture of the packages (empty = derived from the target)")
if(PTDA_DEB_ARCH)
  set(_ptda_deb_arch "${PTDA_DEB_ARCH}")
  if(_ptda_derived_arch AND NOT _ptda_derived_arch STREQUAL PTDA_DEB_ARCH)
    message(WARNING "ptda_package: PTDA_DEB_ARCH=${PTDA_DEB_ARCH}, but the target processor "
                    "'${CMAKE_SYSTEM_PROCESSOR}' looks like ${_ptda_derived_arch}")
  endif()
elseif(_ptda_derived_arch)
  set(_ptda_deb_arch "${_ptda_derived_arch}")
else()
  message(FATAL_ERROR "ptda_package: no Debian architecture known for CMAKE_SYSTEM_PROCESSOR "
                      "'${CMAKE_SYSTEM_PROCESSOR}'; set -DPTDA_DEB_ARCH=<dpkg architecture>")
endif()

# ---- Install layout (Debian 12) -----------------------------------------------------------------
# Relative destinations are below CPACK_PACKAGING_INSTALL_PREFIX (/usr); /etc and /lib are absolute
# (bookworm still ships units and udev rules in /lib: `pkg-config --variable=systemdsystemunitdir
# systemd`; trixie moves them to /usr/lib).
set(PTDA_SYSTEMD_UNIT_DIR "/lib/systemd/system" CACHE STRING "systemd system unit directory")
set(PTDA_UDEV_RULES_DIR "/lib/udev/rules.d" CACHE STRING "udev rules directory")
set(PTDA_SYSUSERS_DIR "/usr/lib/sysusers.d" CACHE STRING "sysusers.d directory")
set(PTDA_TMPFILES_DIR "/usr/lib/tmpfiles.d" CACHE STRING "tmpfiles.d directory")
set(PTDA_CONF_DIR "/etc/ptda")          # ConfigurationDirectory=ptda, ExecStart=... --config /etc/ptda/ptda.toml
set(PTDA_DATA_DIR "share/ptda")         # /usr/share/ptda: scenarios/, examples/
set(PTDA_DATA_FULL_DIR "/usr/share/ptda")
set(PTDA_DOC_DIR "share/doc/ptda-common")

set(_ptda_pkg_src "${PROJECT_SOURCE_DIR}/packaging")
set(_ptda_pkg_gen "${PROJECT_BINARY_DIR}/packaging")

# Example daemon configurations name their simulator scenario relative to the file
# ("../scenarios/x.toml"). Installed in /etc/ptda, that would point at /etc/scenarios, so every
# shipped daemon configuration gets the absolute /usr/share/ptda/scenarios/ path instead (and the
# comments point at the installed examples).
function(ptda_package_rewrite_example in out)
  file(READ "${in}" text)
  string(REGEX REPLACE "scenario = \"(\\.\\./)+scenarios/" "scenario = \"${PTDA_DATA_FULL_DIR}/scenarios/" text "${text}")
  string(REPLACE "config/examples/" "${PTDA_DATA_FULL_DIR}/examples/" text "${text}")
  string(REPLACE "config/scenarios/" "${PTDA_DATA_FULL_DIR}/scenarios/" text "${text}")
  string(REPLACE "config/README.md" "/usr/${PTDA_DOC_DIR}/config/README.md" text "${text}")
  if(text MATCHES "scenario = \"\\.")
    message(FATAL_ERROR "ptda_package: ${in} still has a relative scenario path after the rewrite")
  endif()
  file(WRITE "${out}.tmp" "${text}")
  file(COPY_FILE "${out}.tmp" "${out}" ONLY_IF_DIFFERENT)
  file(REMOVE "${out}.tmp")
  set_property(DIRECTORY "${PROJECT_SOURCE_DIR}" APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS "${in}")
endfunction()

# /etc/ptda/ptda.toml, the conffile: config/examples/ptdad.toml (the live simulator, no hardware
# needed), with a header saying how to configure a real machine without touching the conffile.
ptda_package_rewrite_example("${PROJECT_SOURCE_DIR}/config/examples/ptdad.toml" "${_ptda_pkg_gen}/ptdad.toml")
file(READ "${_ptda_pkg_src}/ptda.toml.header" _ptda_header)
file(READ "${_ptda_pkg_gen}/ptdad.toml" _ptda_body)
file(WRITE "${_ptda_pkg_gen}/ptda.toml.tmp" "${_ptda_header}${_ptda_body}")
file(COPY_FILE "${_ptda_pkg_gen}/ptda.toml.tmp" "${_ptda_pkg_gen}/ptda.toml" ONLY_IF_DIFFERENT)
file(REMOVE "${_ptda_pkg_gen}/ptda.toml.tmp")
set_property(DIRECTORY "${PROJECT_SOURCE_DIR}" APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS "${_ptda_pkg_src}/ptda.toml.header")

file(GLOB _ptda_dropins CONFIGURE_DEPENDS "${PROJECT_SOURCE_DIR}/config/examples/ptdad.d/*.toml")
set(_ptda_gen_dropins)
foreach(f IN LISTS _ptda_dropins)
  get_filename_component(n "${f}" NAME)
  ptda_package_rewrite_example("${f}" "${_ptda_pkg_gen}/ptdad.d/${n}")
  list(APPEND _ptda_gen_dropins "${_ptda_pkg_gen}/ptdad.d/${n}")
endforeach()

# ---- daemon: ptdad -------------------------------------------------------------------------------
# (/usr/bin/ptdad: daemon/CMakeLists.txt)
install(FILES "${PROJECT_SOURCE_DIR}/systemd/ptdad.service" DESTINATION "${PTDA_SYSTEMD_UNIT_DIR}" COMPONENT daemon)
install(FILES "${PTDA_TEMPLATE_UNIT}" DESTINATION "${PTDA_SYSTEMD_UNIT_DIR}" COMPONENT daemon)  # ptda_units.cmake
install(FILES "${PROJECT_SOURCE_DIR}/systemd/ptda.sysusers" DESTINATION "${PTDA_SYSUSERS_DIR}" RENAME ptda.conf
        COMPONENT daemon)
install(FILES "${PROJECT_SOURCE_DIR}/systemd/ptda.tmpfiles" DESTINATION "${PTDA_TMPFILES_DIR}" RENAME ptda.conf
        COMPONENT daemon)
install(FILES "${PROJECT_SOURCE_DIR}/systemd/60-ptda.rules" DESTINATION "${PTDA_UDEV_RULES_DIR}" COMPONENT daemon)
install(FILES "${_ptda_pkg_gen}/ptda.toml" DESTINATION "${PTDA_CONF_DIR}" COMPONENT daemon)   # conffile
install(DIRECTORY DESTINATION "${PTDA_CONF_DIR}/conf.d" COMPONENT daemon)                       # drop-ins

# ---- common: ptda-common (Architecture: all) -----------------------------------------------------
install(DIRECTORY "${PROJECT_SOURCE_DIR}/config/scenarios/" DESTINATION "${PTDA_DATA_DIR}/scenarios"
        COMPONENT common FILES_MATCHING PATTERN "*.toml")
file(GLOB _ptda_job_examples CONFIGURE_DEPENDS "${PROJECT_SOURCE_DIR}/config/examples/*.toml")
list(REMOVE_ITEM _ptda_job_examples "${PROJECT_SOURCE_DIR}/config/examples/ptdad.toml")
install(FILES ${_ptda_job_examples} "${_ptda_pkg_gen}/ptdad.toml" DESTINATION "${PTDA_DATA_DIR}/examples"
        COMPONENT common)
install(FILES ${_ptda_gen_dropins} DESTINATION "${PTDA_DATA_DIR}/examples/ptdad.d" COMPONENT common)
# Not active: the can0 binding, the real-time relaxation, the MQTT network opening and the networkd file are examples (the
# shipped configuration runs the simulator, which needs no can0; docs/packaging.md: how to activate).
install(FILES "${PROJECT_SOURCE_DIR}/systemd/ptdad.service.d/10-can0.conf"
              "${PROJECT_SOURCE_DIR}/systemd/ptdad.service.d/20-realtime.conf.example"
              "${PROJECT_SOURCE_DIR}/systemd/ptdad.service.d/30-mqtt.conf.example"
              "${PROJECT_SOURCE_DIR}/systemd/80-can0.network"
        DESTINATION "${PTDA_DATA_DIR}/examples/systemd" COMPONENT common)
# Fleet view (docs/fleet.md): Prometheus alerting rules with their unit tests, the Grafana dashboard.
install(FILES "${PROJECT_SOURCE_DIR}/packaging/prometheus/ptda-alerts.yml"
              "${PROJECT_SOURCE_DIR}/packaging/prometheus/ptda-alerts.test.yml"
              "${PROJECT_SOURCE_DIR}/packaging/grafana/ptda-joint.json"
        DESTINATION "${PTDA_DATA_DIR}/fleet" COMPONENT common)
install(FILES "${PROJECT_SOURCE_DIR}/README.md" DESTINATION "${PTDA_DOC_DIR}" COMPONENT common)
install(FILES "${PROJECT_SOURCE_DIR}/config/README.md" DESTINATION "${PTDA_DOC_DIR}/config" COMPONENT common)
install(DIRECTORY "${PROJECT_SOURCE_DIR}/docs/" DESTINATION "${PTDA_DOC_DIR}/docs" COMPONENT common
        PATTERN ".*" EXCLUDE)

# ---- CPack ---------------------------------------------------------------------------------------
set(PTDA_DEB_REVISION "1" CACHE STRING "Debian revision of the packages (version = PROJECT_VERSION-revision)")
set(PTDA_PACKAGE_CONTACT "PTDA maintainers <ptda@localhost>" CACHE STRING "Maintainer field of the packages")
set(_ptda_deb_version "${PROJECT_VERSION}-${PTDA_DEB_REVISION}")

set(CPACK_GENERATOR "DEB")
set(CPACK_PACKAGE_NAME "ptda")
set(CPACK_PACKAGE_VERSION "${PROJECT_VERSION}")
set(CPACK_PACKAGE_CONTACT "${PTDA_PACKAGE_CONTACT}")
set(CPACK_PACKAGE_DIRECTORY "${PROJECT_BINARY_DIR}/packages")
# The DEB generator stages with DESTDIR itself: absolute destinations (/etc, /lib) land in the
# package, relative ones below this prefix (not CMAKE_INSTALL_PREFIX).
set(CPACK_PACKAGING_INSTALL_PREFIX "/usr")
# Each component's own description is its summary: keep CPack from prepending the project's.
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "${CMAKE_PROJECT_NAME} built using CMake")

set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL daemon tools common)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_RELEASE "${PTDA_DEB_REVISION}")
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE "${_ptda_deb_arch}")
set(CPACK_DEBIAN_PACKAGE_SOURCE "ptda")
set(CPACK_DEBIAN_PACKAGE_SECTION "misc")
set(CPACK_DEBIAN_PACKAGE_PRIORITY "optional")
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
# Dependencies are listed by hand (below), identical for every architecture: dpkg-shlibdeps would
# need the target architecture's libraries installed. scripts/package_test.sh checks the lists
# against dpkg-shlibdeps (amd64) and against the binaries' DT_NEEDED (every architecture).
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS OFF)
# Debug symbols in <package>-dbgsym .ddeb files (/usr/lib/debug/.build-id/), binaries stripped.
set(CPACK_DEBIAN_DEBUGINFO_PACKAGE ON)
if(CMAKE_OBJCOPY)
  set(CPACK_OBJCOPY_EXECUTABLE "${CMAKE_OBJCOPY}")   # the target's objcopy when cross-building
endif()
if(CMAKE_READELF)
  set(CPACK_READELF_EXECUTABLE "${CMAKE_READELF}")
endif()

# Debian 12 runtime libraries, versions as in bookworm. libkissfft-float131 131.1.0-4.1~deb12u1 fixes
# CVE-2025-34297 (integer overflow on 32-bit systems: armhf) and CVE-2026-41445 (its Debian
# changelog); dpkg-shlibdeps alone would accept any 131.x. libspdlog1.10-fmt9 is the ABI name
# dpkg-shlibdeps uses (spdlog built against fmt 9). libgcc-s1 (>= 4.0): ptda's complex arithmetic
# (`ptda gap`'s phase calibration) calls __muldc3@GCC_4.0.0.
set(_ptda_common_dep "ptda-common (= ${_ptda_deb_version})")
set(_ptda_libs_base "libc6 (>= 2.34), libgcc-s1 (>= 4.0), libstdc++6 (>= 12), libkissfft-float131 (>= 131.1.0-4.1~deb12u1), libtomlplusplus3 (>= 3.2.0)")
set(CPACK_DEBIAN_DAEMON_PACKAGE_NAME "ptdad")
set(CPACK_DEBIAN_DAEMON_PACKAGE_DEPENDS
    "${_ptda_libs_base}, libfmt9 (>= 9.1.0+ds1), libspdlog1.10 (>= 1:1.10.0), libspdlog1.10-fmt9, libgpiod2 (>= 1.6), libsystemd0, libmosquitto1 (>= 2.0.11), ${_ptda_common_dep}, init-system-helpers (>= 1.54~), systemd | systemd-standalone-sysusers | adduser")
set(CPACK_DEBIAN_DAEMON_PACKAGE_SUGGESTS "ptda-tools")
set(CPACK_DEBIAN_DAEMON_DESCRIPTION
    "gearbox condition-monitoring daemon (PTDA)
ptdad monitors the cycloidal (RV) gearbox of a robot joint continuously:
vibration from an IIO ADC, joint speed from CAN, constant-speed windows
scored against a trained baseline by phase-based time domain averaging,
and a k-of-n alarm on a GPIO line and/or a CAN frame.
.
This package contains the daemon, its hardened systemd unit (Type=notify,
watchdog), the sysusers.d, tmpfiles.d and udev files for the unprivileged
user ptda, and /etc/ptda/ptda.toml. As shipped, the configuration runs the
built-in simulator, so no hardware is needed to try it.")
set(CPACK_DEBIAN_DAEMON_PACKAGE_CONTROL_EXTRA
    "${_ptda_pkg_src}/ptdad/conffiles;${_ptda_pkg_src}/ptdad/postinst;${_ptda_pkg_src}/ptdad/prerm;${_ptda_pkg_src}/ptdad/postrm")

set(CPACK_DEBIAN_TOOLS_PACKAGE_NAME "ptda-tools")
set(CPACK_DEBIAN_TOOLS_PACKAGE_DEPENDS "${_ptda_libs_base}, zlib1g (>= 1:1.1.4), libmosquitto1 (>= 2.0.11), ${_ptda_common_dep}")
set(CPACK_DEBIAN_TOOLS_DESCRIPTION
    "gearbox condition-monitoring offline tool (PTDA)
ptda simulates robot joints and their gearbox vibration, imports
recordings, trains baselines, monitors recordings offline with the same
engine as the daemon ptdad, and writes HTML reports.")

set(CPACK_DEBIAN_COMMON_PACKAGE_NAME "ptda-common")
set(CPACK_DEBIAN_COMMON_PACKAGE_ARCHITECTURE "all")
set(CPACK_DEBIAN_COMMON_DEBUGINFO_PACKAGE OFF)
set(CPACK_DEBIAN_COMMON_DESCRIPTION
    "gearbox condition monitoring (PTDA) - data, examples, documentation
Simulator scenarios of the robot jobs (/usr/share/ptda/scenarios), example
pipeline, daemon and systemd configurations (/usr/share/ptda/examples) and
the documentation shared by ptdad and ptda-tools.")

include(CPack)
cpack_add_component(daemon DISPLAY_NAME "ptdad")
cpack_add_component(tools DISPLAY_NAME "ptda-tools")
cpack_add_component(common DISPLAY_NAME "ptda-common")
message(STATUS "ptda packages: ${_ptda_deb_version}, Architecture ${_ptda_deb_arch} (cpack -G DEB in ${PROJECT_BINARY_DIR})")
