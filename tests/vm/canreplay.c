// canreplay: replays a candump log into a SocketCAN interface on an absolute time base: the start of
// ptdad's WAV replay. For the VM test (tests/vm/init.sh, docs/vm-tests.md): every logged frame goes out
// at  origin + (log time - START), which puts the speed frames where the recording had them relative
// to the vibration. The origin is first the kernel receive time of ptdad's first verdict frame (sent
// in activate(), just after the origin), then, as soon as ptdad has logged it, the exact origin.
// canplayer cannot do this: its clock starts when it reads its first line, so it inherits the latency
// of whatever starts it (85 ms measured under TCG), and the windows only tolerate ~20 ms of early and
// ~50 ms of late speed frames. Here a late wake-up delays only the frames due meanwhile; nothing
// accumulates.
//
// Usage: canreplay IFACE LOG START_UNIX TRIGGER_ID LOG_IFACE [DAEMON_LOG]
//   IFACE       interface to send on (vcan0); the trigger is received there too
//   LOG         candump -l log: "(sec.usec) iface ID#DATA" (classic frames; ID 3 hex digits standard,
//               8 extended; DATA hex bytes or R for a remote frame)
//   START_UNIX  log time that maps to the trigger (the recording's start_time)
//   TRIGGER_ID  standard id (hex) of the trigger frame
//   LOG_IFACE   only frames logged on this interface are sent
//   DAEMON_LOG  ptdad's log: once its line "replay timeline: sample 0 at S.N (CLOCK_REALTIME)" shows
//               (ptdad logs it right after activating), that exact origin replaces the trigger's time.
//               The trigger follows the origin by the activations in between (10-25 ms under TCG,
//               microseconds natively); frames sent before the switch are that much late.
// Prints "armed" once it listens (start the trigger's sender after that), "trigger <sec.nsec> ..." when
// it arrives, and a summary at the end (frames, lateness). Runs SCHED_FIFO when allowed. Built static.
#define _GNU_SOURCE
#include <errno.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sched.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

struct entry {
  int64_t t_ns;  // log time - START
  struct can_frame frame;
};

