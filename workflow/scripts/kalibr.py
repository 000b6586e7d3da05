"""Kalibr imu.yaml from the gyro and accel bounds (rule kalibr), imupipe.kalibr.

update_rate is the IMU's sample rate (imupipe.kalibr.imu_rate: one rate for every dataset, else refused with
each dataset's rate; a dataset whose sheet leaves rate_hz empty has the rate its timestamps gave, from the
identify files: imupipe.kalibr.dataset_rates), rostopic the dataset sheet's topic (imupipe.kalibr.rostopic_of), the densities the
bounding continuous-time values with Gauss-Markov terms folded into the random walk, and the comment block the
inflation factor against the identified model.

The values follow the exported Kalman-filter model (kf/{spec}/{sensor}.yaml: the bound after the verified
reduction), so the two files never disagree. One exception: an export without any bias-drift state (the verified
reduction dropped every GM and random walk) takes the bound's drift terms, as Kalibr needs a positive random walk
(imupipe.kalibr.with_bias_drift, stated in the comment block); a bound without any is refused. When the KF export
keeps no line state (none in the bound, or the verified reduction dropped every one), the two-term values are
derived from the exported model, with its reduction and the horizon it holds for in the comment block. An exported model holding a narrowband line state (sigma > 0) is
refused: the file then holds no Kalibr field (Kalibr fails on it rather than using values that do not bound near the
line), only `refused: true`, the reason and those lines, and the two-term values without the line as commented-out
lines for a user who accepts the under-statement knowingly. The run summary flags it."""

import logging
from dataclasses import replace

from imupipe.io import read_yaml, run_job, write_text_atomic

REFUSED = "refused"


def lines_of(kf: dict) -> list:
    """The narrowband line states of an exported KF model (SI: sigma in u, f0 in Hz, zeta), sigma > 0 only (a
    sigma-0 term has no state)."""
    return [t for t in ((kf.get("parameters") or {}).get("narrowband") or []) if float(t.get("sigma") or 0.0) > 0]


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


def main(path_gyro: str, path_accel: str, path_id_gyro: str, path_id_accel: str, rates: dict, topics: dict,
         path_out: str, spec: str, path_kf_gyro: str, path_kf_accel: str) -> None:
    from imupipe.kalibr import (
        dataset_rates, imu_rate, kalibr_imu, model_of_bound, model_of_kf, rostopic_of, with_bias_drift, write_kalibr,
    )
    from imupipe.models import NoiseModel

    bounds = {"gyro": read_yaml(path_gyro), "accel": read_yaml(path_accel)}
    kfs = {"gyro": read_yaml(path_kf_gyro), "accel": read_yaml(path_kf_accel)}
    # the identified model the inflation factors compare with: the selected model refitted (kept components)
    ident = {}
    curve_rates = {}  # "dataset/axis" -> Hz: the rate of each record (its timestamps' where the sheet gives none)
    for s, p in (("gyro", path_id_gyro), ("accel", path_id_accel)):
        doc = read_yaml(p)
        ident[s] = NoiseModel.from_dict(doc.get("model_selected") or doc["model"])
        curve_rates.update(doc.get("rate_hz") or {})
    try:
        rate = imu_rate(dataset_rates(rates, curve_rates))
    except ValueError as exc:  # one Kalibr file holds one IMU rate: refused, and said so, without failing the run
        logging.warning("Kalibr export refused: %s", exc)
        write_text_atomic("# Kalibr IMU noise model NOT WRITTEN by imupipe: the datasets differ in sample rate, and\n"
                          "# Kalibr's update_rate is the IMU's one sample rate. Use the Kalman-filter export\n"
                          f"# kf/{spec}/<sensor>.yaml, or run one configuration per rate.\n"
                          f"{REFUSED}: true\nreason: {str(exc)!r}\n", path_out)
        return
    topic = rostopic_of(topics)
    source = (f"spec sheet {bounds['gyro'].get('spec_name', spec)} ({spec}), {bounds['gyro'].get('mode', '-')}-mode "
              f"bound of {len(rates)} dataset(s) at {rate:g} Hz")
    lines = {s: lines_of(k) for s, k in kfs.items() if lines_of(k)}
    notes = export_notes(kfs, rate)
    # the two-term model of each exported KF model (white, GM folded into the random walk); a line cannot be folded
    # in, so the two-term values are computed without it and, where the KF model has one, only written as comments
    models = {s: replace(model_of_kf(k, p), narrowband=())
              for (s, k), p in zip(kfs.items(), (path_kf_gyro, path_kf_accel), strict=True)}
    # Kalibr needs a positive bias random walk: an export without drift states takes the bound's (said so)
    for s in models:
        models[s], note = with_bias_drift(models[s], model_of_bound(bounds[s]), s)
        if note:
            notes.append(note)
            logging.info("Kalibr: %s", note)
    try:
        imu = kalibr_imu(models["gyro"], models["accel"], update_rate_hz=rate, rostopic=topic,
                         identified_gyro=ident["gyro"], identified_accel=ident["accel"])
    except ValueError as exc:  # no bias drift in the bound either: refused, and said so, without failing the run
        logging.warning("Kalibr export refused: %s", exc)
        write_text_atomic("# Kalibr IMU noise model NOT WRITTEN by imupipe: Kalibr's model needs a positive white noise\n"
                          "# and bias random walk, and the bound has none of one of them. Use the Kalman-filter export\n"
                          f"# kf/{spec}/<sensor>.yaml.\n{REFUSED}: true\nreason: {str(exc)!r}\n", path_out)
        return
    if lines:
        logging.warning("Kalibr export refused: narrowband line state(s) in the exported %s KF model",
                        ", ".join(lines))
        write_text_atomic(refused_text(lines, imu, source, notes), path_out)
        return
    write_kalibr(imu, path_out, source=source, notes=notes)
    logging.info("Kalibr imu.yaml: update_rate %g Hz, rostopic %s, inflation %s", rate, topic, imu.inflation)


if __name__ == "__main__":
    i = snakemake.input
    run_job(main, snakemake.log[0], path_gyro=i.gyro, path_accel=i.accel, path_id_gyro=i.identified_gyro,
            path_id_accel=i.identified_accel, rates=dict(snakemake.params.rates), topics=dict(snakemake.params.topics),
            path_out=snakemake.output.kalibr, spec=snakemake.wildcards.spec, path_kf_gyro=i.kf_gyro,
            path_kf_accel=i.kf_accel)
