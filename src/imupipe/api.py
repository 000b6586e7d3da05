r"""One call from in-memory records to a bounding noise model: :func:`noise_model`.

The steps are the workflow's, in its order, with its defaults (``config/config.yaml``): per curve (one
axis of one record, SI rate units) the overlapping Allan variance of the full-rate samples, the block
average to ``decimate_hz`` and its two-sided Welch PSD; then, over every curve of the sensor type, the pooled
Allan-variance fit (:func:`imupipe.identify.fit_allan`), the model selection for the application band
(:func:`imupipe.identify.select_components`) and the refit of the selected components
(:func:`imupipe.identify.refit_selected`); optionally the narrowband lines of every curve
(:func:`imupipe.lines.find_lines`) and their policy (:func:`imupipe.lines.line_policy`); the all-frequency
PSD bound against the spec sheet (:func:`imupipe.bound.bound_psd` restricted to the kept components, with the
selected refit's upper confidence envelope :func:`imupipe.bound.upper_envelope` imposed below the lowest bin
down to the outage horizon); the Kalman-filter matrices of the bound at the filter step
(:func:`imupipe.kf.export_kf`); and the covariance verification of the bound in the reference scenario
(:func:`imupipe.verify.verification_report`). Stationarity tests, figures and tables are left to the workflow.

Nothing is printed on stdout (HiGHS is run silent by :mod:`imupipe.bound`).

Example
-------
>>> import numpy as np, imupipe.api as api                                      # doctest: +SKIP
>>> rng = np.random.default_rng(1)
>>> curves = {"rec1/x": 4.4e-5 * np.sqrt(20.0) * rng.standard_normal(20 * 5400)}  # rad/s at 20 Hz
>>> res = api.noise_model(curves, rate_hz=20.0, sensor="gyro", spec="config/specs/stim300.yaml")
>>> res.bounded, res.bound.model.white
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imupipe.defaults import DEFAULTS as _D

__all__ = ["NoiseModelResult", "noise_model"]


@dataclass
class NoiseModelResult:
    """Everything :func:`noise_model` computed for one sensor type (SI throughout).

    Attributes
    ----------
    sensor : str
        ``gyro`` or ``accel``.
    spec_name : str
        Name of the spec sheet.
    bound : imupipe.bound.BoundResult
        The global bound; ``bound.model`` is the :class:`~imupipe.models.NoiseModel` to use.
    fit : imupipe.identify.AllanFit
        Pooled Allan-variance fit; ``fit.model`` is the identified model.
    selection : dict
        :func:`imupipe.identify.select_components` result (``kept``, ``dropped``, ``reasons``, ...).
    kf : dict
        :func:`imupipe.kf.export_kf` of the bound at ``kf_dt_s`` (F, G, Qc, Phi, Qd, P0, ...).
    allan : dict
        Curve label -> ``xarray.Dataset`` of :func:`imupipe.allan_variance` (full rate).
    spectra : dict
        Curve label -> ``xarray.Dataset`` of :func:`imupipe.psd` (decimated, two-sided).
    rate_hz, decimate_hz, kf_dt_s : float
        Record rate (Hz), decimated rate (Hz), filter step (s).
    selected : imupipe.identify.AllanFit
        :func:`imupipe.identify.refit_selected`: the fit of the kept components only (the workflow's
        ``model_selected``).
    upper : imupipe.models.NoiseModel
        :func:`imupipe.bound.upper_envelope` of `selected`: imposed by the bound below the lowest PSD bin.
    lines : imupipe.lines.LinePolicy or None
        The lines policy applied to the bound (None when no policy was asked for).
    verification : dict or None
        :func:`imupipe.verify.verification_report` of the bound (None when ``verify=False``).
    """

    sensor: str
    spec_name: str
    bound: Any
    fit: Any
    selection: dict
    kf: dict
    allan: dict = field(repr=False)
    spectra: dict = field(repr=False)
    rate_hz: float = 0.0
    decimate_hz: float = 1.0
    kf_dt_s: float = 1.0
    selected: Any = None
    upper: Any = None
    lines: Any = None
    verification: dict | None = None

    @property
    def model(self):
        """The bounding :class:`~imupipe.models.NoiseModel` (SI)."""
        return self.bound.model

    @property
    def bounded(self) -> bool:
        """True when the model PSD bounds every sample PSD and the spec sheet (``bound.bounded``)."""
        return bool(self.bound.bounded)

    def to_dict(self) -> dict:
        """Plain, YAML-ready dict: ``bound`` (the bound contract's fields), ``identify`` (fit, model,
        selection), ``kf``; SI units, PSDs two-sided."""
        from imupipe.io import plain

        sel = {k: self.selection.get(k) for k in ("kept", "dropped", "reasons", "band_hz")}
        out = {
            "sensor": self.sensor,
            "spec_name": self.spec_name,
            "rate_hz": float(self.rate_hz),
            "decimate_hz": float(self.decimate_hz),
            "curves": list(self.allan),
            "bound": self.bound.to_dict(sensor=self.sensor),
            "identify": {"fit": self.fit.to_dict(), "model": self.fit.model.to_dict(), "selection": plain(sel)},
            "kf": plain(self.kf),
        }
        if self.selected is not None:
            out["identify"]["model_selected"] = self.selected.model.to_dict()
        if self.upper is not None:
            out["upper_envelope"] = self.upper.to_dict()
        if self.lines is not None:
            out["lines"] = plain(self.lines.to_dict())
        if self.verification is not None:
            out["verification"] = plain(self.verification)
        return out


@contextmanager
def _no_stdout_fd():
    """Point file descriptor 1 at the null device for the duration (a compiled solver's banner, e.g.
    HiGHS's on creating its first instance, is written there directly, past ``sys.stdout``)."""
    import os
    import sys

    try:
        fd = sys.__stdout__.fileno() if sys.__stdout__ is not None else 1
        saved = os.dup(fd)
    except (OSError, ValueError, AttributeError):  # no real stdout (embedded interpreter): nothing to guard
        yield
        return
    for stream in (sys.stdout, sys.__stdout__):
        try:
            stream.flush()
        except (AttributeError, ValueError, OSError):
            pass
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, fd)
        yield
    finally:
        try:
            sys.__stdout__.flush()
        except (AttributeError, ValueError, OSError):
            pass
        os.dup2(saved, fd)
        os.close(saved)
        os.close(null)


