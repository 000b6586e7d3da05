/*
 * imupipe._kernels -- compiled inner loops of imupipe.allan (optional; imupipe.allan has a NumPy path
 * that gives the same results to rounding when this module cannot be built or imported).
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
 * lag1_sums(theta, lags, out)
 *     For each lag m, the N = (L-1)//m non-overlapping m-sample means z_i = (theta[(i+1)m] - theta[im]) / m
 *     and their first and second differences w = z, diff(z), diff(z, 2): out[9j + 3d + (0, 1, 2)] =
 *     (sum w, sum w^2, sum w_i w_{i+1}) for d = 0, 1, 2 -- the sums of the lag-1 autocorrelation noise
 *     identification (Riley & Greenhall 2004), in one strided pass over theta per lag.
 *     out : writable contiguous float64 buffer of 9 * len(lags); 1 <= m <= (L - 1) / 2.
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

static void oavar_sums_impl(const double *theta, Py_ssize_t L, const int64_t *lags, Py_ssize_t nlags,
                            double *out)
{
    const Py_ssize_t block = IMUPIPE_BLOCK;
    Py_ssize_t kmax = 0; /* largest number of terms among the small lags */
    for (Py_ssize_t j = 0; j < nlags; j++) {
        out[j] = 0.0;
        if (lags[j] <= IMUPIPE_SMALL_LAG && L - 2 * lags[j] > kmax)
            kmax = L - 2 * lags[j];
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
    }
}

static void lag1_sums_impl(const double *theta, Py_ssize_t L, const int64_t *lags, Py_ssize_t nlags,
                           double *out)
{
    for (Py_ssize_t j = 0; j < nlags; j++) {
        const Py_ssize_t m = (Py_ssize_t)lags[j];
        const Py_ssize_t N = (L - 1) / m;
        const double inv_m = 1.0 / (double)m;
        double s[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
        double z_prev = 0.0, d1_prev = 0.0, d2_prev = 0.0;
        for (Py_ssize_t i = 0; i < N; i++) {
            const double z = (theta[(i + 1) * m] - theta[i * m]) * inv_m;
            s[0] += z;
            s[1] += z * z;
            if (i >= 1) {
                s[2] += z_prev * z;
                const double d1 = z - z_prev;
                s[3] += d1;
                s[4] += d1 * d1;
                if (i >= 2) {
                    s[5] += d1_prev * d1;
                    const double d2 = d1 - d1_prev;
                    s[6] += d2;
                    s[7] += d2 * d2;
                    if (i >= 3)
                        s[8] += d2_prev * d2;
                    d2_prev = d2;
                }
                d1_prev = d1;
            }
            z_prev = z;
        }
        memcpy(out + 9 * j, s, sizeof s);
    }
}

static int check_buffer(const Py_buffer *view, const char *name, char kind, Py_ssize_t itemsize)
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
    if (view->ndim > 1) {
        PyErr_Format(PyExc_ValueError, "%s must be one-dimensional, got %d dimensions", name, view->ndim);
        return -1;
    }
    return 0;
}

static PyObject *py_oavar_sums(PyObject *self, PyObject *args)
{
    PyObject *theta_obj, *lags_obj, *out_obj;
    Py_buffer theta = {0}, lags = {0}, out = {0};
    PyObject *result = NULL;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOO:oavar_sums", &theta_obj, &lags_obj, &out_obj))
        return NULL;
    /* buffer protocol with the element format, so that a float32 or int32 array is refused, not misread */
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
    if (out.len / 8 != nlags) {
        PyErr_Format(PyExc_ValueError, "out has %zd elements, lags has %zd", out.len / 8, nlags);
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
    oavar_sums_impl((const double *)theta.buf, L, m, nlags, (double *)out.buf);
    Py_END_ALLOW_THREADS
    result = Py_NewRef(Py_None);
done:
    /* PyBuffer_Release is a no-op on a view whose obj is NULL (never acquired) */
    PyBuffer_Release(&theta);
    PyBuffer_Release(&lags);
    PyBuffer_Release(&out);
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

static PyMethodDef kernel_methods[] = {
    {"oavar_sums", py_oavar_sums, METH_VARARGS,
     "oavar_sums(theta, lags, out)\n--\n\n"
     "out[j] = sum_k ((theta[k+2m]-theta[k+m]) - (theta[k+m]-theta[k]))**2 over k < len(theta)-2m, m = lags[j].\n"
     "theta: contiguous float64 buffer; lags: contiguous int64 buffer (1 <= m <= (len(theta)-1)//2);\n"
     "out: writable contiguous float64 buffer of len(lags). Releases the GIL."},
    {"lag1_sums", py_lag1_sums, METH_VARARGS,
     "lag1_sums(theta, lags, out)\n--\n\n"
     "For each lag m: z_i = (theta[(i+1)m] - theta[im]) / m, i < (len(theta)-1)//m, and w = z, diff(z),\n"
     "diff(z, 2): out[9j + 3d : 9j + 3d + 3] = (sum w, sum w**2, sum w[:-1]*w[1:]) for d = 0, 1, 2.\n"
     "theta: contiguous float64; lags: contiguous int64 (1 <= m <= (len(theta)-1)//2);\n"
     "out: writable contiguous float64 of 9*len(lags). Releases the GIL."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef kernel_module = {
    PyModuleDef_HEAD_INIT,
    "imupipe._kernels",
    "Compiled inner loops of imupipe.allan (optional; a NumPy path gives the same results).",
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
