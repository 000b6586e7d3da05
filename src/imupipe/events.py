r"""Events in a full-rate IMU axis: bursts (short high-energy spans: a knock) and steps (mean shifts: a tilt).

A static record is modelled as stationary noise (white, Gauss-Markov, flicker, random walk: every component the
Allan fit knows) plus, possibly, events. Both detectors below have a derived threshold and a stated false-alarm
rate per record and axis that holds for coloured Gaussian noise, not only white; the rates are checked by
simulation of event-free records of white + GM + random walk (tests/test_events.py).

Bursts (:func:`find_bursts`)
----------------------------
The record is cut into K disjoint blocks of w samples (``burst_window_s``, 1 s by default). Block j's energy is
:math:`E_j = \sum_{i \in j} (x_i - \bar x_j)^2` (deviations from the block mean: a slow GM, flicker or random walk
hardly moves within one block). For Gaussian noise :math:`E_j` is a quadratic form,
:math:`E_j = \sum_k \lambda_k \chi^2_{1,k}` with :math:`\lambda_k` the eigenvalues of the block's (centred)
covariance matrix; with :math:`\theta_r = \sum_k \lambda_k^r` the power transform

.. math:: y_j = E_j^{\,h}, \qquad h = 1 - \frac{2\,\theta_1\theta_3}{3\,\theta_2^2}

makes :math:`y_j` nearly Gaussian (Jensen & Solomon 1972 [1]_; h = 1/3, the Wilson-Hilferty cube root, for
white noise, where :math:`E_j = \sigma^2\chi^2_{w-1}`; h is negative when a few eigenvalues dominate, e.g. a
short GM, and then :math:`-E_j^h` is used, :math:`\ln E_j` for :math:`|h| < 0.02`: each increasing in E).
The covariance is the Toeplitz matrix of the blocks' mean lag products (up to :data:`ACOV_BLOCKS` blocks
below the threshold of a first pass with h = 1/3, so a burst does not shape it). The centre and scale of
:math:`y` are the median and :math:`1.4826\,\mathrm{MAD}` of the K blocks (robust: a knock changes a few
blocks). A block is energetic when

.. math:: z_j = \frac{y_j - \mathrm{med}(y)}{1.4826\,\mathrm{MAD}(y)} > z_b,
          \qquad z_b = t^{-1}_{\nu_b}\!\left(1 - \frac{\alpha_b}{K}\right),\quad \nu_b = 0.37\,K

(one-sided: a knock adds energy). By the union bound, P(any block of an event-free record flagged) <= K
P(z_j > z_b) = :math:`\alpha_b`, whatever the dependence between blocks; the Student t with :math:`\nu_b`
degrees of freedom carries the scale's own estimation error (the MAD has 37 % efficiency: its relative variance
is that of a standard deviation from :math:`0.37 K` samples [2]_). Energetic blocks no more than one block apart
form one burst; its reported span is that of its samples farther than ``burst_k`` robust sds from the local
median (or the blocks themselves when none is), its peak is the largest :math:`|x - \mathrm{median}|` there.
(The cube root of the first differences' energy, a quadratic form with unequal eigenvalues, puts 1.8x the
Gaussian tail above z = 4: the power must follow the eigenvalues.)

Steps (:func:`find_steps`)
--------------------------
For a window of m samples (:math:`\tau = m/f_s`) the difference of the means of the two adjacent windows at t,

.. math:: D_m(t) = \bar x_{[t, t+m)} - \bar x_{[t-m, t)},

has, for a stationary record (or one with stationary increments: random walk, flicker), zero mean and

.. math:: \mathrm{Var}\, D_m(t) = 2\,\sigma^2_A(\tau)

which is the Allan variance's own definition (Allan 1966 [3]_), so the threshold is valid for any noise whose
Allan variance exists, white or not. A mean step of size :math:`\delta` at :math:`t_0` adds
:math:`\delta\,(1 - |t - t_0|/m)` (a triangle peaking at :math:`t_0`). :math:`\sigma_D(m) = \sqrt{2\sigma_A^2}`
is estimated robustly from the record itself as :math:`1.4826\,\mathrm{median}|D_m|` over the scan (a step
changes :math:`D` only within m of it, a small share of the positions, so it does not inflate the scale it is
tested against; a plain AVAR estimate would). The scan visits the grid :math:`t = m + j h`, :math:`h = m/4`
(K_m positions); a step between two grid points still gives at least :math:`(1 - h/(2m)) = 7/8` of its peak. On a
set of scales :math:`m_s = m_0 2^s` (s = 0..S-1, from ``min_scale_s`` to the largest with at least
``min_windows`` disjoint window pairs in the record) a position is a step candidate when

.. math:: \frac{|D_m(t)|}{\hat\sigma_D(m)} > z_m, \qquad z_m = t^{-1}_{\nu_m}\!\left(1 - \frac{\alpha_s}{2 S K_m}
          \right), \qquad \nu_m = 0.37\,\frac{n - 2m}{2m}.

The union bound over the S scales and the :math:`K_m` positions (valid whatever their correlation, which is
strong: overlapping windows and neighbouring scales) gives

.. math:: P(\text{any step on an event-free record}) \le \sum_s K_{m_s}\, 2\,P(|t_{\nu}| > z_{m_s})
          = \alpha_s .

:math:`\nu_m` counts only the disjoint window pairs (n - 2m)/(2m) at the MAD's efficiency: the overlapping median
uses more, so the t quantile is conservative; :math:`D_m` is Gaussian for Gaussian noise of any colour (a linear
functional), and nearly so for quantised data (a mean of >= m samples). The bound is conservative (the positions
are strongly dependent): the rate it gives is an upper limit, the simulation measures the actual one.

Local scale. A candidate (the largest z of a cluster, below) is kept only where it also exceeds :math:`z_m` against
its neighbourhood's scale, :math:`|D_m(t)| > z_m \max(\hat\sigma_D(m),\ \hat\sigma_{D,\mathrm{loc}}(m, t))`,
the local one :math:`1.4826\,\mathrm{median}|D_m|` over the grid positions within :data:`LOCAL_WINDOWS` window
pairs (2m samples each) on either side. This only removes candidates, so the union bound above still holds; on a
stationary record the two scales agree (a step moves D only within m of it, 8 of the about 1600 positions). Where
the noise level changes (white noise 3x its sd over the second half of a record), the record's scale is too small
for the noisier part and every fluctuation there was a candidate: 20 steps and excursions per record (the most
reported) before, 1.75 now (``benchmarks/events_level_change.py``; the stationarity test is what sees a level
change), the power on mean steps unchanged.

Localisation and size. Exceeding grid positions of one scale form clusters (no more than 2m apart); each cluster
is a candidate at its largest :math:`|D|`; candidates of all scales are taken by decreasing :math:`|D|/\sigma_D`,
one being dropped when it lies within max(m, m') of one already taken. The time of a candidate is refined by the
least-squares single change point (the CUSUM maximiser :math:`\arg\max_k |S_k - (k/L) S_L|/\sqrt{k(L-k)/L}`,
Hinkley 1970 [4]_) over the detecting window (half-width m centred at the candidate, clipped at the neighbouring
candidates and the record's ends: the two means come from all of it), the maximiser searched within half-widths
m, m/4, m/16, ... of the previous estimate, down to :math:`\max(2 f_s,\ 50\,\hat\sigma_1^2/\hat\delta^2)`
samples (:math:`\hat\sigma_1` the per-sample white sd from the first differences: the CUSUM error on white noise
has the sd :math:`\sqrt{26}\,\sigma_1^2/\delta^2` samples, the variance of the argmax of a two-sided Brownian
motion with drift :math:`-|s|/2` being 26). Only the searched range narrows: narrowing the window itself left the
two means resting on a few tens of samples, and the estimate then fell up to 14 samples off the least-squares one
of the whole record on white noise (tests/test_events.py::TestStepLocalisation; slow noise moves the window's
tent-shaped CUSUM by less than the step's slope :math:`\delta/2` per sample wherever the scan detected it). The size is :math:`\hat\delta = D_{m^*}(\hat t_0)` at the scale
:math:`m^*` of smallest :math:`\hat\sigma_D` whose windows fit between the neighbouring events and the record's
ends (chosen from the noise alone, not from D, so there is no selection bias), with the interval
:math:`\hat\delta \pm t_{\nu, 1-(1-c)/2}\,\hat\sigma_D(m^*)` at confidence c. When that interval holds 0
while the detecting scale m saw a shift, the mean moved for less than :math:`m^*` only: the event is a
``transient`` (an excursion), sized at m with m's interval.

Before the step scan, each burst's stretch (:func:`burst_spans`: its span, or its energetic blocks and their tail
where these reach farther, widened by a tenth of a burst window each side) is replaced, its first half by the median
of the samples before it and its second half by that of the samples after it, each over a burst window or half the
stretch, whichever is longer (:func:`_span_fills`; a median, not a mean: a step just before the stretch moves a mean
by its share of those samples, and sized a tilt 1 s before a knock 5 % low): a 17 deg/s knock of 0.1 s moves a 100 s
mean by 0.017 deg/s, and a step inside a knock is then placed at the stretch's middle, its size from the data either
side (the event's ``within_burst_s``: the stretch with the samples its levels are read from, where the step's time
lies). (The stretch was the span alone, its levels medians over a tenth of a window: a 7.3 Hz ringing decaying over
5 s, still 4-5 sds beyond the span, set the two levels apart and was reported as a mean step of 129 deg/h, acting as
a random walk 76x the spec sheet's, in an outside evaluation; some step or transient at the knock in 16 of 16
records at decays 0.5-8 s, now 0 of 16. A straight line between the levels made a step inside the stretch a ramp,
sized 0.83x; medians over one window only held a 16-300 s fill 0.1-0.24 sds off the local mean, a step at its ends
in 6-11 of 50 records, an outside evaluation: over half the stretch, 1 of 30 each. ``docs/performance.md``,
``tests/test_events.py``.)

Total false-alarm rate per record and axis: :math:`\alpha = \alpha_b + \alpha_s`, split equally
(``alpha``, default 0.01: one false event in 100 event-free axes). The step scan's share is a bound (measured
about half of it); the burst scan's rests on the Gaussian approximation of :math:`y_j` (blocks are nearly
independent, so the union bound is nearly exact there) and is nominal: measured 9-10.5 % for a share of 10 %
on 200 simulated records of each of three coloured models, with the Jensen-Solomon power (white, short GM) no
more than 1.2x the Gaussian tail up to z = 4.5. Both assume Gaussian noise: a heavier-tailed sensor (beyond its
quantisation, which the block sums and means absorb) raises the rate.

References
----------
.. [1] D. R. Jensen, H. Solomon, "A Gaussian approximation to the distribution of a definite quadratic form",
       JASA 67 (1972) 898-902 (the power h; h = 1/3 is E. B. Wilson, M. M. Hilferty, PNAS 17 (1931) 684-688).
.. [2] P. J. Rousseeuw, C. Croux, "Alternatives to the median absolute deviation", JASA 88 (1993) 1273-1283.
.. [3] D. W. Allan, "Statistics of atomic frequency standards", Proc. IEEE 54 (1966) 221-230.
.. [4] D. V. Hinkley, "Inference about the change-point in a sequence of random variables", Biometrika 57 (1970)
       1-17.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

__all__ = ["POLICIES", "MAX_EVENT_FLAGS", "detect_events", "event_effect", "event_effects", "find_bursts", "find_steps",
           "event_free_segment", "event_flags", "burst_spans", "fill_bursts", "display_unit", "MAD_EFFICIENCY",
           "BURST_TAIL_Z"]

#: What a found event does (config ``events.policy``; ``split``: imupipe.segments, config/README.md).
POLICIES = ("warn", "exclude", "split")
#: Disjoint window pairs on each side of a step candidate whose |D| give its local scale (module docstring,
#: "Steps": a candidate stands against the larger of the record's scale and its neighbourhood's).
LOCAL_WINDOWS = 100
#: Asymptotic efficiency of the MAD as a scale estimator for Gaussian data (Rousseeuw & Croux 1993).
MAD_EFFICIENCY = 0.37
MAD_TO_SIGMA = 1.482602218505602

#: Display units of event sizes (spec-sheet-like) per sensor: (step unit, SI per unit), (burst unit, SI per unit).
_DISPLAY = {
    "gyro": (("deg/h", math.pi / 180.0 / 3600.0), ("deg/s", math.pi / 180.0)),
    "accel": (("mg", 9.80665e-3), ("g", 9.80665)),
}


def display_unit(sensor: str | None, kind: str) -> tuple[str, float] | None:
    """(unit, SI per unit) in which an event of ``kind`` ('step', 'transient' or 'burst') of ``sensor`` is shown,
    or None."""
    if sensor not in _DISPLAY:
        return None
    return _DISPLAY[sensor][1 if kind == "burst" else 0]


def _t_isf(p: float, nu: float) -> float:
    """Upper p quantile of Student's t with nu degrees of freedom (normal for nu = inf)."""
    from scipy.special import ndtri, stdtrit

    if not math.isfinite(nu):
        return float(-ndtri(p))
    return float(stdtrit(max(nu, 1.0), 1.0 - p))


