/* aerorelay: the relay controller's step in C (written by `aerorelay codegen`, see its README.md).
 *
 * aerorelay.control.relay.RelayController.step: the flight-safety supervisor's envelope (control/supervisor.py), the
 * NMPC, and the fail-safe brake law (control/failsafe.py) that flies the relay to rest inside the workspace after
 * `AR_FAILURES_TO_FALLBACK` consecutive QP failures, at once on a state outside the envelope or on bad input; the
 * NMPC is tried from a fresh plan every step meanwhile and takes over after `AR_SUCCESSES_TO_RESUME` consecutive
 * successes from rest. The brake law's bounded least-squares allocation is SciPy's BVLS (scipy.optimize.lsq_linear,
 * method "bvls", tol 1e-10) step for step, each least-squares subproblem solved at minimum norm by a one-sided Jacobi
 * SVD (NumPy's lstsq solves the same problem by LAPACK's gelsd: equal to rounding). Compiled after ar_controller.c
 * in the same translation unit; nothing is allocated.
 */

static double ar_norm3(const double *v) { return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }
static double ar_dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void ar_cross3(const double *a, const double *b, double *o) {
  o[0] = a[1] * b[2] - a[2] * b[1];
  o[1] = a[2] * b[0] - a[0] * b[2];
  o[2] = a[0] * b[1] - a[1] * b[0];
}

/* Body-to-world rotation R = Rz(psi) Ry(theta) Rx(phi), row-major (models.geometry.rotation_zyx). */
static void ar_rotation_zyx(const double *eta, double R[9]) {
  double cf = cos(eta[0]), sf = sin(eta[0]), ct = cos(eta[1]), st = sin(eta[1]), cp = cos(eta[2]), sp = sin(eta[2]);
  R[0] = cp * ct, R[1] = cp * st * sf - sp * cf, R[2] = cp * st * cf + sp * sf;
  R[3] = sp * ct, R[4] = sp * st * sf + cp * cf, R[5] = sp * st * cf - cp * sf;
  R[6] = -st, R[7] = ct * sf, R[8] = ct * cf;
}

/* ---- the supervisor's envelope ---- */

static double ar_obstacle_distance(int j, const double *p) { /* signed distance to obstacle j itself (no margin) */
  const double *o = AR_OBST_DATA + 6 * j;
  if (AR_OBST_KIND[j] == 0) { /* box lo (3), hi (3) */
    double out = 0.0, qmax = -INFINITY;
    for (int i = 0; i < 3; i++) {
      double c = 0.5 * (o[i] + o[3 + i]), h = 0.5 * (o[3 + i] - o[i]);
      double q = fabs(p[i] - c) - h;
      out += q > 0.0 ? q * q : 0.0;
      qmax = q > qmax ? q : qmax;
    }
    return sqrt(out) + (qmax < 0.0 ? qmax : 0.0);
  }
  /* vertical cylinder: centre (2), radius, z_min, z_max */
  double dx = p[0] - o[0], dy = p[1] - o[1];
  double a = sqrt(dx * dx + dy * dy) - o[2];
  double zc = 0.5 * (o[3] + o[4]), hz = 0.5 * (o[4] - o[3]);
  double b = fabs(p[2] - zc) - hz;
  double am = a > 0.0 ? a : 0.0, bm = b > 0.0 ? b : 0.0, ab = a > b ? a : b;
  return hypot(am, bm) + (ab < 0.0 ? ab : 0.0);
}

