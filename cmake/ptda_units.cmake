# ptdad@.service (one daemon per joint: ptdad@joint4 reads /etc/ptda/joint4.toml) is generated from
# systemd/ptdad.service, so the two units share every hardening line and cannot drift apart. Only the
# lines below differ; a line that is not found stops the configure (ptdad.service was edited: update
# the replacement here). Output: ${PTDA_TEMPLATE_UNIT}, installed by ptda_package.cmake and checked by
# the tests (systemd_units_test, systemd_security_template, systemd_verify_template).
set(PTDA_TEMPLATE_UNIT "${CMAKE_BINARY_DIR}/systemd/ptdad@.service")
set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS "${PROJECT_SOURCE_DIR}/systemd/ptdad.service")
file(READ "${PROJECT_SOURCE_DIR}/systemd/ptdad.service" _ptda_unit)

function(_ptda_unit_replace from to)
  string(FIND "${_ptda_unit}" "${from}" at)
  if(at EQUAL -1)
    message(FATAL_ERROR "cmake/ptda_units.cmake: systemd/ptdad.service has no line \"${from}\"")
  endif()
  string(REPLACE "${from}" "${to}" out "${_ptda_unit}")
  set(_ptda_unit "${out}" PARENT_SCOPE)
endfunction()

_ptda_unit_replace("# ptdad: condition monitoring of a robot joint's cycloidal gearbox (PTDA)."
  "# ptdad@.service: one ptdad per joint (ptdad@joint4.service: /etc/ptda/joint4.toml, drop-ins in\n# /etc/ptda/joint4.conf.d/, status in /run/ptda/joint4/, the label joint=\"joint4\" on its metrics).\n# Generated from ptdad.service by cmake/ptda_units.cmake; docs/fleet.md.\n#\n# ptdad: condition monitoring of a robot joint's cycloidal gearbox (PTDA).")
_ptda_unit_replace("Description=PTDA gearbox condition-monitoring daemon\n"
  "Description=PTDA gearbox condition-monitoring daemon, joint %i\n")
_ptda_unit_replace("ExecStart=/usr/bin/ptdad --config /etc/ptda/ptda.toml\n"
  "ExecStart=/usr/bin/ptdad --config /etc/ptda/%i.toml --config-dir /etc/ptda/%i.conf.d --status-dir /run/ptda/%i --joint %i\n")
# Each instance its own state (baseline) and runtime (status) directory under the shared parents.
_ptda_unit_replace("StateDirectory=ptda\n" "StateDirectory=ptda/%i\n")
_ptda_unit_replace("RuntimeDirectory=ptda\n" "RuntimeDirectory=ptda/%i\n")
file(CONFIGURE OUTPUT "${PTDA_TEMPLATE_UNIT}" CONTENT "${_ptda_unit}" @ONLY)