def _t_sf(z: float, nu: float) -> float:
    """Upper tail P(T > z) of Student's t with nu degrees of freedom (normal for nu = inf): :func:`_t_isf`'s
    inverse."""
    from scipy.special import ndtr, stdtr

    if not math.isfinite(nu):
        return float(ndtr(-z))
    return float(stdtr(max(nu, 1.0), -z))


def _robust_center_scale(y: np.ndarray) -> tuple[float, float]:
    med = float(np.median(y))
    return med, MAD_TO_SIGMA * float(np.median(np.abs(y - med)))


def _white_sd(x: np.ndarray, fills=()) -> float:
    """Per-sample white-noise sd from the first differences: 1.4826 MAD(diff x) / sqrt(2), u, of x with the
    ``fills`` (:func:`_span_fills`) applied. One work array of n - 1 differences, its medians found in
    place."""
    dx = np.diff(x)
    n = x.size
    for a, b, _ in fills:  # the differences that touch a filled span, from the filled values
        lo, hi = max(a - 1, 0), min(b + 1, n)
        if hi - lo >= 2:
            dx[lo:hi - 1] = np.diff(_patched(x, fills, lo, hi))
    dx -= np.median(dx, overwrite_input=True)  # the same order statistics as on a copy: the same value
    np.abs(dx, out=dx)
    return MAD_TO_SIGMA * float(np.median(dx, overwrite_input=True)) / math.sqrt(2.0)


