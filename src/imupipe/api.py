r"""One call from in-memory records to a bounding noise model: :func:`noise_model`.

The steps are the workflow's, in its order, with its defaults (``config/config.yaml``), and the stages are
the workflow's own functions (:mod:`imupipe.stages`, which the workflow scripts call): per curve (one axis of
one record, SI rate units) the overlapping Allan variance of the full-rate samples, the block average to
``decimate_hz`` and its two-sided Welch PSD, optionally its narrowband lines (:func:`imupipe.lines.find_lines`);
then, over every curve of the sensor type, the identification (:func:`imupipe.stages.identify.identify_sensor`:
pooled Allan-variance fit, model selection for the application band, refit of the selected components, their
upper envelope with the random walk capped by the Allan variances, the pooling test and per-axis fits); the
all-frequency PSD bound against the spec sheet (:func:`imupipe.stages.bound.bound_sensor`: the kept
components, the identified envelope imposed below the lowest bin down to a hundredth of 1/(fix + outage), the lines'
policy, the Allan check, per-axis models when the axes differ); the verification in the reference scenario
(:func:`imupipe.stages.verify.verify_sensor`: covariance analysis, replay of the decimated records, reduction
by integrity); the contract (:func:`imupipe.stages.contract.contract_stage`); and the Kalman-filter matrices
of the exported model at the filter step (:func:`imupipe.stages.kf.kf_stage`). The events (bursts, steps) of every
full-rate curve are found as the workflow's outliers stage finds them (:func:`imupipe.stages.outliers.outliers_stage`,
events policy ``warn``): reported in :attr:`NoiseModelResult.events`, ``flags`` and ``to_dict()``, the records
analysed as they are (the line search reads the bursts' stretches filled, as the workflow's). Stationarity tests,
outlier removal, per-axis bounds, figures and tables are left to the workflow (the API takes the records as they
are, every one included).
tests/test_orchestration_parity.py runs the workflow and this function on the same records.

Nothing is printed on stdout (HiGHS is run silent by :mod:`imupipe.bound`).

Example
-------
>>> import numpy as np, imupipe.api as api                                      # doctest: +SKIP
>>> rng = np.random.default_rng(1)
>>> curves = {"rec1/x": 4.4e-5 * np.sqrt(20.0) * rng.standard_normal(20 * 5400)}  # rad/s at 20 Hz
>>> res = api.noise_model(curves, record_rate_hz=20.0, sensor="gyro", spec="config/specs/stim300.yaml")
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
        The KF file's content (:func:`imupipe.stages.kf.kf_stage` at ``kf_dt_s``: F, G, Qc, Phi, Qd, P0, ...,
        the ``bias_initialisation``, the contract's verdict, ``per_axis``): the matrices of the model the
        verification exported (the bound's, or its reduction by integrity). With ``verify=False``, those of the
        bound's model (:func:`imupipe.stages.kf.exported_kf`).
    allan : dict
        Curve label -> ``xarray.Dataset`` of :func:`imupipe.allan_variance` (full rate).
    spectra : dict
        Curve label -> ``xarray.Dataset`` of :func:`imupipe.psd` (decimated, two-sided).
    record_rate_hz, decimate_hz, kf_dt_s : float
        Record rate (Hz), decimated rate (Hz), filter step (s).
    selected : imupipe.identify.AllanFit
        :func:`imupipe.identify.refit_selected`: the fit of the kept components only (the workflow's
        ``model_selected``).
    upper : imupipe.models.NoiseModel
        The identified upper envelope (:func:`imupipe.stages.identify.envelope` of `selected`, its random walk
        capped by :func:`imupipe.bound.random_walk_cap`; dominating every axis's when the axes differ): imposed
        by the bound below the lowest PSD bin.
    lines : imupipe.lines.LinePolicy or None
        The lines policy applied to the bound (None when no policy was asked for).
    verification : dict or None
        :func:`imupipe.stages.verify.verify_stage` of the bound (None when ``verify=False``).
    contract : dict or None
        :func:`imupipe.stages.contract.contract_stage`: the workflow's verdict, ``contract["bounded"]`` (every
        check passed and the verification ran), with ``failed_checks`` (None when ``verify=False``); what
        :attr:`bounded` returns.
    records : dict
        The stages' dicts, as the workflow's files hold them: ``identify``
        (:func:`imupipe.stages.identify.identification_stage`), ``bound``
        (:func:`imupipe.stages.bound.bound_stage`), ``verify`` and ``contract`` (None when ``verify=False``).
    events : list of dict
        The bursts and steps of every curve, as the workflow's outliers files list them
        (:func:`imupipe.stages.outliers.outliers_stage`: ``dataset`` and ``axis`` from the curve label
        ``"<dataset>/<axis>"``, ``kind``, ``time_s`` (s from the record's start), ``size`` (SI) with its interval,
        ``display`` (deg/h, mg for steps; deg/s, g for bursts), ``action``); empty when none was found or the
        search was not asked for (``events=False``).
    """

    sensor: str
    spec_name: str
    bound: Any
    fit: Any
    selection: dict
    kf: dict
    allan: dict = field(repr=False)
    spectra: dict = field(repr=False)
    record_rate_hz: float = 0.0
    decimate_hz: float = 1.0
    kf_dt_s: float = 1.0
    selected: Any = None
    upper: Any = None
    lines: Any = None
    verification: dict | None = None
    contract: dict | None = None
    records: dict = field(default_factory=dict, repr=False)
    events: list = field(default_factory=list)

    @property
    def model(self):
        """The bound's :class:`~imupipe.models.NoiseModel` (SI), before the verification's reduction: the exported
        model, the KF file's (:attr:`kf`), is ``contract["model"]`` (it may drop states the verified outage does not
        need, and then holds for that outage and those fixes only)."""
        return self.bound.model

    @property
    def bounded(self) -> bool:
        """The workflow's verdict: True only when every check passed, the verification included
        (``contract["bounded"]``); False without a verification (``verify=False``): the PSD bound alone does not
        say that a filter using the model will not under-state its error (:attr:`psd_bounded` says that much)."""
        return bool(self.contract is not None and self.contract.get("bounded"))

    @property
    def flags(self) -> list[str]:
        """Every failed or flagged check, as the workflow's summary words them (``"FAIL|FLAG check [where]:
        detail"``; :func:`imupipe.summary.flags_of` on the bound, contract, identification and stationarity records): a
        plausibility FLAG (a unit slip, data far below the sheet, an event in a record: :attr:`events`) does not
        change :attr:`bounded`, so read these too. Empty when nothing failed or was flagged."""
        from imupipe.flagtext import flag_line
        from imupipe.stages.summary import merge_checks
        from imupipe.summary import flags_of

        bound = {**(self.records.get("bound") or {}), **(self.contract or {}), "events": list(self.events)}
        for label, doc in (self.records.get("lines") or {}).items():  # each curve's lines, as the workflow's summary
            dataset, _, axis = str(label).rpartition("/")
            merge_checks(bound, {**doc, "dataset": dataset or None, "sensor": self.sensor, "axis": axis})
        found = flags_of(self.sensor, bound, self.records.get("identify") or {}, self.records.get("stationarity"))
        return [flag_line(f).removeprefix("- ") for f in found]  # the summary's words, without its list bullet

    @property
    def psd_bounded(self) -> bool:
        """True when the model PSD bounds every sample PSD and the spec sheet (``bound.bounded``), nothing more."""
        return bool(self.bound.bounded)

    def to_dict(self) -> dict:
        """Plain, YAML-ready dict: ``bound`` (the bound contract's fields), ``identify`` (fit, model,
        selection), ``kf``, ``events`` (:attr:`events`), ``flags`` (:attr:`flags`); SI units, PSDs two-sided."""
        from imupipe.io import plain

        sel = {k: self.selection.get(k) for k in ("kept", "dropped", "reasons", "band_hz")}
        out = {
            "sensor": self.sensor,
            "spec_name": self.spec_name,
            "rate_hz": float(self.record_rate_hz),
            "decimate_hz": float(self.decimate_hz),
            "curves": list(self.allan),
            "bound": self.bound.to_dict(sensor=self.sensor),
            "identify": {"fit": self.fit.to_dict(), "model": self.fit.model.to_dict(), "selection": plain(sel)},
            "kf": plain(self.kf),
            "events": plain(list(self.events)),
            "flags": list(self.flags),
        }
        if self.selected is not None:
            out["identify"]["model_selected"] = self.selected.model.to_dict()
        if self.upper is not None:
            out["upper_envelope"] = self.upper.to_dict()
        if self.lines is not None:
            out["lines"] = plain(self.lines.to_dict())
        if self.verification is not None:
            out["verification"] = plain(self.verification)
        if self.contract is not None:
            out["contract"] = plain(self.contract)
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


