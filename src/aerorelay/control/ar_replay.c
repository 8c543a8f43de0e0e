/* aerorelay: replay recorded NMPC calls through the C library (written by `aerorelay codegen`).
 *
 * Reads events, one per line, comma-separated, from the file given (or stdin):
 *   reset,<xa0: AR_NXA numbers>
 *   prepare,<x_guess: AR_NX>,<u_prev: AR_NR>,<P: AR_NP x (AR_N + 1), column-major>
 *   feedback,<shift: 0 or 1>,<x: AR_NX>,<u_prev: AR_NR>
 * and writes, for every feedback, one line to stdout: the status (ar_status), the QP's ok flag, its HPIPM status,
 * its iterations, then the AR_NR commanded motor accelerations (Hz/s, %.17g). A line that is not one of these, or
 * has the wrong count of numbers, is reported with its line number on stderr (exit 2); a status other than AR_OK
 * is written, not fatal.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "aerorelay_controller.h"

#define MAX_NUMBERS (AR_NX + AR_NR + AR_NP * (AR_N + 1) + 8)

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
    if (!strcmp(line, "reset") && n == AR_NXA) {
      ar_reset(c, v);
    } else if (!strcmp(line, "prepare") && n == AR_NX + AR_NR + AR_NP * (AR_N + 1)) {
      ar_prepare(c, v + AR_NX + AR_NR, v + AR_NX, v);
    } else if (!strcmp(line, "feedback") && n == 1 + AR_NX + AR_NR) {
      ar_info info;
      ar_status s = ar_feedback(c, v + 1, v + 1 + AR_NX, v[0] != 0.0, u, &info);
      printf("%d,%d,%d,%d", (int)s, info.ok, info.qp_status, info.iterations);
      for (int i = 0; i < AR_NR; i++) printf(",%.17g", u[i]);
      printf("\n");
    } else {
      fprintf(stderr, "replay: line %ld: '%s' with %d numbers is no event (reset %d, prepare %d, feedback %d)\n", number,
              line, n, AR_NXA, AR_NX + AR_NR + AR_NP * (AR_N + 1), 1 + AR_NX + AR_NR);
      return 2;
    }
  }
  ar_destroy(c);
  return 0;
}
