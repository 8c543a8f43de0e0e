/* aerorelay: replay recorded NMPC calls through the C library (written by `aerorelay codegen`).
 *
 *   replay [--params] STEPS.csv
 *
 * Reads control steps, one per line, comma-separated, from the file given (or stdin):
 *   step,<shift: 0 or 1>,<x: AR_NX>,<u_prev: AR_NR>,<P: AR_NP x (AR_N + 1), column-major>
 *   fly,<t>,<shift>,<x: AR_NX>,<u_prev: AR_NR>,<source p, v, a: 9>,<jammers: AR_NJ x 3>,<their powers: AR_NJ>,<a_ext: 3>
 * (`fly`: a tree with the paper's planner, AR_HAS_PLANNER: ar_plan makes P, then ar_step) and writes, for every step,
 * one line to stdout: the status (ar_status), the QP's ok flag, its HPIPM status, its iterations, whether the brake
 * law flew, then the AR_NR commanded motor accelerations (Hz/s, %.17g), and with --params the step's P. A line that
 * is not a step, or has the wrong count of numbers, is reported with its line number on stderr (exit 2); a status
 * other than AR_OK is written, not fatal.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "aerorelay_controller.h"

#define STEP_NUMBERS (1 + AR_NX + AR_NR + AR_NP * (AR_N + 1))
#define MAX_NUMBERS (STEP_NUMBERS + 8)
#if AR_HAS_PLANNER
#define FLY_NUMBERS (2 + AR_NX + AR_NR + 9 + 4 * AR_NJ + 3)
#else
#define FLY_NUMBERS -1
#endif

static int parse(char *rest, double *v, int most) {
  int n = 0;
  char *tok = strtok(rest, ",\n\r");
  while (tok) {
    char *end;
    if (n >= most) return -1;
    v[n++] = strtod(tok, &end);
    if (end == tok || *end != '\0') return -1; /* a number, all of the field: "-6.951.5abc" is none */
    tok = strtok(NULL, ",\n\r");
  }
  return n;
}

int main(int argc, char **argv) {
  int params = argc > 1 && !strcmp(argv[1], "--params");
  const char *path = argc > 1 + params ? argv[1 + params] : NULL;
  FILE *in = path ? fopen(path, "r") : stdin;
  if (!in) {
    fprintf(stderr, "replay: cannot open %s\n", path);
    return 2;
  }
  static double P[AR_NP * (AR_N + 1)];
  ar_controller *c = ar_create();
  if (!c) {
    fprintf(stderr, "replay: no memory for the controller\n");
    return 2;
  }
  static char line[1 << 20];
  static double v[MAX_NUMBERS];
  double u[AR_NR];
  long number = 0;
  while (fgets(line, sizeof line, in)) {
    number++;
    char *comma = strchr(line, ',');
    if (!comma) {
      fprintf(stderr, "replay: line %ld: no event\n", number);
      return 2;
    }
    *comma = '\0';
    int n = parse(comma + 1, v, MAX_NUMBERS);
    ar_info info;
    ar_status s;
    if (!strcmp(line, "step") && n == STEP_NUMBERS) {
      memcpy(P, v + 1 + AR_NX + AR_NR, sizeof P);
      s = ar_step(c, v + 1, v + 1 + AR_NX, P, v[0] != 0.0, u, &info);
#if AR_HAS_PLANNER
    } else if (!strcmp(line, "fly") && n == FLY_NUMBERS) {
      const double *x = v + 2, *up = x + AR_NX, *src = up + AR_NR, *jam = src + 9;
      s = ar_plan(c, v[0], x, src, src + 3, src + 6, jam, jam + 3 * AR_NJ, jam + 4 * AR_NJ, P);
      if (s == AR_OK) s = ar_step(c, x, up, P, v[1] != 0.0, u, &info);
      else ar_step(c, x, up, P, v[1] != 0.0, u, &info); /* bad input: the step refuses it too, with its brake law */
#endif
    } else {
      fprintf(stderr, "replay: line %ld: '%s' with %d numbers is no step (step: %d numbers; fly: %d, -1: no planner)\n",
              number, line, n, STEP_NUMBERS, FLY_NUMBERS);
      return 2;
    }
    printf("%d,%d,%d,%d,%d", (int)s, info.ok, info.qp_status, info.iterations, info.fallback);
    for (int i = 0; i < AR_NR; i++) printf(",%.17g", u[i]);
    if (params)
      for (int i = 0; i < AR_NP * (AR_N + 1); i++) printf(",%.17g", P[i]);
    printf("\n");
  }
  ar_destroy(c);
  return 0;
}
