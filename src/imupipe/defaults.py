r"""The one table of defaults shared by the workflow and the one-call API (:func:`imupipe.api.noise_model`).

``DEFAULTS`` holds the values ``config/config.yaml`` ships for the keys the API also takes; a test
(``tests/test_defaults.py``) checks that the two agree, so the workflow and the API cannot drift apart.
``psd.window_s`` / ``psd.step_s`` are the exception by design: ``config/config.yaml`` states the paper's
7 h / 10 h (its simulated records last 10 h); left unset (``null`` in a config, ``None`` in the API), both
follow :func:`psd_window_step`, which fits the records.
"""

from __future__ import annotations

import math

__all__ = ["DEFAULTS", "PSD_MAX_WINDOW_S", "psd_window_step", "unused_fraction"]

#: Longest Welch window the rule picks, s (the paper's 7 h).
PSD_MAX_WINDOW_S = 25200.0

#: Defaults of the keys the workflow (config/config.yaml) and the API share, by config key.
DEFAULTS: dict[str, object] = {
    "decimate.rate_hz": 1.0,
    "psd.taper": "hann",
    "psd.detrend": "constant",
    "psd.confidence": 0.95,
    "allan.taus": "octave",
    "allan.confidence": 0.683,
    "identify.components": ["white", "gauss_markov", "flicker", "random_walk", "quantization", "ramp"],
    "identify.n_gm": 1,
    "identify.confidence": 0.95,
    "identify.significance": 0.05,
    "identify.relevance": 0.05,
    "identify.adequacy_level": 0.01,
    "identify.pooling_level": 0.01,
    "identify.n_boot": 100,
    "identify.pooling_n_boot": 99,
    "identify.envelope": "marginal",
    "application.filter_rate_hz": 1.0,
    "application.outage_s": 3600.0,
    "bound.mode": "raw",
    "bound.confidence": 0.95,
    "bound.bands_per_decade": 10,
    "stationarity.n_segments": 2,
    "stationarity.alpha": 0.05,
    "stationarity.test": "calibrated",
    "stationarity.n_sim": 199,
    "stationarity.n_sim_max": 1599,
    "stationarity.close_z": 2.0,
    "lines.resolution_hz": 0.002,
    "lines.alpha": 0.01,
    "lines.floor_window_bins": 51,
    "lines.scales": [1],
    "lines.low_band_resolution_hz": None,
    "verify.fix_s": 600.0,
    "verify.reduce": True,
    "verify.replay_z": 2.0,
    "verify.sigma_fix_m": 0.5,
    "verify.sigma_fix_rad": 0.001745,
}


def psd_window_step(duration_s: float, rate_hz: float = 1.0) -> tuple[float, float]:
    r"""Welch window and step that fit a record of `duration_s` seconds (the rule for unset ``psd.window_s``/``step_s``).

    .. math::

        W = \min\!\left(\left\lfloor \tfrac{T f}{4} \right\rfloor / f,\; 25200\ \mathrm{s}\right), \qquad S = W / 2,

    with :math:`T` the duration (s) and :math:`f` the decimated rate (Hz): at least four windows' worth of record,
    half-overlapping Hann segments (Welch 1967), so :math:`K = \lfloor (T - W)/S \rfloor + 1 \ge 7` segments
    and at most :math:`S` seconds (< 1/7 of a record up to 7 h x 4) are left after the last one. Long records
    keep the paper's 7 h window (lowest frequency 1/7 h) with more segments. A 2 h record gets 1800 s / 900 s.

    Raises ValueError for a record shorter than 8 samples at `rate_hz`.
    """
    t, f = float(duration_s), float(rate_hz)
    if not (math.isfinite(t) and t > 0 and f > 0):
        raise ValueError(f"psd_window_step: expected a positive duration (s) and rate (Hz), got {duration_s!r}, {rate_hz!r}")
    n = math.floor(t * f / 4.0)
    if n < 2:
        raise ValueError(f"a record of {t:g} s at {f:g} Hz is too short for a PSD (needs 8 samples)")
    window = min(n / f, PSD_MAX_WINDOW_S)
    step = max(math.floor(window * f / 2.0), 1) / f
    return float(window), float(step)


def unused_fraction(n_samples: int, n_samples_used: int) -> float:
    """Share of a record a Welch estimate leaves out: ``1 - n_samples_used / n_samples`` (0 for an empty record)."""
    n = int(n_samples)
    return 0.0 if n <= 0 else max(0.0, 1.0 - int(n_samples_used) / n)
