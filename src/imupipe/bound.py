r"""PSD overbounding of IMU errors by a Kalman-filter-ready noise model (method.md section 6).

Goal (Gallon, Joerger, Pervan, ION GNSS+ 2021, section II.2.e): a model of white noise, first-order
Gauss-Markov (GM) terms and a random walk whose two-sided PSD

.. math::

    S_m(f) = N^2 + \sum_i \frac{2\sigma_i^2 T_i}{1 + (2\pi f T_i)^2} + \frac{K^2}{(2\pi f)^2}

lies above every sample PSD of one sensor type (15 curves: 5 datasets x 3 axes) at every
frequency and above the spec sheet's PSD. For a stationary error, :math:`S_m \ge S_{true}` at all
:math:`f` makes every covariance of the model dominate the true one, so a linear estimator built on
the model reports a variance that bounds its true error variance (Langel, Garcia-Crespillo,
Joerger, PLANS 2020).

For fixed time constants :math:`T_i` the model PSD is linear in
:math:`x = (N^2, \sigma_i^2, K^2) \ge 0`, so the tightest bound is a linear program
(HiGHS through its own Python interface ``highspy``, the solver behind :func:`scipy.optimize.linprog`):

.. math::

    \min_{x \ge 0}\; \sum_k w_k \frac{S_m(f_k; x)}{E(f_k)} \quad \text{s.t.} \quad
    S_m(f_k; x) \ge \hat S_c(f_k)\ \forall c, k, \qquad S_m(f_j; x) \ge S_{spec}(f_j)\ \forall j,

with :math:`E` the envelope of the targets and :math:`w_k` log-frequency weights (each decade
counts equally). Rows are divided by their target (PSDs span 20 decades in SI) and columns by
their largest entry; the constraints are generated lazily (cutting planes: only a few hundred of
the 10^4 rows are ever binding). :math:`T` is profiled on a log grid and refined.

When the sample PSDs are of block-averaged data (the paper's 1 Hz averages), pass `dt`: the model
is then compared through ``NoiseModel.psd_sampled(f, dt)`` (averaging and aliasing included).

Modes (how the sample PSDs enter the constraints):

``raw``
    the periodograms as they are (paper-faithful). The bound then follows the periodogram maxima:
    for white noise the largest of :math:`n` single-window ordinates is about :math:`\ln n + 0.577`
    times the true PSD (12.7x power, 3.6x amplitude for 15 curves x 12600 bins).
``smoothed``
    log-frequency band averages (:func:`imupipe.spectra.smooth_log_bands` bands, optionally
    merged at the low end to at least `min_edf` degrees of freedom); the model is band-averaged
    the same way.
``confidence``
    the upper chi-squared limit of each band average (or ordinate, with ``bands_per_decade=None``)
    at family-wise level `confidence`, Bonferroni-corrected over all curves x bands
    (:func:`imupipe.spectra.chi2_upper`): with that probability every curve's true band-averaged
    PSD lies below the bound.

References
----------
.. [1] E. Gallon, M. Joerger, B. Pervan, "Development of Stochastic IMU Error Models for INS/GNSS
       Integration", ION GNSS+ 2021, eqs. 7, 9, 12, 13, Table 2, Appendix A.
.. [2] S. Langel, O. Garcia-Crespillo, M. Joerger, "A New Approach for Modeling Correlated Gaussian
       Errors Using Frequency Domain Overbounding", IEEE/ION PLANS 2020.
.. [3] IEEE Std 952-1997, Annex C (Allan-variance forms of the components).
.. [4] Q. Huangfu, J. A. J. Hall, "Parallelizing the dual revised simplex method", Math. Prog.
       Comp. 10, 119-142, 2018 (HiGHS).
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "BOUND_COMPONENTS",
    "DEFAULT_MIN_EDF",
    "MODES",
    "BoundResult",
    "bound_psd",
    "paper_inflation",
    "margin",
    "looseness",
    "check_allan_components",
    "gm_bounds_gm",
    "upper_envelope",
    "check_allan",
]

#: Components a bound may hold (Kalman-filter states; flicker is represented by a GM).
BOUND_COMPONENTS = ("white", "gauss_markov", "random_walk")
#: How the sample PSDs enter the constraints.
MODES = ("raw", "smoothed", "confidence")

_EPS_BOUND = 1e-9  # a margin >= 1 - _EPS_BOUND counts as bounded
#: Low-frequency band merging of the confidence mode (degrees of freedom per band).
DEFAULT_MIN_EDF = 30.0


# ---------------------------------------------------------------------------------------------
# inputs
# ---------------------------------------------------------------------------------------------
def _curves_to_array(curves, n_freq):
    """(C, F) float64 array and labels from an array, a sequence, a dict or an xarray.DataArray."""
    if isinstance(curves, dict):
        labels = [str(k) for k in curves]
        arr = np.stack([np.asarray(v, dtype=np.float64) for v in curves.values()])
    elif hasattr(curves, "dims") and hasattr(curves, "stack"):  # xarray.DataArray
        from imupipe.labelled import stack_curves

        if "frequency" not in curves.dims:
            raise ValueError("an xarray curves argument needs a 'frequency' dimension")
        arr, labels = stack_curves(curves, "frequency")
    else:
        arr = np.asarray(curves, dtype=np.float64)
        if arr.ndim == 1:
            arr = arr[None, :]
        labels = [f"curve {i}" for i in range(arr.shape[0])]
    if arr.ndim != 2 or arr.shape[1] != n_freq:
        raise ValueError(f"curves must have shape (n_curves, {n_freq}) on the frequency grid, got {arr.shape}")
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise ValueError("sample PSDs must be finite and non-negative")
    return arr, labels


def _log_weights(f):
    """Weights proportional to the log-frequency extent of each point, summing to 1."""
    f = np.asarray(f, dtype=np.float64)
    if f.size == 1:
        return np.ones(1)
    lf = np.log(f)
    edges = np.concatenate(([lf[0] - (lf[1] - lf[0]) / 2], (lf[1:] + lf[:-1]) / 2, [lf[-1] + (lf[-1] - lf[-2]) / 2]))
    w = np.diff(edges)
    w = np.maximum(w, 0)
    return w / w.sum()


def _bin_r(taper, max_lag):
    """Squared correlation r_j of periodogram ordinates j bins apart for `taper` (flat spectrum)."""
    if taper is None:
        r = np.zeros(max_lag + 1)
        r[0] = 1.0
        return r
    from imupipe.spectra import get_taper

    n = 4096 if isinstance(taper, str) else len(np.asarray(taper))
    w = get_taper(taper, n)
    w2 = w * w
    spec = np.abs(np.fft.rfft(w2)) ** 2 / float(w2.sum()) ** 2
    r = np.zeros(max_lag + 1)
    k = min(max_lag + 1, spec.size)
    r[:k] = spec[:k]
    r[r < 1e-20] = 0.0
    return r


def _band_groups(f, bands_per_decade, nu, taper, min_edf):
    r"""Contiguous groups of bins: log bands aligned on decades (as in
    :func:`imupipe.spectra.smooth_log_bands`), merged from the low-frequency end until each has at
    least `min_edf` degrees of freedom. Returns (starts, counts, group edf (C, G))."""
    b = np.floor(bands_per_decade * np.log10(f) + 1e-9).astype(np.int64)
    _, counts = np.unique(b, return_counts=True)
    starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
    r = _bin_r(taper, int(f.size))

    def factor(m):
        j = np.arange(1, m)
        return 1.0 + 2.0 * np.sum((1.0 - j / m) * r[1:m])

    nu2 = np.atleast_2d(nu)  # (1 or C, F)
    if min_edf is not None and min_edf > 0:
        merged = []
        cur_s, cur_n = None, 0
        for s0, n0 in zip(starts, counts):
            if cur_s is None:
                cur_s, cur_n = s0, n0
            else:
                cur_n += n0
            e = nu2[:, cur_s : cur_s + cur_n].sum(axis=1).min() / factor(cur_n)
            if e >= min_edf:
                merged.append((cur_s, cur_n))
                cur_s, cur_n = None, 0
        if cur_s is not None:  # leftover at the top end: merge into the previous group
            if merged:
                ps, pn = merged.pop()
                merged.append((ps, pn + cur_n))
            else:
                merged.append((cur_s, cur_n))
        starts = np.array([m[0] for m in merged], dtype=np.int64)
        counts = np.array([m[1] for m in merged], dtype=np.int64)
    fac = np.array([factor(int(m)) for m in counts])
    edf = np.add.reduceat(nu2, starts, axis=1) / fac
    return starts, counts, edf


def _group_mean(a, starts, counts):
    """Mean of a (..., F) over contiguous groups -> (..., G)."""
    return np.add.reduceat(a, starts, axis=-1) / counts


@dataclass
class _Problem:
    """Prepared constraints, shared by the LP and the hand procedure."""

    f: np.ndarray  # positive bin frequencies, Hz (F,)
    raw: np.ndarray  # sample PSDs at the bins (C, F)
    labels: list
    dt: float | None
    starts: np.ndarray | None  # groups (None: rows are bins)
    counts: np.ndarray | None
    f_rows: np.ndarray  # representative frequency of each row (R,)
    targets: np.ndarray  # what the model must exceed, per curve and row (C, R)
    spec: np.ndarray | None  # spec PSD at the bins (F,)
    spec_rows: np.ndarray | None  # spec PSD on rows (R,)
    envelope: np.ndarray  # max of the targets over the curves, on rows (R,)
    env: np.ndarray  # envelope of targets and spec on rows (R,)
    weights: np.ndarray  # objective weights on rows (R,)
    objective_weights: np.ndarray  # weights/env where env > 0, else 0: the objective is this @ (B_rows x) (R,)
    mode: str
    details: dict = field(default_factory=dict)
    lo_f: np.ndarray = field(default_factory=lambda: np.zeros(0))  # all-frequency grid below the bins, Hz
    lo_t: np.ndarray = field(default_factory=lambda: np.zeros(0))  # what the bound must exceed there, u^2/Hz
    k2_req: float = 0.0  # f -> 0: K_bound^2 >= this (u^2/s)
    n2_req: float = 0.0  # f -> inf: N_bound^2 >= this (u^2/Hz)
    _columns: dict = field(default_factory=dict, repr=False)
    _kept: dict = field(default_factory=dict, repr=False)

    def column(self, kind, T=None):
        """Basis PSD of a unit component: (bins (F,), rows (R,), bins non-increasing, rows
        non-increasing), cached."""
        key = (kind, T)
        hit = self._columns.get(key)
        if hit is None:
            from imupipe.models import NoiseModel

            if kind == "white":
                m = NoiseModel(white=1.0)
            elif kind == "random_walk":
                m = NoiseModel(random_walk=1.0)
            elif kind == "gm":
                m = NoiseModel(gauss_markov=((1.0, float(T)),))
            else:  # pragma: no cover
                raise ValueError(kind)
            b = np.asarray(m.psd(self.f) if self.dt is None else m.psd_sampled(self.f, self.dt), dtype=np.float64)
            r = self.to_rows(b)
            hit = (b, r, not np.any(np.diff(b) > 0), not np.any(np.diff(r) > 0))
            if len(self._columns) > 4000:
                self._columns.clear()
            self._columns[key] = hit
        return hit

    def to_rows(self, a):
        return a if self.starts is None else _group_mean(a, self.starts, self.counts)

    def all_frequency_rows(self, names, Ts):
        """Normalised '>= 1' rows of the all-frequency conditions for basis columns `names`: the log grid
        below the lowest bin (continuous PSDs) and the asymptotes K^2 >= k2_req, N^2 >= n2_req."""
        from imupipe.models import NoiseModel

        rows = []
        ok = self.lo_t > 0
        if np.any(ok):
            f = self.lo_f[ok]
            cols = []
            for nm in names:
                if nm == "white":
                    cols.append(np.ones_like(f))
                elif nm == "random_walk":
                    cols.append(1.0 / (2 * np.pi * f) ** 2)
                else:
                    T = float(Ts[int(nm[3:]) - 1])
                    cols.append(NoiseModel(gauss_markov=((1.0, T),)).psd(f))
            rows.append(np.stack(cols, axis=1) / self.lo_t[ok, None])
        for req, nm in ((self.k2_req, "random_walk"), (self.n2_req, "white")):
            if req > 0 and nm in names:
                r = np.zeros((1, len(names)))
                r[0, names.index(nm)] = 1.0 / req
                rows.append(r)
        return np.vstack(rows) if rows else np.zeros((0, len(names)))

    def basis(self, comps, Ts):
        """Columns (bins (F, J), rows (R, J)), names, and whether every column is non-increasing
        along the bins and along the rows, for components and GM time constants."""
        cols, names = [], []
        for c in comps:
            if c == "white":
                cols.append(self.column("white"))
                names.append("white")
            elif c == "gauss_markov":
                for i, T in enumerate(Ts):
                    cols.append(self.column("gm", float(T)))
                    names.append(f"gm_{i + 1}")
            elif c == "random_walk":
                cols.append(self.column("random_walk"))
                names.append("random_walk")
        if not cols:
            return np.zeros((self.f.size, 0)), np.zeros((self.f_rows.size, 0)), names, True, True
        Bb = np.stack([c[0] for c in cols], axis=1)
        Br = Bb if self.starts is None else np.stack([c[1] for c in cols], axis=1)
        return Bb, Br, names, all(c[2] for c in cols), all(c[3] for c in cols)

    def kept_rows(self, B, t, which, monotone):
        """:func:`_undominated` rows of 'B x >= t' given whether B's columns are monotone, cached per
        constraint set `which` (the rows depend on the targets t and that flag only)."""
        key = (which, monotone)
        hit = self._kept.get(key)
        if hit is None:
            hit = self._kept[key] = _undominated(B, t, monotone)
        return hit

    def worst_margin(self, model):
        """min(margin, spec_margin) of :func:`_evaluate`, from the envelope alone: for a model PSD
        m >= 0, min_c fl(m/t_c) = fl(m/max_c t_c) (division is correctly rounded and monotone), so
        the result is exactly that of the full evaluation at a fraction of its cost."""
        mb = self.model_bins(model)
        mr = self.to_rows(mb)
        with np.errstate(divide="ignore", invalid="ignore"):
            m = float(np.min(np.where(self.envelope > 0, mr / self.envelope, np.inf)))
            if self.spec is not None:
                m = min(m, float(np.min(np.where(self.spec > 0, mb / self.spec, np.inf))))
        return m

    def model_bins(self, model):
        v = model.psd(self.f) if self.dt is None else model.psd_sampled(self.f, self.dt)
        return np.asarray(v, dtype=np.float64)


def _prepare(frequency, curves, spec_model, dt, mode, confidence, bands_per_decade, edf, taper, min_edf,
             n_tests=None):
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    f_all = np.asarray(frequency, dtype=np.float64)
    if f_all.ndim != 1 or f_all.size < 2 or np.any(np.diff(f_all) <= 0):
        raise ValueError("frequency must be a 1-D increasing grid (Hz)")
    raw_all, labels = _curves_to_array(curves, f_all.size)
    keep = f_all > 0  # DC carries no information after detrending (and a random walk is infinite there)
    f = f_all[keep]
    raw = raw_all[:, keep]
    nu = np.asarray(2.0 if edf is None else edf, dtype=np.float64)
    if nu.ndim >= 1 and nu.shape[-1] == f_all.size:
        nu = nu[..., keep]
    nu = np.broadcast_to(nu, raw.shape).astype(np.float64)
    if np.any(nu <= 0):
        raise ValueError("edf must be positive")
    details = {}
    if mode == "raw" or (mode == "confidence" and bands_per_decade is None):
        starts = counts = None
        f_rows = f
        targets = raw
        rows_edf = nu
    else:
        if bands_per_decade is None or int(bands_per_decade) < 1:
            raise ValueError("bands_per_decade must be a positive integer in smoothed mode")
        starts, counts, rows_edf = _band_groups(f, int(bands_per_decade), nu, taper, min_edf)
        f_rows = _group_mean(f, starts, counts)
        targets = _group_mean(raw, starts, counts)
        rows_edf = np.broadcast_to(rows_edf, targets.shape)
        details.update(n_bands=int(starts.size), bands_per_decade=int(bands_per_decade),
                       min_edf=None if min_edf is None else float(min_edf))
    if mode == "confidence":
        from imupipe.spectra import chi2_upper

        n = int(targets.size) if n_tests is None else int(n_tests)
        targets = chi2_upper(targets, rows_edf, confidence=confidence, n_tests=n, correction="bonferroni")
        details.update(confidence=float(confidence), n_tests=n, correction="bonferroni")
    details["rows_edf_min"] = float(np.min(rows_edf))
    spec = spec_rows = None
    if spec_model is not None:
        spec = np.asarray(spec_model.psd(f) if dt is None else spec_model.psd_sampled(f, dt), dtype=np.float64)
        spec = np.where(np.isfinite(spec), spec, 0.0)
        spec_rows = spec if starts is None else _group_mean(spec, starts, counts)
    envelope = targets.max(axis=0)
    env = envelope if spec_rows is None else np.maximum(envelope, spec_rows)
    weights = _log_weights(f_rows)
    objective_weights = np.zeros_like(env)
    np.divide(weights, env, out=objective_weights, where=env > 0)
    return _Problem(f, raw, labels, dt, starts, counts, f_rows, targets, spec, spec_rows, envelope, env, weights,
                    objective_weights, mode, details)


# ---------------------------------------------------------------------------------------------
# the linear program
# ---------------------------------------------------------------------------------------------
@dataclass
class _LPSolution:
    x: np.ndarray  # squared coefficients, SI
    names: list
    T: tuple
    objective: float
    n_lp: int


def _undominated(B, t, monotone=None):
    """Indices of the rows of 'B x >= t' (x >= 0) that no other row implies, when every column of B is
    non-increasing along the rows (basis PSDs on increasing frequency: white, GM, random walk).

    Row i is implied by a later row j when B[j] <= B[i] componentwise and t[j] >= t[i]
    (B[i] x >= B[j] x >= t[j] >= t[i]); with non-increasing columns every later row has B[j] <= B[i],
    so only rows whose target exceeds every later target remain (the right-to-left records of t, a few
    hundred of 12 600 periodogram bins). The test is made on the computed floats, so the reduced LP has
    exactly the feasible set of the full one. Rows with t <= 0 are dropped (always satisfied). Without
    monotone columns: every row with t > 0. `monotone`: whether B's columns are non-increasing, when
    the caller knows it (the LP checks each unit column once over all rows); None: checked here on the
    rows with t > 0.
    """
    pos = np.flatnonzero(t > 0)
    if monotone is None:
        monotone = B.shape[1] > 0 and not np.any(np.diff(B[pos], axis=0) > 0)
    if pos.size == 0 or not monotone:
        return pos
    tp = t[pos]
    later_max = np.empty_like(tp)
    later_max[-1] = -np.inf
    later_max[:-1] = np.maximum.accumulate(tp[::-1])[::-1][1:]
    return pos[tp > later_max]


def _constraint_matrix(prob, Bb, Br, mono_b, mono_r, names=(), Ts=()):
    """Normalised '>= 1' rows: data rows (envelope of targets; in raw mode, where rows are bins, with the
    spec) and, off raw mode, spec rows at bins; rows implied by others left out (:func:`_undominated`)."""
    tgt = prob.env if prob.starts is None else prob.envelope
    ok = prob.kept_rows(Br, tgt, "data", mono_r)
    A = Br[ok] / tgt[ok, None]
    if prob.starts is not None and prob.spec is not None:
        oks = prob.kept_rows(Bb, prob.spec, "spec", mono_b)
        A = np.vstack([A, Bb[oks] / prob.spec[oks, None]])
    if names:
        A = np.vstack([A, prob.all_frequency_rows(list(names), Ts)])
    return A


_DIRECT_LP_ROWS = 2000  # at most this many rows: no cutting planes (HiGHS solves them in one go)


_HIGHS = None  # one solver instance per process, reused (each LP replaces the previous model)


def _quiet_highs(highspy):
    """A Highs instance created with file descriptor 1 redirected: the constructor prints a banner on
    stdout before any option can be set, and a workflow script's stdout is its output."""
    import os
    import sys

    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
            h = highspy.Highs()
            h.setOptionValue("output_flag", False)
            h.setOptionValue("log_to_console", False)
    finally:
        os.dup2(saved, 1)
        os.close(saved)
    return h