/* How many of the envelope's limits the state violates (0: inside). */
static int ar_violations(const double *x) {
  if (!AR_SUPERVISOR) return 0;
  if (!ar_finite(x, AR_NX)) return 1;
  int n = 0;
  const double *p = x, *eta = x + 3, *v = x + 6, *w = x + 9, *speeds = x + AR_OMEGA_OFFSET;
  double outside = -INFINITY;
  for (int i = 0; i < 3; i++) {
    double e = AR_WS_MIN[i] - p[i] > p[i] - AR_WS_MAX[i] ? AR_WS_MIN[i] - p[i] : p[i] - AR_WS_MAX[i];
    outside = e > outside ? e : outside;
  }
  n += outside > AR_BOX_TOLERANCE;
  n += p[2] < AR_GROUND_Z;
  for (int j = 0; j < AR_N_OBST; j++) n += ar_obstacle_distance(j, p) < 0.0;
  n += cos(eta[0]) * cos(eta[1]) < AR_COS_MAX_TILT;
  n += ar_norm3(v) > AR_MAX_SPEED;
  double rate = fabs(w[0]) > fabs(w[1]) ? fabs(w[0]) : fabs(w[1]);
  rate = fabs(w[2]) > rate ? fabs(w[2]) : rate;
  n += rate > AR_MAX_BODY_RATE;
  double lo = speeds[0], hi = speeds[0];
  for (int i = 1; i < AR_NR; i++) {
    lo = speeds[i] < lo ? speeds[i] : lo;
    hi = speeds[i] > hi ? speeds[i] : hi;
  }
  n += lo < 0.99 * AR_OMEGA_MIN[0] || hi > 1.01 * AR_OMEGA_MAX[0];
  return n;
}

static int ar_at_rest(const double *x) { /* slow and nearly level: where the NMPC may take over again */
  double tilt = acos(rti_clip(cos(x[3]) * cos(x[4]), -1.0, 1.0)) * (180.0 / 3.141592653589793);
  return ar_norm3(x + 6) < AR_REST_SPEED && tilt < AR_REST_TILT_DEG;
}

/* ---- the brake law ---- */

/* Where and how stiffly to stop from p at velocity v (NULL: rest) and attitude eta (NULL: level): BrakeLaw.hold. */
static ar_hold_t ar_hold_at(const double *p, const double *v, const double *eta) {
  ar_hold_t h;
  double vel[3] = {0.0, 0.0, 0.0};
  if (v && ar_finite(v, 3)) memcpy(vel, v, sizeof vel);
  h.upright = 1;
  if (eta && ar_finite(eta, 3)) h.upright = cos(eta[1]) * cos(eta[0]) > AR_COS_RECOVERY;
  double speed = ar_norm3(vel);
  h.freq = AR_BRAKE_FREQ;
  if (!h.upright || speed < 1e-9) {
    for (int i = 0; i < 3; i++) h.point[i] = rti_clip(p[i], AR_BRAKE_LO[i], AR_BRAKE_HI[i]);
    return h;
  }
  double need = -INFINITY;
  for (int i = 0; i < 3; i++) {
    double room = (vel[i] > 0.0 ? AR_BRAKE_HI[i] - p[i] : p[i] - AR_BRAKE_LO[i]) - fabs(vel[i]) * AR_BRAKE_LAG;
    double n = fabs(vel[i]) / (room > 1e-3 ? room : 1e-3);
    need = n > need ? n : need;
  }
  double cap = AR_BRAKE_MAX_FREQ < AR_BRAKE_MAX_ACCEL / speed ? AR_BRAKE_MAX_FREQ : AR_BRAKE_MAX_ACCEL / speed;
  cap = AR_BRAKE_FREQ > cap ? AR_BRAKE_FREQ : cap;
  h.freq = rti_clip(need, AR_BRAKE_FREQ, cap);
  for (int i = 0; i < 3; i++) h.point[i] = rti_clip(p[i] + vel[i] / h.freq, AR_BRAKE_LO[i], AR_BRAKE_HI[i]);
  return h;
}

#define AR_M (6 + AR_NR) /* the allocation's rows: force (3), moment (3), a rotor's change each (its uniqueness) */

/* Minimum-norm least squares min |A[:, cols] z - b| (A: AR_M x AR_NR, row-major), singular values below rcond times
 * the largest dropped, as LAPACK's gelsd: a one-sided Jacobi SVD of the k columns. */
