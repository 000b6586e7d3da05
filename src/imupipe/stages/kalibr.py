"""The Kalibr export of one spec sheet (rule ``kalibr``): ``imu.yaml`` from the gyro and accel bounds, the exported KF
models, the identify files and the contracts (:mod:`imupipe.kalibr`).

update_rate is the IMU's sample rate (imupipe.kalibr.imu_rate: one rate for every dataset, or the one of theirs the
config's kalibr.update_rate_hz names, else refused with each dataset's rate; a dataset whose sheet leaves rate_hz
empty has the rate its timestamps gave, from the identify files: imupipe.kalibr.dataset_rates), rostopic the
dataset sheet's topic (imupipe.kalibr.rostopic_of), the densities
the smallest Kalibr pair (white noise, random walk) whose PSD bounds the exported model's over the application band
[1/horizon_s, update_rate/2] (imupipe.kalibr.kalibr_pair: an LP; per axis when the KF file has per-axis models, the
largest of each, the comment naming the axis), and the comment block the rule, the exported model's effective
in-band inflation against the spec sheet (the contract's inband_inflation) and the ratio to the identified model's
pair.

The values follow the exported Kalman-filter model (kf/{spec}/{sensor}.yaml: the bound after the verified
reduction), so the two files never disagree. One exception: an export without any bias-drift state (the verified
reduction dropped every GM and random walk) takes the bound's drift terms, as Kalibr needs a positive random walk
(imupipe.kalibr.with_bias_drift, stated in the comment block); a bound without any is refused. When the KF export
keeps no line state (none in the bound, or the verified reduction dropped every one), the two-term values are
derived from the exported model, with its reduction and the horizon it holds for in the comment block. An exported
model holding a narrowband line state (sigma > 0) is refused: the file then holds no Kalibr field (Kalibr fails on
it rather than using values that do not bound near the line), only `refused: true`, the reason and those lines, and
the two-term values without the line as commented-out lines for a user who accepts the under-statement knowingly.
The run summary flags it.

Plain values in (the files' dicts, the dataset sheet's rates and topics), the file's text out
(:func:`kalibr_stage`).
"""

from __future__ import annotations

import logging
from dataclasses import replace

__all__ = ["REFUSED", "axis_models", "band_of", "export_notes", "inband_notes", "kalibr_stage", "lines_of",
           "refused_text"]

REFUSED = "refused"


def lines_of(kf: dict) -> list:
    """The narrowband line states of an exported KF model (SI: sigma in u, f0 in Hz, zeta), sigma > 0 only (a
    sigma-0 term has no state). With per-axis models (``per_axis``) only the models the file exports for some axis
    count, as Kalibr's values come from those (:func:`axis_models`): each axis's own, and the global model only
    when some axis is given it."""
    def states(doc):
        return [t for t in ((doc.get("parameters") or {}).get("narrowband") or []) if float(t.get("sigma") or 0.0) > 0]

    per = kf.get("per_axis") or {}
    out = states(kf) if not per or any(e.get("model") != "own" for e in per.values()) else []
    for e in per.values():  # an axis's own exported model counts as well
        if e.get("model") == "own":
            out += [t for t in states(e) if t not in out]
    return out


def export_notes(kfs: dict, update_rate_hz: float | None = None) -> list:
    """Comment lines stating, per sensor, what exported KF model the values come from (imupipe.kf.export_scope),
    and, when Kalibr's update_rate is not the rate of the reference filter that verified that model, that the
    verification (and any state the reduction dropped) holds at that filter's rate only."""
    out = []
    for sensor, kf in kfs.items():
        scope = kf.get("export") or {}
        out.append(f"{sensor}: from the exported KF model ({scope.get('statement', 'the bound model')})")
        vrate = scope.get("verified_filter_rate_hz")
        if vrate and update_rate_hz and abs(float(vrate) - float(update_rate_hz)) > 1e-9 * float(update_rate_hz):
            out.append(f"{sensor}: verified with a reference filter at {float(vrate):g} Hz, not at this update_rate "
                       f"({float(update_rate_hz):g} Hz): the verification, and any state its reduction dropped, hold "
                       "at that rate only")
        bi = kf.get("bias_initialisation") or {}
        if bi.get("required_std"):
            unit = "rad/s" if sensor == "gyro" else "m/s^2"
            out.append(f"{sensor}: bias initialisation: start the filter's bias with a standard deviation of at "
                       f"least {float(bi['required_std']):.3g} {unit} per axis (variance {float(bi['required_variance']):.3g}"
                       f" ({unit})^2, rests on {bi.get('rests_on', '-')}): Kalibr's random walk alone starts from "
                       "what the records cannot show")
        if not kf.get("bounded", True):
            out.append(f"{sensor}: NOT BOUNDED: the KF model failed its integrity contract; for diagnosis only")
    return out


