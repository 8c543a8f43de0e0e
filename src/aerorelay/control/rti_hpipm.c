/* aerorelay real-time-iteration engine: one RTI step of the NMPC in one C call.
 *
 * Appended by aerorelay.control.hpipm_rti to the CasADi-generated C code of the per-stage
 * linearization ``stage_lin(xa, w, p) -> (xn, A, B, H, g[, h, Jh])`` and of the terminal one
 * ``term_lin(xa, p) -> (H, g)`` (dense outputs, column-major), compiled with the dimensions as
 * macros (RTI_N, RTI_NX, RTI_NW, RTI_NR, RTI_NP, RTI_NBX, RTI_CONSTRAINED, RTI_MU_INDEX) and
 * linked against the HPIPM and BLASFEO libraries shipped in CasADi's wheel.
 *
 * The QP is the one of ``conic_route.build_preparation`` in HPIPM's native stage form, with two
 * variables removed that the CasADi route keeps fixed by equal bounds: the initial state step
 * (eliminated: b_0 = A_0 dx_0 + gap_0, r_0 += S_0 dx_0) and the stage-0 slack (fixed to 0).
 * HPIPM's structures are created once; each step linearizes, optionally partially condenses
 * (to the runtime setting n2 < N stages), runs the IPM, expands, applies the step and shifts
 * the plan.
 */
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <time.h>

#include <blasfeo_d_aux.h>
#include <hpipm_d_ocp_qp_dim.h>
#include <hpipm_d_ocp_qp.h>
#include <hpipm_d_ocp_qp_sol.h>
#include <hpipm_d_ocp_qp_ipm.h>
#include <hpipm_d_part_cond.h>

#define RTI_NZ (RTI_NX + RTI_NW)
#define RTI_NU (RTI_NR + RTI_CONSTRAINED) /* stage inputs for k >= 1 (slack last) */
#define RTI_BIG 1e8

typedef struct {
  int n2, iter_max, warm_start, ric_alg, cold; /* cold: no usable multipliers yet */
  double tol_comp, reg;
  int idxbx[RTI_NBX], idxbu[RTI_NU];
  double lbx[RTI_NBX], ubx[RTI_NBX], lbu[RTI_NR], ubu[RTI_NR];
  double Xb[(RTI_N + 1) * RTI_NX], Wb[RTI_N * RTI_NW]; /* linearization point (the guess) */
  double X[(RTI_N + 1) * RTI_NX], W[RTI_N * RTI_NW];   /* last solution, before the shift */
  /* stage buffers */
  double xn[RTI_NX], A[RTI_NX * RTI_NX], B[RTI_NX * RTI_NW], H[RTI_NZ * RTI_NZ], g[RTI_NZ];
  double h[1], Jh[RTI_NZ], Q[RTI_NX * RTI_NX], S[RTI_NU * RTI_NX], R[RTI_NU * RTI_NU];
  double b[RTI_NX], r[RTI_NU], lbxk[RTI_NBX], ubxk[RTI_NBX], lbuk[RTI_NU], ubuk[RTI_NU];
  double Cg[RTI_NX], Dg[RTI_NU], lg[1], ug[1], dx[RTI_NX], du[RTI_NU];
  /* CasADi work */
  const double **arg;
  double **res;
  long long *iw;
  double *w;
  /* HPIPM */
  int nx[RTI_N + 1], nu[RTI_N + 1], nbx[RTI_N + 1], nbu[RTI_N + 1], ng[RTI_N + 1], ns[RTI_N + 1];
  int block_size[RTI_N + 1];
  struct d_ocp_qp_dim dim, dim2;
  struct d_ocp_qp qp, qp2;
  struct d_ocp_qp_sol sol, sol2;
  struct d_part_cond_qp_arg cond_arg;
  struct d_part_cond_qp_ws cond_ws;
  struct d_ocp_qp_ipm_arg ipm_arg;
  struct d_ocp_qp_ipm_ws ipm_ws;
  void *blocks[20];
  int nblocks;
} rti_mem;

static void *rti_alloc(rti_mem *m, size_t size) {
  void *p = calloc(1, size + 64);
  m->blocks[m->nblocks++] = p;
  return (void *)(((size_t)p + 63) & ~(size_t)63); /* BLASFEO wants aligned memory */
}

static double rti_now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

static double rti_clip(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }

/* settings: n2, iter_max, warm_start, tol_comp, reg, ric_alg; bounds: idxbx, lbx, ubx (k >= 1), lbu, ubu. */
void rti_free(rti_mem *m);

