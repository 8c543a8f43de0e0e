/* aerorelay: the paper's planner in C (written by `aerorelay codegen` when the scenario's relay flies it).
 *
 * ar_plan is, for one relay and its source, what aerorelay's control step does before the NMPC:
 * planning.trajectory_generator.TrajectoryGenerator.update (the surrogate's second-order expansion, CasADi-generated in
 * src/aerorelay_planner.c; the Hessian's eigenvalue floor; the Newton step clipped to the workspace; eq. 17-19 for the
 * velocity and acceleration references; the reference governor), planning.base.ReferenceCheck (a non-finite reference
 * holds where the relay is; a position reference outside the workspace is clipped), and
 * control.relay.RelayController.parameters (the stage parameters: the governed reference extrapolated at v_ref, the
 * thrust direction rho_d of a_ref less the external acceleration, the source at constant acceleration over the
 * horizon, the separation's other vehicle: the source). Compiled after ar_failsafe.c in the same translation unit.
 */

extern int surrogate_expansion(const double **arg, double **res, long long int *iw, double *w, int mem);

static void ar_solve3(const double *A, const double *b, double *x) { /* A x = b, 3 x 3 row-major: LU, partial pivoting */
  double M[3][4];
  for (int i = 0; i < 3; i++) {
    for (int j = 0; j < 3; j++) M[i][j] = A[3 * i + j];
    M[i][3] = b[i];
  }
  for (int k = 0; k < 3; k++) {
    int p = k;
    for (int i = k + 1; i < 3; i++)
      if (fabs(M[i][k]) > fabs(M[p][k])) p = i;
    if (p != k)
      for (int j = 0; j < 4; j++) {
        double t = M[k][j];
        M[k][j] = M[p][j], M[p][j] = t;
      }
    for (int i = k + 1; i < 3; i++) {
      double l = M[i][k] / M[k][k];
      for (int j = k; j < 4; j++) M[i][j] -= l * M[k][j];
    }
  }
  for (int i = 2; i >= 0; i--) {
    double s = M[i][3];
    for (int j = i + 1; j < 3; j++) s -= M[i][j] * x[j];
    x[i] = s / M[i][i];
  }
}

/* The eigenvalue floor (planning.trajectory_generator.regularized): H (3 x 3, row-major, symmetrized) with every
 * eigenvalue raised to eig_floor times its largest magnitude (relative) or max(1, it) (the paper's); a cyclic Jacobi
 * eigen-decomposition. */
static void ar_regularized(const double *H, double *out) {
  double A[3][3], V[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) A[i][j] = 0.5 * (H[3 * i + j] + H[3 * j + i]);
  for (int sweep = 0; sweep < 50; sweep++) {
    double off = fabs(A[0][1]) + fabs(A[0][2]) + fabs(A[1][2]);
    if (off == 0.0) break;
    for (int p = 0; p < 2; p++)
      for (int q = p + 1; q < 3; q++) {
        if (fabs(A[p][q]) <= DBL_EPSILON * 1e-3 * (fabs(A[p][p]) + fabs(A[q][q]))) {
          A[p][q] = A[q][p] = 0.0;
          continue;
        }
        double theta = (A[q][q] - A[p][p]) / (2.0 * A[p][q]);
        double t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
        double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
        for (int k = 0; k < 3; k++) { /* A <- J' A J */
          double akp = A[k][p], akq = A[k][q];
          A[k][p] = c * akp - s * akq, A[k][q] = s * akp + c * akq;
        }
        for (int k = 0; k < 3; k++) {
          double apk = A[p][k], aqk = A[q][k];
          A[p][k] = c * apk - s * aqk, A[q][k] = s * apk + c * aqk;
        }
        for (int k = 0; k < 3; k++) {
          double vkp = V[k][p], vkq = V[k][q];
          V[k][p] = c * vkp - s * vkq, V[k][q] = s * vkp + c * vkq;
        }
      }
  }
  double lam[3] = {A[0][0], A[1][1], A[2][2]}, top = 0.0, low = INFINITY;
  for (int i = 0; i < 3; i++) {
    top = fabs(lam[i]) > top ? fabs(lam[i]) : top;
    low = lam[i] < low ? lam[i] : low;
  }
  /* relative to the largest eigenvalue, or the paper's: at least the floor itself (planning.trajectory_generator) */
  double floor_ = AR_EIG_FLOOR * (AR_RELATIVE_FLOOR || top > 1.0 ? top : 1.0);
  if (low >= floor_) { /* safely positive definite: H itself, unsymmetrized, as numpy returns it */
    memcpy(out, H, 9 * sizeof(double));
    return;
  }
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      double s = 0.0;
      for (int k = 0; k < 3; k++) s += V[i][k] * (lam[k] > floor_ ? lam[k] : floor_) * V[j][k];
      out[3 * i + j] = s;
    }
}

static void ar_clip_norm(const double *v, double limit, double *out) {
  double n = ar_norm3(v);
  for (int i = 0; i < 3; i++) out[i] = n <= limit ? v[i] : v[i] * (limit / n);
}

