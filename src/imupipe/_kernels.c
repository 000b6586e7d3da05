/*
 * imupipe._kernels -- compiled inner loops of imupipe.allan, imupipe.identify, imupipe.simulate,
 * imupipe.stationarity, imupipe.covariance and imupipe.verify
 * (optional; each has a NumPy/SciPy path that gives the same results to rounding when this module cannot be
 * built or imported).
 *
 * oavar_sums(theta, lags, out)
 *     out[j] = sum_{k=0}^{L-2m-1} ((theta[k+2m] - theta[k+m]) - (theta[k+m] - theta[k]))^2,  m = lags[j],
 *     L = len(theta): the sums of squared second differences of the overlapping Allan variance
 *     (NIST SP 1065, eq. 11), AVAR(m tau0) = out[j] / (2 m^2 (L - 2m)) when theta is the cumulative sum of
 *     the rate samples in sample units.
 *
 *     theta : C-contiguous float64 buffer (any object with the buffer protocol, e.g. a NumPy array)
 *     lags  : contiguous int64 buffer, 1 <= m <= (L - 1) / 2
 *     out   : writable contiguous float64 buffer, len(out) == len(lags)
 *
 *     With a fourth argument out9 (float64, 9 * len(lags)) the lag-1 sums below are computed in the same
 *     pass, the small lags' means while their block of theta is in cache.
 *
 * lag1_sums(theta, lags, out)
 *     For each lag m, the N = (L-1)//m non-overlapping m-sample means z_i = (theta[(i+1)m] - theta[im]) / m
 *     and their first and second differences w = z, diff(z), diff(z, 2): out[9j + 3d + (0, 1, 2)] =
 *     (sum w, sum w^2, sum w_i w_{i+1}) for d = 0, 1, 2 -- the sums of the lag-1 autocorrelation noise
 *     identification (Riley & Greenhall 2004), in one strided pass over theta per lag.
 *     out : writable contiguous float64 buffer of 9 * len(lags); 1 <= m <= (L - 1) / 2.
 *     Blocks of means are formed in an L1-sized buffer, then all nine sums in one fused pass, four lanes
 *     per sum (GCC/Clang vector extensions; a scalar loop elsewhere).
 *
 * integrate(y, mean, theta)
 *     theta[0] = 0, theta[k+1] = theta[k] + (y[k] - mean): the same additions in the same order as
 *     numpy.cumsum(y - mean), without the 36 MB temporary of a paper-scale axis.
 *
 * ar1(e, phi, n)
 *     In place, each row of n values: e[0] unchanged, e[i] = phi * e[i-1] + e[i]: the first-order recursion
 *     of scipy.signal.lfilter([1], [1, -phi], e, axis=-1) (same operations in the same order), for the
 *     Gauss-Markov records of imupipe.simulate.
 *
 * car1(z, mu_re, mu_im, n)
 *     In place, each row of n complex values (z: complex128 data as interleaved float64 pairs, 2 n doubles per
 *     row): z[i] = mu z[i-1] + z[i], the complex product as (mu_re s_re - mu_im s_im) + i (mu_re s_im + mu_im s_re):
 *     the first-order complex recursion of scipy.signal.lfilter([1], [1, -mu], z, axis=-1), for the modal
 *     coordinate of imupipe.simulate's damped oscillator (narrowband lines).
 *
 * flicker_bank(w, p, weights, direct, state, y, n)
 *     The flicker bank of imupipe.simulate in one pass over the samples, per row of n values:
 *     u_i[k] = p_i u_i[k-1] + weights_i w[k] for the J = len(p) branches (u_i[-1] = state[row, i]), and
 *     y[k] = direct w[k] + u_0[k] + u_1[k] + ... + u_{J-1}[k], added in that order; state[row, :] receives
 *     u_i[n-1]. The operations of imupipe.simulate._flicker_run's branch-by-branch passes (a multiply, the AR(1)
 *     recursion, an add per branch) in their order, without a pass over the record per branch. y may be w.
 *     J <= 64 (the bank of a record of 1e12 samples has 20 branches).
 *
 * sim_piece(x, white, sw, gm, phi, scale, last, first, rw, krw, rw_sum) -> rw_sum
 *     One piece of m = len(x) samples of imupipe.simulate.simulate_chunks' white, Gauss-Markov and random-walk
 *     terms in one pass, from their unit normal draws: x[k] = ((0 + sw white[k]) + g_0[k] + ... + g_{G-1}[k])
 *     + krw (c[k] + rw_sum), g_j[k] = phi_j g_j[k-1] + scale_j gm[j, k] with g_j[-1] = last[j] (first: g_j[0] =
 *     last[j], the steady-state start), c the running sum of rw. white, rw: None when absent; gm: G x m
 *     (G = len(phi), may be 0); last receives g_j[m-1]; returns c[m-1] + rw_sum (rw_sum when rw is None).
 *     The NumPy passes' operations in their order (a multiply, the recursion, an add per term).
 *
 * segment_stats(x, n, k, m, w, d)
 *     For each record r of n >= k m values (x holds len(w) * n), split into k consecutive segments of m
 *     samples (the last n - k m dropped): w[r] = the median-centred Levene (Brown-Forsythe) statistic of the
 *     k segments and d[r] = max_i of the two-sample Kolmogorov-Smirnov statistic of segments i and i+1.
 *     Each segment is copied and sorted (LSD radix sort of the order-preserving 64-bit keys of the doubles,
 *     11-bit digits, passes whose digit is common to all keys skipped; x is not modified); the medians are
 *     then the middle values, and each KS statistic a merge walk over two sorted runs that reads the
 *     difference of the empirical distribution functions after each run of tied values (exact integer
 *     counts). The Monte Carlo null of imupipe.stationarity.

 * wnnls(A, y, edf, m0, offset, n_iter, rtol, p, m)
 *     The re-weighted non-negative least squares of imupipe.identify._wnnls, the whole iteration in one call:
 *     model m = offset + A p (offset None: 0), weights w = sqrt(edf/2) / m on the current model (first pass on
 *     m0 floored at 1e-6 y, or on y when m0 is None); each pass solves min ||diag(w) (A p - (y - offset))||
 *     subject to p >= 0 on unit-norm columns by the active-set method of Lawson & Hanson (1974, ch. 23) on
 *     the k x k triangle of a Householder QR of the weighted columns (the same objective up to a constant),
 *     each passive-set least-squares problem by Householder QR; the model is floored at 1e-6 y, and the
 *     iteration stops once it moves by less than rtol (relative) at every tau, or after n_iter passes.
 *     Returns chi2 = sum edf/2 ((y - m)/m)^2 (or None when an NNLS pass exceeds 50 k steps: p and m then
 *     hold the last completed pass, as the Python path keeps its last solution). Small problems (k columns
 *     <= 16, the AV basis); the Python path calls scipy.optimize.nnls per pass, ~40 us of overhead each.
 *
 * riccati_fixes, mismatched_fixes, replay_fixes
 *     The per-fix loops of the exact covariance verification (imupipe.covariance.filter_variance,
 *     imupipe.covariance.mismatched_mse_many, imupipe.verify._replay_errors; Gelb 1974, section 7.2): the
 *     filter's Riccati recursion with its convergence test, the truths' augmented second-moment recursion
 *     C <- B (A C A^T + S) B^T + R [0; K][0; K]^T (a rank-1 fix update), and the replay's estimate update over all
 *     windows; one C iteration per fix, A C A^T from the nonzero entries of A's rows (section before
 *     py_riccati_fixes). The NumPy paths give the same results to rounding (tests: 1e-12 relative).
 *
 * Design (measured on a 2-core AMD EPYC, 4.5e6 samples, 100 log-spaced lags):
 *   - the inner loop keeps W = 8 independent partial sums, so that the compiler vectorises it without
 *     -ffast-math (no reassociation of one accumulator is needed); target_clones adds an AVX2 version chosen
 *     at load time;
 *   - summation is two-level: each block of BLOCK terms is summed into the 8 lanes, the block totals are
 *     added in double.  The worst-case relative rounding error of a sum of n positive terms is then about
 *     (BLOCK/8 + n/BLOCK) u instead of (n/8) u (u = 2^-53);
 *   - small lags (m <= SMALL_LAG) are processed blocked over k: for each block of BLOCK values of k, every
 *     small lag is summed while theta[k .. k + BLOCK + 2m] is in cache.  Large lags stream from memory, one
 *     pass per lag, the floor for a method that reads theta once per lag;
 *   - the GIL is released during the loops.
 * No NumPy C headers are used: only the buffer protocol.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <limits.h>
#include <math.h>
#include <float.h>
#include <stdint.h>
#include <string.h>

#ifndef IMUPIPE_BLOCK
#define IMUPIPE_BLOCK 16384 /* terms per block (128 KiB of theta): tuned by measurement, see bench_allan.py */
#endif
#ifndef IMUPIPE_SMALL_LAG
#define IMUPIPE_SMALL_LAG 8192 /* lags processed blocked: window BLOCK + 2m doubles stays in L2 */
#endif

#if defined(__GNUC__) && !defined(__clang__) && (defined(__x86_64__) || defined(__i386__)) && \
    defined(__has_attribute)
#if __has_attribute(target_clones)
#define IMUPIPE_CLONES __attribute__((target_clones("avx2", "default")))
#endif
#endif
#ifndef IMUPIPE_CLONES
#define IMUPIPE_CLONES
#endif

/* Sum of ((c[i] - b[i]) - (b[i] - a[i]))^2 for i < n, with 8 independent lanes. */
IMUPIPE_CLONES
static double block_sum(const double *restrict a, const double *restrict b, const double *restrict c,
                        Py_ssize_t n)
{
    double acc[8] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    Py_ssize_t i = 0;
    for (; i + 8 <= n; i += 8) {
        for (int l = 0; l < 8; l++) {
            double d = (c[i + l] - b[i + l]) - (b[i + l] - a[i + l]);
            acc[l] += d * d;
        }
    }
    double tail = 0.0;
    for (; i < n; i++) {
        double d = (c[i] - b[i]) - (b[i] - a[i]);
        tail += d * d;
    }
    return ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7])) + tail;
}

#ifndef IMUPIPE_LAG1_BLOCK
#define IMUPIPE_LAG1_BLOCK 2048 /* means per block of the lag-1 sums (16 KiB buffer: in L1) */
#endif

/* The nine lag-1 sums over z[k], k in [lo, n) with lo >= 3 (z[lo-3 .. lo-1] exist): with
 * d1[k] = z[k] - z[k-1] and d2[k] = d1[k] - d1[k-1], s += (sum z, sum z^2, sum z[k-1] z[k],
 * sum d1, sum d1^2, sum d1[k-1] d1[k], sum d2, sum d2^2, sum d2[k-1] d2[k]), one mean at a time: the
 * remainder of lag1_block, and lag1_block itself where the compiler has no vector extensions. */
static void lag1_scalar(const double *z, Py_ssize_t lo, Py_ssize_t n, double *s)
{
    for (Py_ssize_t k = lo; k < n; k++) {
        const double z0 = z[k], z1 = z[k - 1], z2 = z[k - 2], z3 = z[k - 3];
        const double a0 = z0 - z1, a1 = z1 - z2, a2 = z2 - z3;
        const double b0 = a0 - a1, b1 = a1 - a2;
        s[0] += z0;
        s[1] += z0 * z0;
        s[2] += z1 * z0;
        s[3] += a0;
        s[4] += a0 * a0;
        s[5] += a1 * a0;
        s[6] += b0;
        s[7] += b0 * b0;
        s[8] += b1 * b0;
    }
}