rti_mem *rti_create(const double *settings, const int *idxbx, const double *lbx, const double *ubx,
                    const double *lbu, const double *ubu) {
  rti_mem *m = (rti_mem *)calloc(1, sizeof(rti_mem));
  int N = RTI_N, k, i;
  long long sz_arg, sz_res, sz_iw, sz_w, sz_w2;
  m->n2 = (int)settings[0];
  m->iter_max = (int)settings[1];
  m->warm_start = (int)settings[2];
  m->tol_comp = settings[3];
  m->reg = settings[4];
  m->ric_alg = (int)settings[5];
  m->cold = 1;
  for (i = 0; i < RTI_NBX; i++) { m->idxbx[i] = idxbx[i]; m->lbx[i] = lbx[i]; m->ubx[i] = ubx[i]; }
  for (i = 0; i < RTI_NR; i++) { m->lbu[i] = lbu[i]; m->ubu[i] = ubu[i]; }
  for (i = 0; i < RTI_NU; i++) m->idxbu[i] = i;
  long long sz_arg2, sz_res2, sz_iw2;
  stage_lin_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
  term_lin_work(&sz_arg2, &sz_res2, &sz_iw2, &sz_w2);
#define RTI_MAX(a, b) ((a) > (b) ? (a) : (b))
  m->arg = (const double **)rti_alloc(m, sizeof(double *) * (size_t)(RTI_MAX(sz_arg, sz_arg2) + 8));
  m->res = (double **)rti_alloc(m, sizeof(double *) * (size_t)(RTI_MAX(sz_res, sz_res2) + 8));
  m->iw = (long long *)rti_alloc(m, sizeof(long long) * (size_t)(RTI_MAX(sz_iw, sz_iw2) + 1));
  m->w = (double *)rti_alloc(m, sizeof(double) * (size_t)(RTI_MAX(sz_w, sz_w2) + 1));
  for (k = 0; k <= N; k++) {
    m->nx[k] = k == 0 ? 0 : RTI_NX;
    m->nu[k] = k == N ? 0 : (k == 0 ? RTI_NR : RTI_NU);
    m->nbx[k] = k == 0 ? 0 : RTI_NBX;
    m->nbu[k] = m->nu[k];
    m->ng[k] = (RTI_CONSTRAINED && k >= 1 && k < N) ? 1 : 0;
    m->ns[k] = 0;
  }
  d_ocp_qp_dim_create(N, &m->dim, rti_alloc(m, d_ocp_qp_dim_memsize(N)));
  d_ocp_qp_dim_set_all(m->nx, m->nu, m->nbx, m->nbu, m->ng, m->ns, &m->dim);
  d_ocp_qp_create(&m->dim, &m->qp, rti_alloc(m, d_ocp_qp_memsize(&m->dim)));
  d_ocp_qp_sol_create(&m->dim, &m->sol, rti_alloc(m, d_ocp_qp_sol_memsize(&m->dim)));
  if (m->n2 < N) {
    d_ocp_qp_dim_create(m->n2, &m->dim2, rti_alloc(m, d_ocp_qp_dim_memsize(m->n2)));
    d_part_cond_qp_compute_block_size(N, m->n2, m->block_size);
    d_part_cond_qp_compute_dim(&m->dim, m->block_size, &m->dim2);
    d_part_cond_qp_arg_create(m->n2, &m->cond_arg, rti_alloc(m, d_part_cond_qp_arg_memsize(m->n2)));
    d_part_cond_qp_arg_set_default(&m->cond_arg);
    d_part_cond_qp_ws_create(&m->dim, m->block_size, &m->dim2, &m->cond_arg, &m->cond_ws,
                             rti_alloc(m, d_part_cond_qp_ws_memsize(&m->dim, m->block_size, &m->dim2, &m->cond_arg)));
    d_ocp_qp_create(&m->dim2, &m->qp2, rti_alloc(m, d_ocp_qp_memsize(&m->dim2)));
    d_ocp_qp_sol_create(&m->dim2, &m->sol2, rti_alloc(m, d_ocp_qp_sol_memsize(&m->dim2)));
  }
  {
    struct d_ocp_qp_dim *d = m->n2 < N ? &m->dim2 : &m->dim;
    d_ocp_qp_ipm_arg_create(d, &m->ipm_arg, rti_alloc(m, d_ocp_qp_ipm_arg_memsize(d)));
    d_ocp_qp_ipm_arg_set_default(SPEED_ABS, &m->ipm_arg);
    d_ocp_qp_ipm_arg_set_iter_max(&m->iter_max, &m->ipm_arg);
    d_ocp_qp_ipm_arg_set_tol_comp(&m->tol_comp, &m->ipm_arg);
    d_ocp_qp_ipm_arg_set_warm_start(&m->warm_start, &m->ipm_arg);
    d_ocp_qp_ipm_arg_set_ric_alg(&m->ric_alg, &m->ipm_arg);
    d_ocp_qp_ipm_ws_create(d, &m->ipm_arg, &m->ipm_ws, rti_alloc(m, d_ocp_qp_ipm_ws_memsize(d, &m->ipm_arg)));
  }
  /* one-sided constraints: the slack's upper bound and the alignment row's upper bound are masked */
  for (k = 0; k < N; k++) d_ocp_qp_set_idxbu(k, m->idxbu, &m->qp);
  for (k = 1; k <= N; k++) d_ocp_qp_set_idxbx(k, m->idxbx, &m->qp);
  if (RTI_CONSTRAINED) {
    double mask[RTI_NU];
    for (i = 0; i < RTI_NU; i++) mask[i] = i < RTI_NR ? 1.0 : 0.0;
    for (k = 1; k < N; k++) {
      double zero = 0.0;
      d_ocp_qp_set_ubu_mask(k, mask, &m->qp);
      d_ocp_qp_set_ug_mask(k, &zero, &m->qp);
    }
  }
  return m;
}

