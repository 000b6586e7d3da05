r"""Stationarity checks of static IMU records (docs/method.md, section "Stationarity").

The paper (Gallon et al. 2021) declares a record stationary when a Levene test of equal variances
and a two-sample Kolmogorov-Smirnov test of equal distributions both accept at the 95 % level,
on the 1 Hz block-averaged record split into segments. Both tests assume **independent** samples.
A stationary white + Gauss-Markov (GM) process at 1 Hz has serially correlated samples, so the
two halves of one record differ by much more than independent samples would: the paper's KS test
then rejects stationarity far more often than its nominal 5 % (about 76 % of stationary records; see
docs/method.md, section "Stationarity"; the tests of this module reproduce the effect).

Three versions are provided:

* :func:`stationarity_tests` - the paper's test (asymptotic scipy p-values), generalised to
  ``n_segments`` segments with a Bonferroni correction over the consecutive KS pairs;
* :func:`calibrated_stationarity` - the same statistics with their null distribution simulated
  from a fitted stationary noise model (parametric Monte Carlo test);
* :func:`bootstrap_stationarity` - the same statistics calibrated by a circular block bootstrap of
  the record itself (no model needed; the block must be long compared with the correlation time).

Every function returns a dict of plain Python types (``float``, ``int``, ``bool``, ``str``,
``list``) that :mod:`yaml` writes as is.

Statistics (both invariant to an offset and a scale factor of the record, so the null
distribution only depends on the *shape* of the model: ratios of its components and time
constants):

* Levene (median-centred, Brown-Forsythe) with :math:`k` segments of :math:`m` samples,
  :math:`z_{ij} = |x_{ij} - \tilde x_i|`:

  .. math::

      W = \frac{N - k}{k - 1}\,
      \frac{\sum_i m (\bar z_i - \bar z)^2}{\sum_i \sum_j (z_{ij} - \bar z_i)^2}, \qquad N = k m;

* two-sample KS between consecutive segments, :math:`D = \sup_x |F_i(x) - F_{i+1}(x)|`; the
  Monte Carlo tests use :math:`D_{max} = \max_i D_i`, which takes care of the multiplicity.

References
----------
.. [1] H. Levene, "Robust tests for equality of variances", in Contributions to Probability and
       Statistics (I. Olkin, ed.), Stanford University Press, 1960, pp. 278-292.
.. [2] M. B. Brown and A. B. Forsythe, "Robust tests for the equality of variances", J. Am. Stat.
       Assoc. 69(346), 364-367, 1974 (the median-centred variant).
.. [3] F. J. Massey, "The Kolmogorov-Smirnov test for goodness of fit", J. Am. Stat. Assoc. 46(253),
       68-78, 1951.
.. [4] A. C. A. Hope, "A simplified Monte Carlo significance test procedure", J. R. Stat. Soc. B
       30(3), 582-598, 1968 (the (1 + #)/(1 + n) Monte Carlo p-value).
.. [5] H. R. Kuensch, "The jackknife and the bootstrap for general stationary observations",
       Ann. Statist. 17(3), 1217-1241, 1989; D. N. Politis and J. P. Romano, "A circular
       block-resampling procedure for stationary data", 1992 (block bootstrap).
.. [6] E. Gallon, M. Joerger, B. Pervan, ION GNSS+ 2021, section "Stationarity".
.. [7] J. Besag, P. Clifford, "Sequential Monte Carlo p-values", Biometrika 78(2), 301-304, 1991
       (stopping the simulation once the decision is known; used by ``stop_early``).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable

import numpy as np

try:  # optional compiled kernel; the NumPy path below gives the same statistics (D exactly, W to rounding)
    from imupipe import _kernels
except ImportError:  # pragma: no cover - exercised by forcing backend="numpy" in the tests
    _kernels = None

from imupipe.io import plain

__all__ = [
    "bootstrap_stationarity",
    "calibrated_stationarity",
    "ks_statistics",
    "levene_statistic",
    "notch",
    "stationarity_tests",
]

# simulated records are processed in batches of about this many samples (bounded memory)
_BATCH_SAMPLES = 1 << 22


# ---------------------------------------------------------------------------------------------
# helpers and vectorised statistics
# ---------------------------------------------------------------------------------------------
def _check_args(x, n_segments, alpha) -> tuple[np.ndarray, int, int]:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 1:
        raise ValueError(f"x must be one-dimensional, got shape {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError("x contains NaN or inf; remove or interpolate them before the stationarity tests")
    k = int(n_segments)
    if k < 2:
        raise ValueError(f"n_segments must be >= 2, got {n_segments!r}")
    if not (0.0 < float(alpha) < 1.0):
        raise ValueError(f"alpha must lie in (0, 1), got {alpha!r}")
    m = a.size // k
    if m < 3:
        raise ValueError(f"record of {a.size} samples is too short for {k} segments (need >= 3 samples each)")
    return a, k, m


def _segments(a: np.ndarray, k: int, m: int) -> np.ndarray:
    """(..., k, m) view: k equal consecutive segments; the last a.size % k samples are dropped."""
    return a[..., : k * m].reshape(a.shape[:-1] + (k, m))


def levene_statistic(segments) -> np.ndarray:
    r"""Median-centred Levene (Brown-Forsythe) statistic :math:`W` of equal-length segments.

    Same value as ``scipy.stats.levene(*segments, center="median").statistic`` (tested), but
    vectorised over leading axes for Monte Carlo use.

    Parameters
    ----------
    segments : array_like, shape (..., k, m)
        k groups of m samples each (any unit; :math:`W` is dimensionless).

    Returns
    -------
    numpy.ndarray or float
        :math:`W`, shape (...). A group set with zero within-group spread gives 0 if all groups
        are identical constants and inf otherwise.
    """
    s = np.asarray(segments, dtype=np.float64)
    k, m = s.shape[-2], s.shape[-1]
    z = np.abs(s - np.median(s, axis=-1, keepdims=True))
    zi = z.mean(axis=-1)
    zbar = zi.mean(axis=-1, keepdims=True)
    between = m * ((zi - zbar) ** 2).sum(axis=-1)
    within = ((z - zi[..., None]) ** 2).sum(axis=(-2, -1))
    n = k * m
    with np.errstate(divide="ignore", invalid="ignore"):
        w = (n - k) / (k - 1) * between / within
    w = np.where(within > 0, w, np.where(between > 0, np.inf, 0.0))
    return w[()] if w.ndim == 0 else w


def ks_statistics(segments) -> np.ndarray:
    r"""Two-sample KS statistics :math:`D_i = \sup_x |F_i(x) - F_{i+1}(x)|` of consecutive segments.

    Same values as ``scipy.stats.ks_2samp(seg[i], seg[i+1]).statistic`` (tested, ties included),
    vectorised over leading axes: the pooled pair is sorted once and the difference of the two
    empirical distribution functions is accumulated, read only at the last element of each run
    of tied values.

    Parameters
    ----------
    segments : array_like, shape (..., k, m)

    Returns
    -------
    numpy.ndarray
        Shape (..., k - 1).
    """
    s = np.asarray(segments, dtype=np.float64)
    k, m = s.shape[-2], s.shape[-1]
    out = np.empty(s.shape[:-2] + (k - 1,))
    step = np.concatenate((np.ones(m, dtype=np.int64), -np.ones(m, dtype=np.int64)))  # exact counts
    for i in range(k - 1):
        pooled = np.concatenate((s[..., i, :], s[..., i + 1, :]), axis=-1)
        order = np.argsort(pooled, axis=-1, kind="stable")
        values = np.take_along_axis(pooled, order, axis=-1)
        count_diff = np.cumsum(step[order], axis=-1)  # m (F_i - F_{i+1}), integer
        last_of_run = np.ones(values.shape, dtype=bool)
        last_of_run[..., :-1] = values[..., 1:] != values[..., :-1]
        out[..., i] = np.max(np.where(last_of_run, np.abs(count_diff), 0), axis=-1) / m
    return out


def _null_statistics(records: np.ndarray, k: int, m: int, backend: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """(W, D_max) of each row of `records` (shape (count, n), n >= k m), split into k segments of m samples.

    Both statistics ignore the order within a segment, so each segment is sorted first: the medians of Levene
    are then the middle values and each KS statistic a merge walk over two sorted runs. The compiled kernel
    (``imupipe._kernels.segment_stats``: radix sort of a copy, then both statistics in one O(k m) pass) costs
    about a third of NumPy's sort plus :func:`levene_statistic` and :func:`ks_statistics` on the sorted
    segments (``backend="numpy"``), which give the same D exactly and W to rounding (summation order).
    `records` is not modified.
    """
    records = np.ascontiguousarray(records, dtype=np.float64)
    count, n = records.shape
    if backend == "c" or (backend == "auto" and _kernels is not None):
        if _kernels is None:
            raise RuntimeError("the compiled kernel imupipe._kernels is not available (use backend='numpy')")
        w, d = np.empty(count), np.empty(count)
        _kernels.segment_stats(records, n, k, m, w, d)
        return w, d
    segs = np.sort(_segments(records, k, m), axis=-1)
    return np.atleast_1d(levene_statistic(segs)), ks_statistics(segs).max(axis=-1)


# ---------------------------------------------------------------------------------------------
# the paper's test
# ---------------------------------------------------------------------------------------------
def stationarity_tests(x, n_segments: int = 2, alpha: float = 0.05) -> dict:
    r"""The paper's stationarity test: Levene (median-centred) and two-sample KS on segments.

    The record is split into `n_segments` equal consecutive segments of :math:`m = \lfloor L/k
    \rfloor` samples (the last :math:`L \bmod k` samples are dropped). Levene's test compares the
    spreads of all segments at once (:func:`scipy.stats.levene`, ``center="median"``); KS
    (:func:`scipy.stats.ks_2samp`, two-sided, ``method="auto"``) compares each pair of consecutive
    segments, :math:`k - 1` tests, each at the Bonferroni level :math:`\alpha/(k-1)`. Verdict:

    .. math::

        \text{stationary} = \left(p_{Levene} > \alpha\right) \wedge
        \left(\min_i p_{KS,i} > \frac{\alpha}{k-1}\right).

    With ``n_segments=2`` this is exactly the paper's test (both at 95 %). The family-wise false
    rejection rate of the combined verdict is at most :math:`2\alpha` for independent samples,
    and far larger for serially correlated samples (see the module docstring): use
    :func:`calibrated_stationarity` for a test with a stated level.

    Parameters
    ----------
    x : array_like
        The (decimated, e.g. 1 Hz) record, any unit. Must be finite.
    n_segments : int, optional
        Number of equal segments, >= 2. Default 2 (halves, as in the paper).
    alpha : float, optional
        Significance level of each of the two tests. Default 0.05 (95 %).

    Returns
    -------
    dict
        ``test``, ``n_segments``, ``segment_length``, ``n_dropped``, ``alpha``,
        ``levene_statistic``, ``levene_p``, ``levene_pass``, ``ks_pairs`` (list of [i, i+1]),
        ``ks_statistic`` (list), ``ks_p`` (list), ``ks_alpha`` (Bonferroni level), ``ks_pass``,
        ``stationary``, ``multiplicity`` (a sentence). Plain Python types.

    Warns
    -----
    UserWarning
        Constant record (Levene undefined; reported as W = 0, p = 1).
    """
    a, k, m = _check_args(x, n_segments, alpha)
    from scipy.stats import ks_2samp, levene

    segs = _segments(a, k, m)
    if np.ptp(a[: k * m]) == 0.0:
        warnings.warn("constant record: Levene's test is undefined; reported as W = 0, p = 1", stacklevel=2)
        lev_w, lev_p = 0.0, 1.0
    else:
        lev = levene(*segs, center="median")
        lev_w, lev_p = float(lev.statistic), float(lev.pvalue)
    ks_stat, ks_p = [], []
    for i in range(k - 1):
        res = ks_2samp(segs[i], segs[i + 1])
        ks_stat.append(float(res.statistic))
        ks_p.append(float(res.pvalue))
    alpha = float(alpha)
    ks_alpha = alpha / (k - 1)
    levene_pass = bool(lev_p > alpha)
    ks_pass = bool(min(ks_p) > ks_alpha)
    return {
        "test": "Levene (median-centred) + two-sample Kolmogorov-Smirnov, asymptotic p-values",
        "n_segments": k,
        "segment_length": int(m),
        "n_dropped": int(a.size - k * m),
        "alpha": alpha,
        "levene_statistic": lev_w,
        "levene_p": lev_p,
        "levene_pass": levene_pass,
        "ks_pairs": [[i, i + 1] for i in range(k - 1)],
        "ks_statistic": ks_stat,
        "ks_p": ks_p,
        "ks_alpha": ks_alpha,
        "ks_pass": ks_pass,
        "stationary": levene_pass and ks_pass,
        "multiplicity": (
            f"KS on the {k - 1} consecutive pair(s), each at alpha/{k - 1} (Bonferroni); "
            "Levene is one test over all segments; the two verdicts are combined with AND"
        ),
    }


# ---------------------------------------------------------------------------------------------
# Monte Carlo calibration (model or block bootstrap)
# ---------------------------------------------------------------------------------------------
def _data_seed(a: np.ndarray, k: int) -> int:
    """A seed from the record's bytes and the number of segments (common random numbers: identical records
    get identical null draws, whatever their axis or dataset name)."""
    import hashlib

    h = hashlib.blake2b(np.ascontiguousarray(a, dtype=np.float64).tobytes(), digest_size=8)
    h.update(int(k).to_bytes(4, "little"))
    return int.from_bytes(h.digest(), "little")


def _generator(rng, a: np.ndarray, k: int):
    """``rng="data"``: a generator seeded from the record (:func:`_data_seed`); otherwise
    ``numpy.random.default_rng(rng)``."""
    if isinstance(rng, str):
        if rng != "data":
            raise ValueError(f"rng must be a Generator, an int, None or 'data', got {rng!r}")
        return np.random.default_rng(_data_seed(a, k)), "data"
    return np.random.default_rng(rng), ("given" if rng is not None else "fresh entropy")


def _monte_carlo(a, k, m, alpha, n_sim, draw: Callable[[int], np.ndarray], null: str, stop_early: bool = False,
                 n_sim_max: int | None = None, close_z: float = 2.0) -> dict:
    """Observed (W, D_max) against n_sim null records drawn in batches by draw(count) -> (count, L).

    stop_early: stop once the verdict of the full n_sim test is certain. With a = 1 + #{W_s >= W_obs}
    and b = 1 + #{D_s >= D_obs} over the final draws, the observed min-p is min(a, b)/(1 + n_sim), and
    every record at least as extreme in the statistic attaining it has a min-p <= the observed one
    (p-values are ranks), so the calibrated p-value is >= min(a, b)/(1 + n_sim). The counts a and b
    only grow with more draws, so once min(a, b)/(1 + n_sim) > alpha on the draws so far the full
    test cannot reject (the sequential Monte Carlo p-value idea of Besag & Clifford 1991).

    n_sim_max: when, after the n_sim draws, the p-value lies within `close_z` Monte Carlo standard errors
    sqrt(p (1 - p)/(n + 1)) of alpha, the number of draws is doubled (up to n_sim_max) until it does not
    (or n_sim_max is reached): the resolution goes where the verdict is close.
    """
    d_obs = ks_statistics(_segments(a, k, m))  # per pair, for the report
    w_obs = float(_null_statistics(a[None, :], k, m)[0][0])  # as the null's W (same rounding)
    batch = max(1, _BATCH_SAMPLES // a.size)
    n_sim = int(n_sim)
    n_sim_max = n_sim if n_sim_max is None else max(int(n_sim_max), n_sim)
    # first batch: enough records for the stopping rule to fire on a typical stationary record
    first = min(batch, 2 * max(1, math.ceil(alpha * (n_sim + 1)))) if stop_early else batch
    w_sim, d_sim = [], []
    done = 0
    stopped = False
    as_extreme_w = as_extreme_d = 1  # records (the observed included) reaching the observed W, D
    target = n_sim
    while True:
        while done < target:
            if stop_early and done and target == n_sim and min(as_extreme_w, as_extreme_d) / (n_sim + 1) > alpha:
                stopped = True
                break
            # batches grow geometrically (first, first, 2 first, ...) so the stopping rule is checked often
            count = min(max(first, done), batch, target - done)
            sims = np.asarray(draw(count), dtype=np.float64)
            if sims.shape != (count, a.size):
                raise ValueError(f"null simulator returned shape {sims.shape}, expected {(count, a.size)}")
            w_batch, d_batch = _null_statistics(sims, k, m)
            w_sim.append(w_batch)
            d_sim.append(d_batch)
            as_extreme_w += int(np.count_nonzero(w_sim[-1] >= w_obs))
            as_extreme_d += int(np.count_nonzero(d_sim[-1] >= d_obs.max()))
            done += count
        pvals, p_combined = _rank_pvalues(w_obs, float(d_obs.max()), w_sim, d_sim)
        se = math.sqrt(p_combined * (1.0 - p_combined) / (done + 1))
        if stopped or target >= n_sim_max or abs(p_combined - alpha) > close_z * se:
            break
        target = min(n_sim_max, 2 * target + 1)  # (target + 1) doubles: alpha (n + 1) stays an integer
    alpha = float(alpha)
    n_all = done + 1
    return {
        "test": "Levene W and max KS D, Monte Carlo null",
        "null": null,
        "n_sim": int(n_sim),
        "n_sim_max": int(n_sim_max),
        "n_sim_run": int(done),
        "stopped_early": stopped,
        "extended": bool(done > n_sim),
        "n_segments": k,
        "segment_length": int(m),
        "n_dropped": int(a.size - k * m),
        "alpha": alpha,
        "levene_statistic": w_obs,
        "levene_p": float(pvals[0]),
        "ks_statistic": [float(v) for v in d_obs],
        "ks_statistic_max": float(d_obs.max()),
        "ks_p": float(pvals[1]),
        "p_value": p_combined,
        "p_value_mc_se": float(se),
        "closeness": float((p_combined - alpha) / se) if se > 0 else math.copysign(math.inf, p_combined - alpha),
        "stationary": bool(p_combined > alpha),
        "combination": (
            "p-values (1 + #null >= observed)/(1 + n_sim) for Levene W and for max_i KS D_i; "
            "verdict from the min of the two, calibrated on the same null draws (single-step min-p)"
        ),
        "sequential": (
            f"draws doubled (up to n_sim_max) while p lies within {close_z:g} Monte Carlo standard errors "
            "sqrt(p (1 - p)/(n_sim_run + 1)) of alpha; closeness = (p - alpha)/se"
        ),
        "min_p_resolution": 1.0 / n_all,
    }


def _rank_pvalues(w_obs, d_obs_max, w_sim, d_sim):
    """Rank p-values (Hope 1968) of the observed record's W and D_max among all draws + 1, and the Monte Carlo
    p-value of their minimum on the same draws (single-step min-p)."""
    w_sim = np.concatenate(w_sim)
    d_sim = np.concatenate(d_sim)
    stats = np.stack([np.concatenate(([w_obs], w_sim)), np.concatenate(([d_obs_max], d_sim))], axis=1)
    n_all = stats.shape[0]
    pvals = np.empty_like(stats)
    for c in range(2):
        sorted_c = np.sort(stats[:, c])
        # number of records with a statistic >= this one
        pvals[:, c] = (n_all - np.searchsorted(sorted_c, stats[:, c], side="left")) / n_all
    minp = pvals.min(axis=1)
    return pvals[0], float(np.count_nonzero(minp <= minp[0]) / n_all)


def notch(x, rate: float, bands) -> np.ndarray:
    r"""The records `x` (u, rows of a (records, n) array or one record, at `rate` Hz) with their mean and the
    Fourier coefficients inside each frequency band of `bands` (pairs (lo, hi) in Hz, lo <= hi) removed: the
    real FFT :math:`X_k` of each mean-removed record is zeroed where :math:`lo \le k\,\mathrm{rate}/n \le hi`
    and transformed back (an ideal band-stop of the record's own circulant extension; a linear map, so a null
    drawn through it is the null of the notched record). Same shape as `x`."""
    a = np.asarray(x, dtype=np.float64)
    n = a.shape[-1]
    f = np.fft.rfftfreq(n, 1.0 / float(rate))
    stop = np.zeros(f.size, dtype=bool)
    for lo, hi in bands:
        stop |= (f >= lo) & (f <= hi)
    X = np.fft.rfft(a - a.mean(axis=-1, keepdims=True), axis=-1)
    X[..., stop] = 0.0
    return np.fft.irfft(X, n=n, axis=-1)


def calibrated_stationarity(
    x,
    rate: float,
    model,
    n_segments: int = 2,
    alpha: float = 0.05,
    n_sim: int = 199,
    rng="data",
    stop_early: bool = True,
    n_sim_max: int | None = 1599,
    close_z: float = 2.0,
    paper: bool = True,
    transform: Callable[[np.ndarray], np.ndarray] | None = None,
) -> dict:
    r"""Levene + KS stationarity test calibrated on a simulated stationary null.

    The statistics are those of :func:`stationarity_tests` (Levene :math:`W` over all segments,
    :math:`D_{max} = \max_i D_i` over consecutive KS pairs), but their null distribution is taken
    from `n_sim` records of the same length simulated from the fitted stationary `model`, so the
    serial correlation of the noise is accounted for. Monte Carlo p-values (Hope 1968):

    .. math::

        p_W = \frac{1 + \#\{W^{(s)} \ge W\}}{1 + n_{sim}}, \qquad
        p_D = \frac{1 + \#\{D_{max}^{(s)} \ge D_{max}\}}{1 + n_{sim}} ,

    and the verdict uses :math:`p = ` the Monte Carlo p-value of :math:`\min(p_W, p_D)`, computed on
    the same draws (rank of the observed min-p among all :math:`n_{sim} + 1`): ``stationary = p >
    alpha``. That is a test of exact level :math:`\alpha` (up to the :math:`1/(n_{sim}+1)`
    resolution) when `model` is the true process, with no Bonferroni penalty.

    Both statistics are invariant to offset and scale, so only the shape of `model` matters (its
    component ratios and time constants). `model` should describe `x` as sampled: for a 1 Hz
    block-averaged record, the 1 Hz model (GM and random-walk terms are practically unaffected by
    1 s averaging; white noise of density N has variance N^2 * rate either way). A random-walk
    component makes the null itself non-stationary; the test then asks whether the record is
    consistent with the model, which is the question that matters for the bound.

    Parameters
    ----------
    x : array_like
        The (decimated) record, any unit, finite.
    rate : float
        Sampling frequency of `x`, Hz.
    model : imupipe.models.NoiseModel or callable
        A fitted stationary model, simulated with ``imupipe.simulate.simulate(model, n, rate, rng)``;
        or a callable ``model(n, rng) -> ndarray (n,)`` drawing one null record (any other null).
    n_segments : int, optional
        Default 2 (halves).
    alpha : float, optional
        Level of the combined test. Default 0.05.
    n_sim : int, optional
        Number of simulated records. Default 199 (p resolution 1/200; keep (n_sim + 1) * alpha an
        integer for an exact level, e.g. 199 or 999).
    rng : numpy.random.Generator or int or None or "data", optional
        Seed or generator (``numpy.random.default_rng(rng)``); ``"data"`` (default): seeded from a hash of
        the record itself (common random numbers: identical records, e.g. the same data on three axes, get
        the same null draws and the same verdict, whatever their names).
    n_sim_max : int or None, optional
        Sequential extension: when the p-value after `n_sim` draws lies within `close_z` Monte Carlo
        standard errors of `alpha`, the draws are doubled until it does not or `n_sim_max` is reached.
        Default 1599 (None: no extension).
    close_z : float, optional
        Standard errors that count as close. Default 2.
    paper : bool, optional
        Add ``paper``, :func:`stationarity_tests` on the same record, for comparison. Default True.
        Its asymptotic p-values need :mod:`scipy.stats` (about 1.2 s to import); the workflow's per-axis
        jobs pass False and its per-sensor summary runs the paper's test once per sensor type.
    stop_early : bool, optional
        Stop drawing once the verdict of the full `n_sim` test is certain: when at least
        :math:`\alpha (1 + n_{sim})` null records reach the observed Levene W and at least as many
        (not necessarily the same) reach the observed KS D: the calibrated p-value is at least the
        observed min-p, which these counts bound from below whatever the other draws. The verdict
        is that of the full test; the p-values are then those of the ``n_sim_run`` records drawn.
        A clearly stationary record stops after 10-40 of 99 draws; one near the level draws all.
        Default True.
    transform : callable, optional
        Applied to the observed record and to every null record before the statistics (rows of a
        (records, n) array in, the same shape out), e.g. :func:`notch` of an axis's spectral lines, so that
        the test reads what is left of both. The generator is seeded from the record as given. Default None.

    Returns
    -------
    dict
        ``levene_statistic``, ``levene_p``, ``ks_statistic`` (per pair), ``ks_statistic_max``,
        ``ks_p``, ``p_value`` (combined), ``p_value_mc_se`` (its Monte Carlo standard error),
        ``closeness`` ((p - alpha)/se), ``stationary``, ``n_sim``, ``n_sim_max``, ``n_sim_run``, ``extended``,
        ``stopped_early``, ``seed`` (how the generator was seeded), ``null``, ``combination`` and the settings;
        plus, with `paper`, ``paper``: the dict of :func:`stationarity_tests` on the same record. Plain
        Python types.
    """
    a, k, m = _check_args(x, n_segments, alpha)
    rate = float(rate)
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"rate must be a positive frequency in Hz, got {rate!r}")
    n_sim = int(n_sim)
    if n_sim < 1:
        raise ValueError("n_sim must be >= 1")
    gen, seeded = _generator(rng, a, k)
    n = a.size

    batch = None
    if hasattr(model, "psd"):  # a NoiseModel
        from imupipe.simulate import simulate

        def one(n_, g):
            return simulate(model, n_, rate, g)

        def batch(count):
            return simulate(model, n, rate, gen, n_records=count)

        null = f"records simulated from the fitted model (imupipe.simulate.simulate): {model!r}"
    elif callable(model):
        one = model
        null = f"records drawn by {getattr(model, '__name__', type(model).__name__)}"
    else:
        raise TypeError(
            f"model must be a NoiseModel or a callable (n, rng) -> array, got {type(model).__name__}"
        )

    def draw(count):
        if batch is not None:
            out = batch(count)
        else:
            out = np.stack([np.asarray(one(n, gen), dtype=np.float64).reshape(n) for _ in range(count)])
        return out if transform is None else transform(out)

    if transform is not None:
        a = np.asarray(transform(a[None, :]), dtype=np.float64).reshape(n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # constant-record warnings belong to the observed record only
        out = _monte_carlo(a, k, m, alpha, n_sim, draw, null, stop_early=stop_early, n_sim_max=n_sim_max,
                           close_z=close_z)
    out["rate_hz"] = rate
    out["seed"] = seeded
    if paper:
        out["paper"] = stationarity_tests(a, n_segments=k, alpha=alpha)
    return plain(out, nonfinite_to_none=False)


def bootstrap_stationarity(
    x,
    rate: float,
    block_s: float,
    n_segments: int = 2,
    alpha: float = 0.05,
    n_boot: int = 200,
    rng=None,
) -> dict:
    r"""Levene + KS stationarity test calibrated by a circular block bootstrap of the record.

    Null records are built by concatenating blocks of :math:`b` = ``round(block_s * rate)``
    samples that start at uniformly random positions of the record, wrapped circularly (Politis
    & Romano's circular block bootstrap), and trimmed to the record length. Pooling the whole
    record imposes the null hypothesis (one distribution for every segment) while keeping the
    serial dependence within blocks; the p-values and the verdict are then as in
    :func:`calibrated_stationarity`. No model is needed, but the block must be long compared with
    the correlation time of the noise (several GM time constants): shorter blocks break the
    correlation and the test rejects too often; blocks approaching the segment length leave
    little to resample. A random walk is not handled (it is not stationary).

    Parameters
    ----------
    x : array_like
        The (decimated) record, finite.
    rate : float
        Sampling frequency, Hz.
    block_s : float
        Block length, s (>= 1 sample, <= the record).
    n_segments, alpha : see :func:`stationarity_tests`.
    n_boot : int, optional
        Number of bootstrap records. Default 200.
    rng : numpy.random.Generator or int or None, optional

    Returns
    -------
    dict
        As :func:`calibrated_stationarity`, with ``block_s`` and ``block_length`` (samples).
    """
    a, k, m = _check_args(x, n_segments, alpha)
    rate = float(rate)
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"rate must be a positive frequency in Hz, got {rate!r}")
    n = a.size
    b = int(round(float(block_s) * rate))
    if not (1 <= b <= n):
        raise ValueError(f"block_s={block_s!r} s gives {b} samples; need 1 .. {n} (the record length)")
    n_boot = int(n_boot)
    if n_boot < 1:
        raise ValueError("n_boot must be >= 1")
    gen = np.random.default_rng(rng)
    n_blocks = -(-n // b)
    offsets = np.arange(b)

    def draw(count):
        starts = gen.integers(0, n, size=(count, n_blocks))
        idx = (starts[:, :, None] + offsets) % n
        return a[idx.reshape(count, n_blocks * b)[:, :n]]

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = _monte_carlo(a, k, m, alpha, n_boot, draw, f"circular block bootstrap, blocks of {b} samples")
    out["rate_hz"] = rate
    out["block_s"] = b / rate
    out["block_length"] = b
    out["paper"] = stationarity_tests(a, n_segments=k, alpha=alpha)
    return plain(out, nonfinite_to_none=False)