#if defined(__GNUC__) || defined(__clang__)
typedef double v4d __attribute__((vector_size(32))); /* four lanes; SSE2 pairs or one AVX register */
#define LOAD4(v, p) memcpy(&(v), (p), sizeof(v4d)) /* unaligned load */

/* lag1_scalar's sums with four lanes per sum, so that the loop vectorises without reassociating any one
 * accumulator. */
IMUPIPE_CLONES
static void lag1_block(const double *restrict z, Py_ssize_t lo, Py_ssize_t n, double *s)
{
    v4d acc[9];
    for (int q = 0; q < 9; q++)
        acc[q] = (v4d){0.0, 0.0, 0.0, 0.0};
    Py_ssize_t k = lo;
    for (; k + 4 <= n; k += 4) {
        v4d z0, z1, z2, z3;
        LOAD4(z0, z + k);
        LOAD4(z1, z + k - 1);
        LOAD4(z2, z + k - 2);
        LOAD4(z3, z + k - 3);
        const v4d a0 = z0 - z1, a1 = z1 - z2, a2 = z2 - z3;
        const v4d b0 = a0 - a1, b1 = a1 - a2;
        acc[0] += z0;
        acc[1] += z0 * z0;
        acc[2] += z1 * z0;
        acc[3] += a0;
        acc[4] += a0 * a0;
        acc[5] += a1 * a0;
        acc[6] += b0;
        acc[7] += b0 * b0;
        acc[8] += b1 * b0;
    }
    double tail[9] = {0.0};
    lag1_scalar(z, k, n, tail);
    for (int q = 0; q < 9; q++)
        s[q] += ((acc[q][0] + acc[q][2]) + (acc[q][1] + acc[q][3])) + tail[q];
}
#else
#define lag1_block lag1_scalar
#endif

/* Zero the nine lag-1 sums s of lag m and add the terms of the first min(N, 3) means, for which not
 * every difference exists yet (the rest: lag1_range). */
static void lag1_head(const double *theta, Py_ssize_t m, Py_ssize_t N, double *s)
{
    const double inv_m = 1.0 / (double)m;
    double z_prev = 0.0, d1_prev = 0.0;
    for (int k = 0; k < 9; k++)
        s[k] = 0.0;
    for (Py_ssize_t i = 0; i < N && i < 3; i++) {
        const double z = (theta[(i + 1) * m] - theta[i * m]) * inv_m;
        s[0] += z;
        s[1] += z * z;
        if (i >= 1) {
            const double d1 = z - z_prev;
            s[2] += z_prev * z;
            s[3] += d1;
            s[4] += d1 * d1;
            if (i >= 2) {
                const double d2 = d1 - d1_prev;
                s[5] += d1_prev * d1;
                s[6] += d2;
                s[7] += d2 * d2;
            }
            d1_prev = d1;
        }
        z_prev = z;
    }
}

/* Add the terms of means i in [i_lo, i_hi) (3 <= i_lo) of lag m to s: z gathered, per chunk of
 * LAG1_BLOCK means, into zb (room for LAG1_BLOCK + 3) from 3 means early -- the differences and lag-1
 * products reach back 3 means -- then the fused sums of lag1_block. */
static void lag1_range(const double *theta, Py_ssize_t m, Py_ssize_t i_lo, Py_ssize_t i_hi, double *zb,
                       double *s)
{
    const double inv_m = 1.0 / (double)m;
    for (Py_ssize_t i0 = i_lo; i0 < i_hi; i0 += IMUPIPE_LAG1_BLOCK) {
        const Py_ssize_t i1 = (i_hi - i0 < IMUPIPE_LAG1_BLOCK) ? i_hi : i0 + IMUPIPE_LAG1_BLOCK;
        const Py_ssize_t nb = i1 - i0 + 3; /* zb[k] is mean i0 - 3 + k */
        const double *t = theta + (i0 - 3) * m;
        if (m == 1)
            for (Py_ssize_t k = 0; k < nb; k++)
                zb[k] = t[k + 1] - t[k];
        else
            for (Py_ssize_t k = 0; k < nb; k++)
                zb[k] = (t[(k + 1) * m] - t[k * m]) * inv_m;
        lag1_block(zb, 3, nb, s);
    }
}

static void lag1_sums_impl(const double *theta, Py_ssize_t L, const int64_t *lags, Py_ssize_t nlags,
                           double *out)
{
    double zb[IMUPIPE_LAG1_BLOCK + 3];
    for (Py_ssize_t j = 0; j < nlags; j++) {
        const Py_ssize_t m = (Py_ssize_t)lags[j], N = (L - 1) / m;
        lag1_head(theta, m, N, out + 9 * j);
        lag1_range(theta, m, 3, N, zb, out + 9 * j);
    }
}

/* out[j]: the overlapping sums of lag lags[j]; with out9 != NULL also its nine lag-1 sums (as
 * lag1_sums_impl) into out9[9j ..], the small lags' means summed while their block of theta is in cache
 * (the noise identification then costs no extra pass over memory). */
static void oavar_sums_impl(const double *theta, Py_ssize_t L, const int64_t *lags, Py_ssize_t nlags,
                            double *out, double *out9, Py_ssize_t *next_mean)
{
    const Py_ssize_t block = IMUPIPE_BLOCK;
    double zb[IMUPIPE_LAG1_BLOCK + 3];
    Py_ssize_t kmax = 0; /* largest number of terms among the small lags */
    for (Py_ssize_t j = 0; j < nlags; j++) {
        out[j] = 0.0;
        if (lags[j] <= IMUPIPE_SMALL_LAG && L - 2 * lags[j] > kmax)
            kmax = L - 2 * lags[j];
        if (out9 != NULL) {
            lag1_head(theta, (Py_ssize_t)lags[j], (L - 1) / lags[j], out9 + 9 * j);
            next_mean[j] = 3;
        }
    }
    /* small lags: blocked over k, every small lag per block */
    for (Py_ssize_t k0 = 0; k0 < kmax; k0 += block) {
        for (Py_ssize_t j = 0; j < nlags; j++) {
            const Py_ssize_t m = (Py_ssize_t)lags[j];
            if (m > IMUPIPE_SMALL_LAG)
                continue;
            const Py_ssize_t K = L - 2 * m;
            if (k0 >= K)
                continue;
            const Py_ssize_t n = (K - k0 < block) ? K - k0 : block;
            out[j] += block_sum(theta + k0, theta + k0 + m, theta + k0 + 2 * m, n);
            if (out9 != NULL) { /* means starting in [k0, k0 + n); all the rest in the lag's last block */
                const Py_ssize_t N = (L - 1) / m;
                Py_ssize_t i_hi = (k0 + n >= K) ? N : (k0 + n + m - 1) / m;
                if (i_hi > N)
                    i_hi = N;
                if (i_hi > next_mean[j]) {
                    lag1_range(theta, m, next_mean[j], i_hi, zb, out9 + 9 * j);
                    next_mean[j] = i_hi;
                }
            }
        }
    }
    /* large lags: streamed, one pass each */
    for (Py_ssize_t j = 0; j < nlags; j++) {
        const Py_ssize_t m = (Py_ssize_t)lags[j];
        if (m <= IMUPIPE_SMALL_LAG)
            continue;
        const Py_ssize_t K = L - 2 * m;
        double total = 0.0;
        for (Py_ssize_t k0 = 0; k0 < K; k0 += block) {
            const Py_ssize_t n = (K - k0 < block) ? K - k0 : block;
            total += block_sum(theta + k0, theta + k0 + m, theta + k0 + 2 * m, n);
        }
        out[j] = total;
        if (out9 != NULL)
            lag1_range(theta, m, 3, (L - 1) / m, zb, out9 + 9 * j);
    }
}

/* theta[0] = 0, theta[k+1] = theta[k] + (y[k] - mean): the integrated mean-removed signal, summed in the
 * same order as numpy.cumsum(y - mean) (bit-identical), without the temporary y - mean. */
static void integrate_impl(const double *y, Py_ssize_t n, double mean, double *theta)
{
    double acc = 0.0;
    theta[0] = 0.0;
    for (Py_ssize_t k = 0; k < n; k++) {
        acc += y[k] - mean;
        theta[k + 1] = acc;
    }
}

IMUPIPE_CLONES
static void ar1_impl(double *e, Py_ssize_t rows, Py_ssize_t n, double phi)
{
    for (Py_ssize_t r = 0; r < rows; r++) {
        double *x = e + r * n;
        for (Py_ssize_t i = 1; i < n; i++)
            x[i] = phi * x[i - 1] + x[i];
    }
}

IMUPIPE_CLONES
static void car1_impl(double *z, Py_ssize_t rows, Py_ssize_t n, double mr, double mi)
{
    for (Py_ssize_t r = 0; r < rows; r++) {
        double *x = z + 2 * r * n;
        double sr = x[0], si = x[1];
        for (Py_ssize_t i = 1; i < n; i++) {
            double tr = mr * sr - mi * si, ti = mr * si + mi * sr;
            sr = tr + x[2 * i];
            si = ti + x[2 * i + 1];
            x[2 * i] = sr;
            x[2 * i + 1] = si;
        }
    }
}

#define IMUPIPE_MAX_BRANCHES 64

/* The flicker bank of J <= IMUPIPE_MAX_BRANCHES branches over rows of n samples (see the header). Each branch's
 * update is fl(fl(p u) + fl(wt w)) and the output fl(...fl(fl(direct w) + u_0) ... + u_{J-1}), the NumPy passes'
 * operations; the branch states stay in a local array (registers/L1) across the samples. */
IMUPIPE_CLONES
static void flicker_bank_impl(const double *w, double *y, double *state, const double *p, const double *wt,
                              double direct, Py_ssize_t rows, Py_ssize_t n, Py_ssize_t J)
{
    double u[IMUPIPE_MAX_BRANCHES], pp[IMUPIPE_MAX_BRANCHES], ww[IMUPIPE_MAX_BRANCHES];
    for (Py_ssize_t i = 0; i < J; i++) {
        pp[i] = p[i];
        ww[i] = wt[i];
    }
    for (Py_ssize_t r = 0; r < rows; r++) {
        const double *x = w + r * n;
        double *out = y + r * n;
        double *st = state + r * J;
        for (Py_ssize_t i = 0; i < J; i++)
            u[i] = st[i];
        for (Py_ssize_t k = 0; k < n; k++) {
            const double wk = x[k];
            for (Py_ssize_t i = 0; i < J; i++) {
                const double a = pp[i] * u[i];
                const double b = ww[i] * wk;
                u[i] = a + b;
            }
            double acc = direct * wk;
            for (Py_ssize_t i = 0; i < J; i++)
                acc += u[i];
            out[k] = acc;
        }
        for (Py_ssize_t i = 0; i < J; i++)
            st[i] = u[i];
    }
}

#define IMUPIPE_MAX_GM 16

/* sim_piece (see the header): the terms added in the order of the NumPy passes, one pass over the samples. */
static double sim_piece_impl(double *x, Py_ssize_t m, const double *white, double sw, const double *gm,
                             const double *phi, const double *scale, double *last, Py_ssize_t G, int first,
                             const double *rw, double krw, double rw_sum)
{
    double g[IMUPIPE_MAX_GM];
    double c = 0.0, v = rw_sum;
    for (Py_ssize_t j = 0; j < G; j++)
        g[j] = last[j];
    for (Py_ssize_t k = 0; k < m; k++) {
        double acc = 0.0;
        if (white)
            acc += white[k] * sw;
        for (Py_ssize_t j = 0; j < G; j++) {
            const double e = gm[j * m + k] * scale[j];
            if (k == 0 && first)
                g[j] = last[j];
            else {
                const double a = phi[j] * g[j];
                g[j] = a + e;
            }
            acc += g[j];
        }
        if (rw) {
            c = k == 0 ? rw[0] : c + rw[k];
            v = c + rw_sum;
            acc += v * krw;
        }
        x[k] = acc;
    }
    for (Py_ssize_t j = 0; j < G; j++)
        last[j] = g[j];
    return v;
}