def _highs_min(c, A, b=None):
    """argmin of c @ u subject to A u >= 1, u >= 0, by HiGHS (highspy; one thread, no output).

    The bounding LPs have 2-4 columns and a few dozen rows after the dominance reduction: HiGHS solves
    one in ~0.2 ms, and ``scipy.optimize.linprog`` spends ~1 ms around the same solve (input checks,
    option validation), which summed to half of a bound job.
    """
    global _HIGHS
    import highspy

    if _HIGHS is None:
        _HIGHS = _quiet_highs(highspy)
        _HIGHS.setOptionValue("output_flag", False)
        _HIGHS.setOptionValue("threads", 1)
    m, n = A.shape
    lp = highspy.HighsLp()
    lp.num_col_, lp.num_row_ = n, m
    lp.col_cost_ = np.ascontiguousarray(c, dtype=np.float64)
    lp.col_lower_ = np.zeros(n)
    lp.col_upper_ = np.full(n, highspy.kHighsInf)
    lp.row_lower_ = np.ones(m) if b is None else np.ascontiguousarray(b, dtype=np.float64)
    lp.row_upper_ = np.full(m, highspy.kHighsInf)
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.start_ = np.arange(0, m * n + 1, m, dtype=np.int32)
    lp.a_matrix_.index_ = np.tile(np.arange(m, dtype=np.int32), n)
    lp.a_matrix_.value_ = np.ascontiguousarray(A.T, dtype=np.float64).ravel()
    _HIGHS.passModel(lp)
    _HIGHS.run()
    status = _HIGHS.getModelStatus()
    if status != highspy.HighsModelStatus.kOptimal:
        raise RuntimeError(f"HiGHS failed on the bounding LP: {_HIGHS.modelStatusToString(status)}")
    return np.array(_HIGHS.getSolution().col_value, dtype=np.float64)


