#!/bin/sh
# /init of the VM test guests (busybox sh; scripts/vm_test.sh builds the initramfs, docs/vm-tests.md).
# Loads the CAN modules, creates vcan0, starts a bus capture, ptdad (WAV replay of the test recording
# + SocketCAN on vcan0 + the CAN verdict frame, and on aarch64 the GPIO output on the PL061), replays
# the recording's CAN log into vcan0 (canreplay) from the moment ptdad activates, sends operator
# clear frames, and prints everything the host needs between markers on the serial console:
#   @@VM <key> <value...>          facts (times are the guest's CLOCK_BOOTTIME from /proc/uptime)
#   @@VM BEGIN <name> / @@VM END <name>   a file, gzip + base64
#   @@VM VERDICT OK|FAIL <reason>  the guest's own checks (the host then checks the capture)
# Parameters come from /test/test.env.
export PATH=/usr/bin:/usr/sbin:/bin:/sbin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
mkdir -p /tmp /run
mount -t tmpfs tmp /tmp
mount -t tmpfs run /run
. /test/test.env

say() { echo "@@VM $*"; }
uptime_s() { cut -d' ' -f1 /proc/uptime; }
send_file() {  # name path
  say "BEGIN $1"
  if [ -f "$2" ]; then gzip -c "$2" | base64; fi
  say "END $1"
}
dump_all() {
  send_file capture.log /tmp/capture.log
  send_file ptdad.log /tmp/ptdad.log
  send_file status.json /run/ptda/status.json
  send_file gpio.log /tmp/gpio.log
  send_file canreplay.log /tmp/canreplay.log
  send_file events.log /tmp/events.log
}
finish() {  # OK|FAIL reason...
  say "VERDICT $*"
  say "poweroff uptime=$(uptime_s)"
  poweroff -f
  sleep 10
}
fail() {
  say "error $*"
  dump_all
  finish FAIL "$@"
}
event() { echo "$(uptime_s) $*" >> /tmp/events.log; }

say "init uptime=$(uptime_s) kernel=$(uname -r) machine=$(uname -m) realtime=$(date +%s)"

# ---- CAN: can.ko, can-raw.ko, can-bcm.ko (the verdict frame's kernel timer), can-dev.ko, vcan.ko (vcan
# needs can-dev; the package has no modules.dep)
for m in can can-raw can-bcm can-dev vcan; do
  insmod "/lib/modules/$m.ko" || fail "insmod $m.ko failed"
done
grep -q CAN_RAW /proc/net/protocols || fail "CAN_RAW missing from /proc/net/protocols after insmod"
grep -q CAN_BCM /proc/net/protocols || fail "CAN_BCM missing from /proc/net/protocols after insmod"
ip link add dev vcan0 type vcan || fail "ip link add dev vcan0 type vcan failed"
ip link set vcan0 up || fail "ip link set vcan0 up failed"
say "vcan0 up uptime=$(uptime_s)"

# ---- GPIO (aarch64): the PL061 of qemu's virt machine
if [ "$GPIO" = 1 ]; then
  [ -c /dev/gpiochip0 ] || fail "/dev/gpiochip0 missing (PL061 not probed?)"
  mount -t debugfs none /sys/kernel/debug || fail "cannot mount debugfs"
  gpioinfo gpiochip0 > /tmp/gpioinfo.before 2>&1
  say "gpiochip0 $(gpiodetect 2>&1 | head -n1)"
  gpiowatch "$GPIO_LINE" "$GPIO_POLL_US" > /tmp/gpio.log 2> /tmp/gpiowatch.err &
  WATCH=$!
fi

# ---- the bus capture, and the replay of the recording's CAN log, armed before ptdad starts
# A 4 MiB receive buffer (rmem_max raised for it): when the host stalls the guest, the frames due
# meanwhile go out in a burst, and the capture runs at a low priority.
echo 8388608 > /proc/sys/net/core/rmem_max
candump -r 4194304 -L vcan0 > /tmp/capture.log 2> /tmp/candump.err &
CAPTURE=$!
# canreplay sends every logged frame at T + (log time - START_UNIX), T = the start of ptdad's WAV replay:
# first the kernel receive time of ptdad's first verdict frame (sent in activate(), just after it),
# then the exact time from ptdad's log line "replay timeline: sample 0 at ...".
canreplay vcan0 /test/recording/can.log "$START_UNIX" "$ALARM_ID" "$LOG_IFACE" /tmp/ptdad.log \
  > /tmp/canreplay.log 2>&1 &