def _truth_of(truth, sensor):
    """The true :class:`~imupipe.models.NoiseModel` of `sensor` from a spec-sheet path or sheet, a model, or None."""
    from imupipe.models import NoiseModel

    if truth is None or isinstance(truth, NoiseModel):
        return truth
    sheet = _spec_of(truth)
    if sensor not in sheet.models:
        raise ValueError(f"truth {sheet.name!r}: no '{sensor}' section")
    return sheet.models[sensor]


def noise_model(
    curves: Mapping[str, Sequence[float]], record_rate_hz: float, sensor: str, spec, *,
    decimate_hz: float = _D["decimate.rate_hz"], window_s: float | None = None, step_s: float | None = None,
    taper: str = _D["psd.taper"], detrend: str = _D["psd.detrend"], psd_confidence: float = _D["psd.confidence"],
    taus=_D["allan.taus"], allan_confidence: float = _D["allan.confidence"],
    components: Sequence[str] = tuple(_D["identify.components"]), n_gm: int = _D["identify.n_gm"],
    n_boot: int = _D["identify.n_boot"], fit_confidence: float = _D["identify.confidence"],
    significance: float = _D["identify.significance"], relevance: float = _D["identify.relevance"],
    adequacy_level: float = _D["identify.adequacy_level"], pooling_level: float = _D["identify.pooling_level"],
    pooling_n_boot: int = _D["identify.pooling_n_boot"], fit_tau_min_samples: float | None = None,
    max_bias_time_s: float | None = None, filter_rate_hz: float = _D["application.filter_rate_hz"],
    outage_s: float = _D["application.outage_s"], mode: str = _D["bound.mode"],
    bound_confidence: float = _D["bound.confidence"], bands_per_decade: int = _D["bound.bands_per_decade"],
    seed: int = 20211, lines_policy: str | None = None, lines_resolution_hz: float = _D["lines.resolution_hz"],
    lines_alpha: float = _D["lines.alpha"], lines_floor_window_bins: int = _D["lines.floor_window_bins"],
    lines_scales=tuple(_D["lines.scales"]),
    lines_low_band_resolution_hz: float | None = _D["lines.low_band_resolution_hz"], fix_s: float = _D["verify.fix_s"],
    verify: bool = True, sigma_fix: float | None = None, fix_rate_hz: float | None = None,
    reduce: bool = _D["verify.reduce"], replay_z: float = _D["verify.replay_z"],
    truth=None, events: bool | Mapping = True, envelope: str = _D["identify.envelope"],
    stationarity: bool | Mapping = True,
) -> NoiseModelResult:
    r"""Identification, bound and Kalman-filter export of one sensor type from in-memory records.

    Parameters
    ----------
    curves : mapping of str to array_like
        Curve label (e.g. ``"lab1/x"``) -> 1-D static record of one axis, in SI (rad/s for a gyro,
        m/s^2 for an accelerometer; a constant offset such as gravity is harmless), sampled at `record_rate_hz`.
    record_rate_hz, sensor, spec :
        Sample rate of every record, Hz; the sensor type, ``"gyro"`` or ``"accel"``; the spec sheet (a YAML file's
        path, or a :class:`imupipe.specsheet.SpecSheet`).
    decimate_hz : float, optional
        Block-average rate for the PSD and stationarity stages, Hz (default 1.0, the paper's).
    window_s, step_s, taper, detrend, psd_confidence :
        Welch settings (window and step in s; default None: :func:`imupipe.defaults.psd_window_step` of the
        shortest curve, the workflow's rule for an unset ``psd.window_s``/``psd.step_s``; Hann, mean removed, 0.95).
    taus, allan_confidence :
        Allan-variance taus (default ``"octave"``) and confidence of its limits (default 0.683).
    components, n_gm, n_boot, fit_confidence, significance, relevance, adequacy_level, pooling_level, pooling_n_boot, fit_tau_min_samples :
        The identification's settings (:func:`imupipe.stages.identify.identify_sensor`, the workflow's
        ``identify`` section; defaults :data:`imupipe.defaults.DEFAULTS`, the workflow's: ``n_boot`` 100). With
        fewer than :func:`imupipe.verify.min_bootstrap` replicates (``n_boot=0`` skips the bootstrap) the
        contract fails its ``identification_intervals`` check: the envelope is then the point fit.
    max_bias_time_s : float, optional
        Longest bias time constant admitted, s (``identify.max_bias_time_s``; None: the verification's rule).
    filter_rate_hz, outage_s : float, optional
        The filter's update rate, Hz (``application.filter_rate_hz``, default 1.0: the KF step is its inverse, the
        reference filter of the verification runs at it) and the outage it must coast through, s
        (``application.outage_s``, default 3600); together they set the band the selection keeps components for.
    mode, bound_confidence, bands_per_decade :
        :func:`imupipe.bound.bound_psd` settings (default ``raw``, 0.95, 10); ``mode="auto"``: every mode's bound
        verified, the tightest passing exported (:mod:`imupipe.bound.auto`; the result's ``bound`` is the winner's,
        ``records["bound"]`` holds every candidate).
    seed : int, optional
        Seed of the fit's bootstrap (default 20211, :data:`imupipe.stages.identify.SEED_FIT`, the workflow's).
    lines_policy : {None, "model", "exclude", "keep"}, optional
        Search every full-rate curve for narrowband lines (:func:`imupipe.lines.find_lines` with the ``lines_*``
        arguments, the ``lines`` section's keys) and apply the policy over the decimated band (None: no search).
    fix_s : float, optional
        Time with position/angle fixes before the outage of the reference scenario, s (default 600): the bound's
        all-frequency span is ``fix_s + outage_s``.
    verify, sigma_fix, reduce, replay_z :
        Run the verification stage on the bound (:func:`imupipe.stages.verify.verify_sensor`: the covariance
        checks, the replay of the decimated records and, with `reduce`, the reduction by integrity; default
        True), as the workflow does; `sigma_fix` the fix sd (m, accel; rad, gyro; default 0.5 m / 0.001745 rad as
        ``verify.sigma_fix_m`` / ``_rad``); `fix_rate_hz` the fixes' rate, Hz (None: the filter's). Then the contract
        and the KF file's matrices of the exported model (:func:`imupipe.stages.kf.kf_stage`); with
        ``verify=False`` the bound's, unreduced, its P0 of p from :meth:`imupipe.biasinit.BiasInitialisation.p0`.
    truth : str, pathlib.Path, imupipe.specsheet.SpecSheet or imupipe.models.NoiseModel, optional
        The true model of simulated records (the workflow's ``simulation.truth``): recorded beside the fit and
        checked by the verification.
    events : bool or mapping, optional
        Find the bursts and steps of every full-rate curve as the workflow's outliers stage does
        (:func:`imupipe.stages.outliers.outliers_stage` on the record as given, :func:`imupipe.events.detect_events`:
        derived thresholds, a false-alarm rate of ``alpha`` per record and axis). True (default): the workflow's
        ``events`` settings (:data:`imupipe.stages.outliers.EVENT_DEFAULTS`); a mapping: those settings over them
        (its ``policy``, if given, must be ``warn``: the API analyses the records as given); False: no search.
        Found events are in the result's ``events``, ``flags`` and ``to_dict()``; the line search fills the bursts.
    stationarity : bool or mapping, optional
        The workflow's stationarity stage on every curve, all kept (:func:`_stationarity_of`): a curve it marks is
        bounded over its noisiest stretch. True (default), settings over the defaults, or False (no test).
    envelope : {"marginal", "joint"}, optional
        The upper envelope's construction (``identify.envelope``, :func:`imupipe.stages.identify.envelope`):
        ``"marginal"`` (default, the paper's) every kept component at its upper limit at once; ``"joint"`` the model
        above the simultaneous band of the fit's PSD over its bootstrap replicates (:mod:`imupipe.identify.joint`).

    Returns
    -------
    NoiseModelResult

    Raises
    ------
    ValueError
        No curves, a curve that is not 1-D or too short for one PSD window, a non-positive rate, an
        unknown sensor, or a spec sheet without that sensor; with `verify`, no decimated record as long as
        ``fix_s + outage_s`` (the replay's window, as in the workflow's verify stage).
    """
    from imupipe.lines import lines_by_curve
    from imupipe.specsheet import display_units
    from imupipe.stages.bound import bound_sensor
    from imupipe.stages.identify import identify_sensor

    spec_sheet = _checked_inputs(curves, record_rate_hz, sensor, spec)
    rate = float(record_rate_hz)
    window_s, step_s = _psd_window(curves, rate, decimate_hz, window_s, step_s)
    found = _events_of(curves, rate, sensor, events)
    allan, spectra, decimated = _per_curve_estimates(curves, rate, sensor, decimate_hz, window_s, step_s, taper,
                                                     detrend, psd_confidence, taus, allan_confidence)
    # identification (rule identify): the curves as the stacked Allan file gives them, NaN entries removed
    true_model = _truth_of(truth, sensor)
    lines = {} if lines_policy is None else _lines_of(curves, rate, sensor, lines_resolution_hz, lines_alpha,
                                                      lines_floor_window_bins, lines_scales, lines_low_band_resolution_hz,
                                                      _event_settings(events))
    ident = identify_sensor(_identification_curves(curves, allan, rate), sensor=sensor, components=list(components),
                            n_gm=n_gm, n_boot=n_boot, confidence=fit_confidence, significance=significance,
                            relevance=relevance, filter_rate_hz=filter_rate_hz, outage_s=outage_s,
                            adequacy_level=adequacy_level, pooling_level=pooling_level, pooling_n_boot=pooling_n_boot,
                            span_s=fix_s + outage_s, fit_tau_min_samples=fit_tau_min_samples,
                            truth=true_model, seed=seed, lines=lines_by_curve(lines, lines_policy or "model"),
                            envelope_lines=lines_policy == "model", envelope_lines_below_hz=0.5 * decimate_hz,
                            envelope_kind=envelope)
    # stationarity (the curves bounded at their noisiest stretch), bound: the stacked spectra, Allan grid, lines files
    stat, stretches = _stationarity_of(curves, decimated, allan, decimate_hz, sensor, lines, stationarity)
    f, dt, first = _stacked_spectra(spectra, decimate_hz)
    with _no_stdout_fd():
        bound = bound_sensor(f, {k: sp["psd"].values for k, sp in spectra.items()},
                             {k: sp["edf"].values for k, sp in spectra.items()}, spec_sheet.models[sensor],
                             ident.record, dt=dt, sensor=sensor, mode=mode, n_gm=n_gm, confidence=bound_confidence,
                             bands_per_decade=bands_per_decade, span_s=fix_s + outage_s,
                             filter_rate_hz=filter_rate_hz, taper=first.attrs.get("taper", taper),
                             allan=_stacked_allan(allan), lines=lines, line_policy=lines_policy or "model",
                             spec_units=display_units(spec_sheet, sensor), spec_name=spec_sheet.name,
                             stretches=stretches)
    # verification (rule verify), the contract (rule contract) and the KF file's matrices (rule kf)
    sigma_fix = _D["verify.sigma_fix_" + ("m" if sensor == "accel" else "rad")] if sigma_fix is None else sigma_fix
    kf_dt = 1.0 / float(filter_rate_hz)
    verification, contract, kf = _verified_kf(
        bound, sensor, spec_sheet, decimated, dt, true_model, fix_s, outage_s, sigma_fix, filter_rate_hz, reduce,
        replay_z, max_bias_time_s, fix_rate_hz, kf_dt, verify)
    bound_record = bound.record  # bound.mode auto: every candidate's entry
    if bound.candidates and verification and verification.get("auto_selection"):  # bound.mode auto: the winner's
        bound = bound.candidates[verification["auto_selection"]["winner"]]
    return NoiseModelResult(sensor=sensor, spec_name=spec_sheet.name, bound=bound.result, fit=ident.fit,
                            selection=ident.selection, kf=kf, allan=allan, spectra=spectra, record_rate_hz=rate,
                            decimate_hz=float(decimate_hz), kf_dt_s=kf_dt, selected=ident.selected,
                            upper=bound.upper, lines=bound.policy if lines_policy is not None else None,
                            verification=verification, contract=contract,
                            records={"identify": ident.record, "bound": bound_record, "verify": verification,
                                     "contract": contract, "stationarity": stat, "lines": lines}, events=found)