static int hexval(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// "(1700000000.001842)" -> ns relative to start (start given as seconds and nanoseconds).
static int parse_time(const char* s, int64_t start_s, int64_t start_ns, int64_t* out) {
  if (*s != '(') return -1;
  char* end = NULL;
  long long sec = strtoll(s + 1, &end, 10);
  if (*end != '.') return -1;
  const char* frac = end + 1;
  int64_t ns = 0;
  int digits = 0;
  while (*frac >= '0' && *frac <= '9') {
    if (digits < 9) {
      ns = ns * 10 + (*frac - '0');
      digits++;
    }
    frac++;
  }
  if (*frac != ')') return -1;
  for (; digits < 9; digits++) ns *= 10;
  *out = ((int64_t)sec - start_s) * 1000000000LL + (ns - start_ns);
  return 0;
}

static int parse_frame(const char* s, struct can_frame* f) {
  memset(f, 0, sizeof *f);
  const char* hash = strchr(s, '#');
  if (hash == NULL || hash[1] == '#') return -1;  // CAN FD is not replayed
  size_t id_len = (size_t)(hash - s);
  uint32_t id = 0;
  for (size_t i = 0; i < id_len; i++) {
    int v = hexval(s[i]);
    if (v < 0) return -1;
    id = id * 16 + (uint32_t)v;
  }
  if (id_len == 8) {
    id |= CAN_EFF_FLAG;
  } else if (id_len != 3) {
    return -1;
  }
  const char* d = hash + 1;
  if (*d == 'R' || *d == 'r') {
    f->can_id = id | CAN_RTR_FLAG;
    return 0;
  }
  f->can_id = id;
  int n = 0;
  while (hexval(d[0]) >= 0 && hexval(d[1]) >= 0 && n < 8) {
    f->data[n++] = (uint8_t)(hexval(d[0]) * 16 + hexval(d[1]));
    d += 2;
    if (*d == '.') d++;
  }
  f->can_dlc = (uint8_t)n;
  return 0;
}

// The origin ptdad logged, in CLOCK_REALTIME ns; 0 = not (yet) there.
static int64_t read_origin(const char* path) {
  static char buf[65536];
  FILE* f = fopen(path, "r");
  if (f == NULL) return 0;
  size_t n = fread(buf, 1, sizeof buf - 1, f);
  fclose(f);
  buf[n] = '\0';
  const char* key = "replay timeline: sample 0 at ";
  const char* p = strstr(buf, key);
  if (p == NULL) return 0;
  p += strlen(key);
  char* end = NULL;
  long long sec = strtoll(p, &end, 10);
  if (*end != '.') return 0;
  int64_t ns = 0;
  int digits = 0;
  for (const char* q = end + 1; *q >= '0' && *q <= '9' && digits < 9; q++, digits++) ns = ns * 10 + (*q - '0');
  if (digits != 9) return 0;
  return (int64_t)sec * 1000000000LL + ns;
}

static void sleep_until(int64_t t) {
  struct timespec ts = {(time_t)(t / 1000000000LL), (long)(t % 1000000000LL)};
  while (clock_nanosleep(CLOCK_REALTIME, TIMER_ABSTIME, &ts, NULL) == EINTR) {
  }
}

static int64_t now_ns(void) {
  struct timespec ts;
  clock_gettime(CLOCK_REALTIME, &ts);
  return (int64_t)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

int main(int argc, char** argv) {
  if (argc != 6 && argc != 7) {
    fprintf(stderr, "usage: canreplay IFACE LOG START_UNIX TRIGGER_ID LOG_IFACE [DAEMON_LOG]\n");
    return 2;
  }
  const char* iface = argv[1];
  const char* log_iface = argv[5];
  const char* daemon_log = argc == 7 ? argv[6] : NULL;
  // START_UNIX as seconds.fraction, exactly (no double rounding of a 1.7e9 value).
  char* end = NULL;
  const int64_t start_s = strtoll(argv[3], &end, 10);
  int64_t start_frac_ns = 0;
  if (*end == '.') {
    int digits = 0;
    for (const char* p = end + 1; *p >= '0' && *p <= '9'; p++) {
      if (digits < 9) {
        start_frac_ns = start_frac_ns * 10 + (*p - '0');
        digits++;
      }
    }
    for (; digits < 9; digits++) start_frac_ns *= 10;
  }
  const uint32_t trigger_id = (uint32_t)strtoul(argv[4], NULL, 16);

  FILE* in = fopen(argv[2], "r");
  if (in == NULL) {
    perror(argv[2]);
    return 1;
  }
  size_t cap = 16384, n = 0;
  struct entry* frames = malloc(cap * sizeof *frames);
  char line[256], t[64], ifn[64], fr[128];
  unsigned long lineno = 0;
  while (fgets(line, sizeof line, in) != NULL) {
    lineno++;
    if (line[0] != '(') continue;
    if (sscanf(line, "%63s %63s %127s", t, ifn, fr) != 3) {
      fprintf(stderr, "%s:%lu: malformed line\n", argv[2], lineno);
      return 1;
    }
    if (strcmp(ifn, log_iface) != 0) continue;
    if (n == cap) {
      cap *= 2;
      frames = realloc(frames, cap * sizeof *frames);
    }
    if (parse_time(t, start_s, start_frac_ns, &frames[n].t_ns) != 0 || parse_frame(fr, &frames[n].frame) != 0) {
      fprintf(stderr, "%s:%lu: cannot parse '%s %s'\n", argv[2], lineno, t, fr);
      return 1;
    }
    n++;
  }
  fclose(in);

  int s = socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (s < 0) {
    perror("socket(PF_CAN)");
    return 1;
  }
  struct can_filter filter = {trigger_id, CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG};
  setsockopt(s, SOL_CAN_RAW, CAN_RAW_FILTER, &filter, sizeof filter);
  const int one = 1;
  setsockopt(s, SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof one);
  struct ifreq ifr;
  memset(&ifr, 0, sizeof ifr);
  snprintf(ifr.ifr_name, sizeof ifr.ifr_name, "%s", iface);
  if (ioctl(s, SIOCGIFINDEX, &ifr) < 0) {
    perror(iface);
    return 1;
  }
  struct sockaddr_can addr;
  memset(&addr, 0, sizeof addr);
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifr.ifr_ifindex;
  if (bind(s, (struct sockaddr*)&addr, sizeof addr) < 0) {
    perror("bind");
    return 1;
  }
  struct sched_param sp = {.sched_priority = 50};
  const int fifo = sched_setscheduler(0, SCHED_FIFO, &sp) == 0;
  printf("armed: %zu frames from %s, SCHED_FIFO %s\n", n, argv[2], fifo ? "on" : "off");
  fflush(stdout);

  // The trigger and its kernel receive time.
  struct can_frame tf;
  char ctrl[CMSG_SPACE(sizeof(struct timespec))];
  struct iovec iov = {&tf, sizeof tf};
  struct msghdr msg;
  memset(&msg, 0, sizeof msg);
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  msg.msg_control = ctrl;
  msg.msg_controllen = sizeof ctrl;
  if (recvmsg(s, &msg, 0) < 0) {
    perror("recvmsg");
    return 1;
  }
  int64_t t0 = -1;
  for (struct cmsghdr* c = CMSG_FIRSTHDR(&msg); c != NULL; c = CMSG_NXTHDR(&msg, c)) {
    if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_TIMESTAMPNS) {
      struct timespec ts;
      memcpy(&ts, CMSG_DATA(c), sizeof ts);
      t0 = (int64_t)ts.tv_sec * 1000000000LL + ts.tv_nsec;
    }
  }
  const int64_t woke = now_ns();
  struct timespec boot;
  clock_gettime(CLOCK_BOOTTIME, &boot);
  if (t0 < 0) t0 = woke;
  // The trigger on CLOCK_BOOTTIME (the clock of /proc/uptime): boot to ptdad's activation.
  const double trigger_uptime = (double)boot.tv_sec + (double)boot.tv_nsec / 1e9 - (double)(woke - t0) / 1e9;
  // Receive nothing more (the trigger's sender goes on sending).
  setsockopt(s, SOL_CAN_RAW, CAN_RAW_FILTER, NULL, 0);
  printf("trigger %lld.%09lld id %03X uptime=%.6f, woke %.3f ms later\n", (long long)(t0 / 1000000000LL),
         (long long)(t0 % 1000000000LL), tf.can_id & CAN_SFF_MASK, trigger_uptime, (double)(woke - t0) / 1e6);
  fflush(stdout);

  int64_t late_max = 0, late_sum = 0;
  size_t late_10ms = 0, sent = 0, retries = 0;
  int64_t base = t0;
  int have_origin = daemon_log == NULL;
  const int64_t give_up = t0 + 5000000000LL;
  for (size_t i = 0; i < n; i++) {
    for (;;) {
      if (!have_origin) {
        const int64_t o = read_origin(daemon_log);
        if (o != 0) {
          base = o;
          have_origin = 1;
          printf("origin %lld.%09lld from %s: the trigger came %.3f ms after it; switched at frame %zu\n",
                 (long long)(o / 1000000000LL), (long long)(o % 1000000000LL), daemon_log,
                 (double)(t0 - o) / 1e6, i);
          fflush(stdout);
        } else if (now_ns() > give_up) {
          have_origin = 1;
          printf("origin: no 'replay timeline' line in %s after 5 s; keeping the trigger's time\n", daemon_log);
          fflush(stdout);
        }
      }
      const int64_t due = base + frames[i].t_ns;
      if (have_origin) {
        sleep_until(due);
        break;
      }
      const int64_t poll = now_ns() + 2000000;  // look at the daemon's log every 2 ms meanwhile
      sleep_until(due < poll ? due : poll);
      if (now_ns() >= due) break;
    }
    for (;;) {
      if (write(s, &frames[i].frame, sizeof frames[i].frame) == (ssize_t)sizeof frames[i].frame) break;
      if (errno != ENOBUFS && errno != EAGAIN) {
        perror("write");
        return 1;
      }
      retries++;
      struct timespec d = {0, 100000};
      nanosleep(&d, NULL);
    }
    const int64_t late = now_ns() - (base + frames[i].t_ns);
    sent++;
    late_sum += late;
    if (late > late_max) late_max = late;
    if (late > 10000000) late_10ms++;
  }
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  printf("sent %zu frames; lateness mean %.3f ms, max %.3f ms, %zu over 10 ms; %zu retries; cpu %.3f s\n", sent,
         sent ? (double)late_sum / (double)sent / 1e6 : 0.0, (double)late_max / 1e6, late_10ms, retries,
         (double)(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) + (double)(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) / 1e6);
  return 0;
}