def _solve_lp(prob, comps, Ts):
    """Tightest squared coefficients for fixed GM time constants (cutting-plane HiGHS LP)."""
    Bb, Br, names, mono_b, mono_r = prob.basis(comps, Ts)
    J = len(names)
    A = _constraint_matrix(prob, Bb, Br, mono_b, mono_r, names, Ts)
    cobj = prob.objective_weights @ Br if J else np.zeros(0)
    if A.shape[0] == 0 or J == 0:
        return _LPSolution(np.zeros(J), names, tuple(Ts), 0.0, 0)
    colmax = A.max(axis=0)
    usable = colmax > 0
    x = np.zeros(J)
    if not usable.any():
        raise ValueError("no component can bound these PSDs (all basis columns vanish)")
    As = A[:, usable] / colmax[usable]
    cs = cobj[usable] / colmax[usable]
    # rows scaled to a largest entry of 1 (right-hand side 1/rowmax): the all-frequency rows and the data rows
    # can differ by 10+ decades in a column, and HiGHS drops matrix entries below 1e-9
    rowmax = As.max(axis=1)
    if np.any(rowmax <= 0):
        raise ValueError("a bounding constraint has no component that can meet it (all its entries vanish)")
    # initial rows: the tightest row of each column and, per log-frequency cell, the row with the
    # smallest normalised basis sum (the most demanding one)
    n_rows = As.shape[0]
    n_lp = 0
    if n_rows <= _DIRECT_LP_ROWS:  # few rows left after the dominance reduction: one LP over all of them
        active = set(range(n_rows))
    else:
        rs = As.sum(axis=1)
        active = set(int(i) for i in np.argmin(As, axis=0))
        for cell in np.array_split(np.arange(n_rows), min(n_rows, 120)):
            if cell.size:
                active.add(int(cell[np.argmin(rs[cell])]))
    for _ in range(60):
        idx = np.fromiter(sorted(active), dtype=np.int64)
        u = _highs_min(cs, As[idx] / rowmax[idx, None], 1.0 / rowmax[idx])
        n_lp += 1
        slack = As @ u - 1.0
        viol = np.flatnonzero(slack < -1e-10)
        if viol.size == 0:
            break
        worst = viol[np.argsort(slack[viol])[:200]]
        active.update(int(i) for i in worst)
    else:  # pragma: no cover - never seen; fall back on the full LP
        u = _highs_min(cs, As / rowmax[:, None], 1.0 / rowmax)
        n_lp += 1
    # exact feasibility: scale up by the worst residual shortfall (all terms scale the PSD linearly)
    m = float(np.min(As @ u))
    if m <= 0:
        raise RuntimeError("bounding LP returned an infeasible point")
    if m < 1.0:
        u = u / m
    x[usable] = u / colmax[usable]
    objective = float(cobj @ x)
    return _LPSolution(x, names, tuple(float(t) for t in Ts), objective, n_lp)


def _default_T_grid(prob, per_decade=10):
    f = prob.f
    lo = math.log10(1.0 / (2 * math.pi * f.max())) - 0.5
    hi = math.log10(1.0 / (2 * math.pi * f.min())) + 1.0
    n = int(round((hi - lo) * per_decade)) + 1
    return np.logspace(lo, hi, n)


# Absolute tolerance of the bounded refinement in ln T (0.1 % in T). The objective is smooth in ln T at its
# minimum, so an error d in ln T costs O(d^2) of looseness: measured on the 15 per-axis gyro bounds of the
# default run, at most 1.5e-6 relative against 1e-4 (1.8e-5 at 1e-2), for 27 % fewer LPs.
_T_XATOL = 1e-3


