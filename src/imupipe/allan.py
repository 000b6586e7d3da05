r"""Allan variance of rate signals: overlapping and non-overlapping estimators, confidence limits.

The input is a rate signal :math:`y_i` (rad/s, m/s^2, or any unit ``u``) sampled every
:math:`\tau_0 = 1/f_s`. With the integrated signal (angle, velocity)

.. math::

    \theta_0 = 0, \qquad \theta_k = \tau_0 \sum_{i<k} (y_i - \bar y), \qquad k = 1..n, \quad L = n + 1,

the **overlapping** Allan variance at :math:`\tau = m\tau_0` is (NIST SP 1065, eq. 11)

.. math::

    \sigma^2(m\tau_0) = \frac{1}{2 (m\tau_0)^2 (L - 2m)} \sum_{k=0}^{L-2m-1}
    (\theta_{k+2m} - 2\theta_{k+m} + \theta_k)^2,

and the **non-overlapping** one uses every m-th value of k only. The sum of squared second differences
depends on :math:`\tau_0` as :math:`\tau_0^2`, so the code accumulates :math:`\theta` in sample units
(:math:`\tau_0 = 1`) and the result is the same; it is in ``u^2``. The mean is removed and the sum is
accumulated in float64 whatever the input dtype (an accelerometer axis at 9.81 m/s^2 with 1e-6 noise
loses three digits otherwise): the second difference annihilates any constant rate, so this changes
nothing but rounding.

Speed (``_kernels``, measured on a 2-core AMD EPYC, 4.5e6 samples, 92 log-spaced averaging factors up
to n/4: 0.14 s; NumPy path 0.5 s; allantools.oadev 2 s; ``benchmarks/bench_allan.py``): a C kernel with
eight independent partial sums (vectorised), small lags blocked over k so that the record is read from
cache; the NumPy path processes each lag in cache-sized chunks. Both give the same sums to rounding.

Dense grids (``taus="all"``: every averaging factor) use an FFT method in :math:`O(N \log^2 N)`
(:func:`_oavar_sums_all`; 11 ms for the 18 000 factors of a 36 000-point record, against 0.6 s for
allantools) with a rounding-error bound; the factors whose bound exceeds ``1e-9`` of the sum are
recomputed with the direct kernel, so every value is exact to 1e-9.

Confidence limits use equivalent degrees of freedom (EDF) from the algorithm of Greenhall & Riley
(2003) for the dominant power-law noise identified at each averaging time by the lag-1 autocorrelation
method of Riley & Greenhall (2004), and chi-squared limits (NIST SP 1065, section 5.3). Noise type
``alpha`` is the exponent of the rate PSD, :math:`S_y(f) \propto f^\alpha`: 2 white angle (white PM,
e.g. quantization), 1 flicker angle, 0 white rate (angle/velocity random walk), -1 flicker rate (bias
instability), -2 random-walk rate (rate random walk).

Public names
------------
allan_variance       Allan variance with confidence limits as an ``xarray.Dataset``
overlapping_avar     overlapping (or non-overlapping) Allan variance, NumPy in, NumPy out
tau_grid             averaging factors and times of a named grid or of an array of times
TauGrid              the named tuple returned by :func:`tau_grid`
noise_id_lag1        power-law noise identification by the lag-1 autocorrelation
edf_greenhall        equivalent degrees of freedom (Greenhall & Riley 2003), unmodified AVAR/HVAR
chi2_limits          chi-squared confidence limits of a variance with a given EDF
ConstantSignalWarning  warning category for a constant (dead) channel

References
----------
.. [1] W. J. Riley, "Handbook of Frequency Stability Analysis", NIST Special Publication 1065, 2008:
       eq. (11) overlapping Allan variance, section 5.3 confidence intervals, section 5.6 noise ID.
.. [2] IEEE Std 952-1997, "IEEE Standard Specification Format Guide and Test Procedure for Single-Axis
       Interferometric Fiber Optic Gyros", Annex C (Allan variance of gyro rate data).
.. [3] C. A. Greenhall and W. J. Riley, "Uncertainty of stability variances based on finite
       differences", Proc. 35th Annual Precise Time and Time Interval (PTTI) Meeting, 2003, pp. 267-278.
.. [4] W. J. Riley and C. A. Greenhall, "Power law noise identification using the lag 1
       autocorrelation", Proc. 18th European Frequency and Time Forum (EFTF), 2004.
.. [5] N. J. Higham, "Accuracy and Stability of Numerical Algorithms", 2nd ed., SIAM, 2002:
       section 4 (summation), section 24.1 (error of the FFT).
"""

from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import numpy as np

from imupipe.backend import choose_backend

try:  # optional compiled kernel; the NumPy path gives the same sums to rounding
    from imupipe import _kernels
except ImportError:  # pragma: no cover - exercised by forcing backend="numpy" in the tests
    _kernels = None

__all__ = [
    "ConstantSignalWarning",
    "TauGrid",
    "allan_variance",
    "allan_variance_labelled",
    "chi2_limits",
    "edf_greenhall",
    "noise_id_lag1",
    "overlapping_avar",
    "tau_grid",
]

_U = 2.0**-53  # unit roundoff of float64
_NUMPY_CHUNK = 1 << 17  # samples per chunk in the NumPy path (two 1 MiB buffers)
_FFT_RTOL = 1e-9  # relative error accepted from the FFT path before a lag is recomputed directly
_FFT_LEAF = 8  # leaf size of the divide-and-conquer head products
_JMAX = 100  # Greenhall & Riley's limit on the explicit sum (their J_max)
_NOISE_ID_MIN_POINTS = 30  # averaged points needed by the lag-1 ACF method (Riley & Greenhall 2004)


class ConstantSignalWarning(UserWarning):
    """A channel is constant: its Allan variance is exactly zero (a dead or stuck sensor axis?)."""


class TauGrid(NamedTuple):
    """Averaging factors ``m`` (samples per cluster, int64) and times ``tau = m / rate`` (s)."""

    m: np.ndarray
    tau: np.ndarray


# ---------------------------------------------------------------------------------------------
# input handling
# ---------------------------------------------------------------------------------------------
def _as_rate_array(x) -> np.ndarray:
    """The samples of `x` as a 1-D array (any real dtype, not yet converted); ValueError otherwise."""
    a = np.asarray(x)
    if a.ndim != 1:
        raise ValueError(f"x must be one-dimensional, got shape {a.shape}")
    if a.dtype.kind not in "fiub":
        raise ValueError(f"x must be real-valued, got dtype {a.dtype}")
    if a.size < 2:
        raise ValueError(f"x has {a.size} sample(s); the Allan variance needs at least 2")
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        bad = np.flatnonzero(~np.isfinite(a))
        raise ValueError(
            f"x contains {bad.size} non-finite value(s) (NaN or inf), first at index {bad[0]}; "
            "remove or interpolate them before computing the Allan variance"
        )
    return a


def _check_rate(rate) -> float:
    rate = float(rate)
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"rate must be a positive sampling frequency in Hz, got {rate}")
    return rate


def _integrate(a: np.ndarray, out: np.ndarray | None = None) -> tuple[np.ndarray, bool]:
    """theta (float64, length n+1, sample units) of the mean-removed signal, and whether it is constant.

    The mean is computed in float64 (pairwise summation) and subtracted in float64; for a constant
    signal theta is exactly zero. `out` (float64, n+1) receives theta; it may be the buffer whose
    ``out[1:]`` is `a` itself (integration in place: sample k is read before theta[k+1] is written),
    which saves a copy of the record (the workflow's full-rate jobs).
    """
    y = np.asarray(a, dtype=np.float64)
    theta = np.empty(y.size + 1) if out is None else out
    if theta.shape != (y.size + 1,) or theta.dtype != np.float64:
        raise ValueError(f"out must be a float64 array of {y.size + 1} elements, got {theta.dtype} {theta.shape}")
    theta[0] = 0.0
    if y[0] == y[-1] and np.all(y == y[0]):
        theta[0] = 0.0
        theta[1:] = 0.0
        return theta, True
    if _kernels is not None and y.flags.c_contiguous:
        _kernels.integrate(y, float(y.mean()), theta)  # the same sums as below, without the temporary
    else:
        np.cumsum(y - y.mean(), out=theta[1:])
    return theta, False


def _pick_backend(backend: str) -> str:
    return choose_backend(backend, _kernels)  # the module's _kernels at call time (tests may unset it)


