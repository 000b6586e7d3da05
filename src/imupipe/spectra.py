r"""Decimation and power spectral densities of static IMU records.

One convention throughout (``docs/architecture.md``): every spectrum returned here is the
**two-sided** density :math:`S_2` (u^2/Hz, integrated over :math:`-\infty..\infty`), listed for
:math:`f \ge 0`, with the attribute ``sidedness = "two-sided"``; the one-sided density is
:math:`S_1 = 2 S_2` and is returned only on request (``onesided=True``). Parseval then reads

.. math::

    \operatorname{var}(x) = 2 \int_0^{f_s/2} S_2(f)\, df .

The Welch average is implemented on :func:`numpy.fft.rfft` (importing :mod:`scipy.signal` costs
about 1.4 s per workflow job); the tests check it against :func:`scipy.signal.welch` to 1e-12.
Only the confidence limits need :mod:`scipy.special` (imported when called, ~0.2 s) and only
:func:`psd` needs :mod:`xarray` (imported when called; the workflow writes :func:`_psd` with netCDF4).

Public names
------------
decimate            block averaging to a lower, integer-related rate
psd                 Welch PSD with chi-squared confidence limits (xarray.Dataset)
get_taper           periodic taper by name (hann, hamming, blackman, boxcar)
welch_edf           equivalent degrees of freedom of a Welch average
smooth_log_bands    band averaging on a log frequency grid, with the bands' degrees of freedom
chi2_upper          upper chi-squared confidence limit with a multiplicity correction
chi2_sf             chi-squared survival function for integer degrees of freedom (closed form, no scipy)

References
----------
.. [1] P. D. Welch, "The use of fast Fourier transform for the estimation of power spectra: a method
       based on time averaging over short, modified periodograms", IEEE Trans. Audio Electroacoust.
       15(2), 70-73, 1967.
.. [2] J. S. Bendat and A. G. Piersol, "Random Data: Analysis and Measurement Procedures", 4th ed.,
       Wiley, 2010, sections 8.5 and 11.5.
.. [3] D. B. Percival and A. T. Walden, "Spectral Analysis for Physical Applications", Cambridge
       University Press, 1993, section 6.17 (eq. 292b: degrees of freedom of the overlapped Welch average).
.. [4] W. J. Riley, "Handbook of Frequency Stability Analysis", NIST SP 1065, 2008, section 6.
.. [5] D. Gallon, M. Joerger, B. Pervan, "Development of Stochastic IMU Error Models for INS/GNSS
       Integration", ION GNSS+ 2021 (7 h windows, 10 h step, 1 Hz block-averaged data).
"""

from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import numpy as np

__all__ = [
    "LogBands",
    "TAPERS",
    "band_edf_factor",
    "bin_correlation",
    "chi2_lower",
    "chi2_sf",
    "chi2_upper",
    "log_band_index",
    "decimate",
    "get_taper",
    "psd",
    "psd_labelled",
    "smooth_log_bands",
    "welch_edf",
]

#: Cosine-sum coefficients a_k of the periodic tapers, w[n] = sum_k (-1)^k a_k cos(2 pi k n / N).
TAPERS: dict[str, tuple[float, ...]] = {
    "boxcar": (1.0,),
    "hann": (0.5, 0.5),
    "hamming": (0.54, 0.46),
    "blackman": (0.42, 0.5, 0.08),
}

# Segments are processed in batches of about this many samples (bounded memory on 125 Hz records).
_BATCH_SAMPLES = 1 << 22


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------
def _as_finite_1d(x, name: str = "x") -> np.ndarray:
    """float64 copy/view of a 1-D finite array; ValueError otherwise."""
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional, got shape {a.shape}")
    finite = np.isfinite(a)
    if not finite.all():
        bad = np.flatnonzero(~finite)
        raise ValueError(
            f"{name} contains {bad.size} non-finite value(s) (NaN or inf), first at index {bad[0]}; "
            "remove or interpolate them before spectral analysis"
        )
    return a


def _check_rate(rate, name: str = "rate") -> float:
    r = float(rate)
    if not (math.isfinite(r) and r > 0):
        raise ValueError(f"{name} must be a positive finite frequency in Hz, got {rate!r}")
    return r


def _on_unique(func, prob, nu):
    """func(prob, nu) evaluated once per distinct nu (a PSD has 1-3 distinct edf over 1e6 bins)."""
    nu = np.asarray(nu, dtype=np.float64)
    values, inverse = np.unique(nu, return_inverse=True)
    return func(prob, values)[inverse].reshape(nu.shape)


def _chi2_ppf(q, nu):
    """Lower-tail quantile of chi-squared with nu degrees of freedom: 2 * P^{-1}(nu/2, q)."""
    from scipy.special import gammaincinv

    return _on_unique(lambda q_, v: 2.0 * gammaincinv(v / 2.0, q_), q, nu)


