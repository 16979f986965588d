// gpiowatch: logs the state of one line of gpiochip0 as the kernel's debugfs shows it, for the VM test
// (tests/vm/init.sh, docs/vm-tests.md). While ptdad holds the line as an output, another process cannot
// request it (EBUSY), but /sys/kernel/debug/gpio lists every requested line with its direction and
// level. This polls that file and prints one line per change:
//   <CLOCK_REALTIME seconds.microseconds> <state>      state: "out hi", "out lo", "in hi", ..., "free"
// Realtime stamps on the same clock and scale as candump -L's kernel receive stamps, so the host can
// put the line's changes next to the verdict frames. Built static (no libraries in the guest).
// Usage: gpiowatch LINE POLL_US     (stops on SIGTERM/SIGINT)
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

static volatile sig_atomic_t g_stop = 0;

static void on_signal(int sig) {
  (void)sig;
  g_stop = 1;
}

// Reads the debugfs file and writes the state of gpiochip0's line `line` into `state`.
static int read_state(int line, char* state, size_t cap) {
  static char buf[16384];
  int fd = open("/sys/kernel/debug/gpio", O_RDONLY);
  if (fd < 0) return -1;
  size_t len = 0;
  for (;;) {
    ssize_t n = read(fd, buf + len, sizeof buf - 1 - len);
    if (n <= 0) break;
    len += (size_t)n;
    if (len == sizeof buf - 1) break;
  }
  close(fd);
  buf[len] = '\0';
  // "gpiochip0: GPIOs 504-511, parent: platform/9030000.pl061, 9030000.pl061:"
  const char* chip = strstr(buf, "gpiochip0: GPIOs ");
  if (chip == NULL) return -1;
  int base = atoi(chip + strlen("gpiochip0: GPIOs "));
  char key[32];
  snprintf(key, sizeof key, " gpio-%d ", base + line);
  const char* next_chip = strstr(chip + 1, "\ngpiochip");
  const char* l = strstr(chip, key);
  if (l == NULL || (next_chip != NULL && l > next_chip)) {
    snprintf(state, cap, "free");
    return 0;
  }
  // " gpio-507 (                    |ptdad-alarm         ) out hi "
  const char* paren = strchr(l, ')');
  if (paren == NULL) return -1;
  paren++;
  while (*paren == ' ') paren++;
  size_t n = 0;
  while (paren[n] != '\0' && paren[n] != '\n' && n + 1 < cap) {
    state[n] = paren[n];
    n++;
  }
  while (n > 0 && state[n - 1] == ' ') n--;
  state[n] = '\0';
  return 0;
}

int main(int argc, char** argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: gpiowatch LINE POLL_US\n");
    return 2;
  }
  const int line = atoi(argv[1]);
  const long poll_us = atol(argv[2]);
  signal(SIGTERM, on_signal);
  signal(SIGINT, on_signal);
  char last[128] = "";
  char now_state[128];
  unsigned long polls = 0;
  while (!g_stop) {
    if (read_state(line, now_state, sizeof now_state) != 0) snprintf(now_state, sizeof now_state, "?");
    polls++;
    if (strcmp(now_state, last) != 0) {
      struct timespec ts;
      clock_gettime(CLOCK_REALTIME, &ts);
      printf("%ld.%06ld %s\n", (long)ts.tv_sec, ts.tv_nsec / 1000, now_state);
      fflush(stdout);
      snprintf(last, sizeof last, "%s", now_state);
    }
    struct timespec d = {poll_us / 1000000, (poll_us % 1000000) * 1000};
    nanosleep(&d, NULL);
  }
  struct timespec ts;
  clock_gettime(CLOCK_REALTIME, &ts);
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  printf("%ld.%06ld end polls=%lu cpu=%.3fs\n", (long)ts.tv_sec, ts.tv_nsec / 1000, polls,
         (double)(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) + (double)(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) / 1e6);
  return 0;
}
