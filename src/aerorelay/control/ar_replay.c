/* aerorelay: replay recorded NMPC calls through the C library (written by `aerorelay codegen`).
 *
 * Reads control steps, one per line, comma-separated, from the file given (or stdin):
 *   step,<shift: 0 or 1>,<x: AR_NX>,<u_prev: AR_NR>,<P: AR_NP x (AR_N + 1), column-major>
 * and writes, for every step, one line to stdout: the status (ar_status), the QP's ok flag, its HPIPM status, its
 * iterations, whether the brake law flew, then the AR_NR commanded motor accelerations (Hz/s, %.17g). A line that is
 * not a step, or has the wrong count of numbers, is reported with its line number on stderr (exit 2); a status other
 * than AR_OK is written, not fatal.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "aerorelay_controller.h"

#define STEP_NUMBERS (1 + AR_NX + AR_NR + AR_NP * (AR_N + 1))
#define MAX_NUMBERS (STEP_NUMBERS + 8)

static int parse(char *rest, double *v, int most) {
  int n = 0;
  char *tok = strtok(rest, ",\n\r");
  while (tok) {
    char *end;
    if (n >= most) return -1;
    v[n++] = strtod(tok, &end);
    if (end == tok) return -1;
    tok = strtok(NULL, ",\n\r");
  }
  return n;
}

int main(int argc, char **argv) {
  FILE *in = argc > 1 ? fopen(argv[1], "r") : stdin;
  if (!in) {
    fprintf(stderr, "replay: cannot open %s\n", argv[1]);
    return 2;
  }
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
    if (!strcmp(line, "step") && n == STEP_NUMBERS) {
      ar_info info;
      ar_status s = ar_step(c, v + 1, v + 1 + AR_NX, v + 1 + AR_NX + AR_NR, v[0] != 0.0, u, &info);
      printf("%d,%d,%d,%d,%d", (int)s, info.ok, info.qp_status, info.iterations, info.fallback);
      for (int i = 0; i < AR_NR; i++) printf(",%.17g", u[i]);
      printf("\n");
    } else {
      fprintf(stderr, "replay: line %ld: '%s' with %d numbers is no step (step: 1 + %d + %d + %d numbers)\n", number,
              line, n, AR_NX, AR_NR, AR_NP * (AR_N + 1));
      return 2;
    }
  }
  ar_destroy(c);
  return 0;
}