static void ar_lstsq(const double *A, const int *cols, int k, const double *b, double rcond, double *z) {
  double U[AR_M][AR_NR], V[AR_NR][AR_NR];
  for (int i = 0; i < AR_M; i++)
    for (int j = 0; j < k; j++) U[i][j] = A[i * AR_NR + cols[j]];
  for (int i = 0; i < k; i++)
    for (int j = 0; j < k; j++) V[i][j] = i == j;
  for (int sweep = 0; sweep < 100; sweep++) {
    int rotated = 0;
    for (int p = 0; p < k - 1; p++)
      for (int q = p + 1; q < k; q++) {
        double alpha = 0.0, beta = 0.0, gamma = 0.0;
        for (int i = 0; i < AR_M; i++) {
          alpha += U[i][p] * U[i][p];
          beta += U[i][q] * U[i][q];
          gamma += U[i][p] * U[i][q];
        }
        if (gamma == 0.0 || fabs(gamma) <= DBL_EPSILON * sqrt(alpha * beta)) continue;
        rotated = 1;
        double zeta = (beta - alpha) / (2.0 * gamma);
        double t = (zeta >= 0.0 ? 1.0 : -1.0) / (fabs(zeta) + sqrt(1.0 + zeta * zeta));
        double cs = 1.0 / sqrt(1.0 + t * t), sn = cs * t;
        for (int i = 0; i < AR_M; i++) {
          double up = U[i][p], uq = U[i][q];
          U[i][p] = cs * up - sn * uq;
          U[i][q] = sn * up + cs * uq;
        }
        for (int i = 0; i < k; i++) {
          double vp = V[i][p], vq = V[i][q];
          V[i][p] = cs * vp - sn * vq;
          V[i][q] = sn * vp + cs * vq;
        }
      }
    if (!rotated) break;
  }
  double s2[AR_NR], smax = 0.0;
  for (int j = 0; j < k; j++) {
    s2[j] = 0.0;
    for (int i = 0; i < AR_M; i++) s2[j] += U[i][j] * U[i][j];
    smax = sqrt(s2[j]) > smax ? sqrt(s2[j]) : smax;
  }
  for (int j = 0; j < k; j++) z[j] = 0.0;
  for (int j = 0; j < k; j++) {
    if (!(sqrt(s2[j]) > rcond * smax)) continue;
    double ub = 0.0;
    for (int i = 0; i < AR_M; i++) ub += U[i][j] * b[i];
    double coef = ub / s2[j];
    for (int i = 0; i < k; i++) z[i] += coef * V[i][j];
  }
}

static double ar_kkt(const double *g, const double *on) { /* the largest violation of the KKT conditions */
  double m = -INFINITY;
  for (int i = 0; i < AR_NR; i++) {
    double v = on[i] == 0.0 ? fabs(g[i]) : g[i] * on[i];
    m = v > m ? v : m;
  }
  return m;
}

/* r = A x - b and g = A' r; returns 0.5 r'r */
static double ar_residual(const double *A, const double *b, const double *x, double *g) {
  double r[AR_M], cost = 0.0;
  for (int i = 0; i < AR_M; i++) {
    double s = 0.0;
    for (int j = 0; j < AR_NR; j++) s += A[i * AR_NR + j] * x[j];
    r[i] = s - b[i];
    cost += r[i] * r[i];
  }
  for (int j = 0; j < AR_NR; j++) {
    g[j] = 0.0;
    for (int i = 0; i < AR_M; i++) g[j] += A[i * AR_NR + j] * r[i];
  }
  return 0.5 * cost;
}

/* b - A (x on the active set): the right-hand side of the free variables' subproblem */
static void ar_free_rhs(const double *A, const double *b, const double *x, const int *active, double *out) {
  for (int i = 0; i < AR_M; i++) {
    double s = 0.0;
    for (int j = 0; j < AR_NR; j++) s += A[i * AR_NR + j] * (active[j] ? x[j] : 0.0);
    out[i] = b[i] - s;
  }
}

/* Bounded-variable least squares, min |A x - b| with lb <= x <= ub: scipy.optimize.lsq_linear(method="bvls", tol=1e-10)
 * (Stark and Parker 1995, as scipy/optimize/_lsq/bvls.py writes it). */
