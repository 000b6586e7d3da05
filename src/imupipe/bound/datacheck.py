r"""The bound's data check: do the records contradict a model?

A bound built from something other than the sample PSDs (the envelope candidate of ``bound.mode: auto``: the
identified model family's envelope, docs/method.md "The data check") can miss what that family cannot represent,
e.g. a spectral line below the lines stage's search band, which the Allan fit's adequacy test does not see. The
check compares the sample PSDs' lower confidence limits with the model's PSD at the same bins (as sampled, as every
margin of the bound):

.. math:: S_{lo} = \frac{\nu \hat S}{\chi^2_\nu(1 - q)}, \qquad q = (1 - c)/n

(:func:`imupipe.spectra.chi2_lower`; Bonferroni over the n curves x bins, c the bound's confidence). The true PSD lies
above every :math:`S_{lo}` with probability at least c, so a model below one of them is contradicted by the data at
that family-wise level. The raw mode's model lies above every periodogram, hence above these limits: it passes by
construction.
"""

from __future__ import annotations

import numpy as np

__all__ = ["data_check"]


def data_check(f_hz, psd, edf, model_psd, labels, confidence: float = 0.95, mask=None) -> dict | None:
    """The check of sample PSDs `psd` (curves x bins, u^2/Hz, two-sided) with degrees of freedom `edf` (same shape)
    at the frequencies `f_hz` (Hz) against the model's PSD `model_psd` at the same bins; `labels` name the curves;
    `mask` (bins, bool): the bins read (an excluded line's bins left out); None without edf or bins.

    Returns ``passed`` (the largest S_lo / model <= 1), ``worst_ratio``, the ``curve`` and ``frequency_hz`` where it
    lies, ``confidence``, ``n_tests``, ``correction`` and a ``statement``."""
    if edf is None:
        return None
    from imupipe.spectra import chi2_lower

    psd = np.asarray(psd, dtype=np.float64)
    use = (psd > 0) & np.isfinite(psd)
    if mask is not None:
        use &= np.asarray(mask, dtype=bool)[None, :]
    n = int(use.sum())
    if n == 0:
        return None
    lo = np.where(use, chi2_lower(np.where(use, psd, 0.0), edf, confidence=confidence, n_tests=n,
                                  correction="bonferroni"), 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(use, lo / np.asarray(model_psd, dtype=np.float64)[None, :], 0.0)
    c, i = np.unravel_index(int(np.argmax(r)), r.shape)
    worst = float(r[c, i])
    return {"passed": bool(worst <= 1.0), "worst_ratio": worst, "curve": labels[c], "frequency_hz": float(f_hz[i]),
            "confidence": float(confidence), "n_tests": n, "correction": "bonferroni",
            "statement": "max over curves and bins of the sample PSD's lower confidence limit over the model's PSD: "
                         "above 1, the records show more power than the model at that frequency"}
