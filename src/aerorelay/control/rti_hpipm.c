/* aerorelay real-time-iteration engine: the NMPC's RTI in two compiled calls.
 *
 * Two feedback modes (settings[6]): 0 = the feedback phase embeds the measured state and runs the
 * IPM; 1 = the preparation phase also runs the IPM at the predicted state (dx_0 = 0) and the
 * feedback applies the forward sensitivity of that solution in the direction (A_0 dx_0, S_0 dx_0)
 * (one Riccati sweep with the factorization at the solution, HPIPM's d_ocp_qp_ipm_sens_frw).
 *
 * Appended by aerorelay.control.hpipm_rti to the CasADi-generated C code of the per-stage
 * linearization ``stage_lin(xa, w, p) -> (xn, A, B, H, g, h, Jh)`` and of the terminal one
 * ``term_lin(xa, p) -> (H, g)`` (dense outputs, column-major), compiled with the dimensions as
 * macros (RTI_N, RTI_NX, RTI_NW = RTI_NR inputs + RTI_NS slacks, RTI_NG constraint rows h >= 0,
 * RTI_NP parameters, RTI_NBX bounded states), all taken from the OCP description and checked
 * against the generated functions before compiling, and linked against the HPIPM and BLASFEO
 * libraries shipped in CasADi's wheel.
 *
 * Like acados' RTI phases: ``rti_prepare`` (before the measurement) linearizes every stage at
 * the shifted plan and fills HPIPM's QP; ``rti_feedback`` (measurement in, input out) embeds the
 * initial state, runs the IPM, applies the step and shifts the plan. Two variables that a
 * generic QP keeps fixed by equal bounds are removed: the initial state step (eliminated:
 * b_0 = gap_0 + A_0 dx_0, r_0 += S_0 dx_0) and the stage-0 slacks (fixed to 0). Slacks are
 * stage inputs bounded below by 0; constraint rows have a masked (absent) upper bound.
 */
#include <stdlib.h>
#include <string.h>
#include <math.h>

#include <blasfeo_d_aux.h>
#include <hpipm_d_ocp_qp_dim.h>
#include <hpipm_d_ocp_qp.h>
#include <hpipm_d_ocp_qp_sol.h>
#include <hpipm_d_ocp_qp_seed.h>
#include <hpipm_d_ocp_qp_ipm.h>
#include <hpipm_d_ocp_qp_res.h>
#include <hpipm_d_part_cond.h>

#define RTI_NZ (RTI_NX + RTI_NW)
#define RTI_NG1 (RTI_NG > 0 ? RTI_NG : 1) /* buffer sizes (no zero-length arrays) */
#define RTI_BIG 1e8
#define RTI_MAX_BLOCKS 32

typedef struct { /* mirrored by hpipm_rti.RtiInfo (the caller times the phases) */
  int ok, status, iter, capped; /* capped: the IPM hit iter_max and its residuals passed accept_tol */
  double slack_max, res_max;    /* res_max: a capped IPM's largest primal residual (NaN: not computed) */
} rti_info;

