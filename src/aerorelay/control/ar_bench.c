/* aerorelay: time the C controller on recorded steps, no Python in the loop (written by `aerorelay codegen`).
 *
 *   bench STEPS.csv [ROUNDS]
 *
 * Reads every `step` line of STEPS.csv (replay's input) into memory first, then, ROUNDS times (default 3), runs them
 * through a fresh controller twice: once with ar_step (the whole step: the supervisor's envelope, the NMPC, the brake
 * law when it flies) and once with the NMPC's two phases (ar_prepare, then ar_feedback), each call timed with
 * CLOCK_MONOTONIC. Writes one line per step and round to stdout: round, step, the whole step, the preparation and the
 * feedback (ns). Pin it to a core (taskset -c 1) for steady numbers.
 */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "aerorelay_controller.h"

#define STEP_NUMBERS (1 + AR_NX + AR_NR + AR_NP * (AR_N + 1))

static long long now_ns(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (long long)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

int main(int argc, char **argv) {
  if (argc < 2) {
    fprintf(stderr, "usage: bench STEPS.csv [ROUNDS]\n");
    return 2;
  }
  FILE *in = fopen(argv[1], "r");
  int rounds = argc > 2 ? atoi(argv[2]) : 3;
  if (!in || rounds < 1) {
    fprintf(stderr, "bench: cannot open %s or rounds < 1\n", argv[1]);
    return 2;
  }
  static char line[1 << 20];
  long n = 0, cap = 1024;
  double *steps = malloc(sizeof(double) * STEP_NUMBERS * cap);
  while (steps && fgets(line, sizeof line, in)) {
    if (strncmp(line, "step,", 5)) {
      fprintf(stderr, "bench: line %ld is not a step\n", n + 1);
      return 2;
    }
    if (n == cap) {
      cap *= 2;
      double *more = realloc(steps, sizeof(double) * STEP_NUMBERS * cap);
      if (!more) break;
      steps = more;
    }
    double *v = steps + n * STEP_NUMBERS;
    char *p = line + 5, *end;
    for (int i = 0; i < STEP_NUMBERS; i++, p = end + 1) {
      v[i] = strtod(p, &end);
      if (end == p || (i < STEP_NUMBERS - 1 && *end != ',')) {
        fprintf(stderr, "bench: line %ld: %d numbers, a step has %d\n", n + 1, i, STEP_NUMBERS);
        return 2;
      }
    }
    n++;
  }
  fclose(in);
  long long *whole = malloc(sizeof(long long) * n), *prep = malloc(sizeof(long long) * n),
            *fb = malloc(sizeof(long long) * n);
  if (!steps || !whole || !prep || !fb) {
    fprintf(stderr, "bench: no memory for %ld steps\n", n);
    return 2;
  }
  double u[AR_NR];
  ar_info info;
  for (int r = 0; r < rounds; r++) {
    ar_controller *c = ar_create();
    for (long k = 0; k < n; k++) {
      const double *v = steps + k * STEP_NUMBERS;
      long long t0 = now_ns();
      ar_step(c, v + 1, v + 1 + AR_NX, v + 1 + AR_NX + AR_NR, v[0] != 0.0, u, &info);
      whole[k] = now_ns() - t0;
    }
    ar_destroy(c);
    c = ar_create();
    for (long k = 0; k < n; k++) {
      const double *v = steps + k * STEP_NUMBERS;
      long long t0 = now_ns();
      ar_prepare(c, v + 1 + AR_NX + AR_NR, v + 1 + AR_NX, v + 1);
      long long t1 = now_ns();
      ar_feedback(c, v + 1, v + 1 + AR_NX, v[0] != 0.0, u, &info);
      fb[k] = now_ns() - t1;
      prep[k] = t1 - t0;
    }
    ar_destroy(c);
    for (long k = 0; k < n; k++) printf("%d,%ld,%lld,%lld,%lld\n", r, k, whole[k], prep[k], fb[k]);
  }
  free(steps), free(whole), free(prep), free(fb);
  return 0;
}
