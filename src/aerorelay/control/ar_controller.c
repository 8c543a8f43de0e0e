/* aerorelay: one relay's NMPC as a C library (written by `aerorelay codegen`, see its README.md).
 *
 * The real-time iteration of aerorelay.control.nmpc.NMPC with the compiled HPIPM engine: `ar_prepare` (before the
 * measurement: the lagged input-rate rows of the stage parameters filled from the last input and the plan, then
 * every stage linearized and HPIPM's QP filled) and `ar_feedback` (measurement in, input out: the QP solved for the
 * measured state, the plan stepped and shifted, the first input clipped as the Python NMPC clips it: to the motor
 * accelerations' bounds and to what keeps the first stage's rotor speeds within theirs). The scenario's settings
 * are baked in (the macros aerorelay codegen writes before this file); nothing is allocated after `ar_create`. Bad input (a non-finite state, input
 * or parameter) is refused with AR_BAD_INPUT before the engine sees it, and the command returned holds the rotor
 * speeds (zero motor acceleration).
 *
 * This file is compiled after the engine (the CasADi-generated linearization, the dimension macros and
 * rti_hpipm.c), in one translation unit with it (the tree's src/aerorelay_controller.c), as aerorelay compiles its own
 * engine. The pointer contract (the header's): a controller not alive, or a NULL array, is AR_BAD_INPUT.
 */
#include "aerorelay_controller.h"

typedef struct { /* where and how stiffly the brake law stops (ar_failsafe.c) */
  double point[3];
  double freq;
  int upright;
} ar_hold_t;

struct ar_controller {
  rti_mem *rti;
  int initialized;
  double P[AR_NP * (AR_N + 1)];
  double Xb[(AR_N + 1) * AR_NXA], Wb[AR_N * RTI_NW], X[(AR_N + 1) * AR_NXA], W[AR_N * RTI_NW];
  double xa0[AR_NXA];
  int last_input_finite; /* the last QP's input was finite (before the clipping) */
  /* the step's fail-safe (ar_failsafe.c) */
  int fallback_active, fallback_episodes, consecutive_failures, successes, safety_handovers, last_unsafe;
  ar_hold_t hold;
  /* ar_trust: the last trusted measurement (its stamp, s; position, m; velocity, m/s) */
  int has_trusted;
  double trusted_stamp, trusted_p[3], trusted_v[3];
  /* the paper's planner (ar_planner.c): the governed reference, the expansion's work */
  double plan_ref[3];
  int has_plan_ref;
  long long int plan_iw[AR_PLAN_SZ_IW + 1];
  double plan_w[AR_PLAN_SZ_W + 1];
};

static void ar_failsafe_init(ar_controller *c);

/* The controllers alive in this process (ar_create to ar_destroy): a call with any other pointer (NULL, destroyed,
 * never created) is AR_BAD_INPUT, never a dereference. */
#define AR_MAX_LIVE 64
static ar_controller *ar_live_set[AR_MAX_LIVE];

static int ar_live(const ar_controller *c) {
  if (!c) return 0;
  for (int i = 0; i < AR_MAX_LIVE; i++)
    if (__atomic_load_n(&ar_live_set[i], __ATOMIC_ACQUIRE) == c) return 1;
  return 0;
}

static int ar_finite(const double *v, int n) {
  for (int i = 0; i < n; i++)
    if (!isfinite(v[i])) return 0;
  return 1;
}

static void ar_hold(double *u) {
  for (int i = 0; i < AR_NR; i++) u[i] = 0.0;
}

ar_controller *ar_create(void) {
  ar_controller *c = calloc(1, sizeof(ar_controller));
  if (!c) return NULL;
  c->rti = rti_create(AR_ENGINE_SETTINGS, AR_IDXBX, AR_LBX, AR_UBX, AR_LBU, AR_UBU);
  if (!c->rti) {
    free(c);
    return NULL;
  }
  ar_failsafe_init(c);
  for (int i = 0; i < AR_MAX_LIVE; i++) {
    ar_controller *none = NULL;
    if (__atomic_compare_exchange_n(&ar_live_set[i], &none, c, 0, __ATOMIC_ACQ_REL, __ATOMIC_ACQUIRE)) return c;
  }
  rti_free(c->rti); /* AR_MAX_LIVE controllers alive already */
  free(c);
  return NULL;
}

void ar_destroy(ar_controller *c) {
  if (!c) return;
  for (int i = 0; i < AR_MAX_LIVE; i++) {
    ar_controller *mine = c;
    if (__atomic_compare_exchange_n(&ar_live_set[i], &mine, NULL, 0, __ATOMIC_ACQ_REL, __ATOMIC_ACQUIRE)) {
      rti_free(c->rti); /* alive until now: freed once; a second ar_destroy finds it gone and does nothing */
      free(c);
      return;
    }
  }
}

