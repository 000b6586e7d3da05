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

__all__ = ["data_check", "lift_to_data"]


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


#: The lift's stricter level (:func:`lift_to_data`): 1 - (1 - c) / LIFT_STRICT_FACTOR, 0.999 for c = 0.95.
LIFT_STRICT_FACTOR = 50


def lift_to_data(model, model_bins, f_hz, psd, edf, labels, confidence: float = 0.95, mask=None):
    r"""`model` (:class:`imupipe.models.NoiseModel`) scaled up where the records contradict it by no more than chance
    does: (model, record or None). `model_bins(model)` gives its PSD at the bins as :func:`data_check` reads it; the
    other arguments are :func:`data_check`'s.

    The bound's ``envelope`` candidate follows the identified upper envelope E closely, and E's white noise is about
    the fitted one, so a record whose most extreme bin lies beyond its lower limit's level (about 1 - c of records
    whatever the model; measured 7.7-12 % on 10 h records with the chi-squared limits of an overlapped Welch average,
    docs/performance.md) failed the check by a few per cent, and auto exported a sample-PSD candidate several times
    looser. Where the worst ratio :math:`r = \max S_{lo} / S_{model}` at the level c exceeds 1 but the check at the
    stricter level :math:`c' = 1 - (1 - c)/50` (:data:`LIFT_STRICT_FACTOR`) passes, every squared coefficient is
    multiplied by :math:`r (1 + 10^{-9})` (:meth:`imupipe.models.NoiseModel.scaled`): the PSD is then above every
    :math:`S_{lo}`, and still above E and the spec sheet (a scale >= 1), so every argument for the unscaled model holds
    for it. Where the check fails at c' too, the records show what the model lacks (a slow line, a step) beyond
    chance at 0.1 %: no lift, and the check fails as before. The price: a feature of one bin whose lower limit lies
    between the two levels' (about 1.2x apart for a Welch average of 13 degrees of freedom over 4500 bins) is covered
    up to its level-c limit only, as one just under the level-c limit always was."""
    mb = model_bins(model)
    dc = data_check(f_hz, psd, edf, mb, labels, confidence, mask)
    if not dc or dc["passed"]:
        return model, None
    strict = 1.0 - (1.0 - float(confidence)) / LIFT_STRICT_FACTOR
    if not data_check(f_hz, psd, edf, mb, labels, strict, mask)["passed"]:
        return model, {"variance_factor": None, "curve": dc["curve"], "frequency_hz": dc["frequency_hz"],
                       "strict_confidence": strict,
                       "statement": "not lifted: the records' lower confidence limit lies above the model at the "
                                    "stricter level too (what the model lacks, beyond chance)"}
    factor = float(dc["worst_ratio"]) * (1.0 + 1e-9)
    return model.scaled(factor), {
        "variance_factor": factor, "curve": dc["curve"], "frequency_hz": dc["frequency_hz"],
        "strict_confidence": strict,
        "statement": "the records' lower confidence limit lay above the model at this bin, within chance at the "
                     "stricter level: every coefficient squared scaled by variance_factor so that the data check "
                     "passes"}