typedef struct {
  int n2, iter_max, warm_start, ric_alg, cold, prepared; /* cold: no usable multipliers yet */
  int iter_continue; /* > 0: a capped IPM whose iterate fails accept_tol continues from it for up to this many iterations */
  int feedback_mode; /* 0: feedback solves the QP; 1: prepare solves it at the predicted state, feedback corrects */
  int pred_status, pred_iter; /* feedback_mode 1: the preparation's IPM */
  int capped, pred_capped;    /* the last IPM stopped at iter_max with residuals <= accept_tol */
  double tol_comp, reg, accept_tol, qp_res, pred_qp_res;
  int idxbx[RTI_NBX], idxbu[RTI_NW];
  double lbx[RTI_NBX], ubx[RTI_NBX], lbu[RTI_NR], ubu[RTI_NR];
  double Xb[(RTI_N + 1) * RTI_NX], Wb[RTI_N * RTI_NW]; /* linearization point (the guess) */
  double X[(RTI_N + 1) * RTI_NX], W[RTI_N * RTI_NW];   /* last solution, before the shift */
  /* stage buffers */
  double xn[RTI_NX], A[RTI_NX * RTI_NX], B[RTI_NX * RTI_NW], H[RTI_NZ * RTI_NZ], g[RTI_NZ];
  double h[RTI_NG1], Jh[RTI_NG1 * RTI_NZ], Q[RTI_NX * RTI_NX], S[RTI_NW * RTI_NX], R[RTI_NW * RTI_NW];
  double b[RTI_NX], r[RTI_NW], lbxk[RTI_NBX], ubxk[RTI_NBX], lbuk[RTI_NW], ubuk[RTI_NW];
  double Cg[RTI_NG1 * RTI_NX], Dg[RTI_NG1 * RTI_NW], lg[RTI_NG1], ug[RTI_NG1], dx[RTI_NX], du[RTI_NW];
  /* stage 0 as prepared: the parts the measured initial state enters */
  double A0[RTI_NX * RTI_NX], S0[RTI_NR * RTI_NX], b0[RTI_NX], r0[RTI_NR];
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
  struct d_ocp_qp_sol sol, sol2, sens;
  struct d_ocp_qp_seed seed;
  struct d_part_cond_qp_arg cond_arg;
  struct d_part_cond_qp_ws cond_ws;
  struct d_ocp_qp_ipm_arg ipm_arg;
  struct d_ocp_qp_ipm_ws ipm_ws;
  struct d_ocp_qp_res qres; /* residuals of an iteration-capped solution */
  struct d_ocp_qp_res_ws qres_ws;
  void *blocks[RTI_MAX_BLOCKS];
  int nblocks;
} rti_mem;

/* Zeroed, 64-byte aligned memory owned by m (BLASFEO wants aligned memory); NULL on failure. */
static void *rti_alloc(rti_mem *m, size_t size) {
  void *p;
  if (m->nblocks >= RTI_MAX_BLOCKS) return NULL;
  p = calloc(1, size + 64);
  if (!p) return NULL;
  m->blocks[m->nblocks++] = p;
  return (void *)(((size_t)p + 63) & ~(size_t)63);
}

static double rti_clip(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }

void rti_free(rti_mem *m) {
  int i;
  if (!m) return;
  for (i = 0; i < m->nblocks; i++) free(m->blocks[i]);
  free(m);
}

#define RTI_TRY_ALLOC(var, size) do { (var) = rti_alloc(m, (size)); if (!(var)) goto fail; } while (0)
#define RTI_MAX(a, b) ((a) > (b) ? (a) : (b))

/* settings: n2, iter_max, warm_start, tol_comp, reg, ric_alg, feedback_mode, accept_tol, iter_continue; bounds: idxbx, lbx, ubx (k >= 1),
 * lbu, ubu (motor accelerations). Returns NULL when memory cannot be had. */