def _stationarity_of(curves, decimated, allan, rate: float, sensor: str, lines, settings):
    """(summary, curve label -> noisiest-stretch scan of the curves it marks) of the decimated curves at `rate` (Hz):
    the rules stationarity (:func:`imupipe.stages.stationarity.stationarity_stage`: the calibrated Levene + KS test,
    the noisiest-stretch scan and its stretch test) and stationarity_summary
    (:func:`~imupipe.stages.stationarity.summary_stage`) with ``on_fail: warn``; (None, {}) when `settings` is False.
    `settings`: True (the workflow's defaults) or a mapping of ``n_segments``, ``alpha``, ``test``, ``n_sim``,
    ``n_sim_max``, ``close_z`` over them (:func:`noise_model`'s ``stationarity``; docs/method.md, "Stationarity")."""
    if settings is False:
        return None, {}
    from imupipe.lines import lines_by_curve
    from imupipe.stages.stationarity import marked_stretches, paper_test, stationarity_stage, summary_stage

    keys = ("n_segments", "alpha", "test", "n_sim", "n_sim_max", "close_z")
    given = dict(settings) if isinstance(settings, Mapping) else {}
    unknown = sorted(set(given) - set(keys))
    if unknown:
        raise ValueError(f"stationarity: unknown setting(s) {unknown}; expected some of {list(keys)}")
    kw = {k: given.get(k, _D[f"stationarity.{k}"]) for k in keys}
    by_curve = lines_by_curve(lines) if lines else {}  # the stationarity job reads every line (policy aside)
    verdicts, papers = [], []
    for label in curves:
        dataset, axis = label.rsplit("/", 1) if "/" in label else (label, label)
        av = allan[label]
        v = stationarity_stage(decimated[label], float(rate), dataset=dataset, sensor=sensor, axis=axis,
                               allan=(av["tau"].values, av["avar"].values, av["edf"].values),
                               lines=by_curve.get(label, ()), **kw)
        verdicts.append(v)
        papers.append(paper_test(v, decimated[label]))
    summary = summary_stage(verdicts, "warn", sensor, papers)
    return summary, marked_stretches(summary)