/* The OCP's initial state: the plant state and, with the exact input-rate cost, the last input. */
static void ar_initial_state(ar_controller *c, const double *x, const double *u_prev) {
  for (int i = 0; i < AR_NX; i++) c->xa0[i] = x[i];
  if (AR_EXACT_INPUT_RATE)
    for (int i = 0; i < AR_NR; i++) c->xa0[AR_NX + i] = u_prev[i];
}

ar_status ar_reset(ar_controller *c, const double *xa0) {
  if (!ar_live(c) || !xa0 || !ar_finite(xa0, AR_NXA)) return AR_BAD_INPUT;
  for (int k = 0; k <= AR_N; k++)
    for (int i = 0; i < AR_NXA; i++) c->Xb[k * AR_NXA + i] = xa0[i];
  for (int i = 0; i < AR_N * RTI_NW; i++) c->Wb[i] = 0.0;
  rti_set_plan(c->rti, c->Xb, c->Wb);
  c->initialized = 1;
  return AR_OK;
}

ar_status ar_guess(ar_controller *c, double *Xb) {
  if (!ar_live(c) || !Xb) return AR_BAD_INPUT;
  if (!c->initialized) return AR_NOT_PREPARED;
  rti_get_plan(c->rti, c->Xb, c->Wb, c->X, c->W);
  memcpy(Xb, c->Xb, sizeof(c->Xb));
  return AR_OK;
}

ar_status ar_failsafe_state(const ar_controller *c, int *state) {
  if (!ar_live(c) || !state) return AR_BAD_INPUT;
  state[0] = c->fallback_active;
  state[1] = c->fallback_episodes;
  state[2] = c->safety_handovers;
  state[3] = c->last_unsafe;
  return AR_OK;
}

ar_status ar_prepare(ar_controller *c, const double *P, const double *u_prev, const double *x_guess) {
  if (!ar_live(c) || !P || !u_prev || !ar_finite(P, AR_NP * (AR_N + 1)) || !ar_finite(u_prev, AR_NR)) return AR_BAD_INPUT;
  if (!c->initialized) {
    if (!x_guess || !ar_finite(x_guess, AR_NX)) return AR_BAD_INPUT;
    ar_initial_state(c, x_guess, u_prev);
    ar_reset(c, c->xa0);
  }
  memcpy(c->P, P, sizeof(c->P));
  if (!AR_EXACT_INPUT_RATE) { /* the lagged rows: the last input at stage 0, the plan's inputs after */
    rti_get_plan(c->rti, c->Xb, c->Wb, c->X, c->W);
    for (int j = 0; j < AR_NR; j++) {
      int row = AR_UPREV_ROWS[j];
      c->P[row] = u_prev[j];
      for (int k = 1; k <= AR_N; k++) c->P[k * AR_NP + row] = c->Wb[(k - 1) * RTI_NW + j];
    }
  }
  rti_prepare(c->rti, c->P);
  return AR_OK;
}

ar_status ar_feedback(ar_controller *c, const double *x, const double *u_prev, int shift, double *u, ar_info *info) {
  rti_info ri;
  ar_info none = {0, -2, 0, 0, 0.0, 0};
  if (info) *info = none;
  if (!u) return AR_BAD_INPUT;
  if (!ar_live(c) || !x || !u_prev || !ar_finite(x, AR_NX) || !ar_finite(u_prev, AR_NR)) {
    ar_hold(u);
    return AR_BAD_INPUT;
  }
  if (!c->initialized) {
    ar_hold(u);
    return AR_NOT_PREPARED;
  }
  ar_initial_state(c, x, u_prev);
  rti_feedback(c->rti, c->xa0, shift, u, &ri);
  int finite = ar_finite(u, AR_NR);
  c->last_input_finite = finite;
  int ok = ri.ok && finite;
  for (int i = 0; i < AR_NR; i++) { /* numpy's nan_to_num, then the motor accelerations' bounds */
    double v = u[i];
    if (isnan(v)) v = 0.0;
    else if (isinf(v)) v = v > 0 ? DBL_MAX : -DBL_MAX;
    v = rti_clip(v, AR_OMEGA_DOT_MIN[i], AR_OMEGA_DOT_MAX[i]);
    /* the first stage's rotor-speed bounds, exact in the input (Omega_1 = Omega_0 + u Ts) */
    double speed = x[AR_OMEGA_OFFSET + i];
    double lo = rti_clip((AR_OMEGA_MIN[i] - speed) / AR_TS, AR_OMEGA_DOT_MIN[i], AR_OMEGA_DOT_MAX[i]);
    double hi = rti_clip((AR_OMEGA_MAX[i] - speed) / AR_TS, AR_OMEGA_DOT_MIN[i], AR_OMEGA_DOT_MAX[i]);
    double top = lo > hi ? lo : hi;
    v = v > lo ? v : lo;
    u[i] = v < top ? v : top;
  }
  if (info) {
    info->ok = ok;
    info->qp_status = ri.status;
    info->iterations = ri.iter;
    info->capped = ri.capped;
    info->slack_max = ok ? (ri.slack_max > 0.0 ? ri.slack_max : 0.0) : NAN;
  }
  return ok ? AR_OK : AR_QP_FAILED;
}