rti_mem *rti_create(const double *settings, const int *idxbx, const double *lbx, const double *ubx,
                    const double *lbu, const double *ubu) {
  rti_mem *m = (rti_mem *)calloc(1, sizeof(rti_mem));
  int N = RTI_N, k, i;
  long long sz_arg, sz_res, sz_iw, sz_w, sz_arg2, sz_res2, sz_iw2, sz_w2;
  void *mem;
  struct d_ocp_qp_dim *d;
  if (!m) return NULL;
  m->n2 = (int)settings[0];
  m->iter_max = (int)settings[1];
  m->warm_start = (int)settings[2];
  m->tol_comp = settings[3];
  m->reg = settings[4];
  m->ric_alg = (int)settings[5];
  m->feedback_mode = (int)settings[6];
  m->accept_tol = settings[7];
  m->iter_continue = (int)settings[8];
  m->cold = 1;
  for (i = 0; i < RTI_NBX; i++) { m->idxbx[i] = idxbx[i]; m->lbx[i] = lbx[i]; m->ubx[i] = ubx[i]; }
  for (i = 0; i < RTI_NR; i++) { m->lbu[i] = lbu[i]; m->ubu[i] = ubu[i]; }
  for (i = 0; i < RTI_NW; i++) m->idxbu[i] = i;
  stage_lin_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
  term_lin_work(&sz_arg2, &sz_res2, &sz_iw2, &sz_w2);
  RTI_TRY_ALLOC(mem, sizeof(double *) * (size_t)(RTI_MAX(sz_arg, sz_arg2) + 8)); m->arg = (const double **)mem;
  RTI_TRY_ALLOC(mem, sizeof(double *) * (size_t)(RTI_MAX(sz_res, sz_res2) + 8)); m->res = (double **)mem;
  RTI_TRY_ALLOC(mem, sizeof(long long) * (size_t)(RTI_MAX(sz_iw, sz_iw2) + 1)); m->iw = (long long *)mem;
  RTI_TRY_ALLOC(mem, sizeof(double) * (size_t)(RTI_MAX(sz_w, sz_w2) + 1)); m->w = (double *)mem;
  for (k = 0; k <= N; k++) {
    m->nx[k] = k == 0 ? 0 : RTI_NX;
    m->nu[k] = k == N ? 0 : (k == 0 ? RTI_NR : RTI_NW);
    m->nbx[k] = k == 0 ? 0 : RTI_NBX;
    m->nbu[k] = m->nu[k];
    m->ng[k] = (k >= 1 && k < N) ? RTI_NG : 0;
    m->ns[k] = 0;
  }
  RTI_TRY_ALLOC(mem, d_ocp_qp_dim_memsize(N)); d_ocp_qp_dim_create(N, &m->dim, mem);
  d_ocp_qp_dim_set_all(m->nx, m->nu, m->nbx, m->nbu, m->ng, m->ns, &m->dim);
  RTI_TRY_ALLOC(mem, d_ocp_qp_memsize(&m->dim)); d_ocp_qp_create(&m->dim, &m->qp, mem);
  RTI_TRY_ALLOC(mem, d_ocp_qp_sol_memsize(&m->dim)); d_ocp_qp_sol_create(&m->dim, &m->sol, mem);
  if (m->feedback_mode == 1) {
    RTI_TRY_ALLOC(mem, d_ocp_qp_sol_memsize(&m->dim)); d_ocp_qp_sol_create(&m->dim, &m->sens, mem);
    RTI_TRY_ALLOC(mem, d_ocp_qp_seed_memsize(&m->dim)); d_ocp_qp_seed_create(&m->dim, &m->seed, mem);
  }
  if (m->n2 < N) {
    RTI_TRY_ALLOC(mem, d_ocp_qp_dim_memsize(m->n2)); d_ocp_qp_dim_create(m->n2, &m->dim2, mem);
    d_part_cond_qp_compute_block_size(N, m->n2, m->block_size);
    d_part_cond_qp_compute_dim(&m->dim, m->block_size, &m->dim2);
    RTI_TRY_ALLOC(mem, d_part_cond_qp_arg_memsize(m->n2)); d_part_cond_qp_arg_create(m->n2, &m->cond_arg, mem);
    d_part_cond_qp_arg_set_default(&m->cond_arg);
    RTI_TRY_ALLOC(mem, d_part_cond_qp_ws_memsize(&m->dim, m->block_size, &m->dim2, &m->cond_arg));
    d_part_cond_qp_ws_create(&m->dim, m->block_size, &m->dim2, &m->cond_arg, &m->cond_ws, mem);
    RTI_TRY_ALLOC(mem, d_ocp_qp_memsize(&m->dim2)); d_ocp_qp_create(&m->dim2, &m->qp2, mem);
    RTI_TRY_ALLOC(mem, d_ocp_qp_sol_memsize(&m->dim2)); d_ocp_qp_sol_create(&m->dim2, &m->sol2, mem);
  }
  d = m->n2 < N ? &m->dim2 : &m->dim;
  RTI_TRY_ALLOC(mem, d_ocp_qp_ipm_arg_memsize(d)); d_ocp_qp_ipm_arg_create(d, &m->ipm_arg, mem);
  d_ocp_qp_ipm_arg_set_default(SPEED_ABS, &m->ipm_arg);
  d_ocp_qp_ipm_arg_set_iter_max(&m->iter_max, &m->ipm_arg);
  d_ocp_qp_ipm_arg_set_tol_comp(&m->tol_comp, &m->ipm_arg);
  d_ocp_qp_ipm_arg_set_warm_start(&m->warm_start, &m->ipm_arg);
  d_ocp_qp_ipm_arg_set_ric_alg(&m->ric_alg, &m->ipm_arg);
  if (m->feedback_mode == 1) { /* the factorization at the solution, for the sensitivity */
    int one = 1;
    d_ocp_qp_ipm_arg_set_update_fact_exit(&one, &m->ipm_arg);
  }
  RTI_TRY_ALLOC(mem, d_ocp_qp_ipm_ws_memsize(d, &m->ipm_arg)); d_ocp_qp_ipm_ws_create(d, &m->ipm_arg, &m->ipm_ws, mem);
  RTI_TRY_ALLOC(mem, d_ocp_qp_res_memsize(d)); d_ocp_qp_res_create(d, &m->qres, mem);
  RTI_TRY_ALLOC(mem, d_ocp_qp_res_ws_memsize(d)); d_ocp_qp_res_ws_create(d, &m->qres_ws, mem);
  /* one-sided constraints: the slacks' upper bounds and the rows' upper bounds are masked */
  for (k = 0; k < N; k++) d_ocp_qp_set_idxbu(k, m->idxbu, &m->qp);
  for (k = 1; k <= N; k++) d_ocp_qp_set_idxbx(k, m->idxbx, &m->qp);
  {
    double umask[RTI_NW], gmask[RTI_NG1];
    for (i = 0; i < RTI_NW; i++) umask[i] = i < RTI_NR ? 1.0 : 0.0;
    for (i = 0; i < RTI_NG1; i++) gmask[i] = 0.0;
    for (k = 1; k < N; k++) {
      if (RTI_NS > 0) d_ocp_qp_set_ubu_mask(k, umask, &m->qp);
      if (RTI_NG > 0) d_ocp_qp_set_ug_mask(k, gmask, &m->qp);
    }
  }
  return m;
fail:
  rti_free(m);
  return NULL;
}

