# The libFuzzer harnesses, "name:library" (tests/fuzz/fuzz_<name>.cpp). Shared by the clang fuzz build
# (tests/fuzz/CMakeLists.txt) and the GCC test build's seed replays (tests/CMakeLists.txt).
set(PTDA_FUZZ_TARGETS
  "candump_line:ptda_formats"
  "wav:ptda_formats"
  "recording_toml:ptda_formats"
  "baseline:ptda_formats"
  "scenario:ptda_sim"
  "iio_scan_type:ptda_drivers"
  "daemon_config:ptda_daemon"
  "can_frame:ptda_drivers"
  "iio_sysfs:ptda_drivers"
  "status_escape:ptda_daemon")