def refused_text(lines: dict, imu, source: str, notes=()) -> str:
    """The comment block and `refused` key of a refused export (see the module docstring)."""
    from imupipe.kalibr import kalibr_text

    out = [
        "# Kalibr IMU noise model NOT WRITTEN by imupipe: the exported KF model has narrowband line state(s) that",
        "# Kalibr's model (white noise + bias random walk) cannot carry. Densities without the line(s) would",
        "# under-state the noise near the line frequencies, so they are not given as Kalibr fields: use the",
        "# Kalman-filter export kf/<spec>/<sensor>.yaml, whose narrowband states carry the line(s) listed below.",
        f"# Source: {source}",
        *[f"# {n}" for n in notes],
        "# Line states of the exported KF model (sigma in the sensor's SI unit, f0 in Hz):",
    ]
    for sensor, terms in lines.items():
        for t in terms:
            out.append(f"#   {sensor}: sigma {t.get('sigma'):.4g}, f0 {t.get('f0_hz'):.6g} Hz, zeta {t.get('zeta'):.3g}")
    out.append("# The two-term values WITHOUT the line(s) (NOT bounding), for a user who accepts that knowingly:")
    out += ["#   " + ln for ln in kalibr_text(imu).splitlines() if not ln.startswith("#")]
    out += [f"{REFUSED}: true",
            f"reason: narrowband line state(s) in the exported {', '.join(lines)} KF model; Kalibr's model cannot "
            "bound them"]
    return "\n".join(out) + "\n"


def band_of(kf: dict, path: str, update_rate_hz: float) -> tuple:
    """Kalibr's band [1/horizon_s, update_rate_hz/2] Hz (imupipe.inband.application_band at the IMU's rate: Kalibr
    runs its filter at update_rate), the horizon from the exported KF model's export scope."""
    from imupipe.inband import application_band

    horizon = (kf.get("export") or {}).get("horizon_s")
    if not horizon:
        raise ValueError(f"{path}: the export scope gives no horizon_s: no band for Kalibr")
    return application_band(float(horizon), float(update_rate_hz))


def axis_models(kf: dict, path: str) -> dict:
    """Label -> the model the KF file exports: per axis (its own model or the global one) when the file has
    per_axis, else {"global": the global model}; lines removed (see lines_of)."""
    from imupipe.kalibr import model_of_kf

    glob = replace(model_of_kf(kf, path), narrowband=())
    per = kf.get("per_axis") or {}
    if not per:
        return {"global": glob}
    return {str(ax): (replace(model_of_kf(e, f"{path} per_axis {ax}"), narrowband=()) if e.get("model") == "own"
                      else glob) for ax, e in per.items()}


def inband_notes(contracts: dict) -> list:
    """Comment lines with each sensor's effective in-band inflation (the contract's inband_inflation)."""
    from imupipe.inband import inband_line

    out = []
    for sensor, con in contracts.items():
        text = inband_line((con or {}).get("inband_inflation"))
        if text:
            out.append(f"{sensor}: exported model {text}")
        for ax, pa in ((con or {}).get("per_axis_models") or {}).items():
            t = inband_line((pa or {}).get("inband_inflation"))
            if t:
                out.append(f"{sensor} axis {ax}: {t}")
    return out


