"""Kalibr-style imu.yaml from the gyro and accel bounds (rule kalibr); GM terms folded into the random
walk conservatively (imupipe.kf.kalibr_yaml)."""

from imupipe.io import read_yaml, run_job, write_yaml_atomic


def model_of(path):
    from imupipe.models import NoiseModel

    b = read_yaml(path)["bound"]
    return NoiseModel(white=b["white"] or 0.0, random_walk=b["random_walk"] or 0.0,
                      gauss_markov=tuple((g["sigma"], g["T"]) for g in b["gauss_markov"]))


def main(path_gyro: str, path_accel: str, rate_hz: float, path_out: str) -> None:
    from imupipe.kf import kalibr_yaml

    write_yaml_atomic(kalibr_yaml(model_of(path_gyro), model_of(path_accel), rate_hz), path_out,
                      header="Kalibr imu.yaml (SI); Gauss-Markov terms folded into the random walk (bounding)")


if __name__ == "__main__":
    run_job(main, snakemake.log[0], path_gyro=snakemake.input.gyro, path_accel=snakemake.input.accel,
            rate_hz=snakemake.params.rate_hz, path_out=snakemake.output.kalibr)