static void ar_bvls(const double *A, const double *b, const double *lb, const double *ub, double *x) {
  const double tol = 1e-10;
  int all[AR_NR], freeset[AR_NR], active[AR_NR], nf = 0;
  double on[AR_NR], g[AR_NR], z[AR_NR], rhs[AR_M], xf_old[AR_NR];
  for (int i = 0; i < AR_NR; i++) all[i] = i;
  ar_lstsq(A, all, AR_NR, b, DBL_EPSILON, x); /* lsq_linear's unbounded solution (lstsq, rcond=-1) */
  int inside = 1;
  for (int i = 0; i < AR_NR; i++) inside &= x[i] >= lb[i] && x[i] <= ub[i];
  if (inside) return;
  for (int i = 0; i < AR_NR; i++) {
    on[i] = 0.0;
    if (x[i] <= lb[i]) x[i] = lb[i], on[i] = -1.0;
    if (x[i] >= ub[i]) x[i] = ub[i], on[i] = 1.0;
    active[i] = on[i] != 0.0;
    if (!active[i]) freeset[nf++] = i;
  }
  double cost = ar_residual(A, b, x, g);
  int iteration = 0;
  while (nf > 0) { /* the initial free set, shrunk to the variables the subproblems keep inside their bounds */
    iteration++;
    ar_free_rhs(A, b, x, active, rhs);
    ar_lstsq(A, freeset, nf, rhs, DBL_EPSILON * (AR_M > nf ? AR_M : nf), z);
    int keep = 0, any = 0;
    for (int j = 0; j < nf; j++) {
      int i = freeset[j];
      if (z[j] < lb[i]) x[i] = lb[i], active[i] = 1, on[i] = -1.0, any = 1;
      else if (z[j] > ub[i]) x[i] = ub[i], active[i] = 1, on[i] = 1.0, any = 1;
      else x[i] = z[j], freeset[keep++] = i;
    }
    cost = ar_residual(A, b, x, g);
    if (!any) break;
    nf = keep;
  }
  int max_iter = AR_NR + iteration, status = 0;
  double optimality = ar_kkt(g, on);
  for (int it = iteration; it < max_iter; it++) { /* BVLS loop A */
    if (optimality < tol) status = 1;
    if (status) break;
    int move = 0;
    for (int i = 1; i < AR_NR; i++)
      if (g[i] * on[i] > g[move] * on[move]) move = i;
    on[move] = 0.0;
    for (;;) { /* loop B */
      nf = 0;
      for (int i = 0; i < AR_NR; i++) {
        active[i] = on[i] != 0.0;
        if (!active[i]) freeset[nf++] = i;
      }
      for (int j = 0; j < nf; j++) xf_old[j] = x[freeset[j]];
      ar_free_rhs(A, b, x, active, rhs);
      ar_lstsq(A, freeset, nf, rhs, DBL_EPSILON * (AR_M > nf ? AR_M : nf), z);
      /* the violators in scipy's order: those under their lower bounds, then those over their upper */
      int best = -1, best_lower = 0;
      double best_alpha = INFINITY;
      for (int pass = 0; pass < 2; pass++)
        for (int j = 0; j < nf; j++) {
          int i = freeset[j];
          int viol = pass == 0 ? z[j] < lb[i] : z[j] > ub[i];
          if (!viol) continue;
          double alpha = ((pass == 0 ? lb[i] : ub[i]) - xf_old[j]) / (z[j] - xf_old[j]);
          if (best < 0 || alpha < best_alpha) best = j, best_alpha = alpha, best_lower = pass == 0;
        }
      if (best >= 0) {
        for (int j = 0; j < nf; j++) {
          double xv = xf_old[j] * (1.0 - best_alpha);
          x[freeset[j]] = xv + best_alpha * z[j];
        }
        on[freeset[best]] = best_lower ? -1.0 : 1.0;
      } else {
        for (int j = 0; j < nf; j++) x[freeset[j]] = z[j];
        break;
      }
    }
    double cost_new = ar_residual(A, b, x, g);
    if (cost - cost_new < tol * cost) status = 2;
    cost = cost_new;
    optimality = ar_kkt(g, on);
  }
}