ar_status ar_trust(ar_controller *c, double t, double stamp, const double *p, const double *v, int *why) {
  int reason = AR_TRUSTED;
  if (!ar_live(c) || !p || !v) reason = AR_UNTRUSTED_BAD_INPUT;
  else if (!ar_finite(p, 3) || !ar_finite(v, 3)) reason = AR_UNTRUSTED_NOT_FINITE;
  else if (!isfinite(stamp) || !isfinite(t)) reason = AR_UNTRUSTED_STAMP;
  else if (stamp > t + AR_HOLD_AFTER_S) reason = AR_UNTRUSTED_AHEAD; /* two processes' clocks may differ this much */
  else if (c->has_trusted) { /* the reach from the last trusted one (control.relay_step.beyond_reach) */
    double dt = stamp - c->trusted_stamp, dp = 0.0, dv = 0.0;
    if (dt < 0.0) reason = AR_UNTRUSTED_BACKWARDS;
    else {
      for (int i = 0; i < 3; i++) {
        double e = p[i] - c->trusted_p[i] - c->trusted_v[i] * dt, f = v[i] - c->trusted_v[i];
        dp += e * e, dv += f * f;
      }
      if (sqrt(dp) > 0.5 * AR_ACCEL_MAX * dt * dt + AR_JUMP_TOLERANCE_M) reason = AR_UNTRUSTED_POSITION_JUMP;
      else if (sqrt(dv) > AR_ACCEL_MAX * dt + AR_JUMP_TOLERANCE_M_S) reason = AR_UNTRUSTED_VELOCITY_JUMP;
    }
  }
  if (why) *why = reason;
  if (reason != AR_TRUSTED) return AR_BAD_INPUT;
  c->has_trusted = 1, c->trusted_stamp = stamp;
  memcpy(c->trusted_p, p, sizeof c->trusted_p);
  memcpy(c->trusted_v, v, sizeof c->trusted_v);
  return AR_OK;
}

/* An autopilot's setpoints (aerorelay's RelayStep.command): the model's RK4 step over one control period and the
 * acceleration there, CasADi-generated in src/aerorelay_model.c. */
extern int ar_model_setpoint(const double **arg, double **res, long long int *iw, double *w, int mem);

ar_status ar_setpoint(const double *x, const double *u, const double *a_ext, double *x1, double *acc) {
  if (!x1 || !acc) return AR_BAD_INPUT;
  if (!x || !u || !a_ext) {
    for (int i = 0; i < AR_NX; i++) x1[i] = x ? x[i] : NAN;
    for (int i = 0; i < 3; i++) acc[i] = 0.0;
    return AR_BAD_INPUT;
  }
  if (!ar_finite(x, AR_NX) || !ar_finite(u, AR_NR) || !ar_finite(a_ext, 3)) {
    memcpy(x1, x, sizeof(double) * AR_NX);
    for (int i = 0; i < 3; i++) acc[i] = 0.0;
    return AR_BAD_INPUT;
  }
  long long int iw[AR_MODEL_SZ_IW + 1];
  double w[AR_MODEL_SZ_W + 1];
  const double *arg[AR_MODEL_SZ_ARG + 1] = {x, u, a_ext};
  double *res[AR_MODEL_SZ_RES + 1] = {x1, acc};
  ar_model_setpoint(arg, res, iw, w, 0);
  if (!ar_finite(x1, AR_NX) || !ar_finite(acc, 3)) { /* a finite but absurd command (u = 1e308): no setpoint */
    memcpy(x1, x, sizeof(double) * AR_NX);
    for (int i = 0; i < 3; i++) acc[i] = 0.0;
    return AR_BAD_INPUT;
  }
  return AR_OK;
}