/* Levene W (median-centred) of k sorted segments of m samples each: s[i*m + j]. */
static double levene_sorted(const double *s, Py_ssize_t k, Py_ssize_t m)
{
    double zbar = 0.0, between = 0.0, within = 0.0;
    double zi[64];
    double *zmean = k <= 64 ? zi : PyMem_RawMalloc((size_t)k * sizeof(double));
    if (zmean == NULL)
        return -1.0; /* caller checks */
    for (Py_ssize_t i = 0; i < k; i++) {
        const double *x = s + i * m;
        const double med = (m % 2) ? x[m / 2] : (x[m / 2 - 1] + x[m / 2]) / 2.0;
        double acc = 0.0;
        for (Py_ssize_t j = 0; j < m; j++)
            acc += x[j] > med ? x[j] - med : med - x[j];
        zmean[i] = acc / (double)m;
        zbar += zmean[i];
    }
    zbar /= (double)k;
    for (Py_ssize_t i = 0; i < k; i++) {
        const double *x = s + i * m;
        const double med = (m % 2) ? x[m / 2] : (x[m / 2 - 1] + x[m / 2]) / 2.0;
        const double zm = zmean[i];
        double acc = 0.0;
        for (Py_ssize_t j = 0; j < m; j++) {
            const double z = (x[j] > med ? x[j] - med : med - x[j]) - zm;
            acc += z * z;
        }
        within += acc;
        between += (zm - zbar) * (zm - zbar);
    }
    between *= (double)m;
    if (zmean != zi)
        PyMem_RawFree(zmean);
    if (within > 0.0)
        return (double)(k * m - k) / (double)(k - 1) * between / within;
    return between > 0.0 ? Py_HUGE_VAL : 0.0;
}

/* max |#{a <= v} - #{b <= v}| over v, for sorted a and b of m samples each (ties read after the run) */
static Py_ssize_t ks_count_sorted(const double *a, const double *b, Py_ssize_t m)
{
    Py_ssize_t ia = 0, ib = 0, best = 0;
    while (ia < m && ib < m) {
        const double v = a[ia] < b[ib] ? a[ia] : b[ib];
        while (ia < m && a[ia] == v)
            ia++;
        while (ib < m && b[ib] == v)
            ib++;
        const Py_ssize_t dif = ia > ib ? ia - ib : ib - ia;
        if (dif > best)
            best = dif;
    }
    return best; /* once one run is exhausted the difference only shrinks */
}

/* order-preserving map of a double's bits to an unsigned key (negative: all bits flipped; else sign set) */
static inline uint64_t f64_key(double v)
{
    uint64_t u;
    memcpy(&u, &v, sizeof u);
    return (u >> 63) ? ~u : (u | 0x8000000000000000ULL);
}

static inline double key_f64(uint64_t u)
{
    u = (u >> 63) ? (u & 0x7FFFFFFFFFFFFFFFULL) : ~u;
    double v;
    memcpy(&v, &u, sizeof v);
    return v;
}

#define RADIX_BITS 11
#define RADIX_SIZE (1 << RADIX_BITS)
#define RADIX_PASSES 6 /* 6 x 11 >= 64 bits */

/* out[0..n) = in[0..n) sorted ascending; a, b: scratch of n keys; hist: RADIX_PASSES * RADIX_SIZE counts */
static void radix_sort_f64(const double *in, Py_ssize_t n, double *out, uint64_t *a, uint64_t *b, Py_ssize_t *hist)
{
    memset(hist, 0, RADIX_PASSES * RADIX_SIZE * sizeof(Py_ssize_t));
    for (Py_ssize_t i = 0; i < n; i++) {
        const uint64_t key = f64_key(in[i]);
        a[i] = key;
        for (int p = 0; p < RADIX_PASSES; p++)
            hist[p * RADIX_SIZE + ((key >> (p * RADIX_BITS)) & (RADIX_SIZE - 1))]++;
    }
    uint64_t *src = a, *dst = b;
    for (int p = 0; p < RADIX_PASSES; p++) {
        Py_ssize_t *h = hist + p * RADIX_SIZE;
        const int shift = p * RADIX_BITS;
        if (n == 0 || h[(src[0] >> shift) & (RADIX_SIZE - 1)] == n)
            continue; /* every key has this digit: the pass would not move anything */
        Py_ssize_t total = 0;
        for (int j = 0; j < RADIX_SIZE; j++) {
            const Py_ssize_t c = h[j];
            h[j] = total;
            total += c;
        }
        for (Py_ssize_t i = 0; i < n; i++) {
            const uint64_t key = src[i];
            dst[h[(key >> shift) & (RADIX_SIZE - 1)]++] = key;
        }
        uint64_t *t = src;
        src = dst;
        dst = t;
    }
    for (Py_ssize_t i = 0; i < n; i++)
        out[i] = key_f64(src[i]);
}

/* scratch: k*m doubles, 2*m keys, the histograms; returns -1 when it cannot be allocated */
static int segment_stats_impl(const double *x, Py_ssize_t rows, Py_ssize_t n, Py_ssize_t k, Py_ssize_t m,
                              double *w, double *d)
{
    double *sorted = PyMem_RawMalloc((size_t)(k * m) * sizeof(double));
    uint64_t *keys = PyMem_RawMalloc((size_t)(2 * m) * sizeof(uint64_t));
    Py_ssize_t *hist = PyMem_RawMalloc((size_t)RADIX_PASSES * RADIX_SIZE * sizeof(Py_ssize_t));
    int status = 0;
    if (sorted == NULL || keys == NULL || hist == NULL) {
        status = -1;
        goto done;
    }
    for (Py_ssize_t r = 0; r < rows; r++) {
        for (Py_ssize_t i = 0; i < k; i++)
            radix_sort_f64(x + r * n + i * m, m, sorted + i * m, keys, keys + m, hist);
        w[r] = levene_sorted(sorted, k, m);
        if (w[r] < 0.0) {
            status = -1;
            goto done;
        }
        Py_ssize_t best = 0;
        for (Py_ssize_t i = 0; i + 1 < k; i++) {
            const Py_ssize_t c = ks_count_sorted(sorted + i * m, sorted + (i + 1) * m, m);
            if (c > best)
                best = c;
        }
        d[r] = (double)best / (double)m;
    }
done:
    PyMem_RawFree(sorted);
    PyMem_RawFree(keys);
    PyMem_RawFree(hist);
    return status;
}

/* ---------------------------------------------------------------------------------------------------------
 * wnnls: re-weighted NNLS (see the header)
 * ------------------------------------------------------------------------------------------------------- */
#define WNNLS_MAX_K 16

/* Euclidean norm of v[j..n), scaled by the largest magnitude against overflow and underflow. */
static double tail_norm(const double *v, Py_ssize_t j, Py_ssize_t n)
{
    double scale = 0.0;
    for (Py_ssize_t i = j; i < n; i++)
        scale = fmax(scale, fabs(v[i]));
    double norm = 0.0;
    if (scale > 0.0) {
        for (Py_ssize_t i = j; i < n; i++)
            norm += (v[i] / scale) * (v[i] / scale);
        norm = scale * sqrt(norm);
    }
    return norm;
}

/* One Householder step on column j of M (n rows, column-major), norm = tail_norm(column j, j, n) > 0: the
 * reflector I - 2 v v^T / v^T v with v = x - alpha e_j is formed in place in M[j..n) of column j and applied to
 * columns j+1 .. ncols-1 of M and to rhs. Returns alpha = R_jj (column j's own entry j is left as v_j). */
static double householder_step(double *M, Py_ssize_t n, int j, int ncols, double *rhs, double norm)
{
    double *v = M + (size_t)n * j;
    double alpha = v[j] > 0.0 ? -norm : norm;
    v[j] -= alpha;
    double vtv = 0.0;
    for (Py_ssize_t i = j; i < n; i++)
        vtv += v[i] * v[i];
    for (int l = j + 1; l < ncols; l++) {
        double *u = M + (size_t)n * l, d = 0.0;
        for (Py_ssize_t i = j; i < n; i++)
            d += v[i] * u[i];
        d = 2.0 * d / vtv;
        for (Py_ssize_t i = j; i < n; i++)
            u[i] -= d * v[i];
    }
    double d = 0.0;
    for (Py_ssize_t i = j; i < n; i++)
        d += v[i] * rhs[i];
    d = 2.0 * d / vtv;
    for (Py_ssize_t i = j; i < n; i++)
        rhs[i] -= d * v[i];
    return alpha;
}

/* Least squares on the columns P[0..q) of B (n x k, column-major): z[P[j]] = argmin ||B_P z - b||, by
 * Householder QR of a copy (work: n*q + n doubles). Returns 0, or -1 when a diagonal of R is below
 * 1e-12 of its column's norm (the new column depends on the others). */
static int ls_passive(const double *B, const double *b, Py_ssize_t n, const int *P, int q, double *z,
                      double *work)
{
    double *Q = work, *c = work + n * q;
    for (int j = 0; j < q; j++)
        memcpy(Q + (size_t)n * j, B + (size_t)n * P[j], (size_t)n * sizeof(double));
    memcpy(c, b, (size_t)n * sizeof(double));
    double rdiag[WNNLS_MAX_K];
    for (int j = 0; j < q; j++) {
        const double *v = Q + (size_t)n * j;
        double norm = tail_norm(v, j, n);
        double colnorm = 0.0; /* the column's full norm, for the rank test */
        for (Py_ssize_t i = 0; i < n; i++)
            colnorm += v[i] * v[i];
        colnorm = sqrt(colnorm);
        if (!(norm > 1e-12 * colnorm))
            return -1;
        rdiag[j] = householder_step(Q, n, j, q, c, norm);
    }
    /* back substitution R zq = c[0..q); R's off-diagonal entries are Q[n*l + j], l > j */
    for (int j = q - 1; j >= 0; j--) {
        double t = c[j];
        for (int l = j + 1; l < q; l++)
            t -= Q[(size_t)n * l + j] * z[P[l]];
        z[P[j]] = t / rdiag[j];
    }
    return 0;
}

/* min ||B x - b|| subject to x >= 0 (Lawson & Hanson's NNLS). B: n x k column-major; gradient entries
 * B_j^T (b - B x) <= tol count as zero. Returns 0, or -1 after max_steps steps. work: n*k + 2n doubles. */