def _checked_inputs(curves, record_rate_hz, sensor, spec):
    """The spec sheet of :func:`noise_model` after its arguments' checks (sensor, rate, curves given, the sheet's
    section of the sensor)."""
    if sensor not in ("gyro", "accel"):
        raise ValueError(f"sensor: expected 'gyro' or 'accel', got {sensor!r}")
    if not (float(record_rate_hz) > 0):
        raise ValueError(f"record_rate_hz: expected a positive sample rate in Hz, got {record_rate_hz!r}")
    if not curves:
        raise ValueError("curves: no record given (expected label -> 1-D array)")
    spec_sheet = _spec_of(spec)
    if sensor not in spec_sheet.models:
        raise ValueError(f"spec {spec_sheet.name!r}: no '{sensor}' section")
    return spec_sheet


def _psd_window(curves, rate: float, decimate_hz: float, window_s, step_s):
    """The Welch window and step, s: those given, else the workflow's rule for an unset ``psd.window_s`` /
    ``psd.step_s`` (:func:`imupipe.defaults.psd_window_step`) on the shortest curve."""
    if window_s is not None and step_s is not None:
        return window_s, step_s
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
    return window_s, step_s


def _per_curve_estimates(curves, rate: float, sensor: str, decimate_hz, window_s, step_s, taper, detrend,
                         psd_confidence, taus, allan_confidence):
    """Per curve (the rules allan, decimate, psd): the overlapping Allan variance of the full-rate record, its
    block average to `decimate_hz` and that's two-sided Welch PSD. Returns (allan, spectra, decimated) by label."""
    from imupipe.allan import allan_variance
    from imupipe.spectra import decimate, psd
    from imupipe.units import SI_UNITS

    units = SI_UNITS[sensor]
    allan, spectra, decimated = {}, {}, {}
    for label, x in curves.items():
        x = np.asarray(x, dtype=np.float64)
        if x.ndim != 1:
            raise ValueError(f"curves[{label!r}]: expected a 1-D record, got shape {x.shape}")
        y, new_rate = decimate(x, rate, decimate_hz)
        if y.size * (1.0 / new_rate) < window_s:
            raise ValueError(f"curves[{label!r}]: {x.size / rate:g} s long, shorter than window_s = {window_s:g} s")
        decimated[label] = y
        allan[label] = allan_variance(x, rate, taus=taus, confidence=allan_confidence, units=units)
        spectra[label] = psd(y, new_rate, window_s=window_s, step_s=step_s, taper=taper,
                             detrend=None if detrend == "none" else detrend, confidence=psd_confidence, units=units)
    return allan, spectra, decimated