REPLAY=$!
# Both must be listening before ptdad's first frame: canreplay says "armed"; the capture's receiver
# shows in the kernel's list.
i=0
while [ $i -lt 500 ]; do
  n_all=$(grep -c vcan0 /proc/net/can/rcvlist_all 2> /dev/null)
  [ "${n_all:-0}" -ge 1 ] && grep -q '^armed' /tmp/canreplay.log && break
  kill -0 $REPLAY 2> /dev/null || fail "canreplay exited: $(cat /tmp/canreplay.log)"
  usleep 10000
  i=$((i + 1))
done
[ $i -lt 500 ] || fail "candump/canreplay not listening after 5 s: $(cat /tmp/canreplay.log /tmp/candump.err)"
say "replay $(head -n 1 /tmp/canreplay.log)"

# ---- ptdad
say "ptdad start uptime=$(uptime_s)"
time ptdad --config /test/joint_rotation.toml --config-dir /test/conf.d --exit-at-end > /tmp/ptdad.log 2>&1 &
PTDAD=$!
# Polled slowly: every fork here takes CPU from ptdad's start-up (canreplay has the exact time).
i=0
while ! grep -q '^trigger' /tmp/canreplay.log; do
  kill -0 $PTDAD 2> /dev/null || fail "ptdad exited before activating: $(tail -n 5 /tmp/ptdad.log)"
  [ $i -lt 600 ] || fail "no verdict frame from ptdad within 60 s"
  usleep 100000
  i=$((i + 1))
done
say "ready $(grep '^trigger' /tmp/canreplay.log)"
event ready

# While ptdad holds the line another requester gets EBUSY; gpioinfo shows the holder.
if [ "$GPIO" = 1 ]; then
  sleep 3
  gpioinfo gpiochip0 > /tmp/gpioinfo.running 2>&1
  say "gpioinfo line $GPIO_LINE: $(grep "line *$GPIO_LINE:" /tmp/gpioinfo.running)"
  gpioget gpiochip0 "$GPIO_LINE" > /tmp/gpioget.out 2>&1
  say "gpioget exit=$? output: $(cat /tmp/gpioget.out)"
fi

# ---- operator clear frames: from CLEAR_FROM_S after activation, every CLEAR_PERIOD_S, while ptdad runs
(
  sleep "$CLEAR_FROM_S"
  while kill -0 $PTDAD 2> /dev/null; do
    cansend vcan0 "$CLEAR_FRAME" && event "clear sent"
    sleep "$CLEAR_PERIOD_S"
  done
) &
CLEARER=$!
# The test's own tools yield to ptdad (canreplay runs SCHED_FIFO: it must keep time).
renice -n 10 -p $CAPTURE $CLEARER > /dev/null 2>&1

# ---- wait for the end of the replay (ptdad --exit-at-end); a guard stops a ptdad that does not end,
# so the files still come back before the host's timeout kills the guest.
(
  sleep "$PTDAD_LIMIT_S"
  touch /tmp/guard.fired
  kill -TERM $PTDAD
) > /dev/null 2>&1 &
GUARD=$!
wait $PTDAD
rc=$?
kill $GUARD 2> /dev/null
say "ptdad exit=$rc uptime=$(uptime_s)"
event "ptdad exit $rc"
sleep 0.3
kill $CLEARER $REPLAY 2> /dev/null
[ "$GPIO" = 1 ] && kill "$WATCH" 2> /dev/null
kill $CAPTURE 2> /dev/null
wait $CAPTURE 2> /dev/null
[ "$GPIO" = 1 ] && wait "$WATCH" 2> /dev/null
if [ "$GPIO" = 1 ]; then
  mkdir -p /tmp/g
  cat /tmp/gpioinfo.before /tmp/gpioinfo.running /tmp/gpiowatch.err > /tmp/g/all 2>&1
  send_file gpioinfo.txt /tmp/g/all
fi
dump_all
[ ! -f /tmp/guard.fired ] || finish FAIL "ptdad still ran $PTDAD_LIMIT_S s after its start (--exit-at-end did not end it); stopped with SIGTERM"
[ "$rc" = 0 ] || finish FAIL "ptdad exited with $rc"
[ -s /tmp/capture.log ] || finish FAIL "empty bus capture"
finish OK "ptdad ran and exited 0; capture $(wc -l < /tmp/capture.log) frames"