/* Whether the AVX2 kernels of blasfeo_avx2.c have run in this process (-1: not compiled in). */
int rti_simd_kernels_ran(void) {
#ifdef RTI_SIMD
  return __atomic_load_n(&aerorelay_simd_kernels_ran, __ATOMIC_RELAXED);
#else
  return -1;
#endif
}

void rti_free(rti_mem *m) {
  int i;
  if (!m) return;
  for (i = 0; i < m->nblocks; i++) free(m->blocks[i]);
  free(m);
}

void rti_set_plan(rti_mem *m, const double *Xb, const double *Wb) {
  memcpy(m->Xb, Xb, sizeof(m->Xb));
  memcpy(m->Wb, Wb, sizeof(m->Wb));
  m->cold = 1;
}

void rti_get_plan(rti_mem *m, double *Xb, double *Wb, double *X, double *W) {
  memcpy(Xb, m->Xb, sizeof(m->Xb));
  memcpy(Wb, m->Wb, sizeof(m->Wb));
  memcpy(X, m->X, sizeof(m->X));
  memcpy(W, m->W, sizeof(m->W));
}

/* State bounds of stage k >= 1 as bounds on the step from the guess xb. */
static void rti_set_state_bounds(rti_mem *m, int k, const double *xb) {
  int i;
  for (i = 0; i < RTI_NBX; i++) {
    m->lbxk[i] = m->lbx[i] - xb[m->idxbx[i]];
    m->ubxk[i] = m->ubx[i] - xb[m->idxbx[i]];
  }
  d_ocp_qp_set_lbx(k, m->lbxk, &m->qp);
  d_ocp_qp_set_ubx(k, m->ubxk, &m->qp);
}