/* Whether the AVX2 kernels of blasfeo_avx2.c have run in this process (-1: not compiled in). */
int rti_simd_kernels_ran(void) {
#ifdef RTI_SIMD
  return __atomic_load_n(&aerorelay_simd_kernels_ran, __ATOMIC_RELAXED);
#else
  return -1;
#endif
}

void rti_set_plan(rti_mem *m, const double *Xb, const double *Wb) {
  memcpy(m->Xb, Xb, sizeof(m->Xb));
  memcpy(m->Wb, Wb, sizeof(m->Wb));
  m->cold = 1;
  m->prepared = 0;
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

/* Input bounds of stage k as bounds on the step: motor accelerations, slacks >= 0 (k >= 1). */
static void rti_set_input_bounds(rti_mem *m, int k, const double *wb) {
  int i, nu = m->nu[k];
  for (i = 0; i < nu; i++) {
    m->lbuk[i] = i < RTI_NR ? m->lbu[i] - wb[i] : -wb[i];
    m->ubuk[i] = i < RTI_NR ? m->ubu[i] - wb[i] : RTI_BIG;
  }
  d_ocp_qp_set_lbu(k, m->lbuk, &m->qp);
  d_ocp_qp_set_ubu(k, m->ubuk, &m->qp);
}

/* Linearize stage k (< N) at (Xb_k, Wb_k, P_k) into the stage buffers; b = gap. */
static void rti_linearize(rti_mem *m, int k, const double *P) {
  int i;
  m->arg[0] = m->Xb + k * RTI_NX; m->arg[1] = m->Wb + k * RTI_NW; m->arg[2] = P + k * RTI_NP;
  m->res[0] = m->xn; m->res[1] = m->A; m->res[2] = m->B; m->res[3] = m->H; m->res[4] = m->g;
  m->res[5] = m->h; m->res[6] = m->Jh;
  stage_lin(m->arg, m->res, m->iw, m->w, 0);
  for (i = 0; i < RTI_NX; i++) m->b[i] = m->xn[i] - m->Xb[(k + 1) * RTI_NX + i];
}

/* R (with regularization) and r of the first nu inputs from the stage Hessian and gradient. */
static void rti_input_blocks(rti_mem *m, int nu) {
  int i, j;
  for (j = 0; j < nu; j++) {
    for (i = 0; i < nu; i++) m->R[i + j * nu] = m->H[(RTI_NX + i) + (RTI_NX + j) * RTI_NZ] + (i == j ? m->reg : 0.0);
    m->r[j] = m->g[RTI_NX + j];
  }
}

/* Stage 0: everything but the measured initial state, which rti_feedback embeds. */
static void rti_prepare_stage0(rti_mem *m, const double *P) {
  int i, j;
  rti_linearize(m, 0, P);
  rti_input_blocks(m, RTI_NR);
  memcpy(m->A0, m->A, sizeof(m->A0));
  memcpy(m->b0, m->b, sizeof(m->b0));
  memcpy(m->r0, m->r, sizeof(m->r0));
  for (j = 0; j < RTI_NX; j++)
    for (i = 0; i < RTI_NR; i++) m->S0[i + j * RTI_NR] = m->H[(RTI_NX + i) + j * RTI_NZ];
  d_ocp_qp_set_B(0, m->B, &m->qp); /* first NR columns of the column-major B */
  d_ocp_qp_set_R(0, m->R, &m->qp);
  rti_set_input_bounds(m, 0, m->Wb);
}

/* Stage k in 1..N-1: dynamics, cost, bounds and constraint rows Jh dz >= -h. */
static void rti_prepare_stage(rti_mem *m, int k, const double *P) {
  int i, j;
  rti_linearize(m, k, P);
  rti_input_blocks(m, RTI_NW);
  for (j = 0; j < RTI_NX; j++) {
    for (i = 0; i < RTI_NX; i++) m->Q[i + j * RTI_NX] = m->H[i + j * RTI_NZ] + (i == j ? m->reg : 0.0);
    for (i = 0; i < RTI_NW; i++) m->S[i + j * RTI_NW] = m->H[(RTI_NX + i) + j * RTI_NZ];
  }
  d_ocp_qp_set_A(k, m->A, &m->qp);
  d_ocp_qp_set_B(k, m->B, &m->qp);
  d_ocp_qp_set_b(k, m->b, &m->qp);
  d_ocp_qp_set_Q(k, m->Q, &m->qp);
  d_ocp_qp_set_S(k, m->S, &m->qp);
  d_ocp_qp_set_R(k, m->R, &m->qp);
  d_ocp_qp_set_q(k, m->g, &m->qp);
  d_ocp_qp_set_r(k, m->r, &m->qp);
  rti_set_state_bounds(m, k, m->Xb + k * RTI_NX);
  rti_set_input_bounds(m, k, m->Wb + k * RTI_NW);
  if (RTI_NG > 0) { /* Jh is (NG, NZ) column-major: C = Jh[:, :NX], D = Jh[:, NX:] */
    for (j = 0; j < RTI_NX; j++)
      for (i = 0; i < RTI_NG; i++) m->Cg[i + j * RTI_NG] = m->Jh[i + j * RTI_NG];
    for (j = 0; j < RTI_NW; j++)
      for (i = 0; i < RTI_NG; i++) m->Dg[i + j * RTI_NG] = m->Jh[i + (RTI_NX + j) * RTI_NG];
    for (i = 0; i < RTI_NG; i++) { m->lg[i] = -m->h[i]; m->ug[i] = RTI_BIG; }
    d_ocp_qp_set_C(k, m->Cg, &m->qp);
    d_ocp_qp_set_D(k, m->Dg, &m->qp);
    d_ocp_qp_set_lg(k, m->lg, &m->qp);
    d_ocp_qp_set_ug(k, m->ug, &m->qp);
  }
}

static void rti_prepare_terminal(rti_mem *m, const double *P) {
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

static int rti_solve_qp(rti_mem *m, int *iter);

/* Preparation phase: P is the (NP, N+1) column-major parameter matrix. In feedback_mode 1 the
 * QP is also solved here, at the predicted initial state (the guess's, dx_0 = 0). */
void rti_prepare(rti_mem *m, const double *P) {
  int k;
  rti_prepare_stage0(m, P);
  for (k = 1; k < RTI_N; k++) rti_prepare_stage(m, k, P);
  rti_prepare_terminal(m, P);
  if (m->feedback_mode == 1) {
    d_ocp_qp_set_b(0, m->b0, &m->qp);
    d_ocp_qp_set_r(0, m->r0, &m->qp);
    m->pred_status = rti_solve_qp(m, &m->pred_iter);
    m->pred_capped = m->capped;
    m->pred_qp_res = m->qp_res;
  }
  m->prepared = 1;
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
  if (warm_start == 1 || warm_start == 2)
    for (k = 0; k <= qp->dim->N; k++) blasfeo_dvecse(qp->dim->nu[k] + qp->dim->nx[k], 0.0, sol->ux + k, 0);
  if (warm_start > 2) warm_start = 2; /* 3: continue from the iterate in sol (its primal part kept) */
  d_ocp_qp_ipm_arg_set_warm_start(&warm_start, &m->ipm_arg);
  d_ocp_qp_ipm_solve(qp, sol, &m->ipm_arg, &m->ipm_ws);
  d_ocp_qp_ipm_get_status(&m->ipm_ws, &status);
  d_ocp_qp_ipm_get_iter(&m->ipm_ws, iter);
  m->qp_res = NAN;
  m->capped = 0;
  if (status == 1 && m->accept_tol > 0.0) {
    /* an iteration cap with a quality check: an interior-point iterate the cap stopped is a
     * primal-feasible but not yet optimal step; it is used when its primal residuals (the
     * linearized dynamics and every inequality row; computed here, the speed_abs IPM does not)
     * are within accept_tol. Stationarity and complementarity are not checked: far from zero
     * after a few iterations (the step is suboptimal, pushed into the interior) */
    double r[2];
    d_ocp_qp_res_compute(qp, sol, &m->qres, &m->qres_ws);
    d_ocp_qp_res_compute_inf_norm(&m->qres);
    d_ocp_qp_res_get_max_res_eq(&m->qres, r);
    d_ocp_qp_res_get_max_res_ineq(&m->qres, r + 1);
    m->qp_res = isfinite(r[0]) && isfinite(r[1]) ? RTI_MAX(fabs(r[0]), fabs(r[1])) : INFINITY;
    m->capped = m->qp_res <= m->accept_tol;
  }
  return m->capped ? 0 : status;
}

/* Solve the filled QP (partial condensing, warm start with a cold retry, expansion). */
static int rti_solve_qp(rti_mem *m, int *iter) {
  int status, N = RTI_N;
  struct d_ocp_qp *qp = &m->qp;
  struct d_ocp_qp_sol *sol = &m->sol;
  if (m->n2 < N) {
    d_part_cond_qp_cond(&m->qp, &m->qp2, &m->cond_arg, &m->cond_ws);
    qp = &m->qp2;
    sol = &m->sol2;
  }
  status = rti_solve(m, qp, sol, m->cold ? 0 : m->warm_start, iter);
  if (status == 1 && m->accept_tol > 0.0 && m->iter_continue > 0) {
    /* the cap stopped an iterate that failed the quality check: continue from it (primal and
     * dual kept) with up to iter_continue more iterations, instead of a cold start that the same
     * cap would stop again */
    int iter2 = 0, cap = m->iter_max;
    d_ocp_qp_ipm_arg_set_iter_max(&m->iter_continue, &m->ipm_arg);
    status = rti_solve(m, qp, sol, 3, &iter2);
    d_ocp_qp_ipm_arg_set_iter_max(&cap, &m->ipm_arg);
    *iter += iter2;
  }
  if (status != 0 && !m->cold && m->warm_start) { /* a warm start gone wrong: once more from cold */
    int iter2 = 0;
    status = rti_solve(m, qp, sol, 0, &iter2);
    *iter += iter2;
  }
  if (m->n2 < N) d_part_cond_qp_expand_sol(&m->qp, &m->sol2, &m->sol, &m->cond_arg, &m->cond_ws);
  return status;
}

/* Read the QP's solution into the plan (X, W) = guess + step; 0 if any entry is not finite. */
static int rti_apply_step(rti_mem *m, const double *dx0, double *slack_max) {
  int k, i, ok = 1, N = RTI_N;
  for (k = 0; k <= N && ok; k++) {
    double *X = m->X + k * RTI_NX, *W = m->W + k * RTI_NW;
    const double *xb = m->Xb + k * RTI_NX, *wb = m->Wb + k * RTI_NW;
    if (k == 0) memcpy(m->dx, dx0, sizeof(m->dx));
    else {
      d_ocp_qp_sol_get_x(k, &m->sol, m->dx);
      if (m->feedback_mode == 1) { /* predicted solution + its first-order correction */
        d_ocp_qp_sol_get_x(k, &m->sens, m->xn);
        for (i = 0; i < RTI_NX; i++) m->dx[i] += m->xn[i];
      }
    }
    for (i = 0; i < RTI_NX; i++) { X[i] = xb[i] + m->dx[i]; ok = ok && isfinite(X[i]); }
    if (k == N) break;
    d_ocp_qp_sol_get_u(k, &m->sol, m->du);
    if (m->feedback_mode == 1) {
      d_ocp_qp_sol_get_u(k, &m->sens, m->r);
      for (i = 0; i < m->nu[k]; i++) m->du[i] += m->r[i];
    }
    for (i = 0; i < RTI_NW; i++) W[i] = i < m->nu[k] ? wb[i] + m->du[i] : 0.0; /* stage-0 slacks are 0 */
    for (i = 0; i < RTI_NW; i++) ok = ok && isfinite(W[i]);
    for (i = RTI_NR; i < RTI_NW && k >= 1; i++) if (W[i] > *slack_max) *slack_max = W[i];
  }
  return ok;
}

/* Feedback phase: xa0 is the measured (augmented) state. u: first input, clipped to its bounds
 * (on failure: the previous plan's input for now). Returns info->ok. */
int rti_feedback(rti_mem *m, const double *xa0, int shift, double *u, rti_info *info) {
  int i, j, status = 0, iter = 0, ok;
  double dx0[RTI_NX], slack_max = 0.0;
  if (!m->prepared) { /* the caller skipped rti_prepare: refuse rather than solve a stale QP */
    info->ok = 0; info->status = -1; info->iter = 0; info->capped = 0; info->slack_max = NAN; info->res_max = NAN;
    for (i = 0; i < RTI_NR; i++) u[i] = rti_clip(isfinite(m->Wb[i]) ? m->Wb[i] : 0.0, m->lbu[i], m->ubu[i]);
    return 0;
  }
  for (i = 0; i < RTI_NX; i++) dx0[i] = xa0[i] - m->Xb[i];
  /* the initial state enters stage 0 only: b_0 = gap_0 + A_0 dx_0, r_0 = r_0 + S_0 dx_0 */
  for (i = 0; i < RTI_NX; i++) m->b[i] = m->feedback_mode == 1 ? 0.0 : m->b0[i];
  for (i = 0; i < RTI_NR; i++) m->r[i] = m->feedback_mode == 1 ? 0.0 : m->r0[i];
  for (j = 0; j < RTI_NX; j++) {
    for (i = 0; i < RTI_NX; i++) m->b[i] += m->A0[i + j * RTI_NX] * dx0[j];
    for (i = 0; i < RTI_NR; i++) m->r[i] += m->S0[i + j * RTI_NR] * dx0[j];
  }
  if (m->feedback_mode == 1) { /* the predicted solution's sensitivity in the direction (db_0, dr_0) */
    status = m->pred_status;
    iter = m->pred_iter;
    m->capped = m->pred_capped;
    m->qp_res = m->pred_qp_res;
    if (status == 0) {
      d_ocp_qp_seed_set_zero(&m->seed);
      d_ocp_qp_seed_set_seed_b(0, m->b, &m->seed);
      d_ocp_qp_seed_set_seed_r(0, m->r, &m->seed);
      d_ocp_qp_ipm_sens_frw(&m->qp, &m->seed, &m->sens, &m->ipm_arg, &m->ipm_ws);
    }
  } else {
    d_ocp_qp_set_b(0, m->b, &m->qp);
    d_ocp_qp_set_r(0, m->r, &m->qp);
    status = rti_solve_qp(m, &iter);
  }
  ok = status == 0 && rti_apply_step(m, dx0, &slack_max);
  m->cold = !ok;
  m->prepared = 0;
  if (ok) {
    for (i = 0; i < RTI_NR; i++) u[i] = rti_clip(m->W[i], m->lbu[i], m->ubu[i]);
    if (shift) rti_shift(m, m->X, m->W);
    else { memcpy(m->Xb, m->X, sizeof(m->X)); memcpy(m->Wb, m->W, sizeof(m->W)); }
  } else { /* the guess is the previous plan shifted to now: apply its first input, shift it on */
    for (i = 0; i < RTI_NR; i++) u[i] = rti_clip(isfinite(m->Wb[i]) ? m->Wb[i] : 0.0, m->lbu[i], m->ubu[i]);
    memcpy(m->X, m->Xb, sizeof(m->X));
    memcpy(m->W, m->Wb, sizeof(m->W));
    rti_shift(m, m->X, m->W);
    slack_max = NAN;
  }
  info->ok = ok;
  info->status = status;
  info->iter = iter;
  info->capped = m->capped;
  info->slack_max = slack_max;
  info->res_max = m->qp_res;
  return ok;
}