def _identification_curves(curves, allan, rate: float) -> list:
    """The identification's :class:`imupipe.stages.identify.Curve` of every curve, NaN entries removed (as the
    stacked Allan file gives them)."""
    from imupipe.stages.identify import Curve

    out = []
    for label, x in curves.items():
        av = allan[label]
        a, e = av["avar"].values, av["edf"].values
        ok = np.isfinite(a) & np.isfinite(e)
        out.append(Curve(label, av["tau"].values[ok], a[ok], e[ok], int(np.asarray(x).size), rate,
                         label.rsplit("/", 1)[-1]))
    return out


def _stacked_spectra(spectra, decimate_hz: float):
    """(frequency grid, Hz; decimated sample interval, s; the first curve's spectrum) of the curves' PSDs, which
    must share one grid (as in the stacked spectra file)."""
    first = next(iter(spectra.values()))
    f = first["frequency"].values
    for label, sp in spectra.items():
        if sp["frequency"].size != f.size:
            raise ValueError(f"curves[{label!r}]: its PSD has {sp['frequency'].size} bins, the first curve's "
                             f"{f.size}: give records whose decimated length covers the same windows")
    return f, 1.0 / float(first.attrs.get("rate_hz", decimate_hz)), first


def _stacked_allan(allan):
    """(tau grid, s; label -> (AV u^2, edf)) on the union of the curves' taus (the stacked Allan file's outer
    join), NaN where a curve has no value."""
    tau = np.unique(np.concatenate([av["tau"].values for av in allan.values()]))
    allan_curves = {}
    for label, av in allan.items():
        at = np.searchsorted(tau, av["tau"].values)
        allan_curves[label] = tuple(np.full(tau.shape, np.nan) for _ in range(2))
        allan_curves[label][0][at], allan_curves[label][1][at] = av["avar"].values, av["edf"].values
    return tau, allan_curves


