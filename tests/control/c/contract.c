/* The C library's pointer contract (issue 77), built with AddressSanitizer and UndefinedBehaviorSanitizer by
 * tests/control/test_codegen_contract.py: a NULL, destroyed or foreign controller, or a NULL array, is AR_BAD_INPUT and
 * never a dereference; a command no vehicle flies gives no setpoint; the planner refuses a time or a jammer power
 * that is no such thing. Prints one line per check and exits 1 at the first that fails. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "aerorelay_controller.h"

static int failures = 0;
#define CHECK(cond, what)                                                   \
  do {                                                                      \
    int ok_ = (cond);                                                       \
    printf("%s %s\n", ok_ ? "ok" : "FAILED", what);                         \
    if (!ok_) failures++;                                                   \
  } while (0)

int main(void) {
  static double P[AR_NP * (AR_N + 1)];
  double x[AR_NX], u_prev[AR_NR], u[AR_NR], x1[AR_NX], acc[3], a_ext[3] = {0, 0, 0};
  double hover[AR_NR] = AR_HOVER_SPEEDS;
  ar_info info;
  memset(x, 0, sizeof x);
  x[2] = 5.0;
  for (int i = 0; i < AR_NR; i++) x[AR_NX - AR_NR + i] = hover[i], u_prev[i] = 0.0;

  CHECK(ar_step(NULL, x, u_prev, P, 1, u, &info) == AR_BAD_INPUT, "ar_step with a NULL controller");
  CHECK(ar_feedback(NULL, x, u_prev, 1, u, &info) == AR_BAD_INPUT, "ar_feedback with a NULL controller");
  CHECK(ar_prepare(NULL, P, u_prev, x) == AR_BAD_INPUT, "ar_prepare with a NULL controller");
  CHECK(ar_reset(NULL, x) == AR_BAD_INPUT, "ar_reset with a NULL controller");
  ar_destroy(NULL);

  ar_controller *c = ar_create();
  CHECK(c != NULL, "ar_create");
  CHECK(ar_step(c, NULL, u_prev, P, 1, u, &info) == AR_BAD_INPUT, "ar_step with a NULL state");
  CHECK(ar_step(c, x, NULL, P, 1, u, &info) == AR_BAD_INPUT, "ar_step with a NULL last input");
  CHECK(ar_step(c, x, u_prev, NULL, 1, u, &info) == AR_BAD_INPUT, "ar_step with NULL stage parameters");
  CHECK(ar_step(c, x, u_prev, P, 1, NULL, &info) == AR_BAD_INPUT, "ar_step with a NULL command");
  CHECK(ar_feedback(c, x, u_prev, 1, NULL, &info) == AR_BAD_INPUT, "ar_feedback with a NULL command");
  CHECK(ar_prepare(c, NULL, u_prev, x) == AR_BAD_INPUT, "ar_prepare with NULL stage parameters");
  CHECK(ar_reset(c, NULL) == AR_BAD_INPUT, "ar_reset with a NULL state");

  double big[AR_NR];
  for (int i = 0; i < AR_NR; i++) big[i] = 1e308;
  ar_status s = ar_setpoint(x, big, a_ext, x1, acc);
  int same = 1;
  for (int i = 0; i < AR_NX; i++) same &= x1[i] == x[i];
  CHECK(s == AR_BAD_INPUT && same && acc[0] == 0.0, "ar_setpoint of u = 1e308: no setpoint, x1 = x");
  CHECK(ar_setpoint(x, u_prev, a_ext, NULL, acc) == AR_BAD_INPUT, "ar_setpoint with a NULL output");
  CHECK(ar_setpoint(x, u_prev, a_ext, x1, acc) == AR_OK && isfinite(x1[2]), "ar_setpoint of a held command");

#if AR_HAS_PLANNER
  double src_p[3] = {3.0, 0.0, 5.0}, zero3[3] = {0, 0, 0}, jam_p[3 * AR_NJ + 1], jam_w[AR_NJ + 1];
  for (int i = 0; i < 3 * AR_NJ; i++) jam_p[i] = 10.0 + i;
  for (int i = 0; i < AR_NJ; i++) jam_w[i] = 1.0;
  CHECK(ar_plan(c, NAN, x, src_p, zero3, zero3, jam_p, jam_w, a_ext, P) == AR_BAD_INPUT, "ar_plan at t = NaN");
  if (AR_NJ > 0) {
    jam_w[0] = -1.0;
    CHECK(ar_plan(c, 0.0, x, src_p, zero3, zero3, jam_p, jam_w, a_ext, P) == AR_BAD_INPUT, "ar_plan with a -1 W jammer");
    jam_w[0] = 1.0;
  }
  CHECK(ar_plan(c, 0.0, x, src_p, zero3, zero3, jam_p, jam_w, a_ext, NULL) == AR_BAD_INPUT, "ar_plan with a NULL output");
  CHECK(ar_plan(c, 0.0, x, src_p, zero3, zero3, jam_p, jam_w, a_ext, P) == AR_OK, "ar_plan of a sound input");
#endif

  ar_destroy(c);
  CHECK(ar_step(c, x, u_prev, P, 1, u, &info) == AR_BAD_INPUT, "ar_step after ar_destroy");
  CHECK(ar_prepare(c, P, u_prev, x) == AR_BAD_INPUT, "ar_prepare after ar_destroy");
  ar_destroy(c); /* a second destroy does nothing */
  int stack_object = 0;
  CHECK(ar_step((ar_controller *)&stack_object, x, u_prev, P, 1, u, &info) == AR_BAD_INPUT,
        "ar_step with a pointer ar_create never returned");
  printf("%d failed\n", failures);
  return failures ? 1 : 0;
}