/* Fill stage k (< N) of HPIPM's QP from the stage linearization at (Xb_k, Wb_k, P_k). */
static void rti_fill_stage(rti_mem *m, int k, const double *P, const double *dx0) {
  int i, j, nu = k == 0 ? RTI_NR : RTI_NU;
  const double *xb = m->Xb + k * RTI_NX, *wb = m->Wb + k * RTI_NW;
  m->arg[0] = xb; m->arg[1] = wb; m->arg[2] = P + k * RTI_NP;
  m->res[0] = m->xn; m->res[1] = m->A; m->res[2] = m->B; m->res[3] = m->H; m->res[4] = m->g;
  m->res[5] = m->h; m->res[6] = m->Jh;
  stage_lin(m->arg, m->res, m->iw, m->w, 0);
  for (i = 0; i < RTI_NX; i++) m->b[i] = m->xn[i] - m->Xb[(k + 1) * RTI_NX + i]; /* gap */
  for (j = 0; j < nu; j++) {                                                     /* R, S, r */
    for (i = 0; i < nu; i++) m->R[i + j * nu] = m->H[(RTI_NX + i) + (RTI_NX + j) * RTI_NZ] + (i == j ? m->reg : 0.0);
    m->r[j] = m->g[RTI_NX + j];
  }
  if (k == 0) { /* eliminate dx_0: b_0 += A dx_0, r_0 += S_0 dx_0 */
    for (j = 0; j < RTI_NX; j++)
      for (i = 0; i < RTI_NX; i++) m->b[i] += m->A[i + j * RTI_NX] * dx0[j];
    for (j = 0; j < RTI_NX; j++)
      for (i = 0; i < nu; i++) m->r[i] += m->H[(RTI_NX + i) + j * RTI_NZ] * dx0[j];
  } else {
    for (j = 0; j < RTI_NX; j++) {
      for (i = 0; i < RTI_NX; i++) m->Q[i + j * RTI_NX] = m->H[i + j * RTI_NZ] + (i == j ? m->reg : 0.0);
      for (i = 0; i < nu; i++) m->S[i + j * nu] = m->H[(RTI_NX + i) + j * RTI_NZ];
    }
    d_ocp_qp_set_A(k, m->A, &m->qp);
    d_ocp_qp_set_Q(k, m->Q, &m->qp);
    d_ocp_qp_set_S(k, m->S, &m->qp);
    d_ocp_qp_set_q(k, m->g, &m->qp);
    rti_set_state_bounds(m, k, xb);
  }
  d_ocp_qp_set_B(k, m->B, &m->qp); /* first nu columns of the column-major B */
  d_ocp_qp_set_b(k, m->b, &m->qp);
  d_ocp_qp_set_R(k, m->R, &m->qp);
  d_ocp_qp_set_r(k, m->r, &m->qp);
  for (i = 0; i < RTI_NR; i++) { m->lbuk[i] = m->lbu[i] - wb[i]; m->ubuk[i] = m->ubu[i] - wb[i]; }
  if (nu > RTI_NR) { m->lbuk[RTI_NR] = -wb[RTI_NR]; m->ubuk[RTI_NR] = RTI_BIG; } /* slack >= 0 */
  d_ocp_qp_set_lbu(k, m->lbuk, &m->qp);
  d_ocp_qp_set_ubu(k, m->ubuk, &m->qp);
  if (RTI_CONSTRAINED && k >= 1) { /* alignment: Jh dz >= mu - h */
    for (i = 0; i < RTI_NX; i++) m->Cg[i] = m->Jh[i];
    for (i = 0; i < nu; i++) m->Dg[i] = m->Jh[RTI_NX + i];
    m->lg[0] = P[k * RTI_NP + RTI_MU_INDEX] - m->h[0];
    m->ug[0] = RTI_BIG;
    d_ocp_qp_set_C(k, m->Cg, &m->qp);
    d_ocp_qp_set_D(k, m->Dg, &m->qp);
    d_ocp_qp_set_lg(k, m->lg, &m->qp);
    d_ocp_qp_set_ug(k, m->ug, &m->qp);
  }
}

static void rti_fill_terminal(rti_mem *m, const double *P) {
  int j, N = RTI_N;
  const double *xb = m->Xb + N * RTI_NX;
  m->arg[0] = xb; m->arg[1] = P + N * RTI_NP;
  m->res[0] = m->Q; m->res[1] = m->b; /* reuse buffers: H_N, g_N */
  term_lin(m->arg, m->res, m->iw, m->w, 0);
  for (j = 0; j < RTI_NX; j++) m->Q[j + j * RTI_NX] += m->reg;
  d_ocp_qp_set_Q(N, m->Q, &m->qp);
  d_ocp_qp_set_q(N, m->b, &m->qp);
  rti_set_state_bounds(m, N, xb);
}

/* Shift the plan (X, W) one stage into the guess (Xb, Wb), repeating the last stage. */
static void rti_shift(rti_mem *m, const double *X, const double *W) {
  memmove(m->Xb, X + RTI_NX, sizeof(double) * RTI_N * RTI_NX);
  memcpy(m->Xb + RTI_N * RTI_NX, X + RTI_N * RTI_NX, sizeof(double) * RTI_NX);
  memmove(m->Wb, W + RTI_NW, sizeof(double) * (RTI_N - 1) * RTI_NW);
  memcpy(m->Wb + (RTI_N - 1) * RTI_NW, W + (RTI_N - 1) * RTI_NW, sizeof(double) * RTI_NW);
}

/* Run the IPM. warm_start 0: cold; 1: primal (the step is zero: the guess); 2: primal at the
 * guess plus the previous QP's multipliers and slacks. Returns HPIPM's status. */