/* The brake law's motor accelerations (Hz/s) that bring x to rest at h (BrakeLaw.__call__). */
static void ar_brake(const double *x, const ar_hold_t *h, double *u) {
  if (!ar_finite(x, AR_NX)) {
    ar_hold(u);
    return;
  }
  const double *p = x, *eta = x + 3, *v = x + 6, *w = x + 9, *speeds = x + AR_OMEGA_OFFSET;
  double R[9], a[3], fd[3], b3[3], heading[3], b2[3], b1[3], eR[3];
  ar_rotation_zyx(eta, R);
  for (int i = 0; i < 3; i++) a[i] = -(h->freq * h->freq) * (p[i] - h->point[i]) - 2.0 * h->freq * v[i];
  double n = ar_norm3(a), a_max = h->upright ? AR_BRAKE_MAX_ACCEL : AR_BRAKE_RECOVERY_MAX_ACCEL;
  if (n > a_max)
    for (int i = 0; i < 3; i++) a[i] *= a_max / n;
  for (int i = 0; i < 3; i++) fd[i] = AR_MASS * (a[i] + (i == 2 ? AR_GRAVITY : 0.0));
  double nf = ar_norm3(fd);
  for (int i = 0; i < 3; i++) b3[i] = fd[i] / nf;
  double col0[3] = {R[0], R[3], R[6]}, col1[3] = {R[1], R[4], R[7]}, z[3] = {R[2], R[5], R[8]};
  memcpy(heading, fabs(ar_dot3(col0, b3)) < 0.95 ? col0 : col1, sizeof heading);
  ar_cross3(b3, heading, b2);
  double n2 = ar_norm3(b2);
  for (int i = 0; i < 3; i++) b2[i] /= n2;
  ar_cross3(b2, b3, b1);
  double Rd[9] = {b1[0], b2[0], b3[0], b1[1], b2[1], b3[1], b1[2], b2[2], b3[2]};
  double S[9]; /* Rd' R - R' Rd */
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      double s1 = 0.0, s2 = 0.0;
      for (int k = 0; k < 3; k++) {
        s1 += Rd[k * 3 + i] * R[k * 3 + j];
        s2 += R[k * 3 + i] * Rd[k * 3 + j];
      }
      S[i * 3 + j] = s1 - s2;
    }
  eR[0] = 0.5 * S[7], eR[1] = 0.5 * S[2], eR[2] = 0.5 * S[3];
  double zb = ar_dot3(z, b3);
  if (zb < 0.0) { /* beyond 90 deg: turn body z by the angle itself */
    double axis[3];
    ar_cross3(z, b3, axis);
    double na = ar_norm3(axis);
    for (int i = 0; i < 3; i++) axis[i] = na > 1e-6 ? axis[i] / na : col0[i];
    double angle = acos(rti_clip(zb, -1.0, 1.0));
    for (int i = 0; i < 3; i++) eR[i] = -angle * (R[i] * axis[0] + R[3 + i] * axis[1] + R[6 + i] * axis[2]);
  }
  const double *kR = h->upright ? AR_KR_UPRIGHT : AR_KR_RECOVERY, *kw = h->upright ? AR_KW_UPRIGHT : AR_KW_RECOVERY;
  double Jw[3], wJw[3], target[AR_M], rows[AR_M], Aw[AR_M * AR_NR], bw[AR_M], w2[AR_NR];
  for (int i = 0; i < 3; i++) Jw[i] = AR_J[3 * i] * w[0] + AR_J[3 * i + 1] * w[1] + AR_J[3 * i + 2] * w[2];
  ar_cross3(w, Jw, wJw);
  for (int i = 0; i < 3; i++) {
    double m1 = kR[3 * i] * eR[0] + kR[3 * i + 1] * eR[1] + kR[3 * i + 2] * eR[2];
    double m2 = kw[3 * i] * w[0] + kw[3 * i + 1] * w[1] + kw[3 * i + 2] * w[2];
    target[3 + i] = -m1 - m2 + wJw[i];
  }
  double w_force = 1.0;
  if (ar_dot3(b3, z) < 0.5) { /* far from the desired attitude: the moments first, half the weight */
    w_force = 0.1;
    target[0] = 0.0, target[1] = 0.0, target[2] = 0.5 * AR_MASS * AR_GRAVITY;
  } else {
    for (int i = 0; i < 3; i++) target[i] = R[i] * fd[0] + R[3 + i] * fd[1] + R[6 + i] * fd[2];
  }
  for (int i = 0; i < 6; i++) rows[i] = i < 3 ? w_force : AR_BRAKE_MOMENT_WEIGHT;
  for (int i = 0; i < 6; i++) {
    bw[i] = target[i] * rows[i];
    for (int j = 0; j < AR_NR; j++) Aw[i * AR_NR + j] = AR_ALLOC[i * AR_NR + j] * rows[i];
  }
  for (int i = 6; i < AR_M; i++) { /* the pull toward the rotors' speeds now: one solution (failsafe.BrakeGains) */
    bw[i] = AR_BRAKE_ALLOC_REG * speeds[i - 6] * speeds[i - 6];
    for (int j = 0; j < AR_NR; j++) Aw[i * AR_NR + j] = i - 6 == j ? AR_BRAKE_ALLOC_REG : 0.0;
  }
  ar_bvls(Aw, bw, AR_W2_MIN, AR_W2_MAX, w2);
  for (int i = 0; i < AR_NR; i++)
    u[i] = rti_clip((sqrt(w2[i]) - speeds[i]) / AR_BRAKE_TAU, AR_OMEGA_DOT_MIN[i], AR_OMEGA_DOT_MAX[i]);
}