ar_status ar_plan(ar_controller *c, double t, const double *x, const double *src_p, const double *src_v,
                  const double *src_a, const double *jam_p, const double *jam_w, const double *a_ext, double *P) {
  if (!ar_live(c) || !x || !src_p || !src_v || !src_a || (AR_NJ > 0 && (!jam_p || !jam_w)) || !a_ext || !P)
    return AR_BAD_INPUT;
  if (!isfinite(t) || !ar_finite(x, AR_NX) || !ar_finite(src_p, 3) || !ar_finite(src_v, 3) || !ar_finite(src_a, 3) ||
      !ar_finite(jam_p, 3 * AR_NJ) || !ar_finite(jam_w, AR_NJ) || !ar_finite(a_ext, 3))
    return AR_BAD_INPUT;
  for (int i = 0; i < AR_NJ; i++)
    if (jam_w[i] < 0.0) return AR_BAD_INPUT; /* a power below zero is no jammer */
  double p_opt[3], p_ref[3], v_ref[3] = {0, 0, 0}, a_ref[3] = {0, 0, 0}, yaw = 0.0;
  /* the trajectory generator: eq. 17-19 at kappa = (relay, source), then the governor */
  double z[AR_PLAN_NZ], out[1 + 6 + 36];
  for (int i = 0; i < 3; i++) z[i] = x[i], z[3 + i] = src_p[i]; /* kappa = (relay, source); the base station baked */
  for (int i = 0; i < 3 * AR_NJ; i++) z[6 + i] = jam_p[i];
  for (int i = 0; i < AR_NJ; i++) z[6 + 3 * AR_NJ + i] = jam_w[i];
  const double *arg[AR_PLAN_SZ_ARG] = {z};
  double *res[AR_PLAN_SZ_RES] = {out};
  surrogate_expansion(arg, res, c->plan_iw, c->plan_w, 0);
  double f = out[0], *g = out + 1, *Hc = out + 7; /* H column-major, 6 x 6 */
  int finite = isfinite(f) && ar_finite(g, 3);
  for (int j = 0; j < 6; j++)
    for (int i = 0; i < 3; i++) finite &= isfinite(Hc[6 * j + i]);
  if (!c->has_plan_ref) {
    memcpy(c->plan_ref, x, 3 * sizeof(double));
    c->has_plan_ref = 1;
  }
  if (!finite) { /* a degenerate geometry: hold the last reference */
    memcpy(p_opt, c->plan_ref, sizeof p_opt);
    memcpy(p_ref, c->plan_ref, sizeof p_ref);
  } else {
    double H11[9], H11r[9], step[3], vd[3], ad[3];
    for (int i = 0; i < 3; i++)
      for (int j = 0; j < 3; j++) H11[3 * i + j] = Hc[6 * j + i];
    ar_regularized(H11, H11r);
    double col[3], Kcol[3][3]; /* K = H11r^-1 H12, by columns as numpy's solve */
    for (int j = 0; j < 3; j++) {
      for (int i = 0; i < 3; i++) col[i] = Hc[6 * (3 + j) + i];
      ar_solve3(H11r, col, Kcol[j]);
    }
    ar_solve3(H11r, g, step);
    for (int i = 0; i < 3; i++) {
      p_opt[i] = rti_clip(x[i] - step[i], AR_PLAN_LO[i], AR_PLAN_HI[i]);
      vd[i] = 0.0, ad[i] = 0.0;
      for (int j = 0; j < 3; j++) vd[i] += Kcol[j][i] * src_v[j], ad[i] += Kcol[j][i] * src_a[j];
      vd[i] = -vd[i], ad[i] = -ad[i];
    }
    /* the reference governor */
    double d[3], max_step = AR_GOVERNOR_SPEED * AR_PERIOD;
    for (int i = 0; i < 3; i++) d[i] = p_opt[i] - c->plan_ref[i];
    double n = ar_norm3(d);
    if (n > max_step)
      for (int i = 0; i < 3; i++) d[i] *= max_step / n;
    if (n > max_step)
      for (int i = 0; i < 3; i++) v_ref[i] = d[i] / AR_PERIOD;
    else
      ar_clip_norm(vd, AR_GOVERNOR_SPEED, v_ref);
    ar_clip_norm(ad, AR_MAX_REF_ACCEL, a_ref);
    for (int i = 0; i < 3; i++) c->plan_ref[i] += d[i];
    memcpy(p_ref, c->plan_ref, sizeof p_ref);
  }
  /* the reference check */
  if (!ar_finite(p_opt, 3) || !ar_finite(p_ref, 3) || !ar_finite(v_ref, 3) || !ar_finite(a_ref, 3)) {
    for (int i = 0; i < 3; i++) p_ref[i] = rti_clip(x[i], AR_WS_NMPC_MIN[i], AR_WS_NMPC_MAX[i]), v_ref[i] = a_ref[i] = 0.0;
    yaw = isfinite(x[5]) ? x[5] : 0.0;
  } else {
    for (int i = 0; i < 3; i++) p_ref[i] = rti_clip(p_ref[i], AR_WS_NMPC_MIN[i], AR_WS_NMPC_MAX[i]);
  }
  /* the stage parameters */
  double thrust[3];
  for (int i = 0; i < 3; i++) thrust[i] = (a_ref[i] - a_ext[i]) + (i == 2 ? AR_GRAVITY : 0.0);
  double nt = ar_norm3(thrust);
  memcpy(P, AR_P_TEMPLATE, sizeof(double) * AR_NP * (AR_N + 1));
  for (int k = 0; k <= AR_N; k++) {
    double *col = P + k * AR_NP, tk = AR_TK[k];
    for (int i = 0; i < 3; i++) {
      double src = src_p[i] + src_v[i] * tk + 0.5 * src_a[i] * (tk * tk);
      col[AR_ROW_P_REF + i] = p_ref[i] + v_ref[i] * tk;
      col[AR_ROW_V_REF + i] = v_ref[i];
      col[AR_ROW_RHO_D + i] = thrust[i] / nt;
      col[AR_ROW_P2 + i] = src;
      if (AR_ROW_P_OTHERS >= 0) col[AR_ROW_P_OTHERS + i] = src;
      if (AR_ROW_A_EXT >= 0) col[AR_ROW_A_EXT + i] = a_ext[i];
    }
    col[AR_ROW_PSI_REF] = yaw;
  }
  return AR_OK;
}