static int nnls_lh(const double *B, const double *b, Py_ssize_t n, int k, double *x, int max_steps, double tol,
                   double *work)
{
    int passive[WNNLS_MAX_K], P[WNNLS_MAX_K], refused[WNNLS_MAX_K];
    double z[WNNLS_MAX_K];
    double *r = work + (size_t)n * k + n, *qr = work;
    for (int j = 0; j < k; j++) {
        x[j] = 0.0;
        passive[j] = 0;
        refused[j] = 0;
    }
    int steps = 0;
    for (;;) {
        /* gradient g = B^T (b - B x) */
        for (Py_ssize_t i = 0; i < n; i++)
            r[i] = b[i];
        for (int j = 0; j < k; j++)
            if (x[j] != 0.0)
                for (Py_ssize_t i = 0; i < n; i++)
                    r[i] -= B[(size_t)n * j + i] * x[j];
        int jmax = -1;
        double gmax = tol;
        for (int j = 0; j < k; j++) {
            double d = 0.0;
            for (Py_ssize_t i = 0; i < n; i++)
                d += B[(size_t)n * j + i] * r[i];
            if (!passive[j] && !refused[j] && d > gmax) {
                gmax = d;
                jmax = j;
            }
        }
        if (jmax < 0)
            return 0;
        passive[jmax] = 1;
        /* inner loop: least squares on the passive set, stepping back to feasibility */
        int first = 1;
        for (;;) {
            if (++steps > max_steps)
                return -1;
            int q = 0;
            for (int j = 0; j < k; j++) {
                z[j] = 0.0;
                if (passive[j])
                    P[q++] = j;
            }
            if (ls_passive(B, b, n, P, q, z, qr) < 0 || (first && !(z[jmax] > 0.0))) {
                /* the new column is dependent on the passive ones, or rounding makes its coefficient <= 0:
                 * refuse it until the next accepted step (Lawson & Hanson's safeguard) */
                passive[jmax] = 0;
                refused[jmax] = 1;
                break;
            }
            first = 0;
            double alpha = 2.0;
            for (int j = 0; j < k; j++)
                if (passive[j] && z[j] <= 0.0) {
                    double a = x[j] / (x[j] - z[j]);
                    if (a < alpha)
                        alpha = a;
                }
            if (alpha > 1.0) { /* z feasible */
                for (int j = 0; j < k; j++)
                    x[j] = z[j];
                for (int j = 0; j < k; j++)
                    refused[j] = 0;
                break;
            }
            for (int j = 0; j < k; j++) {
                if (!passive[j])
                    continue;
                x[j] += alpha * (z[j] - x[j]);
                if (x[j] <= 0.0 || (z[j] <= 0.0 && x[j] <= tol)) {
                    x[j] = 0.0;
                    passive[j] = 0;
                }
            }
        }
    }
}

/* Householder QR of B (n x k column-major, n >= k, overwritten) applied to b too: on return R (k x k,
 * column-major, zero below the diagonal) and c = the first k entries of Q^T b, so that
 * ||B x - b||^2 = ||R x - c||^2 + const for every x: the NNLS of B, b and of R, c have the same solution, and
 * each of its least-squares steps then costs O(k^3) instead of O(n k^2). */
static void qr_reduce(double *B, double *b, Py_ssize_t n, int k, double *R, double *c)
{
    for (int j = 0; j < k; j++) {
        double norm = tail_norm(B + (size_t)n * j, j, n);
        if (norm == 0.0) /* nothing left below the diagonal: no reflection */
            continue;
        /* R_jj (the entries below it hold the reflector and are not copied to R) */
        B[(size_t)n * j + j] = householder_step(B, n, j, k, b, norm);
    }
    for (int j = 0; j < k; j++) {
        for (int i = 0; i < k; i++)
            R[(size_t)k * j + i] = i <= j ? B[(size_t)n * j + i] : 0.0;
        c[j] = b[j];
    }
}

static double wnnls_impl(const double *A, const double *y, const double *edf, const double *m0, const double *off,
                         Py_ssize_t n, int k, int n_iter, double rtol, double *p, double *m, double *work)
{
    double *s = work, *tgt = work + n, *m_new = work + 2 * n, *B = work + 3 * n, *bw = B + (size_t)n * k;
    double *nw = bw + n, col[WNNLS_MAX_K], ps[WNNLS_MAX_K], R[WNNLS_MAX_K * WNNLS_MAX_K], c[WNNLS_MAX_K];
    for (Py_ssize_t i = 0; i < n; i++) {
        s[i] = sqrt(edf[i] / 2.0);
        tgt[i] = off ? y[i] - off[i] : y[i];
        m[i] = m0 ? fmax(m0[i], 1e-6 * y[i]) : y[i];
    }
    for (int j = 0; j < k; j++)
        p[j] = 0.0;
    for (int it = 0; it < n_iter; it++) {
        for (int j = 0; j < k; j++) {
            double c = 0.0;
            for (Py_ssize_t i = 0; i < n; i++) {
                double v = A[i * k + j] * (s[i] / m[i]);
                B[(size_t)n * j + i] = v;
                c += v * v;
            }
            c = sqrt(c);
            col[j] = c == 0.0 ? 1.0 : c;
            for (Py_ssize_t i = 0; i < n; i++)
                B[(size_t)n * j + i] /= col[j];
        }
        double bnorm = 0.0;
        for (Py_ssize_t i = 0; i < n; i++) {
            bw[i] = tgt[i] * (s[i] / m[i]);
            bnorm += bw[i] * bw[i];
        }
        /* a gradient entry within rounding of zero is zero: |B_j^T r| <~ sqrt(n) eps ||b|| per unit column */
        const double tol = 10.0 * DBL_EPSILON * sqrt((double)n) * sqrt(bnorm);
        int status;
        if (n > k) { /* reduce to the k x k triangle first */
            qr_reduce(B, bw, n, k, R, c);
            status = nnls_lh(R, c, k, k, ps, 50 * k, tol, nw);
        } else {
            status = nnls_lh(B, bw, n, k, ps, 50 * k, tol, nw);
        }
        if (status < 0) /* NNLS step limit: keep the last pass's model, as the Python path does */
            break;
        for (int j = 0; j < k; j++)
            p[j] = ps[j] / col[j];
        double change = 0.0;
        for (Py_ssize_t i = 0; i < n; i++) {
            double v = off ? off[i] : 0.0;
            for (int j = 0; j < k; j++)
                v += A[i * k + j] * p[j];
            v = fmax(v, 1e-6 * y[i]);
            change = fmax(change, fabs(v - m[i]) / m[i]);
            m_new[i] = v;
        }
        memcpy(m, m_new, (size_t)n * sizeof(double));
        if (change < rtol)
            break;
    }
    double chi2 = 0.0;
    for (Py_ssize_t i = 0; i < n; i++) {
        double r = (y[i] - m[i]) / m[i];
        chi2 += edf[i] / 2.0 * r * r;
    }
    return chi2;
}

static int check_buffer_nd(const Py_buffer *view, const char *name, char kind, Py_ssize_t itemsize, int max_ndim)
{
    /* kind 'f': float64; kind 'i': 64-bit signed integer (format 'q', 'l' or 'n' of size 8) */
    const char *fmt = view->format ? view->format : "B";
    if (*fmt == '@' || *fmt == '=' || *fmt == '<')
        fmt++;
    int ok;
    if (kind == 'f')
        ok = (strcmp(fmt, "d") == 0);
    else
        ok = (strcmp(fmt, "q") == 0 || strcmp(fmt, "l") == 0 || strcmp(fmt, "n") == 0);
    if (!ok || view->itemsize != itemsize) {
        PyErr_Format(PyExc_TypeError, "%s must be a contiguous buffer of %s, got format '%s' itemsize %zd",
                     name, kind == 'f' ? "float64" : "int64", view->format ? view->format : "B",
                     view->itemsize);
        return -1;
    }
    if (view->ndim > max_ndim) {
        PyErr_Format(PyExc_ValueError, "%s must be one-dimensional, got %d dimensions", name, view->ndim);
        return -1;
    }
    return 0;
}

/* kind and item size checked, one dimension (a C-contiguous buffer of any shape: max_ndim = INT_MAX) */
static int check_buffer(const Py_buffer *view, const char *name, char kind, Py_ssize_t itemsize)
{
    return check_buffer_nd(view, name, kind, itemsize, 1);
}