# ---------------------------------------------------------------------------------------------
# sums of squared second differences
# ---------------------------------------------------------------------------------------------
def _sums_numpy(theta: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """sum_k ((theta[k+2m]-theta[k+m]) - (theta[k+m]-theta[k]))^2 per lag, in cache-sized chunks."""
    L = theta.size
    chunk = _NUMPY_CHUNK
    buf1 = np.empty(min(chunk, L))
    buf2 = np.empty(min(chunk, L))
    out = np.empty(lags.size)
    for j, m in enumerate(lags.tolist()):
        K = L - 2 * m
        total = 0.0
        for k0 in range(0, K, chunk):
            n = min(chunk, K - k0)
            t1 = np.subtract(theta[k0 + 2 * m : k0 + 2 * m + n], theta[k0 + m : k0 + m + n], out=buf1[:n])
            t2 = np.subtract(theta[k0 + m : k0 + m + n], theta[k0 : k0 + n], out=buf2[:n])
            np.subtract(t1, t2, out=t1)
            np.multiply(t1, t1, out=t1)
            total += float(t1.sum())  # pairwise within the chunk, chunk totals added in double
        out[j] = total
    return out


def _sums_direct(theta: np.ndarray, lags: np.ndarray, backend: str) -> np.ndarray:
    """Overlapping sums for the given lags by the direct O(L) method per lag."""
    lags = np.ascontiguousarray(lags, dtype=np.int64)
    if lags.size == 0:
        return np.empty(0)
    if backend == "c":
        out = np.empty(lags.size)
        _kernels.oavar_sums(np.ascontiguousarray(theta, dtype=np.float64), lags, out)
        return out
    return _sums_numpy(theta, lags)


def _sums_nonoverlapping(theta: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """sum_i (theta[(i+2)m] - 2 theta[(i+1)m] + theta[im])^2 over the non-overlapping clusters."""
    out = np.empty(lags.size)
    for j, m in enumerate(lags.tolist()):
        t = theta[::m]
        d = (t[2:] - t[1:-1]) - (t[1:-1] - t[:-2])
        out[j] = float(np.square(d).sum())
    return out


# --- FFT path for all lags ----------------------------------------------------------------------
def _fast_len(n: int) -> int:
    """Smallest 2^a 3^b 5^c >= n (a fast size for numpy.fft)."""
    best = 1 << max(0, (n - 1).bit_length())
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            q = p35
            while q < n:
                q *= 2
            best = min(best, q)
            p35 *= 3
        p5 *= 5
    return best


def _blocked_cumsum(v: np.ndarray) -> np.ndarray:
    """Prefix sums P[j] = sum_{k<j} v[k], j = 0..len(v), summed in blocks of ~sqrt(len(v)).

    The error of each P[j] is at most (b + len(v)/b + 1) u sum|v| (b = block length) instead of
    len(v) u sum|v| for a sequential cumulative sum.
    """
    n = v.size
    b = max(1, int(math.isqrt(n)))
    nb = -(-n // b)
    w = np.zeros(nb * b)
    w[:n] = v
    w = w.reshape(nb, b)
    within = np.cumsum(w, axis=1)
    offsets = np.concatenate(([0.0], np.cumsum(within[:, -1])[:-1]))
    P = np.empty(n + 1)
    P[0] = 0.0
    P[1:] = (within + offsets[:, None]).ravel()[:n]
    return P


def _head_products(rows: np.ndarray, mmax: int) -> np.ndarray:
    r"""h[r, m] = sum_{j<m} v_r[j] v_r[j+m] for m = 0..mmax, for each row v_r of `rows`.

    Divide and conquer on the interval of m (CDQ): on a node [lo, lo+s) the products with
    j in [lo, lo+s/2) and m in [lo+s/2, lo+s) form one correlation of the segments
    v[lo : lo+s/2] and v[2lo+s/2 : 2lo+s/2+s], computed by a real FFT of size s (no wrap-around:
    the lags used stay below s); the two halves recurse. All nodes of one level are strided views of
    v and are transformed together, so the cost is O(P log^2 P) (P the power of two above mmax) in
    O(log P) NumPy calls. Leaves of _FFT_LEAF lags are summed directly (one einsum).
    """
    nrow, L = rows.shape
    P = 1 << max(0, mmax).bit_length()  # power of two > mmax
    leaf = min(_FFT_LEAF, P)
    v = np.zeros((nrow, 3 * P))
    v[:, : min(L, 3 * P)] = rows[:, : 3 * P]
    h = np.zeros((nrow, P))
    s = P
    while s > leaf:
        half, nodes = s // 2, P // s
        a = v[:, :P].reshape(nrow, nodes, s)[:, :, :half]  # v[lo : lo+half], lo = 0, s, 2s, ...
        b = v[:, half : half + 2 * P].reshape(nrow, nodes, 2 * s)[:, :, :s]  # v[2lo+half : 2lo+half+s]
        c = np.fft.irfft(np.conj(np.fft.rfft(a, n=s, axis=-1)) * np.fft.rfft(b, axis=-1), n=s, axis=-1)
        h.reshape(nrow, nodes, s)[:, :, half:] += c[:, :, :half]
        s = half
    # leaves [lo, lo+leaf): h[lo+r] += sum_{q<r} v[lo+q] v[2lo+q+r]
    nodes = P // leaf
    a = v[:, :P].reshape(nrow, nodes, leaf)
    b = v[:, : 2 * P].reshape(nrow, nodes, 2 * leaf)
    hank = np.lib.stride_tricks.sliding_window_view(b, leaf, axis=-1)[:, :, :leaf, :]  # [.., r, q] = b[r+q]
    mask = np.tri(leaf, leaf, -1)  # q < r
    h.reshape(nrow, nodes, leaf)[...] += (hank * mask * a[:, :, None, :]).sum(axis=-1)
    return h[:, : mmax + 1]


def _fft_is_faster(L: int, lags: np.ndarray, backend: str) -> bool:
    """Cost model (measured, 2-core AMD EPYC): FFT path ~0.3 us per point at L = 36 000, growing as
    log^2 L; direct sums 0.25 ns (kernel) or 1.2 ns (NumPy) per term. The FFT path is chosen only
    when it is at least twice as fast (the direct sums are exact to rounding)."""
    if lags.size < 64:
        return False
    fft_cost = 3e-7 * L * (math.log2(L) / 15.0) ** 2
    per_term = 2.5e-10 if backend == "c" else 1.2e-9
    direct_cost = per_term * float(np.sum(L - 2 * lags))
    return 2.0 * fft_cost < direct_cost


def _fft_error_coefficient(L: int, mmax: int) -> float:
    """gamma such that |computed S(m) - S(m)| <= gamma * u * sum(theta_detrended^2); see _oavar_sums_all."""
    n_r = _fast_len(L + 2 * mmax)
    P = 1 << max(0, mmax).bit_length()
    levels = max(0, int(math.log2(P / min(_FFT_LEAF, P))))
    b = max(1, int(math.isqrt(L)))
    eta = 7.0  # Higham (2002) eq. 24.7: eta = mu + gamma_4 (sqrt 2 + mu) ~ 6.7 u per butterfly stage
    c_prefix = 10.0 * (b + L / b + 2.0) + 6.0 * (math.log2(L) + 1.0)
    c_corr = 3.0 * eta * math.log2(n_r)  # forward, product, inverse (RMS per lag, see docstring)
    c_head = 3.0 * eta * math.log2(max(P, 2))
    c_leaf = 8.0 * (_FFT_LEAF - 1)  # leaves: at most leaf - 1 products, summed directly, weight 4 + 4
    return c_prefix + 10.0 * c_corr + 8.0 * levels * c_head + c_leaf


def _oavar_sums_all(theta: np.ndarray, mmax: int, backend: str = "auto", rtol: float = _FFT_RTOL):
    r"""Overlapping sums S(m) for every m = 1..mmax in O(L log^2 L), with an error bound.

    Expanding the square of :math:`d_k = \theta_{k+2m} - 2\theta_{k+m} + \theta_k` over
    :math:`k < K = L - 2m` gives, with :math:`T = \sum_k \theta_k^2`, prefix and suffix sums
    :math:`P(j) = \sum_{k<j} \theta_k^2`, :math:`Q(j) = \sum_{k \ge L-j} \theta_k^2`, the full
    autocorrelation :math:`R(j) = \sum_{k=0}^{L-1-j} \theta_k\theta_{k+j}` (one zero-padded real FFT)
    and the head and tail partial products :math:`h(m) = \sum_{j<m} \theta_j\theta_{j+m}`,
    :math:`t(m) = \sum_{k=L-2m}^{L-m-1} \theta_k\theta_{k+m}` (= h of the reversed series,
    :func:`_head_products`),

    .. math::

        S(m) = 6T - P(2m) - Q(2m) - 4P(m) - 4Q(m) - 8R(m) + 2R(2m) + 4h(m) + 4t(m).

    The second difference annihilates :math:`a + bk`, so :math:`\theta` is first replaced by its
    least-squares residual from a line, which minimises :math:`T` (exactly the same S in exact
    arithmetic).

    **Error bound.** Every term is of order T while S(m) can be much smaller (for a rate random walk
    :math:`T/S(1) \sim L^3`): the expansion cancels. With :math:`u = 2^{-53}`:

    - prefix/suffix sums (blocked, block :math:`b = \sqrt L`): :math:`\le (b + L/b + 2) u T` each,
      ten of them; :math:`6T` (pairwise): :math:`6 (\log_2 L + 1) u T`;
    - an FFT correlation of size n has 2-norm error :math:`\le 3\eta\log_2 n \, u \, \|R\|_2`
      (forward transforms, product and inverse; :math:`\eta \approx 6.7`, Higham 2002 Thm 24.2), so a
      root-mean-square error per lag :math:`\le 3\eta\log_2 n \, u\, T` since :math:`|R(j)| \le T`;
      R(m) and R(2m) enter with weights 8 and 2;
    - h and t: one correlation per divide-and-conquer level, each bounded likewise by
      :math:`3\eta\log_2 P\, u\, T` (Cauchy-Schwarz on the segments), weight 4 + 4 per level.

    Hence :math:`|\Delta S(m)| \le E = \gamma\, u\, T` with
    :math:`\gamma = 10(b + L/b + 2) + 6(\log_2 L + 1) + 30\eta\log_2 n_R + 24\eta\, n_{lev} \log_2 P`
    (plus :math:`8 \cdot 7` for the directly summed leaves of at most 7 products;
    :func:`_fft_error_coefficient`; :math:`E \approx 4\times10^{-12}\,T` for L = 36 001). The FFT
    terms are root-mean-square bounds (the element-wise worst case is larger by up to
    :math:`\sqrt{n}` but is not attained by rounding errors, which are not coherent over the lags);
    the tests measure the actual error against the direct kernel for white, flicker-like, random-walk
    and rate-random-walk inputs and find it 2-4 orders of magnitude below E. A lag is accepted from the
    FFT path only if :math:`E \le` `rtol` :math:`(S_{fft}(m) - E)`, which guarantees a relative error
    at most `rtol`; the others are recomputed with the direct kernel. (Rounding in the detrending
    perturbs S by about :math:`u\sqrt{T S}`, which is below :math:`10^{-15} S` wherever the test
    accepts a lag.) With white rate noise only the first few lags are recomputed; with a dominant rate
    random walk (:math:`T/S` large) up to a few percent of them.

    Returns
    -------
    sums : ndarray, shape (mmax,)
        S(m) for m = 1..mmax.
    direct : ndarray of bool, shape (mmax,)
        True where S(m) was recomputed by the direct kernel.
    bound : float
        E, the absolute error bound of the FFT values.
    """
    L = theta.size
    if not 1 <= mmax <= (L - 1) // 2:
        raise ValueError(f"mmax={mmax} outside 1..{(L - 1) // 2} for {L} integrated points")
    k = np.arange(L, dtype=np.float64)
    kc = k - 0.5 * (L - 1)
    slope = float((kc * theta).sum()) / float((kc * kc).sum()) if L > 1 else 0.0
    v = theta - (theta.mean() + slope * kc)
    v2 = v * v
    T = float(v2.sum())
    m = np.arange(1, mmax + 1)
    if T == 0.0:
        return np.zeros(mmax), np.zeros(mmax, dtype=bool), 0.0
    P = _blocked_cumsum(v2)
    Q = _blocked_cumsum(v2[::-1])
    n_r = _fast_len(L + 2 * mmax)
    fv = np.fft.rfft(v, n=n_r)
    R = np.fft.irfft(fv.real**2 + fv.imag**2, n=n_r)[: 2 * mmax + 1]
    ht = _head_products(np.stack([v, v[::-1]]), mmax)
    S = (
        6.0 * T
        - (P[2 * m] + Q[2 * m] + 4.0 * P[m] + 4.0 * Q[m])
        - 8.0 * R[m]
        + 2.0 * R[2 * m]
        + 4.0 * (ht[0, m] + ht[1, m])
    )
    bound = _fft_error_coefficient(L, mmax) * _U * T
    direct = ~(bound <= rtol * (S - bound))
    if direct.any():
        S[direct] = _sums_direct(theta, m[direct], _pick_backend(backend))
    return S, direct, bound


# ---------------------------------------------------------------------------------------------
# tau grids
# ---------------------------------------------------------------------------------------------
def tau_grid(n: int, rate: float, taus="octave") -> TauGrid:
    """Averaging factors and times for a record of `n` samples at `rate` Hz.

    Parameters
    ----------
    n : int
        Number of rate samples in the record.
    rate : float
        Sampling frequency, Hz.
    taus : {"octave", "decade", "all"}, int or array_like of float, optional
        ``"octave"``: m = 1, 2, 4, 8, ...; ``"decade"``: m = 1, 2, 4, 10, 20, 40, 100, ... (Stable32's
        decade grid); ``"all"``: every m; an int ``k``: ``k`` log-spaced factors per decade
        (m = round(10^(i/k)), duplicates removed). Named and integer grids end at
        ``m <= n // 4`` (a quarter of the record, as Stable32). An array gives averaging times in
        seconds; each is rounded to the nearest multiple of the sample interval (a warning if that
        moves any of them by more than 1e-9 relative, or merges two of them) and must satisfy
        ``1 <= m <= n // 2`` (at least one second difference). Defaults to ``"octave"``.

    Returns
    -------
    TauGrid
        ``m``: averaging factors (int64, increasing, unique); ``tau = m / rate`` (s).

    Raises
    ------
    ValueError
        For an unknown grid name, a record too short for any point of a named grid, or an averaging
        time shorter than half a sample interval or longer than half the record (the message names
        the time and the record length).
    """
    n = int(n)
    rate = _check_rate(rate)
    if isinstance(taus, str):
        m_max = n // 4
        if m_max < 1:
            raise ValueError(
                f"a record of {n} samples ({n / rate:g} s) is too short for the {taus!r} grid, which ends "
                "at a quarter of the record; pass explicit averaging times (up to half the record)"
            )
        if taus == "octave":
            m = 2 ** np.arange(int(math.log2(m_max)) + 1)
        elif taus == "decade":
            m = np.array([c * 10**e for e in range(int(math.log10(m_max)) + 1) for c in (1, 2, 4)])
        elif taus == "all":
            m = np.arange(1, m_max + 1)
        else:
            raise ValueError(f"taus must be 'octave', 'decade', 'all', an int or an array, got {taus!r}")
        m = m[m <= m_max]
    elif isinstance(taus, (int, np.integer)) and not isinstance(taus, bool):
        if taus < 1:
            raise ValueError(f"points per decade must be >= 1, got {taus}")
        m_max = n // 4
        if m_max < 1:
            raise ValueError(f"a record of {n} samples ({n / rate:g} s) is too short for a log grid to n/4")
        k = np.arange(int(math.floor(taus * math.log10(m_max) + 1e-9)) + 1)
        m = np.unique(np.rint(10.0 ** (k / taus)).astype(np.int64))
        m = m[m <= m_max]
    else:
        t = np.asarray(taus, dtype=np.float64).ravel()
        if t.size == 0:
            raise ValueError("taus is an empty array")
        if not np.isfinite(t).all() or (t <= 0).any():
            raise ValueError(f"averaging times must be positive and finite, got {t[~(np.isfinite(t) & (t > 0))][:3]}")
        mf = t * rate
        m = np.rint(mf).astype(np.int64)
        short = m < 1
        if short.any():
            raise ValueError(
                f"averaging time tau={t[short][0]:g} s is shorter than half the sample interval "
                f"({0.5 / rate:g} s at {rate:g} Hz)"
            )
        long_ = m > n // 2
        if long_.any():
            raise ValueError(
                f"averaging time tau={t[long_][0]:g} s needs at least 2 tau = {2 * t[long_][0]:g} s of data; "
                f"the record has {n} samples = {n / rate:g} s (largest tau {(n // 2) / rate:g} s)"
            )
        moved = np.abs(m - mf) > 1e-9 * mf
        mu = np.unique(m)
        if moved.any() or mu.size < m.size:
            warnings.warn(
                f"{int(moved.sum())} averaging time(s) rounded to a multiple of the sample interval "
                f"{1 / rate:g} s; {m.size - mu.size} duplicate(s) merged",
                UserWarning,
                stacklevel=2,
            )
        m = mu
    m = np.asarray(m, dtype=np.int64)
    return TauGrid(m=m, tau=m / rate)


# ---------------------------------------------------------------------------------------------
# low-level estimator
# ---------------------------------------------------------------------------------------------
def overlapping_avar(
    x, rate: float, m, *, overlapping: bool = True, method: str = "direct", backend: str = "auto"
) -> np.ndarray:
    r"""Overlapping (or non-overlapping) Allan variance at averaging factors `m`; NumPy in, NumPy out.

    .. math::

        \sigma^2(m\tau_0) = \frac{1}{2 (m\tau_0)^2 (L - 2m)} \sum_{k=0}^{L-2m-1}
        (\theta_{k+2m} - 2\theta_{k+m} + \theta_k)^2, \qquad
        \theta_k = \tau_0 \sum_{i<k} (y_i - \bar y),\ L = n + 1,

    accumulated in float64 (NIST SP 1065 eq. 11). Non-overlapping: k = 0, m, 2m, ... and the mean over
    those ``n // m - 1`` terms.

    Parameters
    ----------
    x : array_like, shape (n,)
        Rate samples in unit ``u`` (any real dtype; converted to float64 before the mean is removed).
    rate : float
        Sampling frequency, Hz (:math:`\tau_0 = 1/\mathrm{rate}`). The variance does not depend on it.
    m : int or array_like of int
        Averaging factors, ``1 <= m <= n // 2``.
    overlapping : bool, optional
        Overlapping estimator (default True) or non-overlapping.
    method : {"direct", "fft", "auto"}, optional
        Direct sums (default), the FFT method for every factor up to ``max(m)`` (overlapping only,
        relative error <= 1e-9, see :func:`_oavar_sums_all`), or the cost model's choice.
    backend : {"auto", "c", "numpy"}, optional
        Compiled kernel (``"c"``), NumPy path, or the kernel when it is available (default).

    Returns
    -------
    numpy.ndarray
        Allan variance in ``u^2``, same shape as `m`. Exactly 0 for a constant signal.

    Raises
    ------
    ValueError
        Non-finite samples, a signal that is not 1-D, or an averaging factor outside ``1..n//2``.

    References
    ----------
    .. [1] W. J. Riley, "Handbook of Frequency Stability Analysis", NIST SP 1065, 2008, eq. (11).
    """
    a = _as_rate_array(x)
    _check_rate(rate)
    mm = np.asarray(m)
    if mm.dtype.kind not in "iu" and not (mm.dtype.kind == "f" and np.all(mm == np.rint(mm))):
        raise ValueError(f"m must be integer averaging factors, got {mm!r}")
    flat = mm.astype(np.int64).ravel()
    n = a.size
    bad = (flat < 1) | (flat > n // 2)
    if bad.any():
        raise ValueError(
            f"averaging factor m={flat[bad][0]} outside 1..{n // 2} for a record of {n} samples "
            f"(tau={flat[bad][0] / float(rate):g} s, record {n / float(rate):g} s)"
        )
    if method not in ("auto", "direct", "fft"):
        raise ValueError(f"method must be 'auto', 'direct' or 'fft', got {method!r}")
    if method == "fft" and not overlapping:
        raise ValueError("method='fft' applies to the overlapping estimator only")
    be = _pick_backend(backend)
    theta, constant = _integrate(a)
    if overlapping:
        if not constant and (method == "fft" or (method == "auto" and _fft_is_faster(theta.size, flat, be))):
            sums = _oavar_sums_all(theta, int(flat.max()), backend=be)[0][flat - 1]
        else:
            sums = _sums_direct(theta, flat, be)
        terms = theta.size - 2 * flat
    else:
        sums = _sums_nonoverlapping(theta, flat)
        terms = n // flat - 1
    return (sums / (2.0 * flat.astype(np.float64) ** 2 * terms)).reshape(mm.shape)


# ---------------------------------------------------------------------------------------------
# noise identification
# ---------------------------------------------------------------------------------------------
def _lag1_p(z: np.ndarray, dmin: int, dmax: int) -> float:
    """Riley & Greenhall's p = -2(delta + d) of the series z (NaN if it is constant)."""
    d = 0
    while True:
        zc = z - z.mean()
        den = float((zc * zc).sum())
        if den == 0.0 or zc.size < 2:
            return math.nan
        r1 = float((zc[:-1] * zc[1:]).sum()) / den
        delta = r1 / (1.0 + r1)
        if d >= dmin and (delta < 0.25 or d >= dmax):
            return -2.0 * (delta + d)
        z = np.diff(z)
        d += 1


def noise_id_lag1(x, m: int, *, data: str = "frequency", dmin: int = 0, dmax: int = 2) -> float:
    r"""Power-law noise exponent by the lag-1 autocorrelation (Riley & Greenhall 2004).

    The series is reduced to averaging factor `m` (frequency/rate data: non-overlapping means of `m`
    samples; phase/angle data: every m-th sample). Then, with :math:`d = 0`: the lag-1 autocorrelation

    .. math::

        r_1 = \frac{\sum_{t=1}^{N-1} (z_t - \bar z)(z_{t+1} - \bar z)}{\sum_{t=1}^{N} (z_t - \bar z)^2},
        \qquad \delta = \frac{r_1}{1 + r_1},

    estimates the fractional-integration parameter of :math:`z`; if :math:`d \ge d_{min}` and
    (:math:`\delta < 0.25` or :math:`d \ge d_{max}`), :math:`p = -2(\delta + d)`; otherwise :math:`z` is
    differenced, :math:`d \leftarrow d + 1`, and the test repeated. :math:`p` estimates the exponent of the
    PSD of the input data type: ``alpha = p`` for frequency (rate) data, ``alpha = p + 2`` for phase
    (angle) data. Round it (``floor(alpha + 0.5)``) for the integer noise type.

    Parameters
    ----------
    x : array_like, shape (n,)
        Rate (``data="frequency"``) or integrated (``data="phase"``) samples.
    m : int
        Averaging factor (samples per cluster).
    data : {"frequency", "phase"}, optional
        Data type of `x`. Defaults to ``"frequency"``.
    dmin, dmax : int, optional
        Least and largest number of differences; ``dmax = 2`` for the Allan variance (alpha >= -2),
        3 for the Hadamard variance. Defaults to 0 and 2.

    Returns
    -------
    float
        The (non-integer) estimate of alpha, :math:`S_y(f) \propto f^\alpha`; NaN if the reduced series
        is constant. Reliable with 30 or more reduced points (Riley & Greenhall 2004).

    References
    ----------
    .. [1] W. J. Riley and C. A. Greenhall, "Power law noise identification using the lag 1
           autocorrelation", Proc. 18th EFTF, 2004.
    .. [2] W. J. Riley, NIST SP 1065, 2008, section 5.6.
    """
    a = np.asarray(_as_rate_array(x), dtype=np.float64)
    m = int(m)
    if m < 1 or a.size // m < 2:
        raise ValueError(f"averaging factor m={m} leaves fewer than 2 points of a {a.size}-sample record")
    if data == "frequency":
        k = a.size // m
        z = a[: k * m].reshape(k, m).mean(axis=1)
        offset = 0.0
    elif data == "phase":
        z = a[::m]
        offset = 2.0
    else:
        raise ValueError(f"data must be 'frequency' or 'phase', got {data!r}")
    return _lag1_p(z, dmin, dmax) + offset


def _lag1_sums(theta: np.ndarray, lags: np.ndarray, backend: str) -> np.ndarray:
    """(nlags, 3, 3): for d = 0, 1, 2 the sums (sum w, sum w^2, sum w_i w_{i+1}) of w = diff(z, d),
    z the N = n // m non-overlapping m-sample means (theta[(i+1)m] - theta[im]) / m."""
    lags = np.ascontiguousarray(lags, dtype=np.int64)
    out = np.empty((lags.size, 3, 3))
    if lags.size == 0:
        return out
    if backend == "c":
        _kernels.lag1_sums(np.ascontiguousarray(theta, dtype=np.float64), lags, out.reshape(-1))
        return out
    n = theta.size - 1
    for j, m in enumerate(lags.tolist()):
        w = np.diff(theta[: (n // m) * m + 1 : m]) / m
        for d in range(3):
            out[j, d] = (w.sum(), (w * w).sum(), (w[:-1] * w[1:]).sum()) if w.size else (0.0, 0.0, 0.0)
            w = np.diff(w)
    return out


def _lag1_p_from_sums(theta: np.ndarray, lags: np.ndarray, sums: np.ndarray, dmin: int, dmax: int) -> np.ndarray:
    """Riley & Greenhall's p = -2(delta + d) per lag from the sums of :func:`_lag1_sums` (NaN if undefined).

    With N' = N - d points w of sum A, sum of squares B and lag-1 sum C, the centred lag-1
    autocorrelation is r1 = [C - wbar (2A - w_first - w_last) + (N' - 1) wbar^2] / (B - A^2/N'); the
    same test as :func:`_lag1_p` (the two-pass form, used by :func:`noise_id_lag1`).
    """
    n = theta.size - 1
    N = n // lags
    idx = np.stack([np.minimum(k, N) * lags for k in range(4)] + [np.maximum(N - k, 0) * lags for k in range(4)])
    t = theta[idx]
    zf = (t[1:4] - t[0:3]) / lags  # z_0, z_1, z_2
    zl = (t[4:7] - t[5:8]) / lags  # z_{N-1}, z_{N-2}, z_{N-3}
    first = np.stack([zf[0], zf[1] - zf[0], zf[2] - 2 * zf[1] + zf[0]])
    last = np.stack([zl[0], zl[0] - zl[1], zl[0] - 2 * zl[1] + zl[2]])
    p = np.full(lags.size, np.nan)
    open_ = np.ones(lags.size, dtype=bool)
    for d in range(dmax + 1):
        Np = (N - d).astype(np.float64)
        A, B, C = sums[:, d, 0], sums[:, d, 1], sums[:, d, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            mean = A / Np
            den = B - A * mean
            num = C - mean * (2.0 * A - first[d] - last[d]) + (Np - 1.0) * mean * mean
            r1 = num / den
        good = open_ & (Np >= 2) & (den > 0) & np.isfinite(r1)
        open_ &= good  # an undefined step leaves p NaN
        delta = r1 / (1.0 + r1)
        stop = good & (d >= dmin) & ((delta < 0.25) | (d >= dmax))
        p[stop] = -2.0 * (delta[stop] + d)
        open_ &= ~stop
    return p


def _segment_sums(v: np.ndarray, starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Sum of v over each of the contiguous segments [start, start + length) (all lengths >= 1)."""
    return np.add.reduceat(v, starts) if v.size else np.zeros(starts.size)


def _b1_theory(N: np.ndarray, mu: int) -> np.ndarray:
    """Barnes' bias function B1(N, mu) = N (1 - N^mu) / (2 (N - 1) (1 - 2^mu)) (mu = 0: its limit)."""
    N = np.asarray(N, dtype=np.float64)
    if mu == 0:
        return N * np.log(N) / (2.0 * (N - 1) * math.log(2.0))
    return N * (1.0 - N**mu) / (2.0 * (N - 1) * (1.0 - 2.0**mu))


def _noise_id_b1(theta: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """Noise types by the B1 ratio (NIST SP 1065 section 5.6; Stable32 below 30 points), for few means.

    B1 = (sample variance of the N means) / (their Allan variance); the exponent mu of AVAR ~ tau^mu
    whose theoretical B1(N, mu) is nearest in the log sense (boundaries at geometric means) gives
    alpha = -mu - 1 for mu = -1, 0, 1. A ratio in the mu = -2 class (white or flicker angle noise,
    alpha = 2 or 1) is reported as white rate noise (alpha = 0), deliberately: B1 cannot separate the
    two (R(n) needs the modified variance), and with so few means a chance low ratio would otherwise
    assign alpha = 2, whose EDF grows with the number of terms instead of the number of clusters
    (e.g. 12 000 instead of 4 for white rate noise at N = 4): confidence limits orders of magnitude too
    narrow. Returns float alpha, NaN where undefined (constant means).

    Divergence from Stable32 below 30 averages (measured against its result files for PHASE.DAT, the NBS14
    set integrated to phase, and a 19 982 s OCXO record; effect = largest relative change of the 68.3 %
    limits of the deviation when the EDF (Greenhall & Riley) uses Stable32's alpha instead of this one):

    * PHASE.DAT, all taus: 56 of 106 lags differ, almost all alpha = 0 here against Stable32's 1 (its B1 class
      mu = -2, split by R(n)); NBS14 is white frequency noise by construction (alpha = 0), so this rule is
      the right one there, and Stable32's alpha = 1 would give limits 10-40 % narrower. A few lags (m = 93,
      194-231) get alpha = -1 or -2 from B1 with 4-10 means: limits up to 67 % wider than Stable32's
      (conservative).
    * OCXO, all taus: 59 of 106 lags differ by one step (-2 here against -1, or -1 against 0), limits 2-17 %
      wider (the lower alpha has fewer EDF: conservative); octave taus: 2 of 3 lags, 4.3 % and 23 %.

    The divergence only comes from lags with fewer than 30 means, where neither rule tells the noise type
    reliably. In these files it widens the limits against Stable32's on the OCXO record (true type unknown)
    and keeps the true type on PHASE.DAT; it was not found to narrow them.
    """
    n = theta.size - 1
    N = n // lags
    cnt = N + 1
    first = np.concatenate(([0], np.cumsum(cnt)[:-1]))
    pos = np.arange(int(cnt.sum())) - np.repeat(first, cnt)
    t = theta[pos * np.repeat(lags, cnt)]  # theta[0], theta[m], ..., theta[N m] per lag
    z = np.diff(t) / np.repeat(lags.astype(np.float64), cnt)[1:]
    keep = np.ones(z.size, dtype=bool)
    keep[first[1:] - 1] = False  # drop differences across lags
    z = z[keep]
    starts = np.concatenate(([0], np.cumsum(N)[:-1]))
    seg = np.repeat(np.arange(N.size), N)
    Nf = N.astype(np.float64)
    mean = _segment_sums(z, starts, N) / Nf
    ss = _segment_sums((z - mean[seg]) ** 2, starts, N)
    dz2 = np.zeros(z.size)
    dz2[:-1] = np.diff(z) ** 2
    dz2[starts + N - 1] = 0.0  # no difference across lags
    sd = _segment_sums(dz2, starts, N)
    alpha = np.full(N.size, np.nan)
    ok = (N >= 2) & (sd > 0)
    if not ok.any():
        return alpha
    Nk = Nf[ok]
    b1 = (ss[ok] / (Nk - 1)) / (sd[ok] / (2.0 * (Nk - 1)))
    with np.errstate(divide="ignore", invalid="ignore"):
        th = np.stack([_b1_theory(Nk, mu) for mu in (-2, -1, 0, 1)])
    bounds = np.sqrt(th[:-1] * th[1:])  # geometric means between neighbours
    mu = np.sum(b1[None, :] >= bounds, axis=0) - 2  # -2 .. 1
    mu = np.maximum(mu, -1)  # no alpha = 1, 2 from B1 (see above)
    a = (-mu - 1).astype(np.float64)
    a[Nk == 2] = 0.0  # B1 = 1 identically for two means
    alpha[ok] = a
    return alpha


def _noise_ids(theta: np.ndarray, lags: np.ndarray, backend: str = "auto", dmax: int = 2, lag1_sums=None):
    """Integer alpha (rate data) per lag from theta (sample units), and the number of m-sample means N.

    N >= _NOISE_ID_MIN_POINTS: lag-1 autocorrelation (Riley & Greenhall 2004) from one pass over theta
    per lag (:func:`_lag1_sums`, or `lag1_sums` of all `lags` when already computed); fewer: the B1
    ratio (as Stable32). Rounded (floor(p + 0.5)), clipped to -dmax..2; 0 (white) where neither can
    decide (constant means).
    """
    lags = np.asarray(lags, dtype=np.int64)
    N = (theta.size - 1) // lags
    a = np.full(lags.size, np.nan)
    many = N >= _NOISE_ID_MIN_POINTS
    if many.any():
        lm = lags[many]
        sums = _lag1_sums(theta, lm, _pick_backend(backend)) if lag1_sums is None else lag1_sums[many]
        p = _lag1_p_from_sums(theta, lm, sums, 0, dmax)
        a[many] = np.floor(p + 0.5)
    if (~many).any():
        a[~many] = _noise_id_b1(theta, lags[~many])
    return np.clip(np.nan_to_num(a, nan=0.0), -dmax, 2).astype(np.int64), N


# ---------------------------------------------------------------------------------------------
# equivalent degrees of freedom (Greenhall & Riley 2003)
# ---------------------------------------------------------------------------------------------
# Table 2 of Greenhall & Riley (2003): (a0, a1) of 1/edf = (a0 - a1/r)/r for unmodified variances,
# rows alpha = 2 .. -4, columns d = 1, 2, 3 (None: alpha + 2d <= 1, not defined).
_G_TABLE2 = {
    2: ((3 / 2, 1 / 2), (35 / 18, 1.0), (231 / 100, 3 / 2)),
    1: ((78.6, 25.2), (790.0, 410.0), (9950.0, 6520.0)),
    0: ((2 / 3, 1 / 6), (2 / 3, 1 / 3), (7 / 9, 1 / 2)),
    -1: (None, (0.852, 0.375), (0.997, 0.617)),
    -2: (None, (1.079, 0.368), (1.033, 0.607)),
    -3: (None, None, (1.053, 0.553)),
    -4: (None, None, (1.302, 0.535)),
}
# Table 3: (b0, b1) of sz(0, m, 1, d) ~ b0 + b1 ln m (alpha = 1, unmodified), d = 1, 2, 3.
_G_TABLE3 = ((6.0, 4.0), (15.23, 12.0), (47.8, 40.0))


def _sw(t: np.ndarray, alpha: int) -> np.ndarray:
    """Greenhall's sw(t, alpha): generalised autocovariance of the integrated phase, |t|^(3-alpha) or
    t^(3-alpha) ln|t| (odd alpha), alpha = 2..-4 (the common sign per alpha cancels in the EDF)."""
    a = np.abs(t)
    e = 3 - alpha
    if alpha % 2 == 0:
        sign = -1.0 if (e // 2) % 2 == 0 else 1.0  # |t|: -, |t|^3: +, |t|^5: -, |t|^7: +
        return sign * a**e
    with np.errstate(divide="ignore", invalid="ignore"):
        out = a**e * np.log(a)
    out = np.where(a > 0, out, 0.0)
    sign = 1.0 if (e // 2) % 2 == 1 else -1.0  # t^2 ln: +, t^4 ln: -, t^6 ln: +
    return sign * out


def _sx(t: np.ndarray, F: np.ndarray, alpha: int) -> np.ndarray:
    """sx(t, F, alpha) = F^2 [2 sw(t) - sw(t - 1/F) - sw(t + 1/F)], or sw(t, alpha + 2) for F = inf."""
    F = np.broadcast_to(np.asarray(F, dtype=np.float64), np.shape(t))
    finite = np.isfinite(F)
    out = np.empty(np.shape(t))
    if (~finite).any():
        out[~finite] = _sw(np.asarray(t)[~finite], alpha + 2)
    if finite.any():
        tf, Ff = np.asarray(t)[finite], F[finite]
        out[finite] = Ff**2 * (2.0 * _sw(tf, alpha) - _sw(tf - 1.0 / Ff, alpha) - _sw(tf + 1.0 / Ff, alpha))
    return out


def _sz(t: np.ndarray, F, alpha: int, d: int) -> np.ndarray:
    """sz(t, F, alpha, d) = sum_{k=-d}^{d} (-1)^k C(2d, d+k) sx(t + k, F, alpha)."""
    t = np.asarray(t, dtype=np.float64)
    out = np.zeros(t.shape)
    for k in range(-d, d + 1):
        out += (-1.0) ** k * math.comb(2 * d, d + k) * _sx(t + k, F, alpha)
    return out


def _basic_sum(J, M, S, F, alpha: int, d: int) -> np.ndarray:
    """BasicSum(J, M, S, F) = sz(0)^2 + (1 - J/M) sz(J/S)^2 + 2 sum_{j=1}^{J-1} (1 - j/M) sz(j/S)^2,
    vectorised over arrays J (<= _JMAX), M, S, F of one shape."""
    J, M, S, F = (np.atleast_1d(np.asarray(v, dtype=np.float64)) for v in (J, M, S, F))
    j = np.arange(_JMAX + 1, dtype=np.float64)[None, :]
    Jc = J[:, None]
    w = np.where(
        j == 0,
        1.0,
        np.where(j < Jc, 2.0 * (1.0 - j / M[:, None]), np.where(j == Jc, 1.0 - Jc / M[:, None], 0.0)),
    )
    sz = _sz(j / S[:, None], F[:, None], alpha, d)
    return np.sum(w * sz**2, axis=1)


def edf_greenhall(alpha, d: int, m, n_phase: int, *, overlapping: bool = True) -> np.ndarray:
    r"""Equivalent degrees of freedom of unmodified Allan (d = 2) or Hadamard (d = 3) variance estimates.

    Greenhall & Riley (2003) model the estimator as the mean of M squared d-th differences of the
    phase (integrated rate) sampled at stride :math:`\tau/S` (S = m overlapping, 1 non-overlapping), of
    power-law noise :math:`S_y(f) \propto f^\alpha`; its EDF is :math:`2 E[\hat\sigma^2]^2/\mathrm{Var}`:

    .. math::

        \frac{1}{\mathrm{edf}} = \frac{\mathrm{BasicSum}(J, M, S, F)}{M\, s_z(0)^2}, \qquad
        \mathrm{BasicSum} = s_z(0)^2 + \Big(1 - \frac{J}{M}\Big) s_z\Big(\frac{J}{S}\Big)^2
        + 2\sum_{j=1}^{J-1}\Big(1 - \frac{j}{M}\Big) s_z\Big(\frac{j}{S}\Big)^2,

    with :math:`L = 1 + md`, :math:`M = 1 + \lfloor S (N - L)/m \rfloor` (N phase points),
    :math:`J = \min(M, (d+1)S)`, :math:`r = M/S`, :math:`s_z` the generalised autocovariance of the d-th
    difference (their eqs. 7-9, filter factor F = m, or :math:`\infty` when :math:`m(d+1) > J_{max}`).
    For :math:`J > J_{max} = 100` the asymptotic forms of their Tables 2 and 3 are used,
    :math:`1/\mathrm{edf} = (a_0 - a_1/r)/r` (divided by :math:`(b_0 + b_1\ln m)^2` for alpha = 1), or,
    when :math:`r \le d + 1`, the sum with :math:`J = M = J_{max}` and stride :math:`J_{max}/r`. For
    white phase noise (alpha = 2) the exact finite form
    :math:`1/\mathrm{edf} = \frac{1}{M}\sum_{|l| \le \min(d, \lceil r\rceil - 1)} (1 - |l|/r)\rho_l^2`,
    :math:`\rho_l = \binom{2d}{d+l}/\binom{2d}{d}`, is used (it equals :math:`(a_0 - a_1/r)/M` of their
    case 4 when :math:`\lceil r\rceil > d`). Modified variances (their case 1) are not implemented.

    Notes
    -----
    This is the algorithm Stable32 uses: with the noise types of the Stable32 octave files it reproduces
    their confidence limits to 5e-4 (tests). Its filter factor F = m models phase samples averaged over
    :math:`\tau_0`. For white rate noise given as interval averages (an IMU's output; equivalently
    phase sampled instantaneously, F = :math:`\infty`) the exact discrete EDF differs: at m = 1 it is
    15 % lower than this one (666 against 782 for 1000 samples: limits about 8 % too narrow), for
    m = 2..32 it is 3-13 % higher (these limits are then conservative), and from m = 64 on the two agree.

    Parameters
    ----------
    alpha : int or array_like of int
        Power-law exponent of the rate (frequency) PSD, 2 .. -2 for d = 2 (alpha + 2d > 1).
    d : int
        Order of the phase difference: 2 Allan variance, 3 Hadamard variance (1 is accepted).
    m : int or array_like of int
        Averaging factors; broadcast with `alpha`.
    n_phase : int
        Number of phase (integrated) points N = number of rate samples + 1.
    overlapping : bool, optional
        Overlapping (stride tau0, default) or non-overlapping (stride tau) estimator.

    Returns
    -------
    numpy.ndarray of float
        EDF, shape of ``broadcast(alpha, m)``.

    References
    ----------
    .. [1] C. A. Greenhall and W. J. Riley, "Uncertainty of stability variances based on finite
           differences", Proc. 35th PTTI Meeting, 2003, eqs. 7-10, Tables 1-3 and the four cases.
    .. [2] W. J. Riley, NIST SP 1065, 2008, section 5.3.
    """
    alpha_b, m_b = np.broadcast_arrays(np.asarray(alpha, dtype=np.int64), np.asarray(m, dtype=np.int64))
    shape = alpha_b.shape
    alpha_f, m_f = alpha_b.ravel(), m_b.ravel().astype(np.float64)
    if d not in (1, 2, 3):
        raise ValueError(f"d must be 1, 2 or 3, got {d}")
    if np.any(alpha_f + 2 * d <= 1) or np.any(alpha_f > 2):
        raise ValueError(f"alpha must satisfy alpha + 2d > 1 and alpha <= 2 (d={d}), got {np.unique(alpha_f)}")
    if np.any(m_f < 1):
        raise ValueError("averaging factors must be >= 1")
    N = float(n_phase)
    F = m_f.copy()  # unmodified
    S = m_f.copy() if overlapping else np.ones_like(m_f)
    Lf = m_f / F + m_f * d
    if np.any(N < Lf):
        bad = m_f[N < Lf][0]
        raise ValueError(f"m={bad:g} needs {1 + bad * d:g} phase points, only {N:g} given")
    M = 1.0 + np.floor(S * (N - Lf) / m_f)
    J = np.minimum(M, (d + 1) * S)
    r = M / S
    inv = np.empty(m_f.size)
    for a in np.unique(alpha_f).tolist():
        sel = alpha_f == a
        Ms, Js, Ss, rs, ms = M[sel], J[sel], S[sel], r[sel], m_f[sel]
        res = np.empty(Ms.size)
        if a == 2:  # case 4: exact white-phase form
            K = np.ceil(rs)
            c0 = math.comb(2 * d, d)
            tot = np.zeros(Ms.size)
            for l in range(-d, d + 1):
                rho2 = (math.comb(2 * d, d + l) / c0) ** 2
                tot += np.where(np.abs(l) <= K - 1, (1.0 - abs(l) / rs) * rho2, 0.0)
            res = tot / Ms
        else:
            small = Js <= _JMAX
            asym = ~small & (rs > d + 1)
            edge = ~small & ~asym
            if a == 1:
                b0, b1 = _G_TABLE3[d - 1]
                if small.any():
                    Fs = ms[small]  # filter factor m (their note: keep m below ~1e6 for round-off)
                    res[small] = _basic_sum(Js[small], Ms[small], Ss[small], Fs, 1, d) / (
                        Ms[small] * _sz(np.zeros(small.sum()), Fs, 1, d) ** 2
                    )
                if asym.any():
                    a0, a1 = _G_TABLE2[1][d - 1]
                    res[asym] = (a0 - a1 / rs[asym]) / (rs[asym] * (b0 + b1 * np.log(ms[asym])) ** 2)
                if edge.any():
                    mp = _JMAX / rs[edge]
                    res[edge] = _basic_sum(_JMAX, _JMAX, mp, mp, 1, d) / (
                        _JMAX * (b0 + b1 * np.log(ms[edge])) ** 2
                    )
            else:  # case 2: alpha <= 0
                tab = _G_TABLE2[a][d - 1]
                if small.any():
                    Fs = np.where(ms[small] * (d + 1) <= _JMAX, ms[small], np.inf)
                    res[small] = _basic_sum(Js[small], Ms[small], Ss[small], Fs, a, d) / (
                        Ms[small] * _sz(np.zeros(small.sum()), Fs, a, d) ** 2
                    )
                if asym.any():
                    a0, a1 = tab
                    res[asym] = (a0 - a1 / rs[asym]) / rs[asym]
                if edge.any():
                    mp = _JMAX / rs[edge]
                    inf = np.full(mp.size, np.inf)
                    res[edge] = _basic_sum(_JMAX, _JMAX, mp, inf, a, d) / (_JMAX * _sz(np.zeros(mp.size), inf, a, d) ** 2)
        inv[sel] = res
    return (1.0 / inv).reshape(shape)


def chi2_limits(var, edf, confidence: float = 0.683) -> tuple[np.ndarray, np.ndarray]:
    r"""Two-sided chi-squared confidence limits of a variance estimate (NIST SP 1065 eq. 45).

    .. math::

        \frac{\nu\, \hat\sigma^2}{\chi^2_{(1+c)/2}(\nu)} \le \sigma^2 \le
        \frac{\nu\, \hat\sigma^2}{\chi^2_{(1-c)/2}(\nu)},

    with :math:`\nu` the EDF and :math:`\chi^2_q(\nu)` the q-quantile.

    Parameters
    ----------
    var : array_like
        Variance estimates (any unit).
    edf : array_like
        Equivalent degrees of freedom (> 0), broadcast with `var`.
    confidence : float, optional
        Two-sided confidence level in (0, 1). Defaults to 0.683 (Stable32's "1 sigma").

    Returns
    -------
    lower, upper : numpy.ndarray
        Limits, in the unit of `var`.
    """
    from scipy.special import chdtri  # ~0.2 s import, paid only here

    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    var, edf = np.broadcast_arrays(np.asarray(var, dtype=np.float64), np.asarray(edf, dtype=np.float64))
    q = 0.5 * (1.0 - confidence)
    lower = var * edf / chdtri(edf, q)  # chdtri(v, p): upper-tail p quantile
    upper = var * edf / chdtri(edf, 1.0 - q)
    return lower, upper


# ---------------------------------------------------------------------------------------------
# public entry point
# ---------------------------------------------------------------------------------------------
def _square_units(units: str) -> str:
    u = units.strip()
    if u in ("", "1"):
        return "1"
    if all(ch.isalnum() or ch == "_" for ch in u):
        return f"{u}^2"
    return f"({u})^2"


def _rate_from_time(time) -> float:
    t = np.asarray(time)
    if t.size < 2:
        raise ValueError("cannot infer the sampling rate from a time coordinate with fewer than 2 values")
    if t.dtype.kind == "M":
        dt = np.diff(t).astype("timedelta64[ns]").astype(np.float64) * 1e-9
    elif t.dtype.kind == "m":
        dt = np.diff(t).astype("timedelta64[ns]").astype(np.float64) * 1e-9
    else:
        dt = np.diff(t.astype(np.float64))
    step = float(np.median(dt))
    if not step > 0 or np.max(np.abs(dt - step)) > 1e-6 * step:
        raise ValueError("the time coordinate is not uniformly spaced; resample before the Allan variance")
    return 1.0 / step


def allan_variance(
    x,
    rate: float | None = None,
    taus="octave",
    overlapping: bool = True,
    confidence: float = 0.683,
    *,
    units: str | None = None,
    method: str = "auto",
    backend: str = "auto",
):
    r"""Allan variance of a rate signal with equivalent degrees of freedom and confidence limits.

    .. math::

        \sigma^2(\tau) = \frac{1}{2\tau^2 (L-2m)} \sum_{k=0}^{L-2m-1}
        (\theta_{k+2m} - 2\theta_{k+m} + \theta_k)^2, \qquad \tau = m\tau_0,

    where :math:`\theta_k = \tau_0\sum_{i<k}(y_i - \bar y)` is the integrated signal (angle for a gyro,
    velocity for an accelerometer), :math:`L = n + 1` (NIST SP 1065 eq. 11; IEEE Std 952 Annex C).
    The non-overlapping estimator uses k = 0, m, 2m, ... only.

    Confidence limits: at each tau the dominant noise type alpha is identified by the lag-1
    autocorrelation of the m-sample means (Riley & Greenhall 2004), or with fewer than 30 means by the B1
    ratio (NIST SP 1065 section 5.6, as Stable32); the EDF follows Greenhall & Riley (2003)
    (:func:`edf_greenhall`) and the limits are chi-squared (:func:`chi2_limits`). For a composite
    process the EDF of the dominant type is an approximation (a parametric bootstrap from the fitted
    model is more honest).

    Parameters
    ----------
    x : numpy.ndarray or xarray.DataArray, shape (n,)
        Rate samples (rad/s, m/s^2, deg/s, g ...), any real dtype; accumulated in float64. A DataArray
        may carry a ``time`` coordinate (s, or datetime64) giving the rate, and ``attrs["units"]``.
        NaN or inf raise ValueError.
    rate : float, optional
        Sampling frequency, Hz. Required for a NumPy array; for a DataArray with a ``time`` coordinate
        it is inferred (and checked against `rate` if both are given).
    taus : {"octave", "decade", "all"}, int or array_like of float, optional
        Averaging-time grid (:func:`tau_grid`): named grids end at a quarter of the record; an array
        gives times in seconds, each at most half the record. Defaults to ``"octave"``.
    overlapping : bool, optional
        Overlapping estimator (default) or non-overlapping.
    confidence : float, optional
        Two-sided confidence level of the limits. Defaults to 0.683.
    units : str, optional
        Units of `x`; defaults to ``x.attrs["units"]`` for a DataArray, else ``"1"``.
    method : {"auto", "direct", "fft"}, optional
        Sums by the direct kernel, or for all factors at once by the FFT method of
        :func:`_oavar_sums_all` (overlapping only; exact to 1e-9 relative, see there). ``"auto"`` uses
        the FFT method where a cost model predicts it twice as fast (dense grids such as
        ``taus="all"`` on more than a few thousand samples).
    backend : {"auto", "c", "numpy"}, optional
        Compiled kernel or NumPy path for the direct sums. Defaults to the kernel when available.

    Returns
    -------
    xarray.Dataset
        On dimension ``tau`` (s), with coordinates ``m`` (samples per cluster) and ``n_terms`` (number of
        squared differences averaged), data variables

        - ``avar``: Allan variance, units square of the input's (e.g. ``"(rad/s)^2"``);
        - ``avar_lower``, ``avar_upper``: confidence limits at `confidence`, same units;
        - ``edf``: equivalent degrees of freedom;
        - ``alpha``: identified noise type (exponent of the rate PSD, 2 .. -2),

        each with ``long_name`` and ``units``; global attrs name the estimator, rate, record length,
        confidence, EDF and noise-ID methods.

    Raises
    ------
    ValueError
        Non-finite samples, a multi-dimensional signal, a missing or inconsistent rate, or averaging
        times the record cannot support (the message names the time and the record length).

    Warns
    -----
    ConstantSignalWarning
        For a constant channel: the Allan variance and both limits are exactly 0 (not NaN), the EDF is
        that of white noise and alpha is 0.

    References
    ----------
    .. [1] W. J. Riley, "Handbook of Frequency Stability Analysis", NIST SP 1065, 2008, eq. (11),
           sections 5.3 and 5.6.
    .. [2] IEEE Std 952-1997, Annex C.
    .. [3] C. A. Greenhall and W. J. Riley, "Uncertainty of stability variances based on finite
           differences", Proc. 35th PTTI Meeting, 2003.
    .. [4] W. J. Riley and C. A. Greenhall, "Power law noise identification using the lag 1
           autocorrelation", Proc. 18th EFTF, 2004.
    """
    return allan_variance_labelled(x, rate, taus, overlapping, confidence, units=units, method=method,
                           backend=backend).to_xarray()


def allan_variance_labelled(x, rate=None, taus="octave", overlapping=True, confidence=0.683, *, units=None,
                            method="auto", backend="auto", theta_buffer=None):
    """:func:`allan_variance` as :class:`imupipe.labelled.Labelled` arrays, without importing xarray.

    Same estimator, parameters, units and references as :func:`allan_variance` (Allan variance in
    ``units^2`` on ``tau`` in s, chi-squared limits at `confidence`); the result is written to netCDF with
    netCDF4 alone (:meth:`imupipe.labelled.Labelled.to_netcdf`), or turned into the
    :class:`xarray.Dataset` that :func:`allan_variance` returns with ``.to_xarray()``. This is the cheap
    entry point for a short-lived process (one workflow job): importing xarray costs ~0.3 s.

    Parameters
    ----------
    theta_buffer : numpy.ndarray, optional
        float64 array of ``n + 1`` elements that receives the integrated signal (u*s); `x` may be its
        ``[1:]`` view, and is then overwritten in place (no copy of the record). Default: a new array.
    """
    from imupipe.labelled import Labelled

    if hasattr(x, "dims") and hasattr(x, "coords"):  # an xarray.DataArray, recognised without importing xarray
        if x.ndim != 1:
            raise ValueError(f"x must be one-dimensional, got dims {x.dims}")
        if units is None:
            units = x.attrs.get("units")
        if "time" in x.coords:
            inferred = _rate_from_time(x["time"].values)
            if rate is None:
                rate = inferred
            elif abs(float(rate) - inferred) > 1e-6 * inferred:
                raise ValueError(f"rate={rate} Hz disagrees with the time coordinate ({inferred:g} Hz)")
        values = x.values
    else:
        values = x
    if rate is None:
        raise ValueError("rate (Hz) is required unless x is a DataArray with a time coordinate")
    rate = _check_rate(rate)
    units = "1" if units is None else str(units)
    if method not in ("auto", "direct", "fft"):
        raise ValueError(f"method must be 'auto', 'direct' or 'fft', got {method!r}")
    if method == "fft" and not overlapping:
        raise ValueError("method='fft' applies to the overlapping estimator only")
    be = _pick_backend(backend)

    a = _as_rate_array(values)
    n = a.size
    grid = tau_grid(n, rate, taus)
    m = grid.m
    theta, constant = _integrate(a, out=theta_buffer)
    if constant:
        warnings.warn(
            f"the signal is constant ({n} samples equal to {a[0]!r}): its Allan variance is exactly 0 "
            "(dead or stuck channel?)",
            ConstantSignalWarning,
            stacklevel=3,
        )

    fft_used = False
    lag1 = None
    if overlapping:
        n_terms = theta.size - 2 * m
        use_fft = method == "fft" or (method == "auto" and _fft_is_faster(theta.size, m, be))
        if use_fft and not constant:
            sums_all, _, _ = _oavar_sums_all(theta, int(m.max()), backend=be)
            sums = sums_all[m - 1]
            fft_used = True
        elif be == "c" and not constant:  # the noise-ID sums in the same pass over theta
            lag1 = np.empty((m.size, 3, 3))
            sums = np.empty(m.size)
            _kernels.oavar_sums(theta, np.ascontiguousarray(m, dtype=np.int64), sums, lag1.reshape(-1))
        else:
            sums = _sums_direct(theta, m, be)
    else:
        n_terms = n // m - 1
        sums = _sums_nonoverlapping(theta, m)
    avar = sums / (2.0 * m.astype(np.float64) ** 2 * n_terms)

    if constant:
        alpha = np.zeros(m.size, dtype=np.int64)
    else:
        alpha, _ = _noise_ids(theta, m, be, lag1_sums=lag1)
    edf = edf_greenhall(alpha, 2, m, n + 1, overlapping=overlapping)
    lower, upper = chi2_limits(avar, edf, confidence)

    vunits = _square_units(units)
    kind = "overlapping" if overlapping else "non-overlapping"
    cl = f"{confidence:g}"
    return Labelled(
        dim="tau",
        data_vars={
            "avar": (avar, {"long_name": f"{kind} Allan variance", "units": vunits}),
            "avar_lower": (
                lower,
                {"long_name": f"lower {cl} confidence limit of the Allan variance", "units": vunits},
            ),
            "avar_upper": (
                upper,
                {"long_name": f"upper {cl} confidence limit of the Allan variance", "units": vunits},
            ),
            "edf": (edf, {"long_name": "equivalent degrees of freedom", "units": "1"}),
            "alpha": (
                alpha,
                {
                    "long_name": "dominant noise type (exponent of the rate PSD)",
                    "units": "1",
                    "flag_meanings": "2 white angle, 1 flicker angle, 0 white rate, -1 flicker rate, "
                    "-2 random-walk rate",
                },
            ),
        },
        coords={
            "tau": (grid.tau, {"long_name": "averaging time", "units": "s"}),
            "m": (m, {"long_name": "samples per cluster", "units": "1"}),
            "n_terms": (np.asarray(n_terms, dtype=np.int64), {"long_name": "number of terms", "units": "1"}),
        },
        attrs={
            "estimator": f"{kind} Allan variance (NIST SP 1065 eq. 11), mean removed, float64",
            "sums": "FFT method with direct recomputation where its bound exceeds 1e-9" if fft_used else "direct",
            "rate_hz": rate,
            "n_samples": n,
            "input_units": units,
            "confidence": confidence,
            "edf_method": "Greenhall & Riley (2003), unmodified AVAR",
            "noise_id_method": f"lag-1 autocorrelation (Riley & Greenhall 2004) with >= {_NOISE_ID_MIN_POINTS} "
            "m-sample means, B1 ratio (NIST SP 1065) with fewer",
        },
    )


_allan_variance = allan_variance_labelled  # the former private name, kept for now