/* ---- the step ---- */

static void ar_failsafe_init(ar_controller *c) { /* no episode yet; a hold, before one, at the origin clipped in */
  double origin[3] = {0.0, 0.0, 0.0};
  c->hold = ar_hold_at(origin, NULL, NULL);
  c->fallback_active = c->fallback_episodes = c->consecutive_failures = c->successes = c->safety_handovers = 0;
  c->last_unsafe = 0;
}

static void ar_enter_fallback(ar_controller *c, const double *x) {
  if (!c->fallback_active) {
    c->fallback_active = 1;
    c->fallback_episodes++;
    ar_hold_t *h = &c->hold;
    if (ar_finite(x, 3)) *h = ar_hold_at(x, x + 6, x + 3);
    else *h = ar_hold_at(h->point, NULL, NULL);
  }
  c->successes = 0;
  c->consecutive_failures = 0;
}

ar_status ar_step(ar_controller *c, const double *x, const double *u_prev, const double *P, int shift, double *u,
                  ar_info *info) {
  ar_info none = {0, -2, 0, 0, NAN, 0};
  ar_info mine;
  if (!info) info = &mine;
  *info = none;
  if (!u) return AR_BAD_INPUT;
  if (!ar_live(c) || !x) { /* no controller, or no state to brake from: hold */
    ar_hold(u);
    return AR_BAD_INPUT;
  }
  ar_hold_t *h = &c->hold;
  if (!u_prev || !P || !ar_finite(x, AR_NX) || !ar_finite(u_prev, AR_NR) || !ar_finite(P, AR_NP * (AR_N + 1))) {
    /* nothing to fly the NMPC from: the brake law (a held command, zero motor acceleration, when the state itself
     * is not finite) */
    ar_enter_fallback(c, x);
    ar_brake(x, h, u);
    info->fallback = 1;
    return AR_BAD_INPUT;
  }
  int unsafe = ar_violations(x);
  c->last_unsafe = unsafe;
  if (unsafe) { /* outside the safety envelope: the brake law flies, whatever the QP says */
    c->safety_handovers += !c->fallback_active;
    ar_enter_fallback(c, x);
  }
  if (c->fallback_active) { /* the NMPC tried from a fresh plan; it resumes after enough successes from rest */
    c->initialized = 0;
    ar_prepare(c, P, u_prev, x);
    ar_feedback(c, x, u_prev, shift, u, info);
    int handovers_left = !AR_SUPERVISOR || c->safety_handovers == 0 || c->safety_handovers < AR_MAX_HANDOVERS;
    int may_resume = !c->last_unsafe && (!AR_SUPERVISOR || ar_at_rest(x)) && handovers_left;
    c->successes = info->ok && may_resume ? c->successes + 1 : 0;
    if (c->successes >= AR_SUCCESSES_TO_RESUME) {
      c->fallback_active = 0;
      c->successes = 0;
      return AR_OK;
    }
    ar_brake(x, h, u);
    info->fallback = 1;
    return AR_FALLBACK;
  }
  ar_prepare(c, P, u_prev, x);
  ar_status s = ar_feedback(c, x, u_prev, shift, u, info);
  if (info->ok) {
    c->consecutive_failures = 0;
    return AR_OK;
  }
  c->consecutive_failures++;
  if (c->consecutive_failures >= AR_FAILURES_TO_FALLBACK || !c->last_input_finite) {
    ar_enter_fallback(c, x);
    ar_brake(x, h, u);
    info->fallback = 1;
    return AR_FALLBACK;
  }
  return s;
}