def _spec_of(spec):
    from imupipe.specsheet import SpecSheet, load_spec

    if isinstance(spec, SpecSheet):
        return spec
    if isinstance(spec, (str, Path)):
        return load_spec(spec)
    raise TypeError(f"spec: expected a spec-sheet path or an imupipe.specsheet.SpecSheet, got {type(spec).__name__}")


def noise_model(
    curves: Mapping[str, Sequence[float]],
    rate_hz: float,
    sensor: str,
    spec,
    *,
    decimate_hz: float = _D["decimate.rate_hz"],
    window_s: float | None = None,
    step_s: float | None = None,
    taper: str = _D["psd.taper"],
    detrend: str = _D["psd.detrend"],
    psd_confidence: float = _D["psd.confidence"],
    taus=_D["allan.taus"],
    allan_confidence: float = _D["allan.confidence"],
    components: Sequence[str] = tuple(_D["identify.components"]),
    n_gm: int = _D["identify.n_gm"],
    n_boot: int = 0,
    fit_confidence: float = _D["identify.confidence"],
    significance: float = _D["identify.significance"],
    relevance: float = _D["identify.relevance"],
    application_rate_hz: float = _D["application.rate_hz"],
    horizon_s: float = _D["application.horizon_s"],
    mode: str = _D["bound.mode"],
    bound_confidence: float = _D["bound.confidence"],
    bands_per_decade: int = _D["bound.bands_per_decade"],
    seed: int = 20211,
    lines_policy: str | None = None,
    lines_resolution_hz: float = _D["lines.resolution_hz"],
    lines_alpha: float = _D["lines.alpha"],
    fix_s: float = _D["verify.fix_s"],
    verify: bool = True,
    sigma_fix: float | None = None,
) -> NoiseModelResult:
    r"""Identification, bound and Kalman-filter export of one sensor type from in-memory records.

    Parameters
    ----------
    curves : mapping of str to array_like
        Curve label (e.g. ``"lab1/x"``) -> 1-D static record of one axis, in SI (rad/s for a gyro,
        m/s^2 for an accelerometer; a constant offset such as gravity is harmless), sampled at `rate_hz`.
    rate_hz : float
        Sample rate of every record, Hz.
    sensor : {"gyro", "accel"}
        Sensor type (selects the spec sheet's section).
    spec : str, pathlib.Path or imupipe.specsheet.SpecSheet
        The manufacturer's spec sheet (YAML file or parsed).
    decimate_hz : float, optional
        Block-average rate for the PSD, Hz (default 1.0, the paper's).
    window_s, step_s, taper, detrend, psd_confidence :
        Welch settings (window and step in s; default None: :func:`imupipe.defaults.psd_window_step` of the
        shortest curve, the workflow's rule for an unset ``psd.window_s``/``psd.step_s``; Hann, mean removed, 0.95).
    taus, allan_confidence :
        Allan-variance taus (default ``"octave"``) and confidence of its limits (default 0.683).
    components, n_gm, n_boot, fit_confidence, significance, relevance :
        :func:`imupipe.identify.fit_allan` and :func:`~imupipe.identify.select_components` settings
        (defaults :data:`imupipe.defaults.DEFAULTS`, the workflow's, except ``n_boot=0``, which skips the
        bootstrap intervals; the workflow's is 100).
    application_rate_hz : float, optional
        Filter rate, Hz (default 1.0): the KF step is 1/application_rate_hz, and with `horizon_s` (s,
        default 3600, the workflow's) it sets the band the selection keeps components for.
    mode, bound_confidence, bands_per_decade :
        :func:`imupipe.bound.bound_psd` settings (default ``raw``, 0.95, 10).
    seed : int, optional
        Seed of the fit's bootstrap (default 20211, the workflow's).
    lines_policy : {None, "model", "exclude", "keep"}, optional
        Search every full-rate curve for narrowband lines (:func:`imupipe.lines.find_lines` with
        `lines_resolution_hz`, Hz, and `lines_alpha`) and apply :func:`imupipe.lines.line_policy` over the
        whole decimated band (default None: no search).
    fix_s : float, optional
        Time with position/angle fixes before the outage of the reference scenario, s (default 600): the bound's
        all-frequency horizon is ``fix_s + horizon_s``.
    verify, sigma_fix :
        Run :func:`imupipe.verify.verification_report` on the bound (default True); `sigma_fix` is the fix
        standard deviation (m for accel, rad for gyro; default the scenario's).

    Returns
    -------
    NoiseModelResult

    Raises
    ------
    ValueError
        No curves, a curve that is not 1-D or too short for one PSD window, a non-positive rate, an
        unknown sensor, or a spec sheet without that sensor.
    """
    from imupipe.allan import allan_variance
    from imupipe.bound import bound_psd, upper_envelope
    from imupipe.identify import fit_allan, refit_selected, select_components
    from imupipe.kf import export_kf
    from imupipe.models import NoiseModel
    from imupipe.spectra import decimate, psd

    if sensor not in ("gyro", "accel"):
        raise ValueError(f"sensor: expected 'gyro' or 'accel', got {sensor!r}")
    if not (float(rate_hz) > 0):
        raise ValueError(f"rate_hz: expected a positive sample rate in Hz, got {rate_hz!r}")
    if not curves:
        raise ValueError("curves: no record given (expected label -> 1-D array)")
    spec_sheet = _spec_of(spec)
    if sensor not in spec_sheet.models:
        raise ValueError(f"spec {spec_sheet.name!r}: no '{sensor}' section")
    rate = float(rate_hz)
    from imupipe.units import SI_UNITS

    units = SI_UNITS[sensor]

    if window_s is None or step_s is None:
        from imupipe.defaults import psd_window_step

        for label, x in curves.items():
            if np.ndim(x) != 1:
                raise ValueError(f"curves[{label!r}]: expected a 1-D record, got shape {np.shape(x)}")
        label, n_min = min(((k, np.asarray(x).size) for k, x in curves.items()), key=lambda kv: kv[1])
        try:
            rule_w, rule_s = psd_window_step(n_min / rate, decimate_hz)
        except ValueError as exc:
            raise ValueError(f"curves[{label!r}]: {exc}") from exc
        window_s = rule_w if window_s is None else window_s
        step_s = (rule_s if window_s == rule_w else window_s / 2.0) if step_s is None else step_s
    allan, spectra = {}, {}
    record_s = 0.0  # the longest decimated record, s (the workflow's verification measures it so)
    for label, x in curves.items():
        x = np.asarray(x, dtype=np.float64)
        if x.ndim != 1:
            raise ValueError(f"curves[{label!r}]: expected a 1-D record, got shape {x.shape}")
        y, new_rate = decimate(x, rate, decimate_hz)
        if y.size * (1.0 / new_rate) < window_s:
            raise ValueError(f"curves[{label!r}]: {x.size / rate:g} s long, shorter than window_s = {window_s:g} s")
        record_s = max(record_s, y.size / new_rate)
        allan[label] = allan_variance(x, rate, taus=taus, confidence=allan_confidence, units=units)
        spectra[label] = psd(y, new_rate, window_s=window_s, step_s=step_s, taper=taper,
                             detrend=None if detrend == "none" else detrend, confidence=psd_confidence, units=units)

    taus_l, avars, edfs, ns = [], [], [], []
    for label, x in curves.items():
        av = allan[label]
        a, e = av["avar"].values, av["edf"].values
        ok = np.isfinite(a) & np.isfinite(e)
        taus_l.append(av["tau"].values[ok])
        avars.append(a[ok])
        edfs.append(e[ok])
        ns.append(int(np.asarray(x).size))
    fit_kw = dict(n_boot=n_boot, confidence=fit_confidence, rng=seed, dt=1.0 / rate, rate=rate, n_samples=ns)
    fit = fit_allan(taus_l, avars, edfs, components=list(components), n_gm=n_gm, **fit_kw)
    selection = select_components(fit, taus_l, avars, edfs, rate_hz=application_rate_hz, horizon_s=horizon_s,
                                  significance=significance, relevance=relevance)
    kept = selection["kept"]
    selected = refit_selected(fit, selection, taus_l, avars, edfs, **fit_kw)
    upper = upper_envelope(selected, selection, horizon_s=fix_s + horizon_s)

    first = next(iter(spectra.values()))
    f = first["frequency"].values
    psd_curves, edf = {}, []
    for label, sp in spectra.items():
        if sp["frequency"].size != f.size:
            raise ValueError(f"curves[{label!r}]: its PSD has {sp['frequency'].size} bins, the first curve's "
                             f"{f.size}: give records whose decimated length covers the same windows")
        psd_curves[label] = sp["psd"].values
        edf.append(np.broadcast_to(sp["edf"].values, f.shape))
    dt = 1.0 / float(first.attrs.get("rate_hz", decimate_hz))
    policy, line_kw = None, {}
    if lines_policy is not None:
        from imupipe.lines import find_lines, line_policy

        found = [ln for label, x in curves.items()
                 for ln in find_lines(np.asarray(x, dtype=np.float64), rate, resolution_hz=lines_resolution_hz,
                                      alpha=lines_alpha, units=units, label=label).lines]
        policy = line_policy(found, dt, (0.0, 0.5 / dt), policy=lines_policy, frequency=f)
        line_kw = policy.bound_kwargs()
    with _no_stdout_fd():
        result = bound_psd(f, psd_curves, spec_sheet.models[sensor], dt=dt, mode=mode, n_gm=n_gm,
                           confidence=bound_confidence, bands_per_decade=bands_per_decade, edf=np.array(edf),
                           keep=kept, taper=first.attrs.get("taper", taper), horizon_s=fix_s + horizon_s,
                           upper_model=upper, **line_kw)

    # the bound YAML's model as the workflow's KF stage reads it back (narrowband lines included)
    m = NoiseModel.from_dict(result.to_dict(sensor=sensor)["bound"])
    kf_dt = 1.0 / float(application_rate_hz)
    turn_on = spec_sheet.turn_on_bias.get(sensor, 0.0)
    verification = None
    if verify:
        from imupipe.verify import verification_report

        verification = verification_report(m, sensor, spec=spec_sheet.models[sensor], upper=upper, fix_s=fix_s,
                                           horizon_s=horizon_s, sigma_fix=sigma_fix,
                                           filter_rate_hz=application_rate_hz, record_s=record_s,
                                           turn_on_bias=turn_on)
    # the KF file starts the bias where the verification starts the filter (imupipe.biasinit): the bound's model
    from imupipe.biasinit import bias_initialisation

    bias = bias_initialisation(m, spec=spec_sheet.models[sensor], upper=upper, turn_on_bias=turn_on,
                               record_s=record_s, run_s=fix_s + horizon_s)
    p0_rw = bias.p0(m, fix_s + horizon_s) or None
    kf = export_kf(m, kf_dt, sensor=sensor, p0_random_walk=p0_rw, reduced=p0_rw is None)
    return NoiseModelResult(sensor=sensor, spec_name=spec_sheet.name, bound=result, fit=fit, selection=selection,
                            kf=kf, allan=allan, spectra=spectra, rate_hz=rate, decimate_hz=float(decimate_hz),
                            kf_dt_s=kf_dt, selected=selected, upper=upper, lines=policy,
                            verification=verification)
