/* Two relays' C trees (aerorelay codegen --prefix r1 / --prefix r2) in one program: both headers in one translation
 * unit, both libraries linked, both controllers alive at once, each replaying its relay's recorded steps (the
 * `step` lines of aerorelay codegen --record), one step of each in turn.
 *
 *   two_trees R1_STEPS.csv R2_STEPS.csv
 *
 * prints, per step, "tree,fallback,u..." (tree 1 or 2, the brake law's flag, the command, %.17g); exit 2 on a line that
 * is not a step of its tree. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "r1/include/aerorelay_controller.h"
#include "r2/include/aerorelay_controller.h"

#define R1_NUMBERS (1 + R1_NX + R1_NR + R1_NP * (R1_N + 1))
#define R2_NUMBERS (1 + R2_NX + R2_NR + R2_NP * (R2_N + 1))

static int parse(char *line, double *v, int most) { /* "step,<numbers>": the count of numbers, -1 when not a step */
  if (strncmp(line, "step,", 5)) return -1;
  int n = 0;
  for (char *tok = strtok(line + 5, ",\n\r"); tok; tok = strtok(NULL, ",\n\r")) {
    char *end;
    if (n >= most) return -1;
    v[n++] = strtod(tok, &end);
    if (end == tok || *end != '\0') return -1;
  }
  return n;
}

static void print(int tree, const ar_info *info, const double *u, int nr) {
  printf("%d,%d", tree, info->fallback);
  for (int i = 0; i < nr; i++) printf(",%.17g", u[i]);
  printf("\n");
}

int main(int argc, char **argv) {
  if (argc != 3) return 2;
  FILE *f1 = fopen(argv[1], "r"), *f2 = fopen(argv[2], "r");
  if (!f1 || !f2) return 2;
  r1_controller *c1 = r1_create();
  r2_controller *c2 = r2_create();
  if (!c1 || !c2) return 2;
  static char line[1 << 20];
  static double v1[R1_NUMBERS], v2[R2_NUMBERS];
  double u1[R1_NR], u2[R2_NR];
  int more1 = 1, more2 = 1;
  while (more1 || more2) {
    ar_info info;
    if (more1 && fgets(line, sizeof line, f1)) {
      if (parse(line, v1, R1_NUMBERS) != R1_NUMBERS) return 2;
      r1_step(c1, v1 + 1, v1 + 1 + R1_NX, v1 + 1 + R1_NX + R1_NR, v1[0] != 0.0, u1, &info);
      print(1, &info, u1, R1_NR);
    } else more1 = 0;
    if (more2 && fgets(line, sizeof line, f2)) {
      if (parse(line, v2, R2_NUMBERS) != R2_NUMBERS) return 2;
      r2_step(c2, v2 + 1, v2 + 1 + R2_NX, v2 + 1 + R2_NX + R2_NR, v2[0] != 0.0, u2, &info);
      print(2, &info, u2, R2_NR);
    } else more2 = 0;
  }
  r1_destroy(c1);
  r2_destroy(c2);
  return 0;
}
