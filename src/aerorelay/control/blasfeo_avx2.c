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
 * tests/control/test_blasfeo_kernels.py checks them against CasADi's own kernels.
 */
#include <immintrin.h>

long long aerorelay_simd_kernel_calls = 0;

__attribute__((target("avx2,fma"))) static inline void rti_store_4x4(__m256d d0, __m256d d1, __m256d d2, __m256d d3, const double *alpha,
                                 const double *beta, const double *C, double *D) {
  __m256d a = _mm256_broadcast_sd(alpha);
  d0 = _mm256_mul_pd(a, d0);
  d1 = _mm256_mul_pd(a, d1);
  d2 = _mm256_mul_pd(a, d2);
  d3 = _mm256_mul_pd(a, d3);
  if (*beta != 0.0) {
    __m256d b = _mm256_broadcast_sd(beta);
    d0 = _mm256_fmadd_pd(b, _mm256_loadu_pd(C + 0), d0);
    d1 = _mm256_fmadd_pd(b, _mm256_loadu_pd(C + 4), d1);
    d2 = _mm256_fmadd_pd(b, _mm256_loadu_pd(C + 8), d2);
    d3 = _mm256_fmadd_pd(b, _mm256_loadu_pd(C + 12), d3);
  }
  _mm256_storeu_pd(D + 0, d0);
  _mm256_storeu_pd(D + 4, d1);
  _mm256_storeu_pd(D + 8, d2);
  _mm256_storeu_pd(D + 12, d3);
}

/* column j of A B^T += A(:, l) * B(j, l); two accumulator sets hide the FMA latency */
__attribute__((target("avx2,fma"))) void kernel_dgemm_nt_4x4_lib4(int kmax, double *alpha, double *A, double *B, double *beta, double *C, double *D) {
  __m256d c0 = _mm256_setzero_pd(), c1 = c0, c2 = c0, c3 = c0, e0 = c0, e1 = c0, e2 = c0, e3 = c0;
  int l = 0;
  aerorelay_simd_kernel_calls++;
  for (; l + 1 < kmax; l += 2) {
    __m256d a = _mm256_loadu_pd(A + 4 * l), f = _mm256_loadu_pd(A + 4 * l + 4);
    const double *b = B + 4 * l;
    c0 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 0), c0);
    c1 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 1), c1);
    c2 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 2), c2);
    c3 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 3), c3);
    e0 = _mm256_fmadd_pd(f, _mm256_broadcast_sd(b + 4), e0);
    e1 = _mm256_fmadd_pd(f, _mm256_broadcast_sd(b + 5), e1);
    e2 = _mm256_fmadd_pd(f, _mm256_broadcast_sd(b + 6), e2);
    e3 = _mm256_fmadd_pd(f, _mm256_broadcast_sd(b + 7), e3);
  }
  if (l < kmax) {
    __m256d a = _mm256_loadu_pd(A + 4 * l);
    const double *b = B + 4 * l;
    c0 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 0), c0);
    c1 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 1), c1);
    c2 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 2), c2);
    c3 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 3), c3);
  }
  rti_store_4x4(_mm256_add_pd(c0, e0), _mm256_add_pd(c1, e1), _mm256_add_pd(c2, e2), _mm256_add_pd(c3, e3),
                alpha, beta, C, D);
}

/* column j of A B += A(:, l) * B(l, j), with B(l, j) at B + ((offsetB + l) / 4) 4 sdb + (offsetB + l) % 4 + 4 j */
__attribute__((target("avx2,fma"))) void kernel_dgemm_nn_4x4_lib4(int kmax, double *alpha, double *A, int offsetB, double *B, int sdb, double *beta,
                              double *C, double *D) {
  __m256d c0 = _mm256_setzero_pd(), c1 = c0, c2 = c0, c3 = c0, e0 = c0, e1 = c0, e2 = c0, e3 = c0;
  int l = 0, r = offsetB;
  const double *panel = B;
  aerorelay_simd_kernel_calls++;
  for (; l + 1 < kmax; l += 2) {
    const double *b = panel + r, *g;
    __m256d a = _mm256_loadu_pd(A + 4 * l), f = _mm256_loadu_pd(A + 4 * l + 4);
    if (++r == 4) { r = 0; panel += 4 * sdb; }
    g = panel + r;
    if (++r == 4) { r = 0; panel += 4 * sdb; }
    c0 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 0), c0);
    c1 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 4), c1);
    c2 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 8), c2);
    c3 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 12), c3);
    e0 = _mm256_fmadd_pd(f, _mm256_broadcast_sd(g + 0), e0);
    e1 = _mm256_fmadd_pd(f, _mm256_broadcast_sd(g + 4), e1);
    e2 = _mm256_fmadd_pd(f, _mm256_broadcast_sd(g + 8), e2);
    e3 = _mm256_fmadd_pd(f, _mm256_broadcast_sd(g + 12), e3);
  }
  if (l < kmax) {
    const double *b = panel + r;
    __m256d a = _mm256_loadu_pd(A + 4 * l);
    c0 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 0), c0);
    c1 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 4), c1);
    c2 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 8), c2);
    c3 = _mm256_fmadd_pd(a, _mm256_broadcast_sd(b + 12), c3);
  }
  rti_store_4x4(_mm256_add_pd(c0, e0), _mm256_add_pd(c1, e1), _mm256_add_pd(c2, e2), _mm256_add_pd(c3, e3),
                alpha, beta, C, D);
}