def _patched(x: np.ndarray, fills, lo: int, hi: int) -> np.ndarray:
    """x[lo:hi] with the fills (a, b, values: x[a:b] = values, applied in order) that reach it; a view of x when
    none does, else a copy of the slice."""
    seg = x[lo:hi]
    hit = [(max(a, lo), min(b, hi), v[max(a, lo) - a:min(b, hi) - a]) for a, b, v in fills
           if max(a, lo) < min(b, hi)]
    if hit:
        seg = seg.copy()
        for a, b, v in hit:
            seg[a - lo:b - lo] = v
    return seg


# ---------------------------------------------------------------------------------------------------- bursts
def find_bursts(x, rate_hz: float, *, alpha: float = 0.005, window_s: float = 1.0, burst_k: float = 7.0) -> dict:
    """Bursts of one full-rate axis (module docstring, "Bursts").

    Parameters
    ----------
    x : array_like
        Full-rate series, u.
    rate_hz : float
        Sampling rate f_s, Hz.
    alpha : float
        False-alarm probability of the burst scan per record (any burst on an event-free record).
    window_s : float
        Block length w, s.
    burst_k : float
        Robust sds from the local median that delimit a burst's samples.

    Returns
    -------
    dict
        ``bursts``: list of ``{start, stop}`` (sample indices, stop exclusive), ``block_start``, ``block_stop``
        (those of its energetic blocks: a burst's far samples may lie in part of them), ``tail_start``,
        ``tail_stop`` (those blocks and the adjacent ones above :data:`BURST_TAIL_Z`: a ringing's decay), ``peak``
        (largest :math:`|x - \\mathrm{median}|`, u), ``z`` (largest block z), ``family_p`` (K P(t > z): the scan's
        false-alarm probability with its threshold at this z, Bonferroni over the K blocks); ``threshold_z``,
        ``n_blocks``, ``window`` (samples).
    """
    x = np.asarray(x, dtype=np.float64).ravel()
    n = x.size
    w = max(10, int(round(float(window_s) * float(rate_hz))))
    K = n // w
    if K < 20:
        return {"bursts": [], "threshold_z": float("inf"), "n_blocks": int(K), "window": w,
                "note": f"record of {n} samples holds fewer than 20 blocks of {w}: no burst scan"}
    E = np.empty(K)
    step = max(1, EVENTS_BATCH // w)
    for j0 in range(0, K, step):  # whole blocks at a time: no array of the record's length
        j1 = min(K, j0 + step)
        dev = _centred_blocks(x[j0 * w : j1 * w].reshape(j1 - j0, w))
        E[j0:j1] = np.einsum("ij,ij->i", dev, dev)
    del dev
    zb = _t_isf(alpha / K, MAD_EFFICIENCY * K)
    z, h = _energy_z(E, lambda idx: _centred_blocks(x[idx[:, None] * w + np.arange(w)]), w, zb)
    if z is None:
        return {"bursts": [], "threshold_z": zb, "n_blocks": int(K), "window": w, "power": h,
                "note": "block energies have no spread (constant record): no burst scan"}
    hot = np.flatnonzero(z > zb)
    bursts = []
    if hot.size:
        groups = np.split(hot, np.flatnonzero(np.diff(hot) > 2) + 1)  # blocks no more than one block apart
        xmed = float(np.median(x))
        s1 = _white_sd(x)
        for g in groups:
            b0, b1 = int(g[0]) * w, min(n, (int(g[-1]) + 1) * w)
            j0, j1 = int(g[0]), int(g[-1]) + 1  # the burst's tail: adjacent blocks above BURST_TAIL_Z
            while j0 > 0 and z[j0 - 1] > BURST_TAIL_Z:
                j0 -= 1
            while j1 < K and z[j1] > BURST_TAIL_Z:
                j1 += 1
            lo, hi = max(0, b0 - w), min(n, b1 + w)
            ref = np.concatenate([x[lo:b0], x[b1:hi]])
            c = float(np.median(ref)) if ref.size else xmed
            dev = np.abs(x[b0:b1] - c)
            far = np.flatnonzero(dev > burst_k * s1) if s1 > 0 else np.zeros(0, dtype=np.int64)
            start, stop = (b0 + int(far[0]), b0 + int(far[-1]) + 1) if far.size else (b0, b1)
            zg = float(z[g].max())
            bursts.append({"start": start, "stop": stop, "block_start": b0, "block_stop": b1,
                           "tail_start": j0 * w, "tail_stop": min(n, j1 * w), "peak": float(dev.max()), "center": c,
                           "z": zg, "family_p": min(1.0, K * _t_sf(zg, MAD_EFFICIENCY * K))})
    return {"bursts": bursts, "threshold_z": zb, "n_blocks": int(K), "window": w, "power": h}


#: Robust z above which a block adjacent to a burst's energetic blocks is its tail (:func:`find_bursts`): a knock's
#: ringing decays over seconds below the scan's threshold (a 7.3 Hz ringing of decay time 5 s still held 4-5 sds
#: at the end of its span, an outside evaluation); one robust sd keeps a chance block of a quiet record in about 1 of
#: 6, and a ringing stops there where its mean square falls to about 0.14 sigma^2 (1 s blocks of 100 samples of
#: white noise of per-sample sd sigma: the block energy's relative sd is sqrt(2 / 100)).
BURST_TAIL_Z = 1.0
#: Blocks whose lag products estimate the within-block covariance of the burst scan (evenly spaced).
ACOV_BLOCKS = 2000
#: Samples per pass of the burst scan's block energies (whole blocks, at least one): its work arrays are a few
#: times 8 x this many bytes, whatever the record's length.
EVENTS_BATCH = 1 << 18


def _centred_blocks(blocks: np.ndarray) -> np.ndarray:
    """Each row (a block of w samples) less its mean."""
    return blocks - blocks.mean(axis=1, keepdims=True)


def _energy_z(E: np.ndarray, rows, w: int, zb: float):
    """Robust z of the transformed block energies E^h (module docstring, "Bursts"): (z, h), z None when the
    transformed energies have no spread. h from the within-block covariance of the blocks a first pass (h = 1/3)
    leaves below the threshold zb; ``rows(idx)`` gives those blocks (w samples each) less their means."""
    def zscore(h):
        # increasing in E whatever the sign of h; h -> 0 is the log
        y = np.log(np.maximum(E, 1e-300)) if abs(h) < 0.02 else (E**h if h > 0 else -(np.maximum(E, 1e-300) ** h))
        med, sc = _robust_center_scale(y)
        return ((y - med) / sc, h) if sc > 0 else (None, h)

    z, h = zscore(1.0 / 3.0)
    if z is None:
        return z, h
    quiet = np.flatnonzero(z <= zb)
    pick = quiet[np.linspace(0, quiet.size - 1, min(quiet.size, ACOV_BLOCKS)).astype(int)] if quiet.size else None
    if pick is None:
        return z, h
    F = np.fft.rfft(rows(pick), n=2 * w, axis=1)
    lag = np.fft.irfft(np.abs(F) ** 2, n=2 * w, axis=1)[:, :w].mean(axis=0) / (w - np.arange(w))
    from scipy.linalg import toeplitz

    lam = np.clip(np.linalg.eigvalsh(toeplitz(lag)), 0.0, None)
    t1, t2, t3 = (float(np.sum(lam**r)) for r in (1, 2, 3))
    if t2 <= 0:
        return z, h
    h = min(1.0, 1.0 - 2.0 * t1 * t3 / (3.0 * t2 * t2))
    return zscore(h)


# ----------------------------------------------------------------------------------------------------- steps
def _d_at(cs: np.ndarray, t, m: int):
    """D_m(t) from the cumulative sum cs (cs[0] = 0, cs[i] = sum x[:i])."""
    return (cs[t + m] - 2.0 * cs[t] + cs[t - m]) / m


def _abs_d_grid(cs: np.ndarray, m: int, h: int, K: int) -> np.ndarray:
    """|D_m(t)| at the K positions t = m + j h (:func:`_d_at`'s operations in its order on strided views of
    cs: the same values, one array of K elements and no index arrays)."""
    d = 2.0 * cs[m : m + (K - 1) * h + 1 : h]
    np.subtract(cs[2 * m : 2 * m + (K - 1) * h + 1 : h], d, out=d)
    d += cs[0 : (K - 1) * h + 1 : h]
    d /= m
    return np.abs(d, out=d)


def _cusum_argmax(seg: np.ndarray, lo: int = 1, hi: int | None = None) -> int:
    """Least-squares single change point of a segment: k in [max(lo, 1), min(hi, L-1)] (the first k samples before
    the change); the whole segment's samples estimate the two means whatever the searched range."""
    L = seg.size
    s = np.cumsum(seg - seg.mean())[:-1]
    k = np.arange(1, L)
    stat = np.abs(s) / np.sqrt(k * (L - k) / L)
    lo = max(int(lo), 1)
    hi = L - 1 if hi is None else min(int(hi), L - 1)
    return int(np.argmax(stat[lo - 1:hi])) + lo


def _scales(n: int, rate_hz: float, min_scale_s: float, min_windows: int) -> list[int]:
    m0 = max(2, int(round(float(min_scale_s) * float(rate_hz))))
    out = []
    m = m0
    while (n - 2 * m) // (2 * m) >= min_windows:
        out.append(m)
        m *= 2
    return out


def _fill_extents(spans, n: int, pad: int, ref: int | None = None) -> list:
    """Where :func:`_span_fills` replaces each span of an `n`-sample record and what it reads: [(a, b, lo, hi), ...],
    the span widened by `pad` samples each side, [a, b) of L samples, and the samples its levels are read from,
    [lo, a) and [b, hi), each max(`ref`, L / 2) long (`ref` = `pad` when None; clipped to the record)."""
    ref = pad if ref is None else int(ref)
    out = []
    for s0, s1 in spans:
        a, b = max(0, s0 - pad), min(n, s1 + pad)
        r = max(ref, (b - a) // 2)  # a level held over L samples is read over at least L / 2 beside it
        out.append((a, b, max(0, a - r), min(n, b + r)))
    return out


def _span_fills(x: np.ndarray, spans, pad: int, ref: int | None = None, ramp: bool = True) -> list:
    """Each span [start - pad, stop + pad) of L samples replaced from the median of the max(`ref`, L / 2) samples
    before it (`ref` = `pad` when None) and that of those after it (a level held over L samples, read over fewer,
    is off the local mean by more than a step of its length may be): with `ramp` the straight line from the first
    to the second (the line search: no jump), else its first half at the first and its second half at the second (the
    step scan: a step inside a burst is placed at the span's middle, its size the levels' difference). The list of
    (a, b, values), x[a:b] = values applied in order; the step scan reads x through it (:func:`find_steps`,
    ``fills``) instead of a cleaned copy of the record."""
    fills = []
    whole = None
    for a, b, lo, hi in _fill_extents(spans, x.size, pad, ref):
        before, after = x[lo:a], x[b:hi]
        if not before.size and not after.size and whole is None:
            whole = float(np.median(x))
        first = np.median(before) if before.size else (np.median(after) if after.size else whole)
        second = np.median(after) if after.size else (np.median(before) if before.size else whole)
        if ramp:
            fills.append((a, b, np.linspace(first, second, b - a)))
        else:
            mid = (a + b) // 2
            fills += [(a, mid, np.full(mid - a, first)), (mid, b, np.full(b - mid, second))]
    return fills


def find_steps(x, rate_hz: float, *, alpha: float = 0.005, min_scale_s: float = 1.0, min_windows: int = 50,
               confidence: float = 0.95, max_steps: int = 20, fills=()) -> dict:
    """Mean steps of one full-rate axis (module docstring, "Steps").

    Parameters
    ----------
    x : array_like
        Full-rate series, u (bursts already cleaned: :func:`detect_events` does it).
    rate_hz : float
        Sampling rate f_s, Hz.
    alpha : float
        False-alarm probability of the step scan per record (any step on an event-free record).
    min_scale_s : float
        Shortest window tau, s.
    min_windows : int
        Disjoint window pairs the longest scale keeps in the record (its sigma_D estimate's size).
    confidence : float
        Level of the size intervals.
    max_steps : int
        Most steps reported (the strongest).
    fills : sequence of (int, int, array)
        Spans replaced before the scan, (a, b, values of length b - a): the series scanned is x with
        ``x[a:b] = values`` (applied in order) without a copy of x (:func:`detect_events` cleans the bursts
        so: :func:`_span_fills`).

    Returns
    -------
    dict
        ``steps``: list of ``{index, stop, kind, size, size_low, size_high, sigma_d, z, scale, size_scale,
        family_p}`` (index: the first sample after the step; stop: a transient's end at the latest, else the index;
        kind ``step`` or ``transient``; size and interval u; sigma_D at the size scale, u; z = |D|/sigma_D at the
        detecting scale; scales in samples; family_p: the smallest 2 S K_m P(t_nu_m > z'_m) over the scales m that
        detect the step, z' = z over the local scale where that exceeds 1 (the detection's test): the scan's
        false-alarm probability with its thresholds at the step's strongest detection, as the thresholds' own rule);
        ``scales``: per scale ``{m, sigma_d, threshold_z, positions, nu}``.
    """
    x = np.asarray(x, dtype=np.float64).ravel()
    n = x.size
    rate_hz = float(rate_hz)
    scales = _scales(n, rate_hz, min_scale_s, min_windows)
    if not scales:
        return {"steps": [], "scales": [], "note": f"record of {n} samples too short for a step scan"}
    fills = list(fills)
    # per-sample white sd from the first differences (robust); before the cumulative sum, so that the record
    # and one work array of its length are all the scan ever holds
    s1 = _white_sd(x, fills)
    cs = np.zeros(n + 1)  # cs[i] = sum of the first i samples less the median (no other sample-length array)

    def fill_cs():
        cs[1:] = x
        for a, b, v in fills:
            cs[1 + a : 1 + b] = v

    fill_cs()
    med = np.median(cs[1:], overwrite_input=True)  # the median of the (filled) record, found in place
    fill_cs()
    cs[1:] -= med
    np.cumsum(cs[1:], out=cs[1:])
    S = len(scales)
    table, cands = [], []
    for m in scales:
        h = max(1, m // 4)
        K = len(range(m, n - m + 1, h))  # positions t = m + j h
        sd = MAD_TO_SIGMA * float(np.median(_abs_d_grid(cs, m, h, K), overwrite_input=True))
        nu = MAD_EFFICIENCY * (n - 2 * m) / (2 * m)
        zt = _t_isf(alpha / (2.0 * S * K), nu)
        table.append({"m": m, "sigma_d": sd, "threshold_z": zt, "positions": int(K), "nu": nu})
        if sd <= 0:
            continue
        z = _abs_d_grid(cs, m, h, K)  # again: one array of the K positions at a time (its median reorders it)
        z /= sd
        hit = np.flatnonzero(z > zt)
        if hit.size:
            reach = LOCAL_WINDOWS * 2 * m // h  # grid positions on each side of the local scale's span
            for g in np.split(hit, np.flatnonzero(np.diff(hit) > 8) + 1):  # 8 grid steps = 2m
                j = int(g[np.argmax(z[g])])
                # the local scale over the record's: MAD_TO_SIGMA x the median of z = |D| / sd nearby
                local = MAD_TO_SIGMA * float(np.median(z[max(0, j - reach) : j + reach + 1]))
                z_test = float(z[j] / max(1.0, local))
                if z_test > zt:  # with the scan's false-alarm probability at the test's z
                    cands.append((float(z[j]), m + j * h, m, 2.0 * S * K * _t_sf(z_test, nu)))
        del z
    cands.sort(key=lambda c: -c[0])
    taken = []
    for zc, tc, m, pc in cands:
        near = [c for c in taken if abs(tc - c[1]) < max(m, c[2])]
        if not near and len(taken) < max_steps:
            taken.append([zc, tc, m, pc])
        for c in near:  # the same step at another scale: its probability the smallest of its detections
            c[3] = min(c[3], pc)
    sd_of = {row["m"]: row for row in table}
    steps = []
    times = sorted(tc for _, tc, _, _ in taken)
    for zc, tc, m, pc in taken:
        t0 = tc
        delta = _d_at(cs, t0, m)
        half = m
        floor = max(2 * int(rate_hz), int(50.0 * s1**2 / max(delta**2, 1e-300)), 8)
        # the means either side come from the whole detecting window (clipped at the neighbouring candidates):
        # narrowing the window itself, not only the searched range, left ~20 samples a side to estimate them, and
        # the change point's error then had 10x the tail of the least-squares one (docs/performance.md)
        prev_c = max([u for u in times if u < tc], default=0)
        next_c = min([u for u in times if u > tc], default=n)
        while True:
            a, b = max(prev_c, t0 - m, 0), min(next_c, t0 + m, n)
            if b - a >= 4:
                t0 = a + _cusum_argmax(_patched(x, fills, a, b), t0 - half - a, t0 + half - a)
            if half <= floor:
                break
            half = max(floor, half // 4)
        # size scale: the smallest sigma_D whose windows fit between the neighbours and the record's ends
        prev = max([u for u in times if u < tc], default=0)
        nxt = min([u for u in times if u > tc], default=n)
        room = min(t0 - prev, nxt - t0)
        fits = [r for r in table if r["m"] <= room and r["sigma_d"] > 0]
        row = min(fits, key=lambda r: r["sigma_d"]) if fits else sd_of[m]
        ms = row["m"] if fits else min(m, max(1, room))
        size = float(_d_at(cs, t0, ms)) if ms >= 1 and t0 - ms >= 0 and t0 + ms <= n else float(delta)
        q = _t_isf((1.0 - confidence) / 2.0, row["nu"])
        kind, stop = "step", t0
        if abs(size) <= q * row["sigma_d"] and ms != m and t0 - m >= 0 and t0 + m <= n:
            # not a lasting shift: the mean moved over the detecting window only (an excursion shorter than the
            # size window); sized at the detecting scale
            kind, row, stop, ms = "transient", sd_of[m], min(n, t0 + m), m  # its span: the scale it is sized at
            size = float(_d_at(cs, t0, m))
            q = _t_isf((1.0 - confidence) / 2.0, row["nu"])
        steps.append({"index": int(t0), "size": size, "size_low": size - q * row["sigma_d"],
                      "size_high": size + q * row["sigma_d"], "sigma_d": float(row["sigma_d"]), "z": zc,
                      "scale": int(m), "size_scale": int(ms), "kind": kind, "stop": int(stop),
                      "family_p": min(1.0, pc)})
    steps.sort(key=lambda s: s["index"])
    return {"steps": steps, "scales": table}


# ---------------------------------------------------------------------------------------------------- events
def detect_events(x, rate_hz: float, *, alpha: float = 0.01, burst_window_s: float = 1.0, burst_k: float = 7.0,
                  min_scale_s: float = 1.0, min_windows: int = 50, confidence: float = 0.95,
                  sensor: str | None = None) -> dict:
    """Bursts and steps of one full-rate axis, each with a derived threshold (module docstring).

    Parameters
    ----------
    x : array_like
        Full-rate series, u (SI in the workflow: rad/s, m/s^2).
    rate_hz : float
        Sampling rate, Hz.
    alpha : float
        False-alarm probability per record and axis (any event on an event-free record), split equally between
        the burst and the step scans.
    burst_window_s, burst_k : float
        Block length of the burst scan (s) and the robust sds that delimit a burst's samples.
    min_scale_s, min_windows, confidence
        Step scan settings (:func:`find_steps`).
    sensor : {'gyro', 'accel'}, optional
        Gives each event its size in the display unit (deg/h and deg/s, mg and g).

    Returns
    -------
    dict
        ``events``: list sorted by time of ``{kind, time_s, start_s, stop_s, index, size, size_low, size_high,
        z, ...}`` (kind ``burst``, ``step`` or ``transient``: a mean excursion ended by ``stop_s``; times s
        from the record's start, sizes u: a step's mean shift after - before with its interval at
        ``confidence``, a burst's peak deviation from the local median) and ``display`` (the size in the
        display unit), ``p_value`` (twice its scan's ``family_p``: the false-alarm rate per record that both scans
        would have with their thresholds at this event's z, alpha split between them as here, so the event exceeds
        the scan's level alpha exactly where p_value < alpha); ``false_alarm_rate`` (per record), ``burst_scan``,
        ``step_scan`` (thresholds per scale).
    """
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"events alpha must be in (0, 1), got {alpha!r}")
    x = np.asarray(x, dtype=np.float64).ravel()
    rate_hz = float(rate_hz)
    b = find_bursts(x, rate_hz, alpha=alpha / 2.0, window_s=burst_window_s, burst_k=burst_k)
    spans, pad = burst_spans(b), max(5, b["window"] // 10)
    fills = _span_fills(x, spans, pad, b["window"], ramp=False)
    filled = _fill_extents(spans, x.size, pad, b["window"])  # a step seen through a fill lies in its [lo, hi)
    s = find_steps(x, rate_hz, alpha=alpha / 2.0, min_scale_s=min_scale_s, min_windows=min_windows,
                   confidence=confidence, fills=fills)
    events = []
    for e in b["bursts"]:
        events.append({"kind": "burst", "time_s": e["start"] / rate_hz, "start_s": e["start"] / rate_hz,
                       "stop_s": e["stop"] / rate_hz, "index": int(e["start"]), "stop_index": int(e["stop"]),
                       "size": e["peak"], "z": e["z"], "threshold_z": b["threshold_z"],
                       "p_value": min(1.0, 2.0 * e["family_p"])})
    thr = {r["m"]: r["threshold_z"] for r in s["scales"]}
    for e in s["steps"]:
        events.append({"kind": e["kind"], "time_s": e["index"] / rate_hz, "start_s": e["index"] / rate_hz,
                       "stop_s": e["stop"] / rate_hz, "index": int(e["index"]), "stop_index": int(e["stop"]),
                       "size": e["size"], "size_low": e["size_low"], "size_high": e["size_high"],
                       "confidence": float(confidence), "z": e["z"], "threshold_z": thr[e["scale"]],
                       "scale_s": e["scale"] / rate_hz, "size_scale_s": e["size_scale"] / rate_hz,
                       "p_value": min(1.0, 2.0 * e["family_p"])})
        inside = [(lo, hi) for a, c, lo, hi in filled if a <= e["index"] < c]  # a step seen through a burst's fill
        if inside:
            events[-1]["within_burst_s"] = [inside[0][0] / rate_hz, inside[0][1] / rate_hz]
    events.sort(key=lambda e: (e["index"], e["kind"]))
    for e in events:
        du = display_unit(sensor, e["kind"])
        if du is not None:
            unit, f = du
            e["display"] = {"unit": unit, "size": e["size"] / f}
            if "size_low" in e:
                e["display"].update(size_low=e["size_low"] / f, size_high=e["size_high"] / f)
    return {
        "events": events,
        "false_alarm_rate": float(alpha),
        "burst_scan": {"window_s": b["window"] / rate_hz, "blocks": b["n_blocks"], "threshold_z": b["threshold_z"],
                       "alpha": alpha / 2.0, **({"note": b["note"]} if "note" in b else {})},
        "step_scan": {"alpha": alpha / 2.0, "scales": [
            {"tau_s": r["m"] / rate_hz, "sigma_d": r["sigma_d"], "threshold_z": r["threshold_z"],
             "positions": r["positions"]} for r in s["scales"]], **({"note": s["note"]} if "note" in s else {}),
            **_smallest_step(s["scales"], rate_hz, sensor)},
    }


def _smallest_step(scales, rate_hz: float, sensor: str | None) -> dict:
    """``smallest_step`` (u): the least mean step the step scan can report, min over its scales of threshold_z x
    sigma_D (a step of that size at a window's centre reaches the threshold), with its scale ``smallest_step_tau_s``
    (s) and display; {} without a scale of positive sigma_D."""
    rows = [r for r in scales if r["sigma_d"] > 0 and math.isfinite(r["threshold_z"])]
    if not rows:
        return {}
    r = min(rows, key=lambda r: r["threshold_z"] * r["sigma_d"])
    out = {"smallest_step": float(r["threshold_z"] * r["sigma_d"]), "smallest_step_tau_s": r["m"] / rate_hz}
    du = display_unit(sensor, "step")
    if du is not None:
        out["smallest_step_display"] = {"unit": du[0], "size": out["smallest_step"] / du[1]}
    return out


def event_free_segment(n: int, events, guard: int = 0) -> tuple[int, int]:
    """The longest span [i0, i1) of an n-sample record free of events (bursts' spans and steps' points, each
    widened by ``guard`` samples on both sides); (0, n) without events."""
    cuts = sorted((max(0, int(e["index"]) - guard), min(n, int(e.get("stop_index", e["index"])) + guard))
                  for e in events)
    best, pos = (0, 0), 0
    for a, b in cuts:
        if a - pos > best[1] - best[0]:
            best = (pos, a)
        pos = max(pos, b)
    if n - pos > best[1] - best[0]:
        best = (pos, n)
    return best


def burst_spans(scan: Mapping) -> list:
    """The stretch of each burst of a :func:`find_bursts` result that the step scan and the line search read filled,
    [(start, stop), ...] (samples, stop exclusive): its span, or its energetic blocks and their tail where these reach
    farther (a ringing decays below the scan's threshold over seconds: :data:`BURST_TAIL_Z`)."""
    return [(min(e["start"], e["tail_start"]), max(e["stop"], e["tail_stop"])) for e in scan["bursts"]]


def fill_bursts(x, rate_hz: float, *, alpha: float = 0.01, burst_window_s: float = 1.0,
                burst_k: float = 7.0) -> tuple[np.ndarray, tuple]:
    """`x` (u at `rate_hz` Hz) with the span of every burst :func:`detect_events` reports with these settings
    filled (its burst scan, :func:`find_bursts` at its share alpha / 2), and the filled stretches as
    ((start_s, stop_s), ...) (s from the record's start).

    Each burst's span, or its energetic blocks and its tail where they reach farther (a 20 s vibration of 5 sds has
    its samples beyond burst_k sds over about 12 s of them; a ringing decays below the scan's threshold over seconds:
    :data:`BURST_TAIL_Z`), is widened by one burst window on both sides (the cut of events.policy split and exclude)
    and replaced by the straight line from the median of the samples before it to that of the samples after it, each
    over a window or half the stretch (:func:`_span_fills`; the step scan reads a burst in two flat halves). What
    reads it: the line search under events.policy warn (:func:`imupipe.stages.outliers.line_search_series`), where a
    knock's ringing (4.7, 12.3 and 31 Hz decaying over 0.5 s) was found as three lines of a 2 h record and exported
    as filter states. A filled stretch of s seconds takes s / L of a segment of length L's noise, and as much of a
    line's coherent power there. A copy of x where a burst is filled, x itself (as a float64 array, no copy) where
    none is."""
    x = np.asarray(x, dtype=np.float64).ravel()
    rate_hz = float(rate_hz)
    b = find_bursts(x, rate_hz, alpha=alpha / 2.0, window_s=burst_window_s, burst_k=burst_k)
    if not b["bursts"]:
        return x, ()
    w = int(b["window"])
    spans = burst_spans(b)
    out = x.copy()
    for a, c, v in _span_fills(x, spans, w):
        out[a:c] = v
    merged: list = []
    for a, c, _, _ in _fill_extents(spans, x.size, w):
        if merged and a <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], c))
        else:
            merged.append((a, c))
    return out, tuple((a / rate_hz, c / rate_hz) for a, c in merged)


def _sum_sq_diff(x, a: int, b: int) -> float:
    """sum_{k=a}^{b-1} (x[k+1] - x[k])^2 (u^2), in batches of :data:`EVENTS_BATCH` pairs: no record-length array."""
    total = 0.0
    for lo in range(a, b, EVENTS_BATCH):
        hi = min(b, lo + EVENTS_BATCH)
        d = np.diff(x[lo:hi + 1])
        total += float(np.dot(d, d))
    return total


def event_effect(x, rate_hz: float, event: Mapping, guard: int = 0, sensor: str | None = None,
                 total_sq_diff: float | None = None) -> dict:
    r"""What one event kept in the data (``events.policy: warn``) does to the noise model's parameters.

    - A burst: the Allan variance at the shortest tau :math:`\tau_0 = 1/f_s`, where the white noise N is read
      (:math:`\sigma^2(\tau_0) = N^2/\tau_0` for white noise), with and without the burst's samples:
      :math:`\sigma^2(\tau_0) = \tfrac12\,\overline{(x_{k+1}-x_k)^2}`, the mean over every pair of adjacent
      samples, or over the pairs outside the burst's span widened by `guard` samples. ``white_noise_ratio`` =
      :math:`\sqrt{\sigma^2_{with}/\sigma^2_{without}}`: the factor by which the burst raises N read there
      (measured on the record, 1 for a burst that adds no energy).
    - A step of size d (u) in a record of duration :math:`T = n/f_s` (s): each overlapping Allan difference at
      :math:`\tau = m/f_s` that straddles the step carries d times a triangle of half-width m and peak 1 (sum of
      squares :math:`2m/3`), so over the :math:`n - 2m + 1` differences the step adds
      :math:`d^2 m / (3(n-2m+1)) \approx d^2\tau/(3T)` (:math:`\tau \ll T`) to the Allan variance: the random
      walk's :math:`K^2\tau/3` with ``random_walk_equivalent`` :math:`K = |d|/\sqrt{T}` (u/sqrt(s)). A
      transient (a step and its return) adds twice that for :math:`\tau` below its duration:
      :math:`K = |d|\sqrt{2/T}`.

    Returns a dict with ``kind`` and either ``white_noise_ratio`` (1) or ``random_walk_equivalent`` (u/sqrt(s)),
    ``record_s`` (s) and, with `sensor`, ``display`` (the value in (deg/h)/sqrt(s) or mg/sqrt(s)).
    `total_sq_diff`: the record's :math:`\sum_k (x_{k+1}-x_k)^2` (u^2) when the caller has it (one pass for
    every burst of a record: :func:`event_effects`); computed here otherwise.
    Reference: IEEE Std 952-1997, annex C (the Allan variance of white noise and of a random walk)."""
    x = np.asarray(x, dtype=np.float64).ravel()
    n, rate_hz = x.size, float(rate_hz)
    kind = event.get("kind")
    if kind == "burst":
        i0 = max(0, int(event["index"]) - int(guard))
        i1 = min(n, int(event.get("stop_index", event["index"])) + int(guard))
        # pair k = (x_k, x_k+1) touches the span when i0 - 1 <= k < i1; sums in batches (no record-length copy)
        a, b = max(0, i0 - 1), min(max(0, i1), n - 1)
        n_kept = (n - 1) - max(0, b - a)
        if n < 2 or n_kept <= 0:
            return {"kind": kind}
        total = _sum_sq_diff(x, 0, n - 1) if total_sq_diff is None else float(total_sq_diff)
        span = _sum_sq_diff(x, a, b)
        rest = max(total - span, 0.0)
        ratio = float(np.sqrt((total / (n - 1)) / (rest / n_kept))) if rest > 0 else float("inf")
        return {"kind": kind, "white_noise_ratio": ratio, "tau_s": 1.0 / rate_hz}
    T = n / rate_hz
    k = abs(float(event["size"])) * (np.sqrt(2.0 / T) if kind == "transient" else 1.0 / np.sqrt(T))
    out = {"kind": kind, "random_walk_equivalent": float(k), "record_s": float(T)}
    du = display_unit(sensor, "step")
    if du is not None:
        unit = f"({du[0]})/sqrt(s)" if "/" in du[0] else f"{du[0]}/sqrt(s)"  # (deg/h)/sqrt(s), as spec sheets write it
        out["display"] = {"unit": unit, "random_walk_equivalent": float(k) / du[1]}
    return out


def event_effects(x, rate_hz: float, events, guard: int = 0, sensor: str | None = None) -> list:
    """:func:`event_effect` of each of `events` on the record `x`, the record's sum of squared differences
    computed once for all its bursts."""
    x = np.asarray(x, dtype=np.float64).ravel()
    total = _sum_sq_diff(x, 0, x.size - 1) if any(e.get("kind") == "burst" for e in events) else None
    return [event_effect(x, rate_hz, e, guard=guard, sensor=sensor, total_sq_diff=total) for e in events]


def _effect_text(it: Mapping) -> str:
    """The words of an event's effect on the model (:func:`event_effect`, kept under ``warn``)."""
    eff = it.get("effect") if isinstance(it.get("effect"), Mapping) else None
    if not eff:
        return ""
    if eff.get("white_noise_ratio") is not None:
        return (f": with its samples the Allan deviation at the shortest tau ({float(eff['tau_s']):.3g} s, where the "
                f"white noise N is read) is {float(eff['white_noise_ratio']):.3g}x the record's without them, and it "
                "raises every PSD bin: it can inflate N and the bound")
    if eff.get("random_walk_equivalent") is not None:
        disp = eff.get("display") if isinstance(eff.get("display"), Mapping) else None
        k = f"{float(eff['random_walk_equivalent']):.3g} {it.get('units') or 'SI'}/sqrt(s)"
        if disp:
            k += f" ({float(disp['random_walk_equivalent']):.3g} {disp['unit']})"
        return (f": in the Allan variance a {'step' if eff['kind'] == 'step' else 'mean excursion'} in this "
                f"{float(eff['record_s']):.4g} s record acts as a random walk K = {k} (d^2 tau / (3 T)): it can "
                "inflate K (or a long-T GM or a ramp that takes up the rise) and the bound")
    return ""


def _effect_short(it: Mapping) -> str:
    """The first screen's form of :func:`_effect_text`: the number the event can inflate (N's factor at the shortest
    tau, the random walk K a step acts as, in the display unit where there is one)."""
    eff = it.get("effect") if isinstance(it.get("effect"), Mapping) else None
    if not eff:
        return ""
    if eff.get("white_noise_ratio") is not None:
        return f": its samples raise N {float(eff['white_noise_ratio']):.3g}x at the shortest tau"
    if eff.get("random_walk_equivalent") is not None:
        disp = eff.get("display") if isinstance(eff.get("display"), Mapping) else None
        k = (f"{float(disp['random_walk_equivalent']):.3g} {disp['unit']}" if disp else
             f"{float(eff['random_walk_equivalent']):.3g} {it.get('units') or 'SI'}/sqrt(s)")
        return f": acts as a random walk K = {k}, which can inflate the bound"
    return ""


#: more events than this on one record and sensor are summarised in one FLAG line (each stays in the report)
MAX_EVENT_FLAGS = 3


def _event_text(it: Mapping, short: bool = False) -> str:
    """The FLAG text of one event (kind, size in SI with its interval and display unit, time from the start, the
    policy's action and its effect on the model); `short`: the effect as its number only (the summary's first
    screen: :func:`_effect_short`)."""
    unit = it.get("units") or "SI"
    disp = it.get("display") if isinstance(it.get("display"), Mapping) else None

    def fmt(v):
        return f"{float(v):.3g}"

    if it.get("kind") in ("step", "transient"):
        size = f"{'mean step' if it['kind'] == 'step' else 'mean excursion'} {fmt(it['size'])} {unit}"
        if it.get("size_low") is not None:
            size += f" [{fmt(it['size_low'])}, {fmt(it['size_high'])}]"
        if disp:
            size += f" ({fmt(disp['size'])} {disp['unit']})"
        when = f"at {float(it['time_s']):.1f} s"
        if it["kind"] == "transient" and it.get("stop_s") is not None:
            when += f" (back by {float(it['stop_s']):.1f} s)"
        if isinstance(it.get("within_burst_s"), (list, tuple)) and len(it["within_burst_s"]) == 2:
            a, c = (float(v) for v in it["within_burst_s"])
            when = f"between {a:.1f} and {c:.1f} s (at a burst the scan reads filled)"
    else:
        size = f"burst, peak {fmt(it['size'])} {unit}" + (f" ({fmt(disp['size'])} {disp['unit']})" if disp else "")
        when = f"from {float(it['start_s']):.2f} s to {float(it['stop_s']):.2f} s"
    text = f"{size} {when} from the record's start"
    if it.get("action"):
        text += f"; {it['action']}" + (_effect_short(it) if short else _effect_text(it))
    return text


def _group_text(group: list, short: bool = False) -> str:
    """One FLAG text for many events of one record and sensor: counts per axis and kind, the largest step."""
    axes = sorted({str(it.get("axis", "-")) for it in group})
    per_axis = ", ".join(f"{sum(str(it.get('axis', '-')) == a for it in group)} on {a}" for a in axes)
    kinds = {"step": "mean steps", "transient": "mean excursions", "burst": "bursts"}
    counts = ", ".join(f"{n} {kinds.get(k, k)}" for k in kinds
                       if (n := sum(it.get("kind") == k for it in group)))
    steps = [it for it in group if it.get("kind") in ("step", "transient")]
    largest = max(steps or group, key=lambda it: abs(float((it.get("display") or it).get("size", 0.0))))
    return (f"{len(group)} events ({per_axis}; {counts}); the largest, on axis {largest.get('axis', '-')}: "
            f"{_event_text(largest, short)}" + ("" if short else "; each is listed in the outliers report of its axis"))


def event_flags(items, short: bool = False) -> list[tuple[str, str]]:
    """(where, text) of the summary FLAGs of the events of outliers reports (``events``: dicts with ``dataset``,
    ``sensor``, ``axis``, ``kind``, ``time_s``, ``size`` and ``units``, ``display``, ``policy``, ``action``): one
    FLAG per event, or one per record and sensor where that record has more than :data:`MAX_EVENT_FLAGS`. `short`:
    each text with the event's effect on the model as its number only (the summary's first screen), in the same
    order."""
    groups: dict = {}
    for it in items or []:
        if isinstance(it, Mapping):
            groups.setdefault((it.get("dataset"), it.get("sensor")), []).append(it)
    out = []
    for (dataset, sensor), group in groups.items():
        if len(group) > MAX_EVENT_FLAGS:
            where = "/".join(str(v) for v in (dataset, sensor) if v is not None) or "-"
            out.append((where, _group_text(group, short)))
            continue
        for it in group:
            where = "/".join(str(it[k]) for k in ("dataset", "sensor", "axis") if it.get(k) is not None) or "-"
            out.append((where, _event_text(it, short)))
    return out
