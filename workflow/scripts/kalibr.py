"""Kalibr imu.yaml from the gyro and accel bounds (rule kalibr), imupipe.kalibr.

update_rate is the IMU's sample rate (imupipe.kalibr.imu_rate: one rate for every dataset, else refused with
each dataset's rate; a dataset whose sheet leaves rate_hz empty has the rate its timestamps gave, from the
identify files: imupipe.kalibr.dataset_rates), rostopic the dataset sheet's topic (imupipe.kalibr.rostopic_of), the densities the
bounding continuous-time values with Gauss-Markov terms folded into the random walk, and the comment block the
inflation factor against the identified model.

A bound holding a narrowband line is refused: the file then holds no Kalibr field (Kalibr fails on it rather than
using values that do not bound near the line), only `refused: true`, the reason and the lines, and the two-term
values without the line as commented-out lines for a user who accepts the under-statement knowingly. The run
summary flags it."""

import logging
from dataclasses import replace

from imupipe.io import read_yaml, run_job, write_text_atomic

REFUSED = "refused"


def lines_of(bound: dict) -> list:
    """The narrowband terms of a bound contract (SI: sigma in u, f0 in Hz, zeta)."""
    return list((bound.get("bound") or {}).get("narrowband") or [])


def refused_text(lines: dict, imu, source: str) -> str:
    """The comment block and `refused` key of a refused export (see the module docstring)."""
    from imupipe.kalibr import kalibr_text

    out = [
        "# Kalibr IMU noise model NOT WRITTEN by imupipe: the bound has narrowband line(s) that Kalibr's model",
        "# (white noise + bias random walk) cannot carry. Densities without the line(s) would under-state the noise",
        "# near the line frequencies, so they are not given as Kalibr fields: use the Kalman-filter export",
        "# kf/<spec>/<sensor>.yaml, whose narrowband states carry the line(s).",
        f"# Source: {source}",
        "# Lines of the bound (sigma in the sensor's SI unit, f0 in Hz):",
    ]
    for sensor, terms in lines.items():
        for t in terms:
            out.append(f"#   {sensor}: sigma {t.get('sigma'):.4g}, f0 {t.get('f0_hz'):.6g} Hz, zeta {t.get('zeta'):.3g}")
    out.append("# The two-term values WITHOUT the line(s) (NOT bounding), for a user who accepts that knowingly:")
    out += ["#   " + ln for ln in kalibr_text(imu).splitlines() if not ln.startswith("#")]
    out += [f"{REFUSED}: true",
            f"reason: narrowband line(s) in the {', '.join(lines)} bound; Kalibr's model cannot bound them"]
    return "\n".join(out) + "\n"


def main(path_gyro: str, path_accel: str, path_id_gyro: str, path_id_accel: str, rates: dict, topics: dict,
         path_out: str, spec: str) -> None:
    from imupipe.kalibr import dataset_rates, imu_rate, kalibr_imu, model_of_bound, rostopic_of, write_kalibr
    from imupipe.models import NoiseModel

    bounds = {"gyro": read_yaml(path_gyro), "accel": read_yaml(path_accel)}
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
    lines = {s: lines_of(b) for s, b in bounds.items() if lines_of(b)}
    # the two-term model of each bound (white, GM folded into the random walk); a line cannot be folded in, so
    # the two-term values are computed without it and, where a bound has one, only written as comments
    models = {s: replace(model_of_bound(b), narrowband=()) for s, b in bounds.items()}
    imu = kalibr_imu(models["gyro"], models["accel"], update_rate_hz=rate, rostopic=topic,
                     identified_gyro=ident["gyro"], identified_accel=ident["accel"])
    if lines:
        logging.warning("Kalibr export refused: narrowband line(s) in the %s bound", ", ".join(lines))
        write_text_atomic(refused_text(lines, imu, source), path_out)
        return
    write_kalibr(imu, path_out, source=source)
    logging.info("Kalibr imu.yaml: update_rate %g Hz, rostopic %s, inflation %s", rate, topic, imu.inflation)


if __name__ == "__main__":
    i = snakemake.input
    run_job(main, snakemake.log[0], path_gyro=i.gyro, path_accel=i.accel, path_id_gyro=i.identified_gyro,
            path_id_accel=i.identified_accel, rates=dict(snakemake.params.rates), topics=dict(snakemake.params.topics),
            path_out=snakemake.output.kalibr, spec=snakemake.wildcards.spec)