def kalibr_stage(bounds: dict, kfs: dict, identified: dict, contracts: dict, rates: dict, topics: dict, *, spec: str,
                 kf_paths: dict, update_rate_hz: float | None = None) -> str:
    """The text of ``kf/{spec}/kalibr_imu.yaml``. `bounds`, `kfs`, `identified`, `contracts`: {"gyro": dict, "accel":
    dict} of the bound, KF, identify and contract files (contracts may be empty); `rates` {dataset: Hz or None} and
    `topics` {dataset: topic or None} from the dataset sheet; `kf_paths` the KF files' paths (named in messages);
    `update_rate_hz` the config's ``kalibr.update_rate_hz`` (Hz, or None): the rate to export at where the datasets
    differ in rate, one of theirs (:func:`imupipe.kalibr.imu_rate`).
    A refused export (rates that differ, no bias drift, a line state) is a file with ``refused: true`` and the
    reason, logged as a warning; the run goes on."""
    from imupipe.kalibr import (
        RATE_RTOL, dataset_rates, imu_rate, kalibr_imu, kalibr_text, model_of_bound, rostopic_of, with_bias_drift,
    )
    from imupipe.stages.identify import selected_model

    # the identified model the inflation factors compare with: the selected model refitted (kept components)
    ident = {s: selected_model(doc) for s, doc in identified.items()}
    curve_rates = {}  # "dataset/axis" -> Hz: the rate of each record (its timestamps' where the sheet gives none)
    for doc in identified.values():
        curve_rates.update(doc.get("rate_hz") or {})
    try:
        per_dataset = dataset_rates(rates, curve_rates)
        rate = imu_rate(per_dataset, named=update_rate_hz)
    except ValueError as exc:  # one Kalibr file holds one IMU rate: refused, and said so, without failing the run
        logging.warning("Kalibr export refused: %s", exc)
        return ("# Kalibr IMU noise model NOT WRITTEN by imupipe: the datasets differ in sample rate, and\n"
                "# Kalibr's update_rate is the IMU's one sample rate. Set kalibr.update_rate_hz in the config to\n"
                "# the rate Kalibr's IMU runs at (one of the datasets'), or use the Kalman-filter export\n"
                f"# kf/{spec}/<sensor>.yaml.\n"
                f"{REFUSED}: true\nreason: {str(exc)!r}\n")
    topic = rostopic_of(topics)
    source = (f"spec sheet {bounds['gyro'].get('spec_name', spec)} ({spec}), {bounds['gyro'].get('mode', '-')}-mode "
              f"bound of {len(rates)} dataset(s) at {rate:g} Hz")
    lines = {s: lines_of(k) for s, k in kfs.items() if lines_of(k)}
    notes = export_notes(kfs, rate)
    # the named rate of datasets that differ in rate (imu_rate's own tolerance decides what differs)
    if update_rate_hz is not None and any(abs(float(v) - rate) > RATE_RTOL * rate for v in per_dataset.values()):
        notes.append(f"update_rate {rate:g} Hz as the config names it (kalibr.update_rate_hz), of datasets at "
                     + ", ".join(f"{k} {float(v):g} Hz" for k, v in per_dataset.items())
                     + f": the pair bounds the exported model up to {rate / 2:g} Hz, which the records at that rate "
                     "cover")
    # the two-term model of each exported KF model (white, GM folded into the random walk); a line cannot be folded
    # in, so the two-term values are computed without it and, where the KF model has one, only written as comments
    models = {s: axis_models(k, kf_paths[s]) for s, k in kfs.items()}
    # Kalibr's filter runs at update_rate: the pair bounds the exported model from 1/horizon up to its Nyquist
    band = band_of(kfs["gyro"], kf_paths["gyro"], rate)
    # Kalibr needs a positive bias random walk: an export without drift states takes the bound's (said so)
    for s in models:
        for ax in models[s]:
            models[s][ax], note = with_bias_drift(models[s][ax], model_of_bound(bounds[s]), s)
            if note and note not in notes:
                notes.append(note)
                logging.info("Kalibr: %s", note)
    notes += inband_notes(contracts)
    try:
        imu = kalibr_imu(models["gyro"], models["accel"], update_rate_hz=rate, band_hz=band, rostopic=topic,
                         identified_gyro=ident["gyro"], identified_accel=ident["accel"])
    except ValueError as exc:  # no bias drift in the bound either: refused, and said so, without failing the run
        logging.warning("Kalibr export refused: %s", exc)
        return ("# Kalibr IMU noise model NOT WRITTEN by imupipe: Kalibr's model needs a positive white noise\n"
                "# and bias random walk, and the bound has none of one of them. Use the Kalman-filter export\n"
                f"# kf/{spec}/<sensor>.yaml.\n{REFUSED}: true\nreason: {str(exc)!r}\n")
    if lines:
        logging.warning("Kalibr export refused: narrowband line state(s) in the exported %s KF model",
                        ", ".join(lines))
        return refused_text(lines, imu, source, notes)
    logging.info("Kalibr imu.yaml: update_rate %g Hz, rostopic %s, inflation %s", rate, topic, imu.inflation)
    return kalibr_text(imu, source=source, notes=notes)
