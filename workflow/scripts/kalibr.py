"""Kalibr imu.yaml from the gyro and accel bounds, KF exports, identify files and contracts (rule kalibr):
imupipe.stages.kalibr.kalibr_stage; the file's text written as it is (a refused export included)."""

from imupipe.io import read_yaml, run_job, write_text_atomic


def main(path_gyro: str, path_accel: str, path_id_gyro: str, path_id_accel: str, rates: dict, topics: dict,
         path_out: str, spec: str, path_kf_gyro: str, path_kf_accel: str, path_contract_gyro: str | None = None,
         path_contract_accel: str | None = None, update_rate_hz: float | None = None) -> None:
    from imupipe.stages.kalibr import kalibr_stage

    kf_paths = {"gyro": path_kf_gyro, "accel": path_kf_accel}
    contracts = {s: read_yaml(p) for s, p in (("gyro", path_contract_gyro), ("accel", path_contract_accel)) if p}
    text = kalibr_stage({"gyro": read_yaml(path_gyro), "accel": read_yaml(path_accel)},
                        {s: read_yaml(p) for s, p in kf_paths.items()},
                        {"gyro": read_yaml(path_id_gyro), "accel": read_yaml(path_id_accel)}, contracts, rates, topics,
                        spec=spec, kf_paths=kf_paths, update_rate_hz=update_rate_hz)
    write_text_atomic(text, path_out)


if __name__ == "__main__":
    i = snakemake.input
    run_job(main, snakemake.log[0], path_gyro=i.gyro, path_accel=i.accel, path_id_gyro=i.identified_gyro,
            path_id_accel=i.identified_accel, rates=dict(snakemake.params.rates), topics=dict(snakemake.params.topics),
            path_out=snakemake.output.kalibr, spec=snakemake.wildcards.spec, path_kf_gyro=i.kf_gyro,
            path_kf_accel=i.kf_accel, path_contract_gyro=i.contract_gyro, path_contract_accel=i.contract_accel,
            update_rate_hz=snakemake.params.update_rate_hz)