static PyObject *py_oavar_sums(PyObject *self, PyObject *args)
{
    PyObject *theta_obj, *lags_obj, *out_obj, *out9_obj = Py_None;
    Py_buffer theta = {0}, lags = {0}, out = {0}, out9 = {0};
    Py_ssize_t *next_mean = NULL;
    PyObject *result = NULL;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOO|O:oavar_sums", &theta_obj, &lags_obj, &out_obj, &out9_obj))
        return NULL;
    /* buffer protocol with the element format, so that a float32 or int32 array is refused, not misread */
    if (PyObject_GetBuffer(theta_obj, &theta, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
        goto done;
    if (PyObject_GetBuffer(lags_obj, &lags, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
        goto done;
    if (PyObject_GetBuffer(out_obj, &out, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0)
        goto done;
    if (out9_obj != Py_None &&
        PyObject_GetBuffer(out9_obj, &out9, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0)
        goto done;
    if (check_buffer(&theta, "theta", 'f', 8) < 0 || check_buffer(&lags, "lags", 'i', 8) < 0 ||
        check_buffer(&out, "out", 'f', 8) < 0 || (out9.obj != NULL && check_buffer(&out9, "out9", 'f', 8) < 0))
        goto done;
    const Py_ssize_t L = theta.len / 8, nlags = lags.len / 8;
    if (out.len / 8 != nlags) {
        PyErr_Format(PyExc_ValueError, "out has %zd elements, lags has %zd", out.len / 8, nlags);
        goto done;
    }
    if (out9.obj != NULL && out9.len / 8 != 9 * nlags) {
        PyErr_Format(PyExc_ValueError, "out9 has %zd elements, 9 * len(lags) = %zd needed", out9.len / 8,
                     9 * nlags);
        goto done;
    }
    const int64_t *m = (const int64_t *)lags.buf;
    for (Py_ssize_t j = 0; j < nlags; j++) {
        if (m[j] < 1 || 2 * m[j] > L - 1) {
            PyErr_Format(PyExc_ValueError,
                         "lag m=%lld outside 1 <= m <= (L-1)/2 for a cumulative sum of L=%zd points",
                         (long long)m[j], L);
            goto done;
        }
    }
    if (out9.obj != NULL && (next_mean = PyMem_Malloc((nlags > 0 ? nlags : 1) * sizeof(Py_ssize_t))) == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    oavar_sums_impl((const double *)theta.buf, L, m, nlags, (double *)out.buf,
                    out9.obj != NULL ? (double *)out9.buf : NULL, next_mean);
    Py_END_ALLOW_THREADS
    result = Py_NewRef(Py_None);
done:
    /* PyBuffer_Release is a no-op on a view whose obj is NULL (never acquired) */
    PyMem_Free(next_mean);
    PyBuffer_Release(&theta);
    PyBuffer_Release(&lags);
    PyBuffer_Release(&out);
    PyBuffer_Release(&out9);
    return result;
}

static PyObject *py_lag1_sums(PyObject *self, PyObject *args)
{
    PyObject *theta_obj, *lags_obj, *out_obj;
    Py_buffer theta = {0}, lags = {0}, out = {0};
    PyObject *result = NULL;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOO:lag1_sums", &theta_obj, &lags_obj, &out_obj))
        return NULL;
    if (PyObject_GetBuffer(theta_obj, &theta, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
        goto done;
    if (PyObject_GetBuffer(lags_obj, &lags, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
        goto done;
    if (PyObject_GetBuffer(out_obj, &out, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0)
        goto done;
    if (check_buffer(&theta, "theta", 'f', 8) < 0 || check_buffer(&lags, "lags", 'i', 8) < 0 ||
        check_buffer(&out, "out", 'f', 8) < 0)
        goto done;
    const Py_ssize_t L = theta.len / 8, nlags = lags.len / 8;
    if (out.len / 8 != 9 * nlags) {
        PyErr_Format(PyExc_ValueError, "out has %zd elements, 9 * len(lags) = %zd needed", out.len / 8,
                     9 * nlags);
        goto done;
    }
    const int64_t *m = (const int64_t *)lags.buf;
    for (Py_ssize_t j = 0; j < nlags; j++) {
        if (m[j] < 1 || 2 * m[j] > L - 1) {
            PyErr_Format(PyExc_ValueError,
                         "lag m=%lld outside 1 <= m <= (L-1)/2 for a cumulative sum of L=%zd points",
                         (long long)m[j], L);
            goto done;
        }
    }
    Py_BEGIN_ALLOW_THREADS
    lag1_sums_impl((const double *)theta.buf, L, m, nlags, (double *)out.buf);
    Py_END_ALLOW_THREADS
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&theta);
    PyBuffer_Release(&lags);
    PyBuffer_Release(&out);
    return result;
}

static PyObject *py_integrate(PyObject *self, PyObject *args)
{
    PyObject *y_obj, *theta_obj;
    double mean;
    Py_buffer y = {0}, theta = {0};
    PyObject *result = NULL;
    (void)self;
    if (!PyArg_ParseTuple(args, "OdO:integrate", &y_obj, &mean, &theta_obj))
        return NULL;
    if (PyObject_GetBuffer(y_obj, &y, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
        goto done;
    if (PyObject_GetBuffer(theta_obj, &theta, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0)
        goto done;
    if (check_buffer(&y, "y", 'f', 8) < 0 || check_buffer(&theta, "theta", 'f', 8) < 0)
        goto done;
    if (theta.len / 8 != y.len / 8 + 1) {
        PyErr_Format(PyExc_ValueError, "theta has %zd elements, len(y) + 1 = %zd needed", theta.len / 8,
                     y.len / 8 + 1);
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    integrate_impl((const double *)y.buf, y.len / 8, mean, (double *)theta.buf);
    Py_END_ALLOW_THREADS
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&y);
    PyBuffer_Release(&theta);
    return result;
}

static PyObject *py_ar1(PyObject *self, PyObject *args)
{
    PyObject *e_obj;
    double phi;
    Py_ssize_t n;
    Py_buffer e = {0};
    PyObject *result = NULL;
    (void)self;
    if (!PyArg_ParseTuple(args, "Odn:ar1", &e_obj, &phi, &n))
        return NULL;
    if (PyObject_GetBuffer(e_obj, &e, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0)
        goto done;
    /* rows are read from n: any C-contiguous shape is accepted */
    if (check_buffer_nd(&e, "e", 'f', 8, INT_MAX) < 0)
        goto done;
    if (n < 1 || (e.len / 8) % n != 0) {
        PyErr_Format(PyExc_ValueError, "e has %zd values, not a whole number of rows of n=%zd", e.len / 8, n);
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    ar1_impl((double *)e.buf, e.len / 8 / n, n, phi);
    Py_END_ALLOW_THREADS
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&e);
    return result;
}

static PyObject *py_car1(PyObject *self, PyObject *args)
{
    PyObject *z_obj;
    double mr, mi;
    Py_ssize_t n;
    Py_buffer z = {0};
    PyObject *result = NULL;
    (void)self;
    if (!PyArg_ParseTuple(args, "Oddn:car1", &z_obj, &mr, &mi, &n))
        return NULL;
    if (PyObject_GetBuffer(z_obj, &z, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0)
        goto done;
    /* the complex data as float64 pairs (z.view(numpy.float64)); rows are read from n */
    if (check_buffer_nd(&z, "z", 'f', 8, INT_MAX) < 0)
        goto done;
    if (n < 1 || (z.len / 16) % n != 0 || z.len % 16 != 0) {
        PyErr_Format(PyExc_ValueError, "z has %zd float64 values, not a whole number of rows of n=%zd complex values",
                     z.len / 8, n);
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    car1_impl((double *)z.buf, z.len / 16 / n, n, mr, mi);
    Py_END_ALLOW_THREADS
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&z);
    return result;
}

static PyObject *py_flicker_bank(PyObject *self, PyObject *args)
{
    PyObject *w_obj, *p_obj, *wt_obj, *st_obj, *y_obj;
    double direct;
    Py_ssize_t n;
    Py_buffer w = {0}, p = {0}, wt = {0}, st = {0}, y = {0};
    PyObject *result = NULL;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOdOOn:flicker_bank", &w_obj, &p_obj, &wt_obj, &direct, &st_obj, &y_obj, &n))
        return NULL;
    if (PyObject_GetBuffer(w_obj, &w, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0 ||
        PyObject_GetBuffer(p_obj, &p, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0 ||
        PyObject_GetBuffer(wt_obj, &wt, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0 ||
        PyObject_GetBuffer(st_obj, &st, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0 ||
        PyObject_GetBuffer(y_obj, &y, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0)
        goto done;
    if (check_buffer_nd(&w, "w", 'f', 8, INT_MAX) < 0 || check_buffer_nd(&p, "p", 'f', 8, 1) < 0 ||
        check_buffer_nd(&wt, "weights", 'f', 8, 1) < 0 || check_buffer_nd(&st, "state", 'f', 8, INT_MAX) < 0 ||
        check_buffer_nd(&y, "y", 'f', 8, INT_MAX) < 0)
        goto done;
    const Py_ssize_t J = p.len / 8;
    if (J < 1 || J > IMUPIPE_MAX_BRANCHES || wt.len != p.len) {
        PyErr_Format(PyExc_ValueError, "p and weights must hold the same number of branches, 1 to %d; got %zd and %zd",
                     IMUPIPE_MAX_BRANCHES, J, wt.len / 8);
        goto done;
    }
    if (n < 1 || (w.len / 8) % n != 0 || y.len != w.len) {
        PyErr_Format(PyExc_ValueError, "w and y must hold the same whole number of rows of n=%zd; got %zd and %zd values",
                     n, w.len / 8, y.len / 8);
        goto done;
    }
    const Py_ssize_t rows = w.len / 8 / n;
    if (st.len / 8 != rows * J) {
        PyErr_Format(PyExc_ValueError, "state must hold rows x J = %zd x %zd values, got %zd", rows, J, st.len / 8);
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    flicker_bank_impl((const double *)w.buf, (double *)y.buf, (double *)st.buf, (const double *)p.buf,
                      (const double *)wt.buf, direct, rows, n, J);
    Py_END_ALLOW_THREADS
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&w);
    PyBuffer_Release(&p);
    PyBuffer_Release(&wt);
    PyBuffer_Release(&st);
    PyBuffer_Release(&y);
    return result;
}

static PyObject *py_sim_piece(PyObject *self, PyObject *args)
{
    PyObject *x_obj, *white_obj, *gm_obj, *phi_obj, *scale_obj, *last_obj, *rw_obj;
    double sw, krw, rw_sum;
    int first;
    Py_buffer x = {0}, white = {0}, gm = {0}, phi = {0}, scale = {0}, last = {0}, rw = {0};
    PyObject *result = NULL;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOdOOOOpOdd:sim_piece", &x_obj, &white_obj, &sw, &gm_obj, &phi_obj, &scale_obj,
                          &last_obj, &first, &rw_obj, &krw, &rw_sum))
        return NULL;
    if (PyObject_GetBuffer(x_obj, &x, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0 ||
        check_buffer_nd(&x, "x", 'f', 8, 1) < 0)
        goto done;
    const Py_ssize_t m = x.len / 8;
    if (white_obj != Py_None && (PyObject_GetBuffer(white_obj, &white, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0 ||
                                 check_buffer_nd(&white, "white", 'f', 8, INT_MAX) < 0))
        goto done;
    if (rw_obj != Py_None && (PyObject_GetBuffer(rw_obj, &rw, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0 ||
                              check_buffer_nd(&rw, "rw", 'f', 8, INT_MAX) < 0))
        goto done;
    if (PyObject_GetBuffer(gm_obj, &gm, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0 ||
        PyObject_GetBuffer(phi_obj, &phi, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0 ||
        PyObject_GetBuffer(scale_obj, &scale, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0 ||
        PyObject_GetBuffer(last_obj, &last, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0)
        goto done;
    if (check_buffer_nd(&gm, "gm", 'f', 8, INT_MAX) < 0 || check_buffer_nd(&phi, "phi", 'f', 8, 1) < 0 ||
        check_buffer_nd(&scale, "scale", 'f', 8, 1) < 0 || check_buffer_nd(&last, "last", 'f', 8, 1) < 0)
        goto done;
    const Py_ssize_t G = phi.len / 8;
    if (G > IMUPIPE_MAX_GM || scale.len != phi.len || last.len != phi.len || gm.len != G * m * 8 ||
        (white.buf && white.len != m * 8) || (rw.buf && rw.len != m * 8) || m < 1) {
        PyErr_Format(PyExc_ValueError, "sim_piece: x of m=%zd >= 1 samples, white and rw of m (or None), gm of G x m "
                     "and phi, scale, last of G <= %d values expected (G=%zd, gm has %zd)", m, IMUPIPE_MAX_GM, G,
                     gm.len / 8);
        goto done;
    }
    double out;
    Py_BEGIN_ALLOW_THREADS
    out = sim_piece_impl((double *)x.buf, m, white.buf, sw, gm.buf, phi.buf, scale.buf, last.buf, G, first,
                         rw.buf, krw, rw_sum);
    Py_END_ALLOW_THREADS
    result = PyFloat_FromDouble(out);
done:
    PyBuffer_Release(&x);
    PyBuffer_Release(&white);
    PyBuffer_Release(&gm);
    PyBuffer_Release(&phi);
    PyBuffer_Release(&scale);
    PyBuffer_Release(&last);
    PyBuffer_Release(&rw);
    return result;
}

static PyObject *py_segment_stats(PyObject *self, PyObject *args)
{
    PyObject *x_obj, *w_obj, *d_obj;
    Py_ssize_t n, k, m;
    Py_buffer x = {0}, w = {0}, d = {0};
    PyObject *result = NULL;
    int status = 0;
    (void)self;
    if (!PyArg_ParseTuple(args, "OnnnOO:segment_stats", &x_obj, &n, &k, &m, &w_obj, &d_obj))
        return NULL;
    if (PyObject_GetBuffer(x_obj, &x, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
        goto done;
    if (PyObject_GetBuffer(w_obj, &w, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0)
        goto done;
    if (PyObject_GetBuffer(d_obj, &d, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0)
        goto done;
    if (check_buffer_nd(&x, "x", 'f', 8, INT_MAX) < 0 || check_buffer(&w, "w", 'f', 8) < 0 ||
        check_buffer(&d, "d", 'f', 8) < 0)
        goto done;
    const Py_ssize_t rows = w.len / 8;
    if (k < 2 || m < 1 || k * m > n || d.len / 8 != rows || x.len / 8 != rows * n) {
        PyErr_Format(PyExc_ValueError,
                     "segment_stats needs k >= 2, m >= 1, k * m <= n, len(d) == len(w) and len(x) == len(w) * n; "
                     "got n=%zd, k=%zd, m=%zd, len(w)=%zd, len(d)=%zd, len(x)=%zd", n, k, m, rows, d.len / 8,
                     x.len / 8);
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    status = segment_stats_impl((const double *)x.buf, rows, n, k, m, (double *)w.buf, (double *)d.buf);
    Py_END_ALLOW_THREADS
    if (status < 0) {
        PyErr_NoMemory();
        goto done;
    }
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&x);
    PyBuffer_Release(&w);
    PyBuffer_Release(&d);
    return result;
}

static PyObject *py_wnnls(PyObject *self, PyObject *args)
{
    PyObject *A_obj, *y_obj, *e_obj, *m0_obj, *off_obj, *p_obj, *m_obj;
    int n_iter;
    double rtol;
    Py_buffer A = {0}, y = {0}, e = {0}, m0 = {0}, off = {0}, p = {0}, m = {0};
    PyObject *result = NULL;
    double *work = NULL;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOOOidOO:wnnls", &A_obj, &y_obj, &e_obj, &m0_obj, &off_obj, &n_iter, &rtol,
                          &p_obj, &m_obj))
        return NULL;
    if (PyObject_GetBuffer(A_obj, &A, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0 ||
        PyObject_GetBuffer(y_obj, &y, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0 ||
        PyObject_GetBuffer(e_obj, &e, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0 ||
        (m0_obj != Py_None && PyObject_GetBuffer(m0_obj, &m0, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) ||
        (off_obj != Py_None && PyObject_GetBuffer(off_obj, &off, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) ||
        PyObject_GetBuffer(p_obj, &p, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0 ||
        PyObject_GetBuffer(m_obj, &m, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0)
        goto done;
    if (check_buffer_nd(&A, "A", 'f', 8, 2) < 0 || check_buffer(&y, "y", 'f', 8) < 0 ||
        check_buffer(&e, "edf", 'f', 8) < 0 || (m0.buf && check_buffer(&m0, "m0", 'f', 8) < 0) ||
        (off.buf && check_buffer(&off, "offset", 'f', 8) < 0) || check_buffer(&p, "p", 'f', 8) < 0 ||
        check_buffer(&m, "m", 'f', 8) < 0)
        goto done;
    const Py_ssize_t n = y.len / 8, k = p.len / 8;
    if (k < 1 || k > WNNLS_MAX_K || n < 1 || A.len / 8 != n * k || e.len / 8 != n || m.len / 8 != n ||
        (m0.buf && m0.len / 8 != n) || (off.buf && off.len / 8 != n) || n_iter < 1) {
        PyErr_Format(PyExc_ValueError,
                     "wnnls needs A of len(y) x len(p) values with 1 <= len(p) <= %d, edf, m (and m0, offset) of "
                     "len(y), n_iter >= 1; got len(A)=%zd, len(y)=%zd, len(p)=%zd, len(edf)=%zd, len(m)=%zd",
                     WNNLS_MAX_K, A.len / 8, n, k, e.len / 8, m.len / 8);
        goto done;
    }
    work = PyMem_Malloc(sizeof(double) * (size_t)(n * (2 * k + 8)));
    if (work == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    double chi2 = wnnls_impl((const double *)A.buf, (const double *)y.buf, (const double *)e.buf,
                             (const double *)m0.buf, (const double *)off.buf, n, (int)k, n_iter, rtol,
                             (double *)p.buf, (double *)m.buf, work);
    result = PyFloat_FromDouble(chi2);
done:
    PyMem_Free(work);
    PyBuffer_Release(&A);
    PyBuffer_Release(&y);
    PyBuffer_Release(&e);
    if (m0.buf)
        PyBuffer_Release(&m0);
    if (off.buf)
        PyBuffer_Release(&off);
    PyBuffer_Release(&p);
    PyBuffer_Release(&m);
    return result;
}

/* ---------------------------------------------------------------------------------------------
 * Per-fix loops of imupipe.covariance (filter_variance, mismatched_mse_many) and imupipe.verify
 * (_replay_errors): the same recursions as their NumPy paths, one C iteration per fix.
 *
 * The transitions are sparse (block-diagonal noise states, the kinematic integrator, the augmented
 * system's coupling block), so A C A^T is formed from the nonzero entries of A's rows (exact zeros
 * skipped: adding 0 * x is exact for finite x): O(nnz(A) n) per product instead of O(n^3).
 * ------------------------------------------------------------------------------------------- */

/* row-compressed nonzeros of a dense n x n matrix; ptr: n + 1, col/val: up to n * n */
static void sparse_rows(const double *A, Py_ssize_t n, Py_ssize_t *ptr, Py_ssize_t *col, double *val)
{
    Py_ssize_t p = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        ptr[i] = p;
        for (Py_ssize_t k = 0; k < n; k++) {
            if (A[i * n + k] != 0.0) {
                col[p] = k;
                val[p] = A[i * n + k];
                p++;
            }
        }
    }
    ptr[n] = p;
}

/* X = A C A^T + S for a symmetric C, A as sparse rows: tmp = A C (row i: axpys of C's rows), tmpT = its
   transpose (= C A^T), then row i of X = S[i] + sum_p A[i, col p] tmpT[col p] (axpys again: both passes are
   contiguous inner loops the compiler vectorises). X is the transpose of the NumPy path's (A @ C) @ A.T, equal to
   it up to rounding (C symmetric); both are symmetrised after the fix update. */
static void sandwich(Py_ssize_t n, const Py_ssize_t *ptr, const Py_ssize_t *col, const double *val,
                     const double *C, const double *S, double *tmp, double *X)
{
    for (Py_ssize_t i = 0; i < n; i++) {
        double *ti = X + i * n; /* X as scratch for A C */
        for (Py_ssize_t j = 0; j < n; j++)
            ti[j] = 0.0;
        for (Py_ssize_t p = ptr[i]; p < ptr[i + 1]; p++) {
            const double a = val[p];
            const double *ck = C + col[p] * n;
            for (Py_ssize_t j = 0; j < n; j++)
                ti[j] += a * ck[j];
        }
    }
    for (Py_ssize_t i = 0; i < n; i++)
        for (Py_ssize_t j = 0; j < n; j++)
            tmp[j * n + i] = X[i * n + j];
    for (Py_ssize_t i = 0; i < n; i++) {
        double *xi = X + i * n;
        memcpy(xi, S + i * n, (size_t)n * sizeof(double));
        for (Py_ssize_t p = ptr[i]; p < ptr[i + 1]; p++) {
            const double a = val[p];
            const double *tk = tmp + col[p] * n;
            for (Py_ssize_t j = 0; j < n; j++)
                xi[j] += a * tk[j];
        }
    }
}

/* r C r^T of a dense n x n C (the NumPy path's ((Rs @ C) * Rs).sum(axis=1) for one row) */
static double quad_form(Py_ssize_t n, const double *r, const double *C)
{
    double q = 0.0;
    for (Py_ssize_t b = 0; b < n; b++) {
        double s = 0.0;
        for (Py_ssize_t a = 0; a < n; a++)
            s += r[a] * C[a * n + b];
        q += s * r[b];
    }
    return q;
}

/* the variances of the m sub-steps after a fix (steps k0 .. k0 + m - 1, those >= 0) of the covariance C:
   m = 1: C[idx, idx] (the unit row e_idx; idx < 0: c C c^T with the row c); else Rs[s] C Rs[s]^T + sub[s] */
static void record_substeps(double *out, Py_ssize_t k0, Py_ssize_t m, Py_ssize_t n, const double *C,
                            const double *Rs, const double *sub, Py_ssize_t idx, const double *c, double *work)
{
    if (m == 1) {
        if (k0 < 0)
            return;
        if (idx >= 0) {
            out[k0] = C[idx * n + idx];
        } else {
            double q = 0.0;
            for (Py_ssize_t a = 0; a < n; a++) {
                double s = 0.0;
                for (Py_ssize_t b = 0; b < n; b++)
                    s += C[a * n + b] * c[b];
                work[a] = s;
            }
            for (Py_ssize_t a = 0; a < n; a++)
                q += c[a] * work[a];
            out[k0] = q;
        }
        return;
    }
    for (Py_ssize_t s = 0; s < m; s++) {
        if (k0 + s >= 0)
            out[k0 + s] = quad_form(n, Rs + s * n, C) + sub[s];
    }
}

/* the filter's Riccati recursion fix by fix until convergence (imupipe.covariance.filter_variance);
   returns the number of fixes done, *steady = 1 when it stopped on convergence. P holds the state after the
   last fix done. work: 5 n^2 + 2 n doubles, ptr n + 1, col n^2. */
static Py_ssize_t riccati_impl(Py_ssize_t n, const double *Am, const double *Sm, const double *h, double R,
                               double *P, Py_ssize_t J, Py_ssize_t m, const double *Rs, const double *sub,
                               double *pvar, double *gains, Py_ssize_t check_every, double p_rtol, int *steady,
                               double *work, Py_ssize_t *ptr, Py_ssize_t *col)
{
    double *val = work, *tmp = work + n * n, *X = work + 2 * n * n, *Pprev = work + 3 * n * n;
    double *u = work + 4 * n * n, *K = u + n, *sd = K + n;
    double d_prev = -1.0; /* none yet */
    Py_ssize_t j = 0;
    *steady = 0;
    sparse_rows(Am, n, ptr, col, val);
    while (j < J) {
        record_substeps(pvar, j * m - 1, m, n, P, Rs, sub, 0, NULL, NULL);
        sandwich(n, ptr, col, val, P, Sm, tmp, X);
        double s = 0.0;
        for (Py_ssize_t a = 0; a < n; a++) {
            double v = 0.0;
            for (Py_ssize_t b = 0; b < n; b++)
                v += X[a * n + b] * h[b];
            u[a] = v;
        }
        for (Py_ssize_t a = 0; a < n; a++)
            s += h[a] * u[a];
        s += R;
        for (Py_ssize_t a = 0; a < n; a++)
            K[a] = u[a] / s;
        for (Py_ssize_t a = 0; a < n; a++)
            for (Py_ssize_t b = 0; b < n; b++)
                X[a * n + b] -= K[a] * u[b];
        memcpy(Pprev, P, (size_t)(n * n) * sizeof(double));
        for (Py_ssize_t a = 0; a < n; a++)
            for (Py_ssize_t b = 0; b < n; b++)
                P[a * n + b] = 0.5 * (X[a * n + b] + X[b * n + a]);
        memcpy(gains + j * n, K, (size_t)n * sizeof(double));
        j++;
        if (j % check_every)
            continue;
        for (Py_ssize_t a = 0; a < n; a++)
            sd[a] = sqrt(fmax(P[a * n + a], DBL_MIN));
        double d = 0.0;
        for (Py_ssize_t a = 0; a < n; a++)
            for (Py_ssize_t b = 0; b < n; b++)
                d = fmax(d, fabs(P[a * n + b] - Pprev[a * n + b]) / (sd[a] * sd[b]));
        if (d == 0.0) {
            *steady = 1;
            break;
        }
        if (d_prev >= 0.0 && d <= p_rtol && d < d_prev) {
            double rho = pow(d / d_prev, 1.0 / (double)check_every);
            if (d * rho / (1.0 - rho) <= p_rtol) {
                *steady = 1;
                break;
            }
        }
        d_prev = d;
    }
    return j;
}

/* the truths' fix-by-fix phase (imupipe.covariance.mismatched_mse_many), fixes 0 .. jstop - 1. Truth t has
   dimension na = dims[t] (its own states, then the filter's nf): its matrices are packed one after the other
   (Am, Sm, C: na x na; u, c: na; Rs: m x na; sub: m), unpadded, so a small truth costs what its size does.
   unit_idx[t] >= 0: c = e_unit_idx (c^T C c read as that diagonal entry), else the quadratic form. */
static void mismatched_impl(Py_ssize_t T, const int64_t *dims, Py_ssize_t nf, const double *Am_p,
                            const double *Sm_p, const double *u_p, const double *c_p, const int64_t *unit_idx,
                            double *C_p, const double *gains, Py_ssize_t jstop, double R, Py_ssize_t m,
                            const double *Rs_p, const double *sub_p, double *mse, Py_ssize_t n_steps, double *work,
                            Py_ssize_t nmax, Py_ssize_t *idx)
{
    double *tmp = work, *X = tmp + nmax * nmax, *y = X + nmax * nmax, *val = y + nmax;
    /* per truth: offsets of its n^2 and n blocks, its sparse rows of Am and the nonzeros of u */
    Py_ssize_t *o2 = idx, *o1 = o2 + T, *optr = o1 + T, *ptr = optr + T, *col = ptr + T * (nmax + 1);
    Py_ssize_t *unz = col + T * nmax * nmax, *nunz = unz + T * nmax;
    Py_ssize_t s2 = 0, s1 = 0;
    for (Py_ssize_t t = 0; t < T; t++) {
        const Py_ssize_t n = (Py_ssize_t)dims[t];
        o2[t] = s2;
        o1[t] = s1;
        optr[t] = t * (nmax + 1);
        sparse_rows(Am_p + s2, n, ptr + optr[t], col + s2, val + s2);
        nunz[t] = 0;
        for (Py_ssize_t b = 0; b < n; b++)
            if (u_p[s1 + b] != 0.0)
                unz[t * nmax + nunz[t]++] = b;
        s2 += n * n;
        s1 += n;
    }
    for (Py_ssize_t j = 0; j < jstop; j++) {
        const double *K = gains + j * nf;
        const Py_ssize_t k0 = j * m - 1;
        for (Py_ssize_t t = 0; t < T; t++) {
            const Py_ssize_t n = (Py_ssize_t)dims[t], nt = n - nf;
            double *C = C_p + o2[t];
            const double *u = u_p + o1[t];
            const Py_ssize_t *uz = unz + t * nmax;
            record_substeps(mse + t * n_steps, k0, m, n, C, Rs_p + m * o1[t], sub_p + t * m, unit_idx[t],
                            c_p + o1[t], y);
            sandwich(n, ptr + optr[t], col + o2[t], val + o2[t], C, Sm_p + o2[t], tmp, X);
            /* y = X u, w = (u^T y)/2 + R/2; z = 2 (y + w [0; K]); X[nt + a, :] += K[a] z; C = (X + X^T)/2 */
            for (Py_ssize_t a = 0; a < n; a++) {
                double v = 0.0;
                for (Py_ssize_t q = 0; q < nunz[t]; q++)
                    v += X[a * n + uz[q]] * u[uz[q]];
                y[a] = v;
            }
            double uy = 0.0;
            for (Py_ssize_t a = 0; a < n; a++)
                uy += u[a] * y[a];
            const double w = uy * 0.5 + 0.5 * R;
            for (Py_ssize_t a = 0; a < nf; a++)
                y[nt + a] += w * K[a];
            for (Py_ssize_t a = 0; a < n; a++)
                y[a] *= 2.0;
            for (Py_ssize_t a = 0; a < nf; a++) {
                double *xr = X + (nt + a) * n;
                const double ka = K[a];
                for (Py_ssize_t b = 0; b < n; b++)
                    xr[b] += ka * y[b];
            }
            for (Py_ssize_t a = 0; a < n; a++)
                for (Py_ssize_t b = a; b < n; b++)
                    C[a * n + b] = C[b * n + a] = 0.5 * (X[a * n + b] + X[b * n + a]);
        }
    }
}

/* the replay's fix phase (imupipe.verify._replay_errors): windows w < W, true positions x (W, n_steps_fix)
   at steps 0 .. J m - 1, fixes at steps (j + 1) m - 1; the estimate xh (W, nf) propagates by PT = (Phi^m)^T
   between fixes and its position at i steps after a fix is xh . G[i - 1]. sq[k] = sum_w (est - x)^2. */
static void replay_impl(Py_ssize_t W, Py_ssize_t nsteps, Py_ssize_t nf, const double *x, double *xh,
                        const double *PT, const double *G, const double *h, const double *gains, Py_ssize_t J,
                        Py_ssize_t m, double *sq, double *prior)
{
    for (Py_ssize_t k = 0; k < J * m; k++)
        sq[k] = 0.0;
    for (Py_ssize_t w = 0; w < W; w++) {
        const double *xw = x + w * nsteps;
        double *xhw = xh + w * nf;
        Py_ssize_t last = -1;
        for (Py_ssize_t j = 0; j < J; j++) {
            const Py_ssize_t f = (j + 1) * m - 1;
            for (Py_ssize_t k = last + 1; k < f; k++) {
                const double *g = G + (k - last - 1) * nf;
                double e = 0.0;
                for (Py_ssize_t a = 0; a < nf; a++)
                    e += xhw[a] * g[a];
                e -= xw[k];
                sq[k] += e * e;
            }
            double innov = xw[f];
            for (Py_ssize_t b = 0; b < nf; b++) {
                double v = 0.0;
                for (Py_ssize_t a = 0; a < nf; a++)
                    v += xhw[a] * PT[a * nf + b];
                prior[b] = v;
            }
            double ph = 0.0;
            for (Py_ssize_t b = 0; b < nf; b++)
                ph += prior[b] * h[b];
            innov -= ph;
            const double *K = gains + j * nf;
            for (Py_ssize_t b = 0; b < nf; b++)
                xhw[b] = prior[b] + innov * K[b];
            const double e = xhw[0] - xw[f];
            sq[f] += e * e;
            last = f;
        }
    }
}

/* a float64 C-contiguous buffer of exactly `count` elements (count < 0: any) */
static int get_f64(PyObject *obj, Py_buffer *view, const char *name, Py_ssize_t count, int writable)
{
    if (PyObject_GetBuffer(obj, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0)) < 0)
        return -1;
    if (check_buffer_nd(view, name, 'f', 8, INT_MAX) < 0)
        return -1;
    if (count >= 0 && view->len / 8 != count) {
        PyErr_Format(PyExc_ValueError, "%s has %zd float64 values, %zd expected", name, view->len / 8, count);
        return -1;
    }
    return 0;
}

static PyObject *py_riccati_fixes(PyObject *self, PyObject *args)
{
    PyObject *Am_o, *Sm_o, *h_o, *P_o, *Rs_o, *sub_o, *pvar_o, *g_o;
    Py_ssize_t n, J, m, check_every;
    double R, p_rtol;
    Py_buffer Am = {0}, Sm = {0}, h = {0}, P = {0}, Rs = {0}, sub = {0}, pvar = {0}, g = {0};
    PyObject *result = NULL;
    double *work = NULL;
    Py_ssize_t *idx = NULL;
    (void)self;
    if (!PyArg_ParseTuple(args, "nOOOdOnnOOOOnd:riccati_fixes", &n, &Am_o, &Sm_o, &h_o, &R, &P_o, &J, &m, &Rs_o,
                          &sub_o, &pvar_o, &g_o, &check_every, &p_rtol))
        return NULL;
    if (n < 1 || J < 0 || m < 1 || check_every < 1) {
        PyErr_SetString(PyExc_ValueError, "riccati_fixes needs n >= 1, J >= 0, m >= 1, check_every >= 1");
        return NULL;
    }
    if (get_f64(Am_o, &Am, "Am", n * n, 0) < 0 || get_f64(Sm_o, &Sm, "Sm", n * n, 0) < 0 ||
        get_f64(h_o, &h, "h", n, 0) < 0 || get_f64(P_o, &P, "P", n * n, 1) < 0 ||
        get_f64(Rs_o, &Rs, "Rs", m * n, 0) < 0 || get_f64(sub_o, &sub, "sub", m, 0) < 0 ||
        get_f64(pvar_o, &pvar, "pvar", -1, 1) < 0 || get_f64(g_o, &g, "gains", J * n, 1) < 0)
        goto done;
    if (pvar.len / 8 < J * m) {
        PyErr_Format(PyExc_ValueError, "pvar has %zd values, at least J m = %zd needed", pvar.len / 8, J * m);
        goto done;
    }
    work = PyMem_Malloc(sizeof(double) * (size_t)(5 * n * n + 3 * n));
    idx = PyMem_Malloc(sizeof(Py_ssize_t) * (size_t)(n * n + n + 1));
    if (work == NULL || idx == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    int steady = 0;
    Py_ssize_t done_j;
    Py_BEGIN_ALLOW_THREADS
    done_j = riccati_impl(n, Am.buf, Sm.buf, h.buf, R, P.buf, J, m, Rs.buf, sub.buf, pvar.buf, g.buf,
                          check_every, p_rtol, &steady, work, idx, idx + n + 1);
    Py_END_ALLOW_THREADS
    result = Py_BuildValue("(nO)", done_j, steady ? Py_True : Py_False);
done:
    PyMem_Free(work);
    PyMem_Free(idx);
    PyBuffer_Release(&Am);
    PyBuffer_Release(&Sm);
    PyBuffer_Release(&h);
    PyBuffer_Release(&P);
    PyBuffer_Release(&Rs);
    PyBuffer_Release(&sub);
    PyBuffer_Release(&pvar);
    PyBuffer_Release(&g);
    return result;
}

static PyObject *py_mismatched_fixes(PyObject *self, PyObject *args)
{
    PyObject *d_o, *Am_o, *Sm_o, *u_o, *c_o, *ui_o, *C_o, *g_o, *Rs_o, *sub_o, *mse_o;
    Py_ssize_t nf, jstop, m, n_steps;
    double R;
    Py_buffer d = {0}, Am = {0}, Sm = {0}, u = {0}, c = {0}, ui = {0}, C = {0}, g = {0}, Rs = {0}, sub = {0},
              mse = {0};
    PyObject *result = NULL;
    double *work = NULL;
    Py_ssize_t *idx = NULL;
    (void)self;
    if (!PyArg_ParseTuple(args, "OnOOOOOOOndnOOOn:mismatched_fixes", &d_o, &nf, &Am_o, &Sm_o, &u_o, &c_o, &ui_o,
                          &C_o, &g_o, &jstop, &R, &m, &Rs_o, &sub_o, &mse_o, &n_steps))
        return NULL;
    if (PyObject_GetBuffer(d_o, &d, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0 ||
        check_buffer(&d, "dims", 'i', 8) < 0 || PyObject_GetBuffer(ui_o, &ui, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0 ||
        check_buffer(&ui, "unit_idx", 'i', 8) < 0)
        goto done;
    const Py_ssize_t T = d.len / 8;
    const int64_t *dims = d.buf;
    Py_ssize_t s1 = 0, s2 = 0, nmax = 0;
    for (Py_ssize_t t = 0; t < T; t++) {
        if (dims[t] <= nf) {
            PyErr_Format(PyExc_ValueError, "truth %zd: dimension %lld must exceed the filter's %zd", t,
                         (long long)dims[t], nf);
            goto done;
        }
        s1 += dims[t];
        s2 += dims[t] * dims[t];
        nmax = dims[t] > nmax ? dims[t] : nmax;
    }
    if (T < 1 || nf < 1 || jstop < 0 || m < 1 || n_steps < jstop * m || ui.len / 8 != T) {
        PyErr_SetString(PyExc_ValueError, "mismatched_fixes needs len(dims) = len(unit_idx) >= 1, nf >= 1, "
                                          "jstop >= 0, m >= 1, n_steps >= jstop m");
        goto done;
    }
    if (get_f64(Am_o, &Am, "Am", s2, 0) < 0 || get_f64(Sm_o, &Sm, "Sm", s2, 0) < 0 ||
        get_f64(u_o, &u, "u", s1, 0) < 0 || get_f64(c_o, &c, "c", s1, 0) < 0 ||
        get_f64(C_o, &C, "C", s2, 1) < 0 || get_f64(g_o, &g, "gains", -1, 0) < 0 ||
        get_f64(Rs_o, &Rs, "Rs", m * s1, 0) < 0 || get_f64(sub_o, &sub, "sub", T * m, 0) < 0 ||
        get_f64(mse_o, &mse, "mse", T * n_steps, 1) < 0)
        goto done;
    if (g.len / 8 < jstop * nf) {
        PyErr_Format(PyExc_ValueError, "gains has %zd values, at least jstop nf = %zd needed", g.len / 8, jstop * nf);
        goto done;
    }
    work = PyMem_Malloc(sizeof(double) * (size_t)(2 * nmax * nmax + nmax + s2));
    idx = PyMem_Malloc(sizeof(Py_ssize_t) * (size_t)(3 * T + T * (nmax + 1) + T * nmax * nmax + T * nmax + T));
    if (work == NULL || idx == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    mismatched_impl(T, dims, nf, Am.buf, Sm.buf, u.buf, c.buf, ui.buf, C.buf, g.buf, jstop, R, m, Rs.buf, sub.buf,
                    mse.buf, n_steps, work, nmax, idx);
    Py_END_ALLOW_THREADS
    result = Py_NewRef(Py_None);
done:
    PyMem_Free(work);
    PyMem_Free(idx);
    PyBuffer_Release(&d);
    PyBuffer_Release(&Am);
    PyBuffer_Release(&Sm);
    PyBuffer_Release(&u);
    PyBuffer_Release(&c);
    PyBuffer_Release(&ui);
    PyBuffer_Release(&C);
    PyBuffer_Release(&g);
    PyBuffer_Release(&Rs);
    PyBuffer_Release(&sub);
    PyBuffer_Release(&mse);
    return result;
}

static PyObject *py_replay_fixes(PyObject *self, PyObject *args)
{
    PyObject *x_o, *xh_o, *PT_o, *G_o, *h_o, *g_o, *sq_o;
    Py_ssize_t W, nsteps, nf, J, m;
    Py_buffer x = {0}, xh = {0}, PT = {0}, G = {0}, h = {0}, g = {0}, sq = {0};
    PyObject *result = NULL;
    double *prior = NULL;
    (void)self;
    if (!PyArg_ParseTuple(args, "nnnOOOOOOnnO:replay_fixes", &W, &nsteps, &nf, &x_o, &xh_o, &PT_o, &G_o, &h_o,
                          &g_o, &J, &m, &sq_o))
        return NULL;
    if (W < 0 || nf < 1 || J < 0 || m < 1 || nsteps < J * m) {
        PyErr_SetString(PyExc_ValueError, "replay_fixes needs W >= 0, nf >= 1, J >= 0, m >= 1, nsteps >= J m");
        return NULL;
    }
    if (get_f64(x_o, &x, "x", W * nsteps, 0) < 0 || get_f64(xh_o, &xh, "xh", W * nf, 1) < 0 ||
        get_f64(PT_o, &PT, "PT", nf * nf, 0) < 0 || get_f64(G_o, &G, "G", -1, 0) < 0 ||
        get_f64(h_o, &h, "h", nf, 0) < 0 || get_f64(g_o, &g, "gains", J * nf, 0) < 0 ||
        get_f64(sq_o, &sq, "sq", -1, 1) < 0)
        goto done;
    if (G.len / 8 < (m - 1) * nf || sq.len / 8 < J * m) {
        PyErr_Format(PyExc_ValueError, "G needs (m - 1) nf = %zd values (has %zd), sq J m = %zd (has %zd)",
                     (m - 1) * nf, G.len / 8, J * m, sq.len / 8);
        goto done;
    }
    prior = PyMem_Malloc(sizeof(double) * (size_t)nf);
    if (prior == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    replay_impl(W, nsteps, nf, x.buf, xh.buf, PT.buf, G.buf, h.buf, g.buf, J, m, sq.buf, prior);
    Py_END_ALLOW_THREADS
    result = Py_NewRef(Py_None);
done:
    PyMem_Free(prior);
    PyBuffer_Release(&x);
    PyBuffer_Release(&xh);
    PyBuffer_Release(&PT);
    PyBuffer_Release(&G);
    PyBuffer_Release(&h);
    PyBuffer_Release(&g);
    PyBuffer_Release(&sq);
    return result;
}

static PyMethodDef kernel_methods[] = {
    {"oavar_sums", py_oavar_sums, METH_VARARGS,
     "oavar_sums(theta, lags, out, out9=None)\n--\n\n"
     "out[j] = sum_k ((theta[k+2m]-theta[k+m]) - (theta[k+m]-theta[k]))**2 over k < len(theta)-2m, m = lags[j].\n"
     "theta: contiguous float64 buffer; lags: contiguous int64 buffer (1 <= m <= (len(theta)-1)//2);\n"
     "out: writable contiguous float64 buffer of len(lags). out9: None, or a writable contiguous float64\n"
     "buffer of 9*len(lags) that receives the sums of lag1_sums in the same pass. Releases the GIL."},
    {"lag1_sums", py_lag1_sums, METH_VARARGS,
     "lag1_sums(theta, lags, out)\n--\n\n"
     "For each lag m: z_i = (theta[(i+1)m] - theta[im]) / m, i < (len(theta)-1)//m, and w = z, diff(z),\n"
     "diff(z, 2): out[9j + 3d : 9j + 3d + 3] = (sum w, sum w**2, sum w[:-1]*w[1:]) for d = 0, 1, 2.\n"
     "theta: contiguous float64; lags: contiguous int64 (1 <= m <= (len(theta)-1)//2);\n"
     "out: writable contiguous float64 of 9*len(lags). Releases the GIL."},
    {"integrate", py_integrate, METH_VARARGS,
     "integrate(y, mean, theta)\n--\n\n"
     "theta[0] = 0, theta[k+1] = theta[k] + (y[k] - mean): numpy.cumsum(y - mean) without the temporary.\n"
     "y: contiguous float64; theta: writable contiguous float64 of len(y) + 1. Releases the GIL."},
    {"ar1", py_ar1, METH_VARARGS,
     "ar1(e, phi, n)\n--\n\n"
     "In place, per row of n values: e[i] = phi * e[i-1] + e[i] for i >= 1 (scipy.signal.lfilter([1], [1, -phi],\n"
     "e, axis=-1)). e: writable C-contiguous float64 of a whole number of rows. Releases the GIL."},
    {"car1", py_car1, METH_VARARGS,
     "car1(z, mu_re, mu_im, n)\n--\n\n"
     "In place, per row of n complex values: z[i] = mu z[i-1] + z[i] for i >= 1 (scipy.signal.lfilter([1], [1, -mu],\n"
     "z, axis=-1)). z: writable C-contiguous float64 view of complex128 data (2 n values per row). Releases the GIL."},
    {"flicker_bank", py_flicker_bank, METH_VARARGS,
     "flicker_bank(w, p, weights, direct, state, y, n)\n--\n\n"
     "Per row of n values: u_i[k] = p_i u_i[k-1] + weights_i w[k] (u_i[-1] = state[row, i]), y[k] = direct w[k] +\n"
     "u_0[k] + ... + u_{J-1}[k] in that order; state receives the last u_i. w: C-contiguous float64 of whole rows;\n"
     "p, weights: float64 of J <= 64; state: writable float64 of rows x J; y: writable float64 like w (may be w).\n"
     "Releases the GIL."},
    {"sim_piece", py_sim_piece, METH_VARARGS,
     "sim_piece(x, white, sw, gm, phi, scale, last, first, rw, krw, rw_sum)\n--\n\n"
     "x[k] = ((0 + sw white[k]) + g_0[k] + ... + g_{G-1}[k]) + krw (c[k] + rw_sum): g_j[k] = phi_j g_j[k-1] +\n"
     "scale_j gm[j, k], g_j[-1] = last[j] (first: g_j[0] = last[j]); c the running sum of rw. white, rw: float64 of\n"
     "len(x) or None; gm: G x len(x); last (writable) receives g_j[-1]. Returns c[-1] + rw_sum. Releases the GIL."},
    {"segment_stats", py_segment_stats, METH_VARARGS,
     "segment_stats(x, n, k, m, w, d)\n--\n\n"
     "Per record r (x: C-contiguous float64 of len(w) * n values, n >= k * m), split into k consecutive\n"
     "segments of m samples: w[r] = median-centred Levene statistic, d[r] = max over consecutive pairs of the\n"
     "two-sample KS statistic. x is not modified. w, d: writable contiguous float64, one value per record.\n"
     "Releases the GIL."},
    {"wnnls", py_wnnls, METH_VARARGS,
     "wnnls(A, y, edf, m0, offset, n_iter, rtol, p, m)\n--\n\n"
     "Re-weighted NNLS of imupipe.identify._wnnls: A (len(y) x len(p), C-contiguous float64), y, edf; m0, offset:\n"
     "float64 of len(y) or None; p (len(p) <= 16) and m (len(y)) writable float64, receive the coefficients and\n"
     "the model. Returns chi2 = sum(edf/2 ((y - m)/m)**2)."},
    {"riccati_fixes", py_riccati_fixes, METH_VARARGS,
     "riccati_fixes(n, Am, Sm, h, R, P, J, m, Rs, sub, pvar, gains, check_every, p_rtol)\n--\n\n"
     "The filter's Riccati recursion fix by fix (imupipe.covariance.filter_variance) until convergence:\n"
     "P (n x n, in/out) the state after the last fix done, pvar the sub-step variances, gains (J x n) the gains.\n"
     "Returns (fixes done, converged). Releases the GIL."},
    {"mismatched_fixes", py_mismatched_fixes, METH_VARARGS,
     "mismatched_fixes(dims, nf, Am, Sm, u, c, unit_idx, C, gains, jstop, R, m, Rs, sub, mse, n_steps)\n--\n\n"
     "The truths' fix-by-fix phase of imupipe.covariance.mismatched_mse_many, fixes 0 .. jstop-1: truth t of\n"
     "dimension dims[t] (int64), its matrices packed one after the other, unpadded; C (in/out) the covariances,\n"
     "mse (len(dims) x n_steps) written at the steps before each fix. Releases the GIL."},
    {"replay_fixes", py_replay_fixes, METH_VARARGS,
     "replay_fixes(W, nsteps, nf, x, xh, PT, G, h, gains, J, m, sq)\n--\n\n"
     "The replay's fix phase (imupipe.verify._replay_errors): sq[k] = sum over windows of the squared position\n"
     "error at steps k < J m; xh (W x nf, in/out) the estimates after the last fix. Releases the GIL."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef kernel_module = {
    PyModuleDef_HEAD_INIT,
    "imupipe._kernels",
    "Compiled inner loops of imupipe.allan, .identify, .simulate, .stationarity, .covariance and .verify (optional; NumPy paths give the same results).",
    -1,
    kernel_methods,
};

PyMODINIT_FUNC PyInit__kernels(void)
{
    PyObject *mod = PyModule_Create(&kernel_module);
    if (mod == NULL)
        return NULL;
    if (PyModule_AddIntConstant(mod, "BLOCK", IMUPIPE_BLOCK) < 0 ||
        PyModule_AddIntConstant(mod, "SMALL_LAG", IMUPIPE_SMALL_LAG) < 0) {
        Py_DECREF(mod);
        return NULL;
    }
    return mod;
}