def _chi2_isf(p, nu):
    """Upper-tail quantile of chi-squared: 2 * Q^{-1}(nu/2, p) (accurate for small p)."""
    from scipy.special import gammainccinv

    return _on_unique(lambda p_, v: 2.0 * gammainccinv(v / 2.0, p_), p, nu)


def chi2_sf(dof: int, x: float) -> float:
    r"""Survival function :math:`P(\chi^2_k > x) = Q(k/2, x/2)` of chi-squared with an integer number `dof` = k
    >= 1 of degrees of freedom, by its closed form (Abramowitz & Stegun 26.4.4 and 26.4.5), so that a job
    needing only this does not import :mod:`scipy.special` (about 0.5 s of CPU per job):

    .. math::

        Q = e^{-x/2} \sum_{j=0}^{k/2-1} \frac{(x/2)^j}{j!} \ (k \text{ even}), \qquad
        Q = \operatorname{erfc}\sqrt{x/2} + e^{-x/2} \sum_{j=0}^{(k-3)/2}
            \frac{(x/2)^{j+1/2}}{\Gamma(j+3/2)} \ (k \text{ odd}).

    Every term is positive (no cancellation); each is evaluated as the exponential of its logarithm, so nothing
    overflows for large k or x. Same values as ``scipy.special.chdtrc(k, x)`` to about 1e-13 relative
    (tests/test_spectra.py). `x` is dimensionless (a chi-squared statistic); x <= 0 gives 1.
    """
    k = int(dof)
    if k != dof or k < 1:
        raise ValueError(f"chi2_sf needs an integer number of degrees of freedom >= 1, got {dof!r}")
    x = float(x)
    if math.isnan(x):
        return math.nan
    if x <= 0.0:
        return 1.0
    if math.isinf(x):
        return 0.0
    h = 0.5 * x
    log_h = math.log(h)
    if k % 2 == 0:
        return math.fsum(math.exp(-h + j * log_h - math.lgamma(j + 1.0)) for j in range(k // 2))
    tail = math.fsum(math.exp(-h + (j + 0.5) * log_h - math.lgamma(j + 1.5)) for j in range((k - 1) // 2))
    return math.erfc(math.sqrt(h)) + tail


def _psd_units(units: str | None) -> str:
    if units is None or units in ("", "1"):
        return "1/Hz"
    if any(c in units for c in "/^* "):
        return f"({units})^2/Hz"
    return f"{units}^2/Hz"


# ---------------------------------------------------------------------------------------------
# decimation
# ---------------------------------------------------------------------------------------------
def decimate(x, rate: float, target_rate: float) -> tuple[np.ndarray, float]:
    r"""Block-average a record to a lower rate.

    .. math::

        y_j = \frac{1}{M} \sum_{i=0}^{M-1} x_{jM + i}, \qquad M = f_s / f_t ,
        \qquad j = 0 \dots \lfloor L/M \rfloor - 1 .

    This is what the paper does ("averaging over 1 s intervals", 125 Hz -> 1 Hz) and what a
    rate-integrating sensor reports: the block average of a rate over :math:`M` samples is the
    increment of angle (velocity) over the block divided by its duration. White noise of density
    :math:`N` (u/sqrt(Hz)) stays white with two-sided PSD :math:`N^2`: its sample variance goes from
    :math:`N^2 f_s` to :math:`N^2 f_t`. The block average is not an anti-aliasing filter (its
    response is :math:`\operatorname{sinc}`-shaped): compare it with a model through
    ``NoiseModel.psd_sampled``, which includes the averaging and the aliasing.

    Parameters
    ----------
    x : array_like
        Samples along the last axis, in any unit u (e.g. rad/s or m/s^2). Any float or integer
        dtype; the averages are accumulated in float64.
    rate : float
        Sampling frequency of `x`, Hz.
    target_rate : float
        Output frequency, Hz. ``rate / target_rate`` must be an integer (to 1e-9 relative);
        otherwise a ValueError names both rates.

    Returns
    -------
    y : numpy.ndarray
        float64 block averages, shape ``x.shape[:-1] + (L // M,)``. **The incomplete last block**
        (the final ``L % M`` samples) **is dropped.**
    new_rate : float
        ``rate / M``, Hz.

    Raises
    ------
    ValueError
        Non-integer rate ratio, target above the input rate, or a record shorter than one block.

    Examples
    --------
    >>> decimate([1.0, 2.0, 3.0, 4.0, 5.0], rate=2.0, target_rate=1.0)
    (array([1.5, 3.5]), 1.0)
    """
    rate = _check_rate(rate)
    target_rate = _check_rate(target_rate, "target_rate")
    ratio = rate / target_rate
    m = round(ratio)
    if m < 1 or abs(ratio - m) > 1e-9 * ratio:
        raise ValueError(
            f"block-average decimation needs an integer ratio rate/target_rate; got rate={rate:g} Hz "
            f"and target_rate={target_rate:g} Hz (ratio {ratio:.12g})"
        )
    a = np.asarray(x)
    n_blocks = a.shape[-1] // m
    if n_blocks < 1:
        raise ValueError(
            f"record of {a.shape[-1]} samples is shorter than one block of {m} samples "
            f"(rate={rate:g} Hz -> target_rate={target_rate:g} Hz)"
        )
    blocks = a[..., : n_blocks * m].reshape(a.shape[:-1] + (n_blocks, m))
    y = blocks.mean(axis=-1, dtype=np.float64)
    return y, rate / m


# ---------------------------------------------------------------------------------------------
# tapers and degrees of freedom
# ---------------------------------------------------------------------------------------------
def get_taper(taper, nperseg: int) -> np.ndarray:
    r"""Periodic taper (data window) of length `nperseg`.

    .. math::

        w_n = \sum_k (-1)^k a_k \cos\!\left(\frac{2\pi k n}{N}\right), \qquad n = 0 \dots N-1,

    with :data:`TAPERS` giving :math:`a_k` (hann 0.5, 0.5; hamming 0.54, 0.46; blackman 0.42, 0.5,
    0.08; boxcar 1). These are the "periodic" (DFT-even) forms, i.e. what
    ``scipy.signal.get_window(name, N)`` returns (``fftbins=True``, equivalently ``sym=False``).

    Parameters
    ----------
    taper : str or array_like
        A name from :data:`TAPERS`, or explicit weights of length `nperseg`.
    nperseg : int
        Segment length, samples.

    Returns
    -------
    numpy.ndarray
        float64 weights, dimensionless.
    """
    if isinstance(taper, str):
        try:
            coeffs = TAPERS[taper.lower()]
        except KeyError:
            raise ValueError(
                f"unknown taper {taper!r}; choose one of {sorted(TAPERS)} or pass weights"
            ) from None
        if nperseg == 1:  # a one-point taper is 1, as scipy.signal.get_window returns
            return np.ones(1)
        n = np.arange(nperseg, dtype=np.float64)
        w = np.zeros(nperseg)
        for k, a in enumerate(coeffs):
            w += (-1) ** k * a * np.cos(2.0 * np.pi * k * n / nperseg)
        return w
    w = np.asarray(taper, dtype=np.float64)
    if w.shape != (nperseg,):
        raise ValueError(f"explicit taper must have shape ({nperseg},), got {w.shape}")
    if not np.isfinite(w).all() or not np.any(w):
        raise ValueError("explicit taper must be finite and not all zero")
    return w


def welch_edf(taper, nperseg: int, step: int, n_segments: int) -> float:
    r"""Equivalent degrees of freedom of a Welch average (interior frequencies).

    .. math::

        \nu = \frac{2K}{1 + 2 \sum_{m=1}^{K-1} \left(1 - \frac{m}{K}\right) \rho(m)}, \qquad
        \rho(m) = \frac{\left(\sum_n w_n w_{n+mS}\right)^2}{\left(\sum_n w_n^2\right)^2},

    for :math:`K` segments of length :math:`N` started every :math:`S` samples with taper
    :math:`w` (Welch 1967; Percival & Walden 1993, eq. 292b). The formula assumes a Gaussian
    process whose spectrum is locally flat over the taper's bandwidth. Non-overlapping segments
    (:math:`S \ge N`, the paper's 7 h / 10 h) give exactly :math:`\nu = 2K`; Hann at 50 % overlap
    has :math:`\rho(1) = (1/6)^2 = 1/36`, so :math:`\nu \to 2K/1.056` for large :math:`K`.
    At DC and at the Nyquist frequency (even :math:`N`) each periodogram ordinate of real data
    has 1 degree of freedom, not 2, so the value there is :math:`\nu/2`.

    Parameters
    ----------
    taper : str or array_like
        Taper name or weights (see :func:`get_taper`).
    nperseg, step, n_segments : int
        Segment length, segment start spacing (samples) and number of segments averaged.

    Returns
    -------
    float
        :math:`\nu` (dimensionless).
    """
    k = int(n_segments)
    if k < 1:
        raise ValueError("n_segments must be >= 1")
    w = get_taper(taper, nperseg)
    denom = float(np.dot(w, w)) ** 2
    total = 0.0
    for m in range(1, k):
        shift = m * step
        if shift >= nperseg:
            break
        rho = float(np.dot(w[: nperseg - shift], w[shift:])) ** 2 / denom
        total += (1.0 - m / k) * rho
    return 2.0 * k / (1.0 + 2.0 * total)


def bin_correlation(taper, max_lag: int, nperseg: int | None = None) -> np.ndarray:
    r"""Squared correlation :math:`r_j`, j = 0 .. `max_lag`, of periodogram ordinates j bins apart
    (Gaussian data, locally flat spectrum; Percival & Walden 1993, section 6.7).

    .. math:: r_j = \left|\sum_n w_n^2 e^{-2\pi i j n / N}\right|^2 \Big/ \left(\sum_n w_n^2\right)^2

    `taper` is a name of :data:`TAPERS` (evaluated at N = `nperseg`, default 4096: for a cosine-sum taper
    r_j does not depend on N once N > twice its number of terms), an array of taper values, or None
    (independent ordinates: r_0 = 1, r_j = 0 otherwise, exact for the boxcar). Dimensionless.
    """
    if taper is None:
        out = np.zeros(max_lag + 1)
        out[0] = 1.0
        return out
    if isinstance(taper, str):
        # cosine-sum tapers: r_j does not depend on N once N > 2 * (number of terms)
        nperseg = 4096 if nperseg is None else nperseg
    w = get_taper(taper, nperseg if nperseg is not None else len(np.asarray(taper)))
    w2 = w * w
    spec = np.fft.rfft(w2)
    r = np.abs(spec) ** 2 / float(w2.sum()) ** 2
    out = np.zeros(max_lag + 1)
    n = min(max_lag + 1, r.size)
    out[:n] = r[:n]
    # numerical zeros of cosine-sum tapers are exactly zero in exact arithmetic
    out[out < 1e-20] = 0.0
    return out


#: The former private name (kept for callers of the library).
_bin_correlation = bin_correlation


def band_edf_factor(r, m: int) -> float:
    r"""Degrees-of-freedom divisor of an average of `m` adjacent periodogram ordinates whose squared
    correlations j bins apart are ``r[j]`` (:func:`bin_correlation`):
    :math:`1 + 2 \sum_{j=1}^{m-1} (1 - j/m)\, r_j` (Percival & Walden 1993, section 6.7): the band's edf is
    the sum of its ordinates' edf divided by this. Dimensionless, >= 1."""
    j = np.arange(1, m)
    return 1.0 + 2.0 * np.sum((1.0 - j / m) * r[1:m])


def log_band_index(frequency, bands_per_decade: int) -> np.ndarray:
    r"""Log band of each (positive) frequency: :math:`b = \lfloor B \log_{10} f \rfloor` (B =
    `bands_per_decade`; band b holds :math:`10^{b/B} \le f < 10^{(b+1)/B}`, edges aligned on decades, so
    bands coincide across records of the same grid; a 1e-9 guard puts a bin on an edge in the upper band).
    Integer array of the shape of `frequency` (Hz)."""
    return np.floor(bands_per_decade * np.log10(frequency) + 1e-9).astype(np.int64)


# ---------------------------------------------------------------------------------------------
# Welch core
# ---------------------------------------------------------------------------------------------
def _detrend_inplace(seg: np.ndarray, detrend: str | None) -> None:
    """Detrend each row of seg (float64, writable) in place.

    The first sample is subtracted before the mean: a constant row becomes exactly zero, and a
    large offset (9.81 m/s^2) is removed before any rounding of the mean.
    """
    if detrend is None:
        return
    seg -= seg[:, :1]
    if detrend == "constant":
        seg -= seg.mean(axis=1, keepdims=True)
    elif detrend == "linear":
        n = seg.shape[1]
        t = np.arange(n, dtype=np.float64) - (n - 1) / 2.0
        tt = float(np.dot(t, t))
        a = seg.mean(axis=1, keepdims=True)
        b = np.einsum("ij,j->i", seg, t)[:, None] / tt if tt > 0 else 0.0
        seg -= a
        seg -= b * t


def _welch_periodogram(
    x: np.ndarray, nperseg: int, step: int, w: np.ndarray, detrend
) -> tuple[np.ndarray, int]:
    r"""Mean over segments of :math:`|\mathrm{rfft}(w \cdot d(x_{seg}))|^2`; returns (sum/K, K)."""
    windows = np.lib.stride_tricks.sliding_window_view(x, nperseg)[::step]
    k = windows.shape[0]
    batch = max(1, _BATCH_SAMPLES // nperseg)
    acc = np.zeros(nperseg // 2 + 1)
    for i in range(0, k, batch):
        seg = np.array(windows[i : i + batch], dtype=np.float64)  # writable copy
        _detrend_inplace(seg, detrend)
        seg *= w
        spec = np.fft.rfft(seg, axis=-1)
        acc += (spec.real**2 + spec.imag**2).sum(axis=0)
    return acc / k, k


def _normalise_detrend(detrend):
    if detrend is None or detrend is False or (isinstance(detrend, str) and detrend.lower() == "none"):
        return None
    if isinstance(detrend, str) and detrend.lower() in ("constant", "linear"):
        return detrend.lower()
    raise ValueError(f"detrend must be 'constant', 'linear' or None/'none', got {detrend!r}")


def psd(
    x,
    rate: float,
    window_s: float = 25200.0,
    step_s: float = 36000.0,
    taper="hann",
    detrend="constant",
    confidence: float = 0.95,
    onesided: bool = False,
    units: str | None = None,
    long_name: str | None = None,
):
    r"""Welch power spectral density with chi-squared confidence limits.

    The record is cut into :math:`K` segments of :math:`N` samples started every :math:`S` samples
    (:math:`K = \lfloor (L - N)/S \rfloor + 1`; samples after the last segment are not used), each
    segment is detrended and tapered, and the periodograms are averaged:

    .. math::

        S_2(f_k) = \frac{1}{K} \sum_{j=0}^{K-1}
        \frac{\left|\sum_{n=0}^{N-1} w_n\, d_j[n]\, e^{-2\pi i k n/N}\right|^2}{f_s \sum_n w_n^2},
        \qquad f_k = k f_s / N, \quad k = 0 \dots \lfloor N/2 \rfloor,

    the two-sided density (u^2/Hz). The one-sided density (``onesided=True``, scipy's default) is
    :math:`S_1 = 2 S_2` except at DC and, for even :math:`N`, at Nyquist, where :math:`S_1 = S_2`
    (those bins have no negative-frequency twin). The discrete Parseval identity, exact for every
    segment, is

    .. math::

        \Delta f \sum_{k=0}^{\lfloor N/2 \rfloor} c_k S_2(f_k) = \frac{1}{K} \sum_j
        \frac{\sum_n w_n^2 d_j[n]^2}{\sum_n w_n^2}, \qquad \Delta f = f_s/N,\;
        c_k = \begin{cases} 1 & k = 0 \text{ or } k = N/2 \\ 2 & \text{otherwise,} \end{cases}

    i.e. the taper-weighted variance of the detrended data (the plain variance for the boxcar).

    Confidence limits: :math:`\nu \hat S / S \sim \chi^2_\nu`, so the two-sided interval at level
    :math:`c = 1 - a` is

    .. math::

        \frac{\nu \hat S}{\chi^2_\nu(1 - a/2)} \le S \le \frac{\nu \hat S}{\chi^2_\nu(a/2)},

    per frequency (no multiplicity correction: see :func:`chi2_upper` for that). :math:`\nu` is
    :func:`welch_edf`: :math:`2K` for non-overlapping segments, Welch's overlap correction
    otherwise, and half of that at DC and Nyquist. Bins within the taper's main lobe of DC are
    depressed by the detrending and their limits are only indicative.

    Settings of the paper (Gallon et al. 2021, after Langel et al. PLANS 2020, whose text we do not
    have): "t = 7 h, t_s = 10 h" on the 1 Hz block-averaged 10 h records, read as 7 h windows
    (`window_s` = 25200 s) started every 10 h (`step_s` = 36000 s): a single Hann-tapered
    periodogram per 10 h record (:math:`\nu = 2`; the last 3 h are not used). Overlapping Welch (``step_s < window_s``) is
    accepted as well.

    Parameters
    ----------
    x : array_like or xarray.DataArray
        One-dimensional record, unit u (e.g. rad/s). Must be finite. A DataArray's
        ``attrs["units"]`` is used when `units` is not given.
    rate : float
        Sampling frequency, Hz.
    window_s : float, optional
        Segment length, s; rounded to the nearest whole sample (the attrs hold the value used).
        Default 25200 s (7 h). A record shorter than one window raises ValueError (no silent
        truncation of the window).
    step_s : float, optional
        Spacing of the segment starts, s (> window_s leaves gaps, < window_s overlaps).
        Default 36000 s (10 h).
    taper : str or array_like, optional
        ``"hann"`` (default), ``"hamming"``, ``"blackman"``, ``"boxcar"`` (periodic forms, see
        :func:`get_taper`) or explicit weights.
    detrend : {"constant", "linear", None}, optional
        Per-segment detrending before the taper. Default ``"constant"`` (mean removal).
    confidence : float, optional
        Level of the two-sided chi-squared interval, in (0, 1). Default 0.95.
    onesided : bool, optional
        Return :math:`S_1` instead of the project's two-sided :math:`S_2`. Default False.
    units : str, optional
        Unit of `x` (``"rad/s"`` -> PSD unit ``"(rad/s)^2/Hz"``). Default: ``x.attrs["units"]`` if
        present, else dimensionless (``"1/Hz"``).
    long_name : str, optional
        Description placed in the ``psd`` variable's ``long_name``.

    Returns
    -------
    xarray.Dataset
        Coordinate ``frequency`` (Hz, :math:`0 \dots f_s/2`); variables ``psd``, ``psd_lower``,
        ``psd_upper`` (u^2/Hz, attrs ``sidedness``, ``units``, ``long_name``) and ``edf`` (degrees
        of freedom per frequency); dataset attrs ``window_s``, ``step_s``, ``nperseg``,
        ``step_samples``, ``taper``, ``detrend``, ``n_segments``, ``edf`` (interior),
        ``rate_hz``, ``confidence``, ``n_samples``, ``n_samples_used``, ``sidedness``.

    Raises
    ------
    ValueError
        Non-finite samples, a record shorter than the window, or invalid settings.

    Warns
    -----
    UserWarning
        Constant record: the PSD (and its limits) is returned as exact zeros (after detrending).

    References
    ----------
    .. [1] P. D. Welch, IEEE Trans. Audio Electroacoust. 15(2), 70-73, 1967.
    .. [2] J. S. Bendat and A. G. Piersol, "Random Data", 4th ed., Wiley, 2010, eqs. 8.159, 11.101.
    .. [3] D. B. Percival and A. T. Walden, "Spectral Analysis for Physical Applications", 1993, eq. 292b.
    """
    return psd_labelled(x, rate, window_s, step_s, taper, detrend, confidence, onesided, units, long_name).to_xarray()


def psd_labelled(x, rate, window_s=25200.0, step_s=36000.0, taper="hann", detrend="constant", confidence=0.95,
                 onesided=False, units=None, long_name=None):
    """:func:`psd` as :class:`imupipe.labelled.Labelled` arrays, without importing xarray.

    Same estimator, parameters, units (two-sided PSD in ``units^2/Hz`` on ``frequency`` in Hz unless
    `onesided`) and references as :func:`psd`; the result is written to netCDF with netCDF4 alone
    (:meth:`imupipe.labelled.Labelled.to_netcdf`), or turned into the :class:`xarray.Dataset` that
    :func:`psd` returns with ``.to_xarray()``. This is the cheap entry point for a short-lived process
    (one workflow job): importing xarray costs ~0.3 s.
    """
    from imupipe.labelled import Labelled

    if units is None:
        units = getattr(x, "attrs", {}).get("units")
    a = _as_finite_1d(getattr(x, "values", x))
    rate = _check_rate(rate)
    if not (0.0 < float(confidence) < 1.0):
        raise ValueError(f"confidence must lie in (0, 1), got {confidence!r}")
    if not (math.isfinite(window_s) and window_s > 0):
        raise ValueError(f"window_s must be a positive duration in s, got {window_s!r}")
    if not (math.isfinite(step_s) and step_s > 0):
        raise ValueError(f"step_s must be a positive duration in s, got {step_s!r}")
    n = a.size
    nperseg = int(round(window_s * rate))
    step = int(round(step_s * rate))
    if nperseg < 2:
        raise ValueError(f"window_s={window_s:g} s is less than 2 samples at {rate:g} Hz")
    if step < 1:
        raise ValueError(f"step_s={step_s:g} s is less than 1 sample at {rate:g} Hz")
    if nperseg > n:
        raise ValueError(
            f"window_s={window_s:g} s ({nperseg} samples) is longer than the record "
            f"({n} samples = {n / rate:g} s at {rate:g} Hz); use a shorter window_s"
        )
    det = _normalise_detrend(detrend)
    w = get_taper(taper, nperseg)
    taper_name = taper.lower() if isinstance(taper, str) else "custom"

    if np.ptp(a) == 0.0:
        warnings.warn(
            "constant record: its PSD is identically zero after detrending (no noise to analyse)"
            if det is not None
            else "constant record: its PSD is confined to DC",
            UserWarning,
            stacklevel=3,
        )

    mean_sq, k = _welch_periodogram(a, nperseg, step, w, det)
    s2 = mean_sq / (rate * float(np.dot(w, w)))
    nfreq = s2.size
    freq = np.arange(nfreq) * (rate / nperseg)

    nu = welch_edf(w, nperseg, step, k)
    edf = np.full(nfreq, nu)
    edf[0] = nu / 2.0
    if nperseg % 2 == 0:
        edf[-1] = nu / 2.0

    if onesided:
        out = 2.0 * s2
        out[0] = s2[0]
        if nperseg % 2 == 0:
            out[-1] = s2[-1]
        sidedness = "one-sided"
    else:
        out = s2
        sidedness = "two-sided"

    alpha = 1.0 - float(confidence)
    lower = edf * out / _chi2_isf(alpha / 2.0, edf)
    upper = edf * out / _chi2_ppf(alpha / 2.0, edf)

    psd_units = _psd_units(units)
    pct = f"{100 * float(confidence):g} %"
    base = {"units": psd_units, "sidedness": sidedness}
    return Labelled(
        dim="frequency",
        data_vars={
            "psd": (
                out,
                {**base, "long_name": long_name or f"power spectral density ({sidedness})"},
            ),
            "psd_lower": (
                lower,
                {**base, "long_name": f"lower {pct} chi-squared confidence limit of the PSD",
                 "confidence": float(confidence)},
            ),
            "psd_upper": (
                upper,
                {**base, "long_name": f"upper {pct} chi-squared confidence limit of the PSD",
                 "confidence": float(confidence)},
            ),
            "edf": (edf, {"units": "1", "long_name": "equivalent degrees of freedom"}),
        },
        coords={"frequency": (freq, {"units": "Hz", "long_name": "frequency"})},
        attrs={
            "estimator": "Welch average of modified periodograms (numpy.fft.rfft)",
            "sidedness": sidedness,
            "window_s": nperseg / rate,
            "step_s": step / rate,
            "nperseg": nperseg,
            "step_samples": step,
            "taper": taper_name,
            "detrend": det if det is not None else "none",
            "n_segments": k,
            "edf": nu,
            "confidence": float(confidence),
            "rate_hz": rate,
            "n_samples": n,
            "n_samples_used": (k - 1) * step + nperseg,
        },
    )


# ---------------------------------------------------------------------------------------------
# statistics of sample PSDs, for the bound
# ---------------------------------------------------------------------------------------------


_psd = psd_labelled  # the former private name, kept for now


class LogBands(NamedTuple):
    """Band-averaged PSD (see :func:`smooth_log_bands`)."""

    frequency: np.ndarray  #: mean frequency of the bins in each band, Hz
    psd: np.ndarray  #: band average of the PSD, same unit and sidedness as the input
    edf: np.ndarray  #: equivalent degrees of freedom of each band average
    n_bins: np.ndarray  #: number of frequency bins averaged
    f_low: np.ndarray  #: lowest bin frequency in the band, Hz
    f_high: np.ndarray  #: highest bin frequency in the band, Hz


def smooth_log_bands(frequency, psd, bands_per_decade: int = 10, edf=2.0, taper=None) -> LogBands:
    r"""Average a sample PSD over log-spaced frequency bands.

    Band :math:`b` holds the bins with :math:`10^{b/B} \le f < 10^{(b+1)/B}` (:math:`B` =
    `bands_per_decade`; the edges are aligned on decades, so bands coincide across records with
    the same frequency grid). DC (:math:`f = 0`) is dropped; empty bands are skipped. The average
    of :math:`M` ordinates each with :math:`\nu_i` degrees of freedom has

    .. math::

        \nu_b = \frac{\sum_{i \in b} \nu_i}{1 + 2 \sum_{j=1}^{M-1} (1 - j/M)\, r_j},\qquad
        r_j = \frac{\left|\sum_n w_n^2 e^{-2\pi i j n/N}\right|^2}{\left(\sum_n w_n^2\right)^2},

    where :math:`r_j` is the squared correlation of ordinates :math:`j` bins apart for a taper
    :math:`w` (Gaussian data, locally flat spectrum; Percival & Walden 1993, section 6.7). Without
    `taper` the ordinates are taken as independent (:math:`r_j = 0`, exact for the boxcar), i.e.
    :math:`\nu_b = \nu M`; with ``taper="hann"`` (:math:`r_1 = 4/9`, :math:`r_2 = 1/36`) a wide band
    has about half that.

    Parameters
    ----------
    frequency : array_like
        Bin frequencies, Hz, shape (F,), non-negative and increasing.
    psd : array_like
        PSD ordinates, shape (..., F) (several curves may be stacked), any unit.
    bands_per_decade : int, optional
        Default 10.
    edf : float or array_like, optional
        Degrees of freedom of each ordinate (scalar or shape (F,), e.g. the ``edf`` variable of
        :func:`psd`). Default 2 (a single periodogram).
    taper : str or array_like, optional
        Taper used by the periodogram, for the bin correlation; None means independent bins.

    Returns
    -------
    LogBands
        ``frequency``, ``psd`` (shape (..., nb)), ``edf``, ``n_bins``, ``f_low``, ``f_high``.
    """
    f = np.asarray(frequency, dtype=np.float64)
    s = np.asarray(psd, dtype=np.float64)
    if f.ndim != 1 or s.shape[-1] != f.size:
        raise ValueError(f"psd's last axis ({s.shape}) must match frequency ({f.shape})")
    if int(bands_per_decade) < 1:
        raise ValueError("bands_per_decade must be >= 1")
    nu = np.broadcast_to(np.asarray(edf, dtype=np.float64), f.shape)
    keep = f > 0
    f, s, nu = f[keep], s[..., keep], nu[keep]
    if f.size == 0:
        raise ValueError("no positive frequency to band-average")
    b = log_band_index(f, bands_per_decade)
    order = np.argsort(b, kind="stable")  # no-op for an increasing frequency grid
    f, s, nu, b = f[order], s[..., order], nu[order], b[order]
    counts = np.unique(b, return_counts=True)[1]
    start = np.concatenate(([0], np.cumsum(counts)[:-1]))
    psd_b = np.add.reduceat(s, start, axis=-1) / counts
    f_b = np.add.reduceat(f, start) / counts
    nu_sum = np.add.reduceat(nu, start)
    if taper is not None:
        r = bin_correlation(taper, int(counts.max()))
        factor = np.array([band_edf_factor(r, int(m)) for m in counts])
        nu_b = nu_sum / factor
    else:
        nu_b = nu_sum
    f_low = f[start]
    f_high = f[start + counts - 1]
    return LogBands(f_b, psd_b, nu_b, counts.astype(np.int64), f_low, f_high)


def _per_test_level(confidence, n_tests, correction) -> float:
    """The per-test tail probability q of a family-wise level `confidence` over `n_tests` ordinates (Bonferroni
    (1 - c)/n, Sidak 1 - c^(1/n))."""
    c = float(confidence)
    if not (0.0 < c < 1.0):
        raise ValueError(f"confidence must lie in (0, 1), got {confidence!r}")
    n = int(n_tests)
    if n < 1:
        raise ValueError("n_tests must be >= 1")
    if correction == "bonferroni":
        return (1.0 - c) / n
    if correction == "sidak":
        return -math.expm1(math.log(c) / n)
    raise ValueError(f"correction must be 'bonferroni' or 'sidak', got {correction!r}")


def _chi2_limit(psd, edf, confidence, n_tests, correction, upper: bool):
    """nu S / chi2_nu(q) (upper limit, the lower-tail quantile) or nu S / chi2_nu(1 - q) (lower limit, the upper-tail
    quantile), q the per-test level of :func:`_per_test_level`."""
    q = _per_test_level(confidence, n_tests, correction)
    s = np.asarray(psd, dtype=np.float64)
    nu = np.asarray(edf, dtype=np.float64)
    if np.any(nu <= 0):
        raise ValueError("edf must be positive")
    return nu * s / (_chi2_ppf(q, nu) if upper else _chi2_isf(q, nu))


def chi2_lower(psd, edf, confidence: float = 0.95, n_tests: int = 1, correction: str = "bonferroni"):
    r"""Lower chi-squared confidence limit of a PSD estimate, corrected for multiplicity: the mirror of
    :func:`chi2_upper`.

    With :math:`\nu \hat S/S \sim \chi^2_\nu`, :math:`S_{lo} = \nu \hat S / \chi^2_\nu(1 - q)` (the upper-tail
    quantile, q as in :func:`chi2_upper`): the true PSD lies above :math:`S_{lo}` at all `n_tests` ordinates
    simultaneously with probability at least `confidence`. A model whose PSD is below :math:`S_{lo}` at some ordinate
    is contradicted by the data there at that family-wise level (the bound's data check,
    :mod:`imupipe.bound.datacheck`). Same parameters and unit as :func:`chi2_upper`.
    """
    return _chi2_limit(psd, edf, confidence, n_tests, correction, upper=False)


def chi2_upper(psd, edf, confidence: float = 0.95, n_tests: int = 1, correction: str = "bonferroni"):
    r"""Upper chi-squared confidence limit of a PSD estimate, corrected for multiplicity.

    With :math:`\nu \hat S/S \sim \chi^2_\nu` the one-sided upper limit at per-test level
    :math:`1 - q` is

    .. math::

        S_{up} = \frac{\nu \hat S}{\chi^2_\nu(q)}, \qquad
        q = \begin{cases} (1-c)/n & \text{Bonferroni}\\ 1 - c^{1/n} & \text{Sidak,}\end{cases}

    so that the true PSD lies below :math:`S_{up}` at all :math:`n` tested ordinates (bins x curves)
    simultaneously with probability at least :math:`c` (Bonferroni: any dependence; Sidak: exact
    for independent ordinates, and valid for positively dependent ones). This is the
    statistically stated alternative to bounding the raw periodograms (docs/method.md, section "Estimators").

    Parameters
    ----------
    psd : array_like
        Estimates :math:`\hat S` (any unit, any sidedness: the limit has the same).
    edf : float or array_like
        Degrees of freedom :math:`\nu` (broadcast against `psd`); ordinates with zero estimate give 0.
    confidence : float, optional
        Family-wise level :math:`c` in (0, 1). Default 0.95.
    n_tests : int, optional
        Number of ordinates covered simultaneously, :math:`n \ge 1`. Default 1 (no correction).
    correction : {"bonferroni", "sidak"}, optional

    Returns
    -------
    numpy.ndarray
        :math:`S_{up}`, same unit as `psd`.
    """
    return _chi2_limit(psd, edf, confidence, n_tests, correction, upper=True)