def _event_settings(events) -> dict | None:
    """The ``events`` settings of :func:`noise_model`'s `events` argument over
    :data:`imupipe.stages.outliers.EVENT_DEFAULTS`; None when `events` is False (no search). TypeError or
    ValueError naming what is wrong (an unknown key, a policy other than ``warn``)."""
    if events is False or events is None:
        return None
    from imupipe.stages.outliers import EVENT_DEFAULTS

    if events is True:
        settings = dict(EVENT_DEFAULTS)
    elif isinstance(events, Mapping):
        unknown = sorted(set(events) - set(EVENT_DEFAULTS))
        if unknown:
            raise ValueError(f"events: unknown setting(s) {unknown}; expected some of {sorted(EVENT_DEFAULTS)}")
        settings = {**EVENT_DEFAULTS, **events}
    else:
        raise TypeError(f"events: expected True, False or a mapping of the events settings, got {events!r}")
    if settings["policy"] != "warn":
        raise ValueError(f"events: policy {settings['policy']!r}: the API analyses the records as given; only "
                         "'warn' (report the events) is available here (the workflow's events.policy has the others)")
    return settings


def _events_of(curves, rate: float, sensor: str, events) -> list:
    """The events of every full-rate curve as the workflow's outliers files list them (rule outliers:
    :func:`imupipe.stages.outliers.outliers_stage` with the events policy ``warn``), in the curves' order; [] when
    `events` is False. A curve label ``"<dataset>/<axis>"`` gives the event's dataset and axis (else the whole
    label is the dataset)."""
    settings = _event_settings(events)
    if settings is None:
        return []
    from imupipe.stages.outliers import outliers_stage
    from imupipe.units import SI_UNITS

    out = []
    for label, x in curves.items():
        dataset, _, axis = str(label).rpartition("/")
        report, _ = outliers_stage(np.asarray(x, dtype=np.float64), rate, units=SI_UNITS[sensor],
                                   dataset=dataset or str(label), sensor=sensor, axis=axis if dataset else None,
                                   events=settings, series=f"curves[{label!r}]")
        out += report.get("events") or []
    return out