def _profile_T(prob, comps, n_gm, T_grid, extra_T=(), refine=True):
    """LP over the GM time constants: grid, then bounded refinement (Nelder-Mead for n_gm > 1)."""
    from scipy.optimize import minimize, minimize_scalar

    n_lp = 0
    if "gauss_markov" not in comps or n_gm == 0:
        sol = _solve_lp(prob, comps, ())
        return sol, (np.zeros(0), np.zeros(0))
    grid = np.unique(np.concatenate([np.asarray(T_grid, dtype=np.float64), np.asarray(extra_T, dtype=np.float64)]))
    if n_gm == 1:
        sols = [_solve_lp(prob, comps, (T,)) for T in grid]
        n_lp += sum(s.n_lp for s in sols)
        objs = np.array([s.objective for s in sols])
        i = int(np.argmin(objs))
        best = sols[i]
        if refine and grid.size >= 3:
            lo = math.log(grid[max(i - 1, 0)])
            hi = math.log(grid[min(i + 1, grid.size - 1)])
            cache = {}

            def fun(lt):
                s = _solve_lp(prob, comps, (math.exp(lt),))
                cache[lt] = s
                return s.objective

            minimize_scalar(fun, bounds=(lo, hi), method="bounded", options={"xatol": _T_XATOL})
            for s in cache.values():
                n_lp += s.n_lp
                if s.objective < best.objective:
                    best = s
        best.n_lp = n_lp
        return best, (grid, objs)
    from itertools import combinations

    coarse = grid[:: max(1, grid.size // 14)]
    best = None
    for Ts in combinations(coarse, n_gm):
        s = _solve_lp(prob, comps, Ts)
        n_lp += s.n_lp
        if best is None or s.objective < best.objective:
            best = s
    if refine:
        cache = []

        def fun(lt):
            s = _solve_lp(prob, comps, tuple(np.exp(np.sort(lt))))
            cache.append(s)
            return s.objective

        minimize(fun, np.log(best.T), method="Nelder-Mead", options={"xatol": 1e-3, "fatol": 1e-9, "maxiter": 300})
        for s in cache:
            n_lp += s.n_lp
            if s.objective < best.objective:
                best = s
    best.n_lp = n_lp
    return best, (coarse, np.array([]))


def _x_to_model(sol, dt):
    from imupipe.models import NoiseModel

    N = K = 0.0
    gm = []
    for name, v in zip(sol.names, sol.x):
        if name == "white":
            N = math.sqrt(max(v, 0.0))
        elif name == "random_walk":
            K = math.sqrt(max(v, 0.0))
        else:
            i = int(name[3:]) - 1
            if v > 0:
                gm.append((math.sqrt(v), sol.T[i]))
    gm.sort(key=lambda st: st[1])
    return NoiseModel(white=N, gauss_markov=tuple(gm), random_walk=K, dt=dt)


# ---------------------------------------------------------------------------------------------
# evaluation helpers
# ---------------------------------------------------------------------------------------------
def _evaluate(prob, model):
    """Margins of `model` against the mode's targets, the spec and the raw curves; looseness."""
    mb = prob.model_bins(model)
    mr = prob.to_rows(mb)
    out = {}
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(prob.targets > 0, mr[None, :] / prob.targets, np.inf)
    c, r = np.unravel_index(int(np.argmin(ratio)), ratio.shape)
    out.update(margin=float(ratio[c, r]), margin_curve=prob.labels[c], margin_frequency=float(prob.f_rows[r]))
    with np.errstate(divide="ignore", invalid="ignore"):
        rraw = np.where(prob.raw > 0, mb[None, :] / prob.raw, np.inf)
    c, i = np.unravel_index(int(np.argmin(rraw)), rraw.shape)
    out.update(raw_margin=float(rraw[c, i]), raw_margin_curve=prob.labels[c], raw_margin_frequency=float(prob.f[i]))
    if prob.spec is not None:
        with np.errstate(divide="ignore", invalid="ignore"):
            rs = np.where(prob.spec > 0, mb / prob.spec, np.inf)
        j = int(np.argmin(rs))
        out.update(spec_margin=float(rs[j]), spec_margin_frequency=float(prob.f[j]))
    else:
        out.update(spec_margin=float("inf"), spec_margin_frequency=None)
    out["looseness"] = float(prob.objective_weights @ mr)  # the LP's objective
    out.update(_all_frequency_margin(prob, model))
    return out


def _all_frequency_margin(prob, model):
    """Margins of the all-frequency conditions: the grid below the lowest bin and the asymptotes."""
    res = {"allf_margin": float("inf"), "allf_margin_frequency": None}
    ok = prob.lo_t > 0
    if np.any(ok):
        r = np.asarray(model.psd(prob.lo_f[ok]), dtype=np.float64) / prob.lo_t[ok]
        j = int(np.argmin(r))
        res.update(allf_margin=float(r[j]), allf_margin_frequency=float(prob.lo_f[ok][j]))
    for req, val, what in ((prob.k2_req, model.random_walk**2, 0.0), (prob.n2_req, model.white**2, float("inf"))):
        if req > 0 and val / req < res["allf_margin"]:
            res.update(allf_margin=float(val / req), allf_margin_frequency=what)
    return res


def _upper_psd(model, f):
    return np.zeros_like(f) if model is None else np.asarray(model.psd(f), dtype=np.float64)


def _setup_all_frequency(prob, spec_model, upper_model, horizon_s, f_floor_hz, per_decade=10, upper_band="all"):
    """Fill the all-frequency rows of `prob` (module docstring, "Bound over all frequencies")."""
    f_min = float(prob.f.min())
    if f_floor_hz is None:
        f_floor_hz = 0.01 / float(horizon_s) if horizon_s else f_min / 100.0
    f_floor_hz = min(float(f_floor_hz), f_min / 10.0)
    n = max(2, int(math.ceil(math.log10(f_min / f_floor_hz) * per_decade)) + 1)
    lo_f = np.logspace(math.log10(f_floor_hz), math.log10(f_min), n)[:-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        lo_t = np.maximum(_upper_psd(spec_model, lo_f), _upper_psd(upper_model, lo_f))
    if upper_model is not None and upper_band == "all":  # the envelope on the sampled band too (continuous PSDs)
        f_max = float(prob.f.max())
        n_in = max(2, int(math.ceil(math.log10(f_max / f_min) * per_decade)) + 1)
        in_f = np.logspace(math.log10(f_min), math.log10(f_max), n_in)
        lo_f = np.concatenate([lo_f, in_f])
        lo_t = np.concatenate([lo_t, _upper_psd(upper_model, in_f)])
    elif upper_band not in ("all", "below"):
        raise ValueError(f"upper_band must be 'all' or 'below', got {upper_band!r}")
    prob.lo_f, prob.lo_t = lo_f, np.where(np.isfinite(lo_t), lo_t, 0.0)
    k_spec = spec_model.random_walk if spec_model is not None else 0.0
    k_up = upper_model.random_walk if upper_model is not None else 0.0
    prob.k2_req = max(k_spec, k_up) ** 2
    prob.n2_req = (spec_model.white if spec_model is not None else 0.0) ** 2
    return {"f_floor_hz": float(f_floor_hz), "n_grid": int(lo_f.size), "f_top_hz": f_min,
            "K_required": math.sqrt(prob.k2_req), "K_spec": float(k_spec), "K_upper": float(k_up),
            "N_required": math.sqrt(prob.n2_req), "upper_band": upper_band,
            "flicker": "a spec or identified flicker is bounded down to f_floor_hz (no K is forced by it)",
            "units": "Hz; K u/sqrt(s); N u/sqrt(Hz)"}


def _apply_exclude(prob, exclude):
    """Drop the sample-curve targets of rows inside the `exclude` intervals (never the spec or the
    all-frequency rows); returns the list of what was excluded and why."""
    out = []
    if not exclude:
        return out
    prob.targets = np.array(prob.targets, dtype=np.float64, copy=True)
    if prob.starts is None:
        lo_edge = hi_edge = prob.f_rows
    else:
        ends = np.append(prob.starts[1:], prob.f.size) - 1
        lo_edge, hi_edge = prob.f[prob.starts], prob.f[ends]
    for item in exclude:
        try:
            f_lo, f_hi, reason = item
            f_lo, f_hi = float(f_lo), float(f_hi)
        except (TypeError, ValueError):
            raise ValueError(f"exclude entries must be (f_lo_hz, f_hi_hz, reason), got {item!r}") from None
        if not (0 <= f_lo < f_hi):
            raise ValueError(f"exclude interval must have 0 <= f_lo_hz < f_hi_hz, got ({f_lo}, {f_hi})")
        rows = np.flatnonzero((hi_edge >= f_lo) & (lo_edge <= f_hi))
        prob.targets[:, rows] = 0.0
        if prob.starts is None:
            bins = prob.f_rows[rows]
        else:
            bins = np.concatenate([prob.f[prob.starts[r]:prob.starts[r] + prob.counts[r]] for r in rows]) \
                if rows.size else np.zeros(0)
        out.append({"f_lo_hz": f_lo, "f_hi_hz": f_hi, "reason": str(reason), "n_bins": int(bins.size),
                    "bins_hz": [float(b) for b in bins]})
    prob.envelope = prob.targets.max(axis=0)
    prob.env = prob.envelope if prob.spec_rows is None else np.maximum(prob.envelope, prob.spec_rows)
    prob.objective_weights = np.zeros_like(prob.env)
    np.divide(prob.weights, prob.env, out=prob.objective_weights, where=prob.env > 0)
    prob._kept.clear()
    return out


def _result(prob, model, spec_model, t0: float, **rest) -> BoundResult:
    """The :class:`BoundResult` of `model` on `prob`: margins and looseness from :func:`_evaluate`,
    ``bounded`` when both the target and the spec margins reach 1 - _EPS_BOUND, the inflation against
    `spec_model`, the time since `t0`; `rest` gives the other fields."""
    ev = _evaluate(prob, model)
    bounded = (ev["margin"] >= 1 - _EPS_BOUND and ev["spec_margin"] >= 1 - _EPS_BOUND
               and ev["allf_margin"] >= 1 - _EPS_BOUND)
    return BoundResult(model=model, spec=spec_model, inflation=_inflation(model, spec_model), bounded=bool(bounded),
                       **ev, solve_time_s=time.perf_counter() - t0, **rest)


def _spec_components(spec):
    if spec is None:
        return list(BOUND_COMPONENTS)
    comps = []
    if spec.white > 0:
        comps.append("white")
    if len(spec.gauss_markov) > 0 or getattr(spec, "flicker", 0.0) > 0:
        comps.append("gauss_markov")
    if spec.random_walk > 0:
        comps.append("random_walk")
    return comps


def _inflation(bound, spec):
    """Inflation factors bound/spec per parameter; None where the spec has no such component."""

    def ratio(b, s):
        if s is None or s == 0:
            return None
        return float(b / s)

    out = {
        "N": ratio(bound.white, spec.white if spec is not None else None),
        "K": ratio(bound.random_walk, spec.random_walk if spec is not None else None),
    }
    sgm = sorted(spec.gauss_markov, key=lambda st: st[1]) if spec is not None else []
    bgm = sorted(bound.gauss_markov, key=lambda st: st[1])
    n = max(len(sgm), len(bgm), 1)
    for i in range(n):
        sfx = "" if n == 1 else f"_{i + 1}"
        s = sgm[i] if i < len(sgm) else None
        b = bgm[i] if i < len(bgm) else (0.0, None)
        out["sigma" + sfx] = ratio(b[0], s[0]) if s is not None else None
        out["T" + sfx] = ratio(b[1], s[1]) if (s is not None and b[1] is not None) else None
    return out


# ---------------------------------------------------------------------------------------------
# result
# ---------------------------------------------------------------------------------------------
@dataclass
class BoundResult:
    r"""Result of :func:`bound_psd` or :func:`paper_inflation` (SI throughout).

    Attributes
    ----------
    model : imupipe.models.NoiseModel
        The bound: white N (u/sqrt(Hz)), GM terms (sigma u, T s), random walk K (u/sqrt(s)).
    spec : imupipe.models.NoiseModel or None
        The spec-sheet model the bound was asked to dominate.
    inflation : dict
        bound/spec per parameter (``N``, ``K``, ``sigma``, ``T``; ``sigma_i``/``T_i`` for several
        GM terms, matched by increasing T); None where the spec has no such component.
    bounded : bool
        Model >= every target and >= the spec at every compared frequency (to 1e-9).
    margin : float
        :math:`\min_{c,k} S_m(f_k)/\hat S_c(f_k)` over the mode's targets (>= 1 - 1e-9 when bounded).
    margin_curve, margin_frequency :
        Label of the curve and frequency (Hz) that set `margin`.
    raw_margin, raw_margin_curve, raw_margin_frequency :
        The same against the raw periodograms (below 1 in smoothed/confidence modes, by design).
    spec_margin, spec_margin_frequency :
        :math:`\min S_m/S_{spec}` and where.
    looseness : float
        LP objective: log-frequency mean of :math:`S_m/E` (E = envelope of targets and spec).
    mode : str
        ``raw``, ``smoothed``, ``confidence`` or ``paper`` (hand inflation, raw targets).
    components : list of str
        Components the bound was allowed to use.
    decisions : dict
        Component -> reason it was used or not.
    T_profile : tuple of numpy.ndarray
        (T grid, looseness) of the single-GM profile.
    n_lp : int
        Linear programs solved.
    solve_time_s : float
        Wall time, s.
    details : dict
        Mode settings (bands, edf, confidence, number of tests) and, for the hand procedure, the
        step history.
    """

    model: object
    spec: object
    inflation: dict
    bounded: bool
    margin: float
    margin_curve: str
    margin_frequency: float
    raw_margin: float
    raw_margin_curve: str
    raw_margin_frequency: float
    spec_margin: float
    spec_margin_frequency: float | None
    looseness: float
    mode: str
    components: list
    decisions: dict
    T_profile: tuple = field(repr=False, default=(np.zeros(0), np.zeros(0)))
    n_lp: int = 0
    solve_time_s: float = 0.0
    details: dict = field(default_factory=dict)
    allf_margin: float = float("inf")
    allf_margin_frequency: float | None = None

    def to_dict(self, spec_units: dict | None = None, sensor: str | None = None) -> dict:
        """Plain dict for YAML: bound and spec in SI and, with `spec_units`, in the spec's units.

        Parameters
        ----------
        spec_units : dict, optional
            Unit per quantity as written in the spec sheet, keys among ``white``, ``gm_sigma``,
            ``time``, ``random_walk`` (e.g. ``{"white": "deg/sqrt(h)", "gm_sigma": "deg/h",
            "time": "s", "random_walk": "(deg/h)/sqrt(s)"}``). Converted with
            :func:`imupipe.units.from_si`; without it (or without that module) only SI is written.
        sensor : str, optional
            ``gyro`` or ``accel`` (passed to the unit conversion).
        """

        def fl(x):
            if x is None:
                return None
            x = float(x)
            return x if math.isfinite(x) else None

        def params(m):
            if m is None:
                return None
            return {
                "white": fl(m.white),
                "gauss_markov": [{"sigma": fl(s), "T": fl(T)} for s, T in m.gauss_markov],
                "random_walk": fl(m.random_walk),
            }

        out = {
            "units": "SI: white u/sqrt(Hz), gauss_markov sigma u and T s, random_walk u/sqrt(s); "
            "u = rad/s (gyro) or m/s^2 (accel); PSDs two-sided",
            "bound": params(self.model),
            "spec": params(self.spec),
            "inflation": {k: fl(v) for k, v in self.inflation.items()},
            "bounded": bool(self.bounded),
            "margin": fl(self.margin),
            "margin_curve": self.margin_curve,
            "margin_frequency_hz": fl(self.margin_frequency),
            "raw_margin": fl(self.raw_margin),
            "raw_margin_curve": self.raw_margin_curve,
            "raw_margin_frequency_hz": fl(self.raw_margin_frequency),
            "spec_margin": fl(self.spec_margin),
            "spec_margin_frequency_hz": fl(self.spec_margin_frequency),
            "looseness": fl(self.looseness),
            "all_frequency_margin": fl(self.allf_margin),
            "all_frequency_margin_frequency_hz": fl(self.allf_margin_frequency),
            "mode": self.mode,
            "components": list(self.components),
            "decisions": dict(self.decisions),
            "n_lp": int(self.n_lp),
            "solve_time_s": fl(self.solve_time_s),
            "details": _plain(self.details),
        }
        if spec_units:
            out["bound_spec_units"], note = _to_spec_units(self.model, spec_units, sensor)
            if self.spec is not None:
                out["spec_spec_units"], _ = _to_spec_units(self.spec, spec_units, sensor)
            if note:
                out["unit_note"] = note
        return out


def _plain(obj):
    """numpy scalars/arrays -> Python floats/lists (YAML-safe)."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return [_plain(v) for v in obj.tolist()]
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    return obj


def _to_spec_units(model, spec_units, sensor):
    """Model parameters in the spec's units via imupipe.units.from_si (SI only if unavailable)."""
    try:
        from imupipe.units import from_si
    except ImportError:
        return None, "imupipe.units not available: values in SI only"
    out = {}
    try:
        if "white" in spec_units:
            out["white"] = {"value": float(from_si(model.white, spec_units["white"], "white", sensor, "white")),
                            "unit": spec_units["white"]}
        if "random_walk" in spec_units:
            out["random_walk"] = {
                "value": float(from_si(model.random_walk, spec_units["random_walk"], "random_walk", sensor,
                                       "random_walk")),
                "unit": spec_units["random_walk"],
            }
        gms = []
        for s, T in model.gauss_markov:
            d = {}
            if "gm_sigma" in spec_units:
                d["sigma"] = {"value": float(from_si(s, spec_units["gm_sigma"], "gm_sigma", sensor, "gm_sigma")),
                              "unit": spec_units["gm_sigma"]}
            if "time" in spec_units:
                d["T"] = {"value": float(from_si(T, spec_units["time"], "time", sensor, "time")),
                          "unit": spec_units["time"]}
            gms.append(d)
        out["gauss_markov"] = gms
    except Exception as exc:  # unit helper with another signature: keep SI, say why
        return None, f"unit conversion failed ({exc}); values in SI only"
    return out, None


# ---------------------------------------------------------------------------------------------
# public functions
# ---------------------------------------------------------------------------------------------
def _normalise_keep(keep):
    if keep is None:
        return None
    if isinstance(keep, dict):  # a select_components result
        keep = keep.get("kept", [])
    comps = set()
    for k in keep:
        if k in ("white", "random_walk", "gauss_markov"):
            comps.add(k)
        elif k == "flicker":
            comps.add("gauss_markov")  # flicker is bounded by GM terms
    return [c for c in BOUND_COMPONENTS if c in comps]


def bound_psd(
    frequency,
    curves,
    spec_model=None,
    dt: float | None = None,
    mode: str = "raw",
    n_gm: int = 1,
    T_grid=None,
    confidence: float = 0.95,
    bands_per_decade: int | None = 10,
    edf=None,
    keep=None,
    taper="hann",
    min_edf="auto",
    add_threshold: float = 0.05,
    n_tests: int | None = None,
    horizon_s: float | None = None,
    upper_model=None,
    f_floor_hz: float | None = None,
    exclude=(),
    narrowband=(),
    upper_band: str = "all",
) -> BoundResult:
    r"""Tightest white + GM + random-walk model whose PSD bounds sample PSDs and a spec sheet.

    For each set of GM time constants the squared coefficients
    :math:`x = (N^2, \sigma_1^2, \dots, K^2) \ge 0` solve the linear program (module docstring)

    .. math::

        \min_x \sum_k w_k \frac{S_m(f_k)}{E(f_k)} \quad\text{s.t.}\quad
        S_m(f_k) \ge \hat S_c(f_k)\;\forall c,k;\quad S_m(f_j) \ge S_{spec}(f_j)\;\forall j,

    with :math:`S_m = N^2 + \sum_i 2\sigma_i^2 T_i/(1+(2\pi f T_i)^2) + K^2/(2\pi f)^2`
    (Gallon et al. 2021, eq. 13; two-sided), or its block-averaged, sampled form
    ``NoiseModel.psd_sampled(f, dt)`` when `dt` is given. :math:`w_k` weights each decade of
    frequency equally; :math:`E` is the envelope of targets and spec. The time constants are
    profiled on a log grid (spec's T included) and refined; the returned model is scaled by the
    LP's residual shortfall so that the margin is >= 1 to rounding.

    Which components: `keep` (names, or a :func:`imupipe.identify.select_components` result;
    ``flicker`` maps to a GM term, quantization and ramp are not states) fixes them. Without `keep`,
    the spec's components are used (a spec flicker counts as GM) and each of white, GM and random
    walk that the spec leaves out is added only if the data need it: if it lowers the looseness by
    more than `add_threshold` (relative). ``decisions`` records why.

    Parameters
    ----------
    frequency : array_like
        Frequency grid of the sample PSDs, Hz, increasing (DC is ignored).
    curves : array_like, sequence, dict or xarray.DataArray
        Two-sided sample PSDs, u^2/Hz, shape (n_curves, n_freq); a dict maps labels to curves; a
        DataArray with a ``frequency`` dimension is stacked over its other dimensions (labels such
        as ``"dataset=d1, axis=x"``).
    spec_model : imupipe.models.NoiseModel, optional
        Spec-sheet model (SI); the bound must dominate its PSD at every bin.
    dt : float, optional
        Sample interval of the (block-averaged) data, s; compares with ``psd_sampled``.
    mode : {"raw", "smoothed", "confidence"}, optional
        How the sample PSDs enter (module docstring). Default ``"raw"`` (paper).
    n_gm : int, optional
        Number of GM terms (0 allowed). Default 1.
    T_grid : array_like, optional
        Trial time constants, s, or an int: that many per decade over the default span. Default 10
        per decade spanning the frequency grid's corner
        frequencies :math:`1/(2\pi T)`, with half a decade below and one above.
    confidence : float, optional
        Family-wise level of the ``confidence`` mode. Default 0.95.
    bands_per_decade : int or None, optional
        Log bands for ``smoothed`` and ``confidence`` modes (None in ``confidence`` mode: per
        ordinate). Default 10.
    edf : float or array_like, optional
        Degrees of freedom of each ordinate (scalar, (n_freq,) or (n_curves, n_freq)), e.g. the
        ``edf`` variable of :func:`imupipe.spectra.psd`. Default 2 (one periodogram).
    keep : sequence of str or dict, optional
        Components to use (see above).
    taper : str or array_like or None, optional
        Taper of the periodograms, for the correlation of neighbouring ordinates in the band
        degrees of freedom. Default ``"hann"``.
    min_edf : float or None or "auto", optional
        Merge low-frequency bands until each has at least this many degrees of freedom (None: no
        merging). ``"auto"`` (default): :data:`DEFAULT_MIN_EDF` in ``confidence`` mode, None
        otherwise. A single 7 h Hann periodogram has 2 degrees of freedom per ordinate, and the
        Bonferroni-corrected upper limit of such an ordinate is about :math:`n/(1-c)` times the
        estimate (thousands): the lowest bands must be merged for the limit to mean anything.
        The price is frequency resolution below about ``min_edf`` bins (30 bins of a 7 h window
        reach 1.2e-3 Hz); the constraint there is on the band average.
    add_threshold : float, optional
        Relative looseness gain required to add a component the spec lacks. Default 0.05.
    n_tests : int, optional
        Multiplicity of the confidence mode. Default: number of (curve, band) pairs.

    Returns
    -------
    BoundResult

    Raises
    ------
    ValueError
        Bad shapes, negative or non-finite PSDs, unknown mode.
    """
    t0 = time.perf_counter()
    if isinstance(min_edf, str):
        if min_edf != "auto":
            raise ValueError(f"min_edf must be a number, None or 'auto', got {min_edf!r}")
        min_edf = DEFAULT_MIN_EDF if mode == "confidence" else None
    prob = _prepare(frequency, curves, spec_model, dt, mode, confidence, bands_per_decade, edf, taper, min_edf,
                    n_tests)
    allf = _setup_all_frequency(prob, spec_model, upper_model, horizon_s, f_floor_hz, upper_band=upper_band)
    excluded = _apply_exclude(prob, exclude)
    if narrowband:
        raise NotImplementedError("narrowband line columns in bound_psd are not implemented on this branch yet")
    if T_grid is None:
        grid = _default_T_grid(prob)
    elif np.ndim(T_grid) == 0:  # points per decade of the default span
        grid = _default_T_grid(prob, per_decade=int(T_grid))
    else:
        grid = np.asarray(T_grid, dtype=np.float64)
    if grid.size == 0 or np.any(grid <= 0):
        raise ValueError("T_grid must hold positive time constants (s)")
    extra_T = [T for _, T in spec_model.gauss_markov] if spec_model is not None else []
    n_gm = int(n_gm)
    decisions = {}
    n_lp = 0

    def solve(comps):
        nonlocal n_lp
        sol, prof = _profile_T(prob, comps, n_gm, grid, extra_T)
        n_lp += sol.n_lp
        return sol, prof

    fixed = _normalise_keep(keep)

    def require(comps):
        if prob.k2_req > 0 and "random_walk" not in comps:
            decisions["random_walk"] = (f"required by the all-frequency bound: K >= {math.sqrt(prob.k2_req):.6g} "
                                        f"u/sqrt(s) (max of spec {allf['K_spec']:.6g} and identified upper limit "
                                        f"{allf['K_upper']:.6g})")
            comps = [c for c in BOUND_COMPONENTS if c in comps or c == "random_walk"]
        if prob.n2_req > 0 and "white" not in comps:
            decisions["white"] = "required by the all-frequency bound (spec white noise, f -> inf)"
            comps = [c for c in BOUND_COMPONENTS if c in comps or c == "white"]
        return comps

    if not np.any(prob.env > 0) and not np.any(prob.lo_t > 0) and prob.k2_req == 0 and prob.n2_req == 0:
        comps = fixed if fixed is not None else _spec_components(spec_model)
        from imupipe.models import NoiseModel

        model = NoiseModel(dt=dt)
        decisions["all"] = "all targets are zero: the zero model bounds them"
        prof = (np.zeros(0), np.zeros(0))
    else:
        if fixed is not None:
            comps = fixed
            for c in BOUND_COMPONENTS:
                decisions[c] = "requested by keep" if c in comps else "excluded by keep"
            if not comps:
                raise ValueError("keep leaves no component to bound with")
            comps = require(comps)
            sol, prof = solve(comps)
        else:
            comps = _spec_components(spec_model)
            for c in comps:
                decisions[c] = "in the spec sheet"
            if not comps:
                comps = ["white"]
                decisions["white"] = "spec has no component: start from white noise"
            comps = require(comps)
            sol, prof = solve(comps)
            for cand in ("gauss_markov", "random_walk", "white"):
                if cand in comps or (cand == "gauss_markov" and n_gm == 0):
                    continue
                trial = [c for c in BOUND_COMPONENTS if c in comps or c == cand]
                s2, p2 = solve(trial)
                gain = 1.0 - s2.objective / sol.objective if sol.objective > 0 else 0.0
                if gain > add_threshold:
                    comps, sol, prof = trial, s2, p2
                    decisions[cand] = (f"not in the spec; added because the data need it "
                                       f"(looseness {1 - gain:.3g} of the bound without it)")
                else:
                    decisions[cand] = (f"not in the spec and not needed by the data "
                                       f"(looseness gain {gain:.3g} <= {add_threshold:g})")
        model = _x_to_model(sol, dt)
    details = dict(prob.details)
    details.update(n_frequencies=int(prob.f.size), n_curves=int(prob.raw.shape[0]), n_rows=int(prob.f_rows.size),
                   dt=dt, n_gm=n_gm, all_frequency=allf, excluded=excluded)
    return _result(prob, model, spec_model, t0, mode=mode, components=list(comps), decisions=decisions,
                   T_profile=prof, n_lp=n_lp, details=details)


def margin(model, frequency, curves, dt: float | None = None):
    r"""Smallest ratio :math:`\min_{c,k} S_m(f_k)/\hat S_c(f_k)` of a model PSD to sample PSDs.

    Parameters
    ----------
    model : imupipe.models.NoiseModel
    frequency : array_like
        Hz (DC ignored).
    curves : array_like, sequence, dict or xarray.DataArray
        Two-sided sample PSDs, u^2/Hz (as in :func:`bound_psd`).
    dt : float, optional
        Compare with ``model.psd_sampled(f, dt)``.

    Returns
    -------
    tuple
        (margin, curve label, frequency in Hz); margin is inf if every ordinate is zero.
    """
    prob = _prepare(frequency, curves, None, dt, "raw", 0.95, None, None, None, None)
    ev = _evaluate(prob, model)
    return ev["raw_margin"], ev["raw_margin_curve"], ev["raw_margin_frequency"]


def looseness(model, frequency, curves, spec_model=None, dt: float | None = None):
    r"""The LP's objective for any model: :math:`\sum_k w_k S_m(f_k)/E(f_k)` (raw targets).

    Lets a hand-tuned model and the LP bound be compared on the same footing.
    """
    prob = _prepare(frequency, curves, spec_model, dt, "raw", 0.95, None, None, None, None)
    return _evaluate(prob, model)["looseness"]


def paper_inflation(
    frequency,
    curves,
    spec_model,
    dt: float | None = None,
    step: float = 1.05,
    order=("sigma", "T", "K", "N"),
    min_gain: float = 0.5,
    max_steps: int = 5000,
) -> BoundResult:
    r"""The paper's hand procedure: multiplicative inflation of the spec until the PSD bounds.

    Gallon et al. 2021 (Appendix A.2, Figure 8) inflate :math:`\sigma`, deflate :math:`T`, inflate
    :math:`K`, then inflate :math:`N`, each "until its part of the curve is bounded". Here each phase
    multiplies its parameter by `step` (divides, for T) while that keeps paying off: for
    :math:`\sigma, K, N` a step must raise the worst margin
    :math:`\min_{c,k} S_m/\hat S_c` (raw ordinates and spec) by at least `min_gain` of the step's
    power factor in log (i.e. the component carries about that share of the model where the bound
    fails); for :math:`T` any increase of the margin is accepted. Phases repeat in `order` until
    bounded; if a full round makes no progress the parameter with the largest gain is stepped
    (white noise always gains, so the procedure ends).

    Parameters
    ----------
    frequency, curves, spec_model, dt :
        As in :func:`bound_psd` (raw targets). The spec supplies the starting point; components
        it lacks (a zero N or K, no GM) stay absent.
    step : float, optional
        Multiplicative step (> 1). Default 1.05.
    order : sequence of str, optional
        Phase order. Default ("sigma", "T", "K", "N") (the paper's).
    min_gain : float, optional
        Required effectiveness of a step (see above). Default 0.5.
    max_steps : int, optional
        Safety limit. Default 5000.

    Returns
    -------
    BoundResult
        ``mode = "paper"``; ``details["history"]`` lists (parameter, N, sigma, T, K, margin) after
        every accepted step (for the inflation-steps figure).
    """
    from imupipe.models import NoiseModel

    if not step > 1:
        raise ValueError("step must be > 1")
    t0 = time.perf_counter()
    prob = _prepare(frequency, curves, spec_model, dt, "raw", 0.95, None, None, None, None)
    gm = sorted(spec_model.gauss_markov, key=lambda st: st[1])
    state = {
        "N": float(spec_model.white),
        "sigma": float(gm[0][0]) if gm else 0.0,
        "T": float(gm[0][1]) if gm else 0.0,
        "K": float(spec_model.random_walk),
    }
    extra_gm = tuple(gm[1:])

    def model_of(s):
        g = ((s["sigma"], s["T"]),) + extra_gm if s["sigma"] > 0 else extra_gm
        return NoiseModel(white=s["N"], gauss_markov=g, random_walk=s["K"], dt=dt)

    def worst(s):
        return prob.worst_margin(model_of(s))

    def moved(s, p):
        s2 = dict(s)
        s2[p] = s[p] / step if p == "T" else s[p] * step
        return s2

    active = [p for p in order if state[p] > 0]
    cur = worst(state)
    history = [("spec", state["N"], state["sigma"], state["T"], state["K"], cur)]
    n = 0
    log_pow = math.log(step**2)
    while cur < 1 - _EPS_BOUND and n < max_steps:
        progress = False
        for p in active:
            while cur < 1 - _EPS_BOUND and n < max_steps:
                cand = moved(state, p)
                m = worst(cand)
                gain = math.log(m / cur) / log_pow if m > 0 and cur > 0 else 0.0
                ok = m > cur * (1 + 1e-12) if p == "T" else gain >= min_gain
                if not ok:
                    break
                state, cur = cand, m
                n += 1
                progress = True
                history.append((p, state["N"], state["sigma"], state["T"], state["K"], cur))
        if not progress and cur < 1 - _EPS_BOUND:
            best_p, best_m = None, cur
            for p in active:
                if p == "T":
                    continue
                m = worst(moved(state, p))
                if m > best_m:
                    best_p, best_m = p, m
            if best_p is None:
                if "N" not in active:  # a spec without white noise: white is the last resort
                    state["N"] = max(state["N"], 1e-30)
                    active.append("N")
                    continue
                break
            state, cur = moved(state, best_p), best_m
            n += 1
            history.append((best_p, state["N"], state["sigma"], state["T"], state["K"], cur))
    result = _result(
        prob, model_of(state), spec_model, t0,
        mode="paper",
        components=_spec_components(spec_model),
        decisions={"procedure": f"multiplicative steps of {step:g} in the order {list(order)}"},
        n_lp=0,
        details={"history": [list(h) for h in history], "n_steps": n, "step": step, "order": list(order),
                 "history_columns": ["parameter", "N", "sigma", "T", "K", "margin"]},
    )
    if not result.bounded:
        warnings.warn(f"paper_inflation stopped after {n} steps without a bound (margin {cur:.3g})",
                      RuntimeWarning, stacklevel=2)
    return result


def gm_bounds_gm(sigma_m: float, T_m: float, sigma: float, T: float, rtol: float = 0.0) -> bool:
    r"""Whether GM (sigma_m, T_m) bounds GM (sigma, T) in PSD at every frequency.

    With :math:`a = (2\pi f)^2`, the difference of the two PSDs over the positive common
    denominator is

    .. math::

        2(\sigma_m^2 T_m - \sigma^2 T) + 2 a\, T T_m (\sigma_m^2 T - \sigma^2 T_m),

    linear in :math:`a \ge 0`, so it is non-negative for all :math:`f` iff both coefficients are:

    .. math::

        \sigma_m^2 T_m \ge \sigma^2 T \quad (f \to 0) \qquad\text{and}\qquad
        \sigma_m^2 / T_m \ge \sigma^2 / T \quad (f \to \infty).

    Parameters
    ----------
    sigma_m, T_m : float
        Bounding GM: standard deviation (u) and time constant (s).
    sigma, T : float
        Bounded GM.
    rtol : float, optional
        Relative slack on both inequalities. Default 0.

    Returns
    -------
    bool
    """
    lo = sigma_m**2 * T_m >= sigma**2 * T * (1 - rtol)
    hi = sigma_m**2 / T_m >= sigma**2 / T * (1 - rtol)
    return bool(lo and hi)


def check_allan_components(bound_model, identified_model, tau) -> dict:
    r"""Component-wise AV check: does each bound component dominate its identified counterpart?

    The paper (Gallon et al. 2021, Figure 6) verifies in the AV domain that the bound's white noise
    dominates the identified white noise, its random walk the identified random walk, and its GM
    the identified bias instability. Here, on the grid `tau`:

    * ``white``: :math:`N_b^2/\tau \ge N^2/\tau`, margin :math:`N_b^2/N^2`;
    * ``random_walk``: margin :math:`K_b^2/K^2`;
    * ``gauss_markov``: :math:`\sum_i AV_{GM}(\tau; \sigma_{b,i}, T_{b,i}) \ge
      \sum_j AV_{GM}(\tau; \sigma_j, T_j)`, margin = min over `tau` of the ratio;
    * ``flicker``: the bound's GM terms against the flicker AV :math:`(2\ln 2/\pi) B^2` over the
      taus where flicker is the identified model's largest AV term (a GM's AV vanishes as
      :math:`\tau \to 0`, so no GM covers flat flicker at every tau; elsewhere the other components
      carry the AV); ``passed = None`` if flicker never dominates. A GM with :math:`\sigma = B`
      does not cover it: its ADEV peaks at :math:`0.6174\sigma < 0.664 B` (method.md 2.3);
    * ``bias (gauss_markov + flicker)``: the bound's GM terms against the identified GM and flicker
      together, when both are present;
    * ``quantization``, ``ramp``: not Kalman-filter states; reported with ``passed = None``.

    The check holds on the `tau` grid only (use the AV grid of the data).

    Parameters
    ----------
    bound_model, identified_model : imupipe.models.NoiseModel
        SI models.
    tau : array_like
        Averaging times, s.

    Returns
    -------
    dict
        Component -> ``{"passed": bool or None, "margin": float, "tau_at_min": float or None,
        "reason": str}``; margin is min over tau of AV_bound/AV_identified (inf if the identified
        component is absent).
    """
    from imupipe.models import FLICKER_AV, gm_avar

    t = np.asarray(tau, dtype=np.float64)
    t = t[np.isfinite(t) & (t > 0)]
    if t.size == 0:
        raise ValueError("tau must contain positive averaging times (s)")

    def gm_av(model):
        out = np.zeros_like(t)
        for s, T in model.gauss_markov:
            out = out + np.asarray(gm_avar(t, s, T), dtype=np.float64)
        return out

    def entry(av_b, av_i, what, t=t):
        if not np.any(av_i > 0):
            return {"passed": True, "margin": float("inf"), "tau_at_min": None,
                    "reason": f"no identified {what}"}
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(av_i > 0, av_b / av_i, np.inf)
        k = int(np.argmin(r))
        ok = bool(r[k] >= 1 - _EPS_BOUND)
        return {"passed": ok, "margin": float(r[k]), "tau_at_min": float(t[k]),
                "reason": f"bound {'dominates' if ok else 'falls below'} the identified {what} in AV "
                          f"(min ratio {r[k]:.4g} at tau = {t[k]:.4g} s)"}

    b, i = bound_model, identified_model
    out = {
        "white": entry(np.full_like(t, b.white**2) / t, np.full_like(t, i.white**2) / t, "white noise"),
        "random_walk": entry(b.random_walk**2 * t / 3, np.full_like(t, i.random_walk**2) * t / 3, "random walk"),
        "gauss_markov": entry(gm_av(b), gm_av(i), "Gauss-Markov"),
    }
    flick = np.full_like(t, FLICKER_AV * getattr(i, "flicker", 0.0) ** 2)
    # A GM's AV vanishes as tau -> 0 while flicker's is flat, so no GM covers flicker at every tau;
    # what matters is the plateau, the taus where flicker is the identified model's largest term
    # (elsewhere other components carry the AV and are checked on their own).
    parts = [np.full_like(t, i.white**2) / t, i.random_walk**2 * t / 3, gm_av(i),
             3.0 * getattr(i, "quantization", 0.0) ** 2 / t**2, getattr(i, "ramp", 0.0) ** 2 * t**2 / 2]
    window = flick > np.max(np.stack(parts), axis=0)
    if np.any(flick > 0) and not np.any(window):
        out["flicker"] = {"passed": None, "margin": None, "tau_at_min": None,
                          "reason": "identified flicker is never the largest AV term on this tau grid; covered by the "
                                    "other components' checks"}
    else:
        sel = window if np.any(window) else np.ones_like(t, dtype=bool)
        sub = t[sel]
        res = entry(gm_av(b)[sel], flick[sel], "flicker (by the bound's GM, where flicker dominates)", t=sub)
        if res["tau_at_min"] is not None and np.any(window):
            res["tau_window"] = [float(sub.min()), float(sub.max())]
        out["flicker"] = res
        if len(i.gauss_markov) and getattr(i, "flicker", 0.0) > 0 and np.any(window):
            out["gauss_markov+flicker"] = entry(gm_av(b)[sel], (gm_av(i) + flick)[sel],
                                                "GM + flicker (by the bound's GM, where flicker dominates)", t=sub)
    for name in ("quantization", "ramp"):
        v = getattr(i, name, 0.0)
        if v > 0:
            out[name] = {"passed": None, "margin": None, "tau_at_min": None,
                         "reason": f"identified {name} is not a Kalman-filter state; covered only through the PSD bound"}
    return out


# ---------------------------------------------------------------------------------------------
# identified upper envelope and the Allan-domain check against kept components
# ---------------------------------------------------------------------------------------------
def upper_envelope(fit, kept=None):
    r"""The identified model's upper confidence envelope, for the all-frequency rows of :func:`bound_psd`.

    Each KEPT component at the upper end of its interval (``fit.intervals``, level ``fit.confidence``;
    the point estimate where the interval is NaN): white :math:`N_{up}`, flicker :math:`B_{up}`, each GM
    term as the tightest single GM dominating every GM of the box :math:`\sigma \le \sigma_{up}`,
    :math:`T_{lo} \le T \le T_{hi}`: :math:`T_m = \sqrt{T_{lo} T_{hi}}`,
    :math:`\sigma_m^2 = \sigma_{up}^2 \sqrt{T_{hi}/T_{lo}}` (a GM dominates another iff
    :math:`\sigma_m^2 T_m \ge \sigma^2 T` and :math:`\sigma_m^2/T_m \ge \sigma^2/T`).
    The random walk at its upper limit **whether or not it was kept**: a random walk the data cannot
    exclude at the stated confidence is an integrity risk below the lowest bin (the profile limit
    ``random_walk_profile["upper"]`` exists when K was fitted as zero).

    Parameters
    ----------
    fit : imupipe.identify.AllanFit
    kept : sequence of str or dict, optional
        Components kept by model selection (names or a ``select_components`` result). Default: all of
        the fit's components with a non-zero estimate.

    Returns
    -------
    imupipe.models.NoiseModel
        SI.
    """
    from imupipe.models import NoiseModel

    if isinstance(kept, dict):
        kept = kept.get("kept", [])
    p, iv = fit.params, fit.intervals

    def up(name):
        v = float(p.get(name, 0.0) or 0.0)
        lo_hi = iv.get(name)
        if lo_hi is not None and math.isfinite(lo_hi[1]):
            v = max(v, float(lo_hi[1]))
        return v if math.isfinite(v) else 0.0

    def is_kept(name):
        if kept is None:
            return name in p and float(p.get(name) or 0.0) > 0
        return name in kept

    gm = []
    if is_kept("gauss_markov") or (kept is None):
        i = 1
        while f"gm_sigma_{i}" in p:
            s, T = up(f"gm_sigma_{i}"), float(p.get(f"gm_T_{i}", float("nan")))
            if s > 0 and math.isfinite(T) and T > 0:
                lo_hi = iv.get(f"gm_T_{i}", (float("nan"), float("nan")))
                T_lo = lo_hi[0] if math.isfinite(lo_hi[0]) and lo_hi[0] > 0 else T
                T_hi = lo_hi[1] if math.isfinite(lo_hi[1]) and lo_hi[1] > 0 else T
                a, c = min(T, T_lo), max(T, T_hi)
                # the tightest single GM above every GM with sigma <= s and T in [a, c]: sigma_m^2 T_m >= s^2 c
                # (f -> 0) and sigma_m^2 / T_m >= s^2 / a (f -> inf) (method.md, "The bound")
                gm.append((s * (c / a) ** 0.25, math.sqrt(a * c)))
            i += 1
    k = up("random_walk")
    prof = getattr(fit, "random_walk_profile", {}) or {}
    if math.isfinite(prof.get("upper", float("nan")) or float("nan")):
        k = max(k, float(prof["upper"]))
    return NoiseModel(white=up("white") if is_kept("white") else 0.0, gauss_markov=tuple(gm), random_walk=k,
                      flicker=up("flicker") if is_kept("flicker") else 0.0)


def check_allan(bound_model, identified_model, tau, kept=None, sample_avar=None, sample_edf=None, labels=None,
                horizon_s: float | None = None, confidence: float = 0.95) -> dict:
    r"""Allan-domain check that distinguishes a real shortfall from a component without counterpart.

    1. Component against component, **kept components only** (`kept`, e.g. the ``select_components``
       result; default: every component of `identified_model`): white against white, random walk
       against random walk, the identified GM terms against the bound's GM terms, and the identified
       flicker against the bound's GM terms **plus** its white noise (the bound represents flicker
       that way) over the taus where flicker is the largest identified term. A bound component with
       no kept identified counterpart is reported as ``no counterpart`` (not a failure), and so is an
       identified component that the bound represents by another one.
    2. Total AV against every sample AV: the bound's total AV :math:`\sigma^2_b(\tau)` must reach the
       lower confidence limit of each sample AV, :math:`\hat\sigma^2 \nu/\chi^2_\nu(1-\alpha/M)` (level
       `confidence`, Bonferroni over the M curves x taus compared), for :math:`\tau \le` `horizon_s`.
       A sample AV below the bound's by chance is not a shortfall; one whose lower limit is above it is.

    Returns
    -------
    dict
        ``components``: name -> {status: ``ok`` | ``shortfall`` | ``no counterpart`` | ``not a state``,
        margin, tau_s, reason}; ``total``: {passed, worst_ratio, curve, tau_s, n_compared, shortfalls:
        [{curve, tau_s, ratio}]}; ``passed``: no shortfall anywhere.
    """
    from imupipe.models import FLICKER_AV, gm_avar

    t = np.asarray(tau, dtype=np.float64)
    good = np.isfinite(t) & (t > 0)
    t = t[good]
    if t.size == 0:
        raise ValueError("check_allan: tau must contain positive averaging times (s)")
    if isinstance(kept, dict):
        kept = kept.get("kept", [])
    i = identified_model
    present = {"white": i.white > 0, "random_walk": i.random_walk > 0, "gauss_markov": len(i.gauss_markov) > 0,
               "flicker": getattr(i, "flicker", 0.0) > 0}
    kept = [c for c, v in present.items() if v] if kept is None else [c for c in kept if present.get(c, False)]
    b = bound_model

    def gm_av(model):
        out = np.zeros_like(t)
        for s, T in model.gauss_markov:
            out = out + np.asarray(gm_avar(t, s, T), dtype=np.float64)
        return out

    def compare(av_b, av_i, what, sel=None):
        sel = np.ones_like(t, dtype=bool) if sel is None else sel
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(sel & (av_i > 0), av_b / av_i, np.inf)
        k = int(np.argmin(r))
        ok = bool(r[k] >= 1 - _EPS_BOUND)
        return {"status": "ok" if ok else "shortfall", "margin": float(r[k]), "tau_s": float(t[k]),
                "reason": f"bound {what}: min AV ratio {r[k]:.4g} at tau = {t[k]:.4g} s"}

    comps = {}
    if "white" in kept:
        comps["white"] = compare(np.full_like(t, b.white**2) / t, np.full_like(t, i.white**2) / t, "white vs white")
    if "random_walk" in kept:
        comps["random_walk"] = compare(b.random_walk**2 * t / 3, i.random_walk**2 * t / 3, "random walk vs random walk")
    if "gauss_markov" in kept:
        comps["gauss_markov"] = compare(gm_av(b), gm_av(i), "GM vs GM")
        if comps["gauss_markov"]["status"] == "shortfall":
            # a short-T identified GM (T below the bound's resolution) is white noise to the bound: its
            # representation there is GM + white, as for flicker
            alt = compare(gm_av(b) + b.white**2 / t, gm_av(i), "GM + white vs GM")
            if alt["status"] == "ok":
                alt["reason"] += (" (the bound's GM alone falls short at short tau, where the identified GM "
                                  "acts as white noise and the bound's white noise represents it)")
                comps["gauss_markov"] = alt
    if "flicker" in kept:
        fl = np.full_like(t, FLICKER_AV * i.flicker**2)
        others = [np.full_like(t, i.white**2) / t, i.random_walk**2 * t / 3, gm_av(i)]
        sel = fl > np.max(np.stack(others), axis=0)
        if not np.any(sel):
            comps["flicker"] = {"status": "no counterpart", "margin": None, "tau_s": None,
                                "reason": "identified flicker is never the largest AV term: covered by the others"}
        else:
            comps["flicker"] = compare(gm_av(b) + b.white**2 / t, fl, "GM + white vs flicker", sel)
    for c, has in (("white", b.white > 0), ("random_walk", b.random_walk > 0),
                   ("gauss_markov", len(b.gauss_markov) > 0)):
        if has and c not in comps and not (c == "gauss_markov" and "flicker" in comps):
            comps[c] = {"status": "no counterpart", "margin": None, "tau_s": None,
                        "reason": f"bound {c} has no kept identified counterpart (covers the spec or the PSD)"}
    for c in ("quantization", "ramp"):
        if getattr(i, c, 0.0) > 0:
            comps[c] = {"status": "not a state", "margin": None, "tau_s": None,
                        "reason": f"{c} is not a Kalman-filter state; its AV is covered by the total check"}
    total = {"passed": None, "worst_ratio": None, "curve": None, "tau_s": None, "n_compared": 0, "shortfalls": []}
    if sample_avar is not None:
        from scipy.stats import chi2

        av = np.atleast_2d(np.asarray(sample_avar, dtype=np.float64))[:, good]
        nu = np.broadcast_to(np.asarray(2.0 if sample_edf is None else sample_edf, dtype=np.float64),
                             np.atleast_2d(np.asarray(sample_avar)).shape)[:, good]
        lab = labels if labels is not None else [f"curve {j}" for j in range(av.shape[0])]
        band = t <= (horizon_s if horizon_s is not None else np.inf)
        ok = np.isfinite(av) & (av > 0) & np.isfinite(nu) & (nu > 0) & band[None, :]
        M = int(ok.sum())
        total["n_compared"] = M
        if M:
            alpha = (1.0 - confidence) / M
            lower = np.where(ok, av * nu / chi2.ppf(1.0 - alpha, np.where(ok, nu, 1.0)), 0.0)
            mb = np.asarray(b.avar(t), dtype=np.float64)
            with np.errstate(divide="ignore", invalid="ignore"):
                r = np.where(ok & (lower > 0), mb[None, :] / lower, np.inf)
            c, k = np.unravel_index(int(np.argmin(r)), r.shape)
            total.update(worst_ratio=float(r[c, k]), curve=str(lab[c]), tau_s=float(t[k]),
                         passed=bool(r[c, k] >= 1 - _EPS_BOUND))
            for cc, kk in zip(*np.nonzero(r < 1 - _EPS_BOUND)):
                total["shortfalls"].append({"curve": str(lab[cc]), "tau_s": float(t[kk]), "ratio": float(r[cc, kk])})
    passed = all(v["status"] != "shortfall" for v in comps.values()) and total["passed"] is not False
    return {"components": comps, "total": total, "passed": bool(passed), "confidence": float(confidence),
            "units": "tau s; ratios of Allan variances (dimensionless)"}
