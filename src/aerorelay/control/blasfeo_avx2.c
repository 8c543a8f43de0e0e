/* AVX2/FMA versions of the two BLASFEO kernels that dominate HPIPM's time on the NMPC's QP.
 *
 * CasADi's wheel ships BLASFEO built for its generic target (plain C 4x4 kernels, 5.6 GFlop/s on
 * a 32x32 dgemm on the development machine). A profile of the RTI step (perf, nominal mission)
 * puts 41% of all samples in kernel_dgemm_nt_4x4_lib4 and kernel_dgemm_nn_4x4_lib4. When the
 * CPU has AVX2 and FMA, aerorelay.control.hpipm_rti compiles this file into the engine library:
 * the dynamic linker then resolves libblasfeo's calls of these two (exported, called through
 * the PLT) to the definitions below, which compute the same panel-major products with 256-bit
 * fused multiply-adds. Same contract as BLASFEO's generic kernels:
 *   D = alpha * A * B^T + beta * C   (nt)      D = alpha * A * B + beta * C   (nn)
 * A: 4 x k panel (element (i, l) at A[i + 4 l]); nt: B a 4 x k panel; nn: B a k x 4 block of a
 * panel-major matrix starting at row offset offsetB of the panel at B, panel stride 4 sdb;
 * C, D: 4 x 4 panels (element (i, j) at [i + 4 j]). beta == 0 does not read C.
 * Their contracts are written out in aerorelay.control.blasfeo_contract: the engine compiles
 * this file in only when CasADi's own kernels compute exactly those (checked at run time), and
 * tests/control/test_blasfeo_kernels.py holds these to the same and to CasADi's kernels.
 *
 * Tried on the next kernels by profile (cold IPM solves of a heavy coplanar QP, 2026-12-02):
 * AVX2 dgemv_n / dgemv_t made an IPM iteration 8-12% faster but, like any change of summation
 * order, move the paper's controller's C_min at the rounding level (coplanar -0.34%): not kept
 * (README, Speed). AVX2 dtrsm_nt_rl_inv, dpotrf_nt_l and dtrmm_nn_rl 4x4 were slower than
 * BLASFEO's generic ones calling the dgemm kernel below: their 4 x 4 triangular parts are
 * latency-bound chains, which the generic scalar code interleaves better.
 */
#include <immintrin.h>

/* BLASFEO's own names (and the flag they set), interposed: weak definitions, the same in every C tree aerorelay
 * writes, so a program that links several relays' trees has one of each (the dynamic linker resolves libblasfeo's
 * calls to a weak definition as to any other) */
#define RTI_INTERPOSED __attribute__((weak))

RTI_INTERPOSED int aerorelay_simd_kernels_ran = 0; /* set (relaxed atomic store) by every call */

#define RTI_AVX2 __attribute__((target("avx2,fma")))

/* c[j] += a * b[j * stride], j = 0..3: one column of A times one row of B (stride 1 in a panel
 * of B^T, 4 along a panel-major row of B) */
RTI_AVX2 static inline void rti_rank1(__m256d a, const double *b, int stride, __m256d *c) {
  c[0] = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b), c[0]);
  c[1] = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + stride), c[1]);
  c[2] = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 2 * stride), c[2]);
  c[3] = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 3 * stride), c[3]);
}

/* D(:, j) = alpha (c[j] + e[j]) + beta C(:, j); C is not read when beta == 0 */
RTI_AVX2 static inline void rti_store_4x4(const __m256d *c, const __m256d *e, const double *alpha,
                                          const double *beta, const double *C, double *D) {
  __m256d a = _mm256_broadcast_sd(alpha), b = _mm256_broadcast_sd(beta);
  int j;
  for (j = 0; j < 4; j++) {
    __m256d d = _mm256_mul_pd(a, _mm256_add_pd(c[j], e[j]));
    if (*beta != 0.0) d = _mm256_fmadd_pd(b, _mm256_loadu_pd(C + 4 * j), d);
    _mm256_storeu_pd(D + 4 * j, d);
  }
}

/* two accumulator sets (even and odd l) hide the FMA latency */
RTI_AVX2 RTI_INTERPOSED void kernel_dgemm_nt_4x4_lib4(int kmax, double *alpha, double *A, double *B, double *beta, double *C,
                                       double *D) {
  __m256d c[4], e[4];
  int l = 0, j;
  for (j = 0; j < 4; j++) c[j] = e[j] = _mm256_setzero_pd();
  __atomic_store_n(&aerorelay_simd_kernels_ran, 1, __ATOMIC_RELAXED);
  for (; l + 1 < kmax; l += 2) {
    rti_rank1(_mm256_loadu_pd(A + 4 * l), B + 4 * l, 1, c);
    rti_rank1(_mm256_loadu_pd(A + 4 * l + 4), B + 4 * l + 4, 1, e);
  }
  if (l < kmax) rti_rank1(_mm256_loadu_pd(A + 4 * l), B + 4 * l, 1, c);
  rti_store_4x4(c, e, alpha, beta, C, D);
}

/* row l of B is row r = (offsetB + l) % 4 of panel (offsetB + l) / 4, panels 4 sdb apart */
RTI_AVX2 RTI_INTERPOSED void kernel_dgemm_nn_4x4_lib4(int kmax, double *alpha, double *A, int offsetB, double *B, int sdb,
                                       double *beta, double *C, double *D) {
  __m256d c[4], e[4];
  int l = 0, j, r = offsetB;
  const double *panel = B, *b, *g;
  for (j = 0; j < 4; j++) c[j] = e[j] = _mm256_setzero_pd();
  __atomic_store_n(&aerorelay_simd_kernels_ran, 1, __ATOMIC_RELAXED);
  for (; l + 1 < kmax; l += 2) {
    b = panel + r;
    if (++r == 4) { r = 0; panel += 4 * sdb; }
    g = panel + r;
    if (++r == 4) { r = 0; panel += 4 * sdb; }
    rti_rank1(_mm256_loadu_pd(A + 4 * l), b, 4, c);
    rti_rank1(_mm256_loadu_pd(A + 4 * l + 4), g, 4, e);
  }
  if (l < kmax) rti_rank1(_mm256_loadu_pd(A + 4 * l), panel + r, 4, c);
  rti_store_4x4(c, e, alpha, beta, C, D);
}
