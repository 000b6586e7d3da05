r"""The classic slope-line reading of an Allan deviation (IEEE Std 952 Annex C; Kalibr; MATLAB ``allanvar``
examples), kept beside :func:`imupipe.identify.fit_allan` for comparison. SI units."""

from __future__ import annotations

import math

import numpy as np

from imupipe.identify.basis import _FLICKER_ADEV

__all__ = ["slope_line"]


def slope_line(tau, adev, slope_tol: float = 0.25) -> dict:
    r"""Classic slope-line reading of an Allan deviation (IEEE Std 952 Annex C; Kalibr; MATLAB).

    * White (angle/velocity random walk): the :math:`-1/2` line through the point whose local
      log-log slope is closest to :math:`-1/2`, read at :math:`\tau = 1` s:
      :math:`N = \sigma(\tau_k)\sqrt{\tau_k}`.
    * Random walk: the :math:`+1/2` line through the point whose slope is closest to
      :math:`+1/2`, read at :math:`\tau = 3` s: :math:`K = \sigma(\tau_k)\sqrt{3/\tau_k}`
      (from :math:`\sigma^2 = K^2 \tau/3`).
    * Bias instability (flicker): :math:`B = \min \sigma / 0.664`, with
      :math:`0.664 = \sqrt{2\ln 2/\pi}`.

    The lines are drawn through :math:`\tau_k` (``tau_white``, ``tau_random_walk``), which can be far from
    the read-off tau: where the curve at 1 s (3 s) is not on the slope, the line's value there differs from
    the curve's. So the curve itself at the read-off taus is given too, interpolated linearly in
    :math:`(\log\tau, \log\sigma)` (None outside the curve): ``adev_at_1s`` (u; equal to N in u/sqrt(Hz)
    where the -1/2 line holds at 1 s) and ``adev_at_3s`` (u; :math:`K = \sigma(3\,s)` there).

    Local slopes are centred differences of :math:`\log\sigma` against :math:`\log\tau`. A line
    is reported only if the closest slope is within `slope_tol` of its nominal value; otherwise
    the value is None.

    Parameters
    ----------
    tau : array_like
        Averaging times, s, increasing.
    adev : array_like
        Allan deviation, u (e.g. rad/s).
    slope_tol : float, optional
        Accepted distance from +-1/2. Default 0.25.

    Returns
    -------
    dict
        ``white`` (N, u/sqrt(Hz)), ``random_walk`` (K, u/sqrt(s)), ``flicker`` (B, u),
        ``tau_white``, ``slope_white``, ``tau_random_walk``, ``slope_random_walk``, ``tau_min``
        (s), ``adev_min``, ``adev_at_1s``, ``adev_at_3s`` (u), ``method``.
    """
    t = np.asarray(tau, dtype=np.float64)
    s = np.asarray(adev, dtype=np.float64)
    ok = np.isfinite(t) & np.isfinite(s) & (t > 0) & (s > 0)
    t, s = t[ok], s[ok]
    if t.size < 3:
        raise ValueError("slope_line needs at least 3 positive, finite points")
    order = np.argsort(t)
    t, s = t[order], s[order]
    slope = np.gradient(np.log(s), np.log(t))
    out = {"method": "slope lines (IEEE Std 952 Annex C): N from the -1/2 line through tau_white read at tau=1 s, "
                     "K from the +1/2 line through tau_random_walk read at tau=3 s, B=min(ADEV)/0.664; "
                     "adev_at_1s/adev_at_3s: the curve itself there"}
    for name, at in (("adev_at_1s", 1.0), ("adev_at_3s", 3.0)):
        inside = t[0] <= at <= t[-1]
        out[name] = float(np.exp(np.interp(math.log(at), np.log(t), np.log(s)))) if inside else None
    i = int(np.argmin(np.abs(slope + 0.5)))
    if abs(slope[i] + 0.5) <= slope_tol:
        out.update(white=float(s[i] * math.sqrt(t[i])), tau_white=float(t[i]), slope_white=float(slope[i]))
    else:
        out.update(white=None, tau_white=None, slope_white=float(slope[i]))
    j = int(np.argmin(np.abs(slope - 0.5)))
    if abs(slope[j] - 0.5) <= slope_tol:
        out.update(
            random_walk=float(s[j] * math.sqrt(3.0 / t[j])), tau_random_walk=float(t[j]),
            slope_random_walk=float(slope[j]),
        )
    else:
        out.update(random_walk=None, tau_random_walk=None, slope_random_walk=float(slope[j]))
    k = int(np.argmin(s))
    out.update(flicker=float(s[k] / _FLICKER_ADEV), tau_min=float(t[k]), adev_min=float(s[k]))
    return out