static int rti_solve(rti_mem *m, struct d_ocp_qp *qp, struct d_ocp_qp_sol *sol, int warm_start, int *iter) {
  int k, status;
  if (warm_start >= 1)
    for (k = 0; k <= qp->dim->N; k++) blasfeo_dvecse(qp->dim->nu[k] + qp->dim->nx[k], 0.0, sol->ux + k, 0);
  d_ocp_qp_ipm_arg_set_warm_start(&warm_start, &m->ipm_arg);
  d_ocp_qp_ipm_solve(qp, sol, &m->ipm_arg, &m->ipm_ws);
  d_ocp_qp_ipm_get_status(&m->ipm_ws, &status);
  d_ocp_qp_ipm_get_iter(&m->ipm_ws, iter);
  return status;
}

/* One RTI step. xa0: measured (augmented) state; P: (NP, N+1) column-major parameters.
 * u: first input, clipped to its bounds. info: ok, hpipm status, iterations, slack max,
 * preparation ms, QP ms (condensing + IPM + expansion + update). Returns ok. */
int rti_step(rti_mem *m, const double *xa0, const double *P, int shift, double *u, double *info) {
  int N = RTI_N, k, i, status = 0, iter = 0, ok = 1;
  double t0 = rti_now_ms(), t1, dx0[RTI_NX], slack_max = 0.0;
  for (i = 0; i < RTI_NX; i++) dx0[i] = xa0[i] - m->Xb[i];
  for (k = 0; k < N; k++) rti_fill_stage(m, k, P, dx0);
  rti_fill_terminal(m, P);
  t1 = rti_now_ms();
  struct d_ocp_qp *qp = &m->qp;
  struct d_ocp_qp_sol *sol = &m->sol;
  if (m->n2 < N) {
    d_part_cond_qp_cond(&m->qp, &m->qp2, &m->cond_arg, &m->cond_ws);
    qp = &m->qp2;
    sol = &m->sol2;
  }
  status = rti_solve(m, qp, sol, m->cold ? 0 : m->warm_start, &iter);
  if (status != 0 && !m->cold && m->warm_start) { /* a warm start gone wrong: once more from cold */
    int iter2 = 0;
    status = rti_solve(m, qp, sol, 0, &iter2);
    iter += iter2;
  }
  if (m->n2 < N) d_part_cond_qp_expand_sol(&m->qp, &m->sol2, &m->sol, &m->cond_arg, &m->cond_ws);
  ok = status == 0;
  for (k = 0; k <= N && ok; k++) {
    int nu = m->nu[k];
    double *X = m->X + k * RTI_NX, *W = m->W + k * RTI_NW;
    const double *xb = m->Xb + k * RTI_NX, *wb = m->Wb + k * RTI_NW;
    if (k == 0) memcpy(m->dx, dx0, sizeof(dx0));
    else d_ocp_qp_sol_get_x(k, &m->sol, m->dx);
    for (i = 0; i < RTI_NX; i++) { X[i] = xb[i] + m->dx[i]; ok = ok && isfinite(X[i]); }
    if (k == N) break;
    d_ocp_qp_sol_get_u(k, &m->sol, m->du);
    for (i = 0; i < RTI_NW; i++) W[i] = i < nu ? wb[i] + m->du[i] : 0.0; /* fixed slacks are 0 */
    for (i = 0; i < nu; i++) ok = ok && isfinite(W[i]);
    if (RTI_CONSTRAINED && k >= 1 && W[RTI_NR] > slack_max) slack_max = W[RTI_NR];
  }
  m->cold = !ok;
  if (ok) {
    for (i = 0; i < RTI_NR; i++) u[i] = rti_clip(m->W[i], m->lbu[i], m->ubu[i]);
    if (shift) rti_shift(m, m->X, m->W);
    else { memcpy(m->Xb, m->X, sizeof(m->X)); memcpy(m->Wb, m->W, sizeof(m->W)); }
  } else { /* fallback: the guess is the previous plan shifted to now; apply its first input */
    for (i = 0; i < RTI_NR; i++) u[i] = rti_clip(isfinite(m->Wb[i]) ? m->Wb[i] : 0.0, m->lbu[i], m->ubu[i]);
    memcpy(m->X, m->Xb, sizeof(m->X));
    memcpy(m->W, m->Wb, sizeof(m->W));
    rti_shift(m, m->X, m->W);
    slack_max = NAN;
  }
  info[0] = ok;
  info[1] = status;
  info[2] = iter;
  info[3] = slack_max;
  info[4] = t1 - t0;
  info[5] = rti_now_ms() - t1;
  return ok;
}