def _lines_of(curves, rate: float, sensor: str, resolution_hz, alpha, floor_window_bins, scales=(1,),
              low_band_resolution_hz=None, events=None) -> dict:
    """The lines file of every full-rate curve (rule lines: :func:`imupipe.lines.find_lines` on the curve, with its
    bursts filled under the `events` settings, :func:`imupipe.stages.outliers.line_search_series`; None: no burst
    search), by label."""
    from dataclasses import replace

    from imupipe.lines import find_lines
    from imupipe.stages.outliers import line_search_series
    from imupipe.units import SI_UNITS

    out = {}
    for label, x in curves.items():
        y, filled = line_search_series(np.asarray(x, dtype=np.float64), rate, events)
        search = find_lines(y, rate, resolution_hz=resolution_hz, alpha=alpha, floor_window_bins=floor_window_bins,
                            units=SI_UNITS[sensor], label=label, scales=scales,
                            low_band_resolution_hz=low_band_resolution_hz)
        out[label] = replace(search, bursts_filled_s=filled).to_dict()
    return out


def _verified_kf(bound, sensor, spec_sheet, decimated, dt, true_model, fix_s, outage_s, sigma_fix, filter_rate_hz,
                 reduce, replay_z, max_bias_time_s, fix_rate_hz, kf_dt, verify):
    """The rules verify, contract and kf on the bound (:class:`imupipe.stages.bound.BoundStage`): (verification,
    contract, KF file's content); without `verify`, (None, None, the KF matrices of the bound's model unreduced,
    its bias started where the verification would start it)."""
    from imupipe.stages.contract import contract_stage
    from imupipe.stages.kf import exported_kf, kf_stage
    from imupipe.stages.verify import verify_sensor

    turn_on = spec_sheet.turn_on_bias.get(sensor, 0.0)
    if verify:
        verification = verify_sensor(bound.record, sensor, spec=spec_sheet.models[sensor], records=decimated,
                                     record_rate_hz=1.0 / dt, truth=true_model, turn_on_bias=turn_on, fix_s=fix_s,
                                     outage_s=outage_s, sigma_fix=sigma_fix, filter_rate_hz=filter_rate_hz,
                                     reduce=reduce, replay_z=replay_z, max_bias_time_s=max_bias_time_s,
                                     fix_rate_hz=fix_rate_hz)[0]
        contract = contract_stage(bound.record, verification, spec_sheet, sensor=sensor, kf_file=None,
                                  on_failure="warn", kf_rate_hz=filter_rate_hz, outage_s=outage_s,
                                  filter_rate_hz=filter_rate_hz)
        kf = kf_stage(bound.record, verification, contract, dt_s=kf_dt, outage_s=outage_s, sensor=sensor)
        return verification, contract, kf
    from imupipe.biasinit import bias_initialisation
    from imupipe.stages.verify import model_of

    m = model_of(bound.record["bound"])
    record_s = max(y.size for y in decimated.values()) * dt
    bias = bias_initialisation(m, spec=spec_sheet.models[sensor], upper=bound.upper, turn_on_bias=turn_on,
                               record_s=record_s, max_bias_time_s=max_bias_time_s, run_s=fix_s + outage_s,
                               flicker_band_hz=(0.01 / outage_s, 0.5 * filter_rate_hz))
    kf = exported_kf({"model": m.to_dict(), "bias_initialisation": {
        "p0_random_walk": bias.p0(m, fix_s + outage_s)}}, kf_dt, sensor)
    return None, None, kf
