/* aerorelay: time the C controller on recorded steps, no Python in the loop (written by `aerorelay codegen`).
 *
 *   bench STEPS.csv [ROUNDS]
 *
 * Reads every line of STEPS.csv (what `aerorelay codegen --record` writes: `step` lines, or `fly` lines for a tree
 * with the paper's planner, whose stage parameters it then reads from STEPS.csv.params, the recording's sidecar) into
 * memory first, then, ROUNDS times (default 3), runs them
 * through a fresh controller twice: once with ar_step (the whole step: the supervisor's envelope, the NMPC, the brake
 * law when it flies) and once with the NMPC's two phases (ar_prepare, then ar_feedback), each call timed with
 * CLOCK_MONOTONIC. Writes one line per step and round to stdout: round, step, the whole step, the preparation and the
 * feedback (ns), and the interior-point iterations ar_step's NMPC spent (ar_info.iterations). Pin it to a core
 * (taskset -c 1) for steady numbers.
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
  char *rend = NULL;
  long rounds = argc > 2 ? strtol(argv[2], &rend, 10) : 3;
  if (!in || rounds < 1 || rounds > 1000 || (rend && *rend != '\0')) {
    fprintf(stderr, "bench: cannot open %s, or ROUNDS is not a whole number 1..1000\n", argv[1]);
    return 2;
  }
  FILE *params = NULL; /* fly lines: their stage parameters, one row per step (STEPS.csv.params) */
  static char line[1 << 20];
  long n = 0, cap = 1024;
  double *steps = malloc(sizeof(double) * STEP_NUMBERS * cap);
  while (steps && fgets(line, sizeof line, in)) {
    int fly = !strncmp(line, "fly,", 4);
    if (strncmp(line, "step,", 5) && !fly) {
      fprintf(stderr, "bench: line %ld is neither a step nor a fly event\n", n + 1);
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
    if (fly) { /* t, shift, x, u_prev, ... : the step's shift, state and last input; P from the sidecar's row */
      double head[2 + AR_NX + AR_NR];
      p = line + 4;
      for (int i = 0; i < 2 + AR_NX + AR_NR; i++, p = end + 1) {
        head[i] = strtod(p, &end);
        if (end == p || *end != ',') {
          fprintf(stderr, "bench: line %ld: a fly event needs its time, shift, state and last input\n", n + 1);
          return 2;
        }
      }
      v[0] = head[1];
      memcpy(v + 1, head + 2, sizeof(double) * (AR_NX + AR_NR));
      if (!params) {
        char name[4096];
        snprintf(name, sizeof name, "%s.params", argv[1]);
        params = fopen(name, "r");
        if (!params) {
          fprintf(stderr, "bench: %s has fly events; their stage parameters are in %s, which cannot be opened\n", argv[1], name);
          return 2;
        }
      }
      static char row[1 << 20];
      if (!fgets(row, sizeof row, params)) {
        fprintf(stderr, "bench: %s.params has fewer rows than %s has steps (%ld)\n", argv[1], argv[1], n + 1);
        return 2;
      }
      p = row;
      for (int i = 0; i < AR_NP * (AR_N + 1); i++, p = end + 1) {
        v[1 + AR_NX + AR_NR + i] = strtod(p, &end);
        if (end == p || (i < AR_NP * (AR_N + 1) - 1 && *end != ',')) {
          fprintf(stderr, "bench: %s.params row %ld: %d numbers, a step's parameters are %d\n", argv[1], n + 1, i,
                  AR_NP * (AR_N + 1));
          return 2;
        }
      }
      n++;
      continue;
    }
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
  if (params) fclose(params);
  if (n == 0) {
    fprintf(stderr, "bench: %s has no step\n", argv[1]);
    return 2;
  }
  long long *whole = malloc(sizeof(long long) * n), *prep = malloc(sizeof(long long) * n),
            *fb = malloc(sizeof(long long) * n);
  int *iters = malloc(sizeof(int) * n);
  if (!steps || !whole || !prep || !fb || !iters) {
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
      iters[k] = info.iterations;
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
    for (long k = 0; k < n; k++) printf("%d,%ld,%lld,%lld,%lld,%d\n", r, k, whole[k], prep[k], fb[k], iters[k]);
  }
  free(steps), free(whole), free(prep), free(fb), free(iters);
  return 0;
}
