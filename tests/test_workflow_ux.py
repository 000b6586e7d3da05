"""What a user reads at the end of a run, end to end on the tiny configuration (session fixture `tiny_run`):
the run summary (file, HTML, report front page, terminal), the Kalibr file read back with Kalibr's field names
and units against the bound it comes from, the figures, and the Kalibr rule's refusal of a bound with a line."""

import pytest
import yaml

from workflow_helpers import RES, dry_run_jobs, snakemake, stage_script as _script


def _read(work, rel):
    return yaml.safe_load((work / rel).read_text())


def test_summary_states_each_verdict_and_every_flag_of_the_run_files(tiny_run):
    work, _ = tiny_run
    text = (work / RES / "summary.md").read_text()
    n_flags = 0
    for sensor in ("gyro", "accel"):
        bound = _read(work, f"{RES}/bound/stim300/{sensor}.yaml")
        bounded = _read(work, f"{RES}/contract/stim300/{sensor}.yaml")["bounded"]  # the verdict is the contract's
        assert f"## {sensor}: {'BOUNDED' if bounded else 'NOT BOUNDED'}" in text
        # every non-stationary curve of the verdict file is a FLAG line naming the curve
        for c in _read(work, f"{RES}/stationarity/{sensor}.yaml")["curves"]:
            if c.get("stationary") is False:
                n_flags += 1
                assert f"FLAG stationarity [{c['dataset']}/{sensor}/{c['axis']}]" in text
        # every failed Allan check is a FAIL line naming the component
        for comp, v in (bound.get("allan_check") or {}).items():
            if isinstance(v, dict) and v.get("passed") is False:
                n_flags += 1
                assert f"FAIL allan check [{comp}" in text
        # the inflation table in the spec sheet's units: the white-noise row's bound value as the bound file has it
        n_bound = bound["bound_spec_units"]["white"]
        assert f"| white noise N | {'deg/sqrt(h)' if sensor == 'gyro' else 'm/s/sqrt(h)'} |" in text
        assert f"{n_bound['value'] if isinstance(n_bound, dict) else n_bound:.4g}" in text
    # the tiny run has flagged checks (seed 7: a non-stationary gyro axis, a failed Allan check): the test must
    # see at least one, else it shows nothing about flags
    assert n_flags >= 1
    assert "Kalibr imu.yaml" in text and "update_rate 20 Hz" in text


def test_report_front_page_and_html_carry_the_verdict(tiny_run):
    work, _ = tiny_run
    html = (work / RES / "summary.html").read_text()
    front = (work / RES / "report" / "workflow.rst").read_text()
    for sensor in ("gyro", "accel"):
        bounded = _read(work, f"{RES}/contract/stim300/{sensor}.yaml")["bounded"]
        verdict = f"{sensor}: {'BOUNDED' if bounded else 'NOT BOUNDED'}"
        assert verdict in html and verdict in front
    assert "<table>" in front and ".. raw:: html" in front
    # the HTML is kept out of the report's Jinja rendering
    assert front.index("{% raw %}") < front.index(".. raw:: html") < front.index("{% endraw %}")
    assert "<table>" in (work / RES / "tables" / "stim300" / "inflation.html").read_text()


def test_kalibr_file_has_kalibr_fields_at_the_imu_rate_from_the_exported_kf_model(tiny_run):
    from imupipe.kalibr import KALIBR_UNITS, read_kalibr

    work, config = tiny_run
    path = work / RES / "kf" / "stim300" / "kalibr_imu.yaml"
    k = read_kalibr(path)
    text = path.read_text()
    # update_rate is the IMU sample rate of the simulation (20 Hz), not application.filter_rate_hz (1 Hz)
    cfg = yaml.safe_load(config.read_text())
    assert k["update_rate"] == cfg["simulation"]["record_rate_hz"] != cfg["application"]["filter_rate_hz"]
    assert k["rostopic"] == "/imu0"  # simulated data name no topic: Kalibr's default
    from imupipe.kalibr import kalibr_pair, model_of_kf

    for prefix, sensor in (("gyroscope", "gyro"), ("accelerometer", "accel")):
        kf = _read(work, f"{RES}/kf/stim300/{sensor}.yaml")
        # Kalibr's band: 1/outage_s to half its update_rate (its filter runs at the IMU's rate)
        band = (1.0 / cfg["application"]["outage_s"], 0.5 * k["update_rate"])
        # continuous-time densities of the exported KF model (the bound after the verified reduction): the smallest
        # pair whose PSD bounds the model's over that band (imupipe.kalibr.kalibr_pair); 7 digits
        pair = kalibr_pair(model_of_kf(kf), band)
        # up to the IMU's Nyquist the white noise dominates: Kalibr's density is at least the model's white noise
        assert pair.noise_density >= model_of_kf(kf).white * (1 - 1e-6)
        assert k[f"{prefix}_noise_density"] == pytest.approx(pair.noise_density, rel=1e-6)
        assert k[f"{prefix}_random_walk"] == pytest.approx(pair.random_walk, rel=1e-6)
        assert f"# {KALIBR_UNITS[f'{prefix}_noise_density']}" in text
        assert f"# {sensor}: exported model in-band (" in text  # the contract's in-band inflation
    assert "# Rule: (N, K) is the pair whose two-sided PSD" in text
    assert "BOUNDING VALUES" in text and "no further inflation" in text
    assert "gyroscope_noise_density: " in text and " times the identified value" in text  # the factor


def test_figures_include_the_allan_readoffs(tiny_run):
    work, _ = tiny_run
    for sensor in ("gyro", "accel"):
        for fig in ("psd_bound", "allan_components", "inflation_steps", "allan_readoffs"):
            path = work / RES / "figures" / "stim300" / f"{fig}_{sensor}.png"
            assert path.stat().st_size > 10_000, path


def test_figures_section_reruns_only_the_figures(tiny_run):
    work, config = tiny_run
    cfg = yaml.safe_load(config.read_text())
    for change in ({"units": "SI", "format": "png"}, {"units": "spec", "format": "svg"}):
        cfg["figures"] = change
        changed = work / "changed_figures.yaml"
        changed.write_text(yaml.safe_dump(cfg))
        jobs = dry_run_jobs(work, config=changed)
        # (and the run verdict, the last job of every run)
        assert set(jobs) <= {"figures", "inflation_effect", "integrity", "all"} and "figures" in jobs, (change, jobs)


def test_kalibr_refuses_a_kf_export_with_a_line(tiny_run, tmp_path):
    """A narrowband state of the exported KF model cannot be carried by Kalibr's two terms: the file gets no Kalibr
    field (so Kalibr fails on it), says why, and the summary flags it."""
    from imupipe.kalibr import read_kalibr

    work, _ = tiny_run
    kalibr = _script("kalibr")
    kf = _read(work, f"{RES}/kf/stim300/accel.yaml")
    kf["parameters"]["narrowband"] = [{"sigma": 1e-3, "f0_hz": 0.47, "zeta": 0.01}]
    with_line = tmp_path / "accel.yaml"
    with_line.write_text(yaml.safe_dump(kf))
    out = tmp_path / "kalibr_imu.yaml"
    kalibr.main(str(work / RES / "bound/stim300/gyro.yaml"), str(work / RES / "bound/stim300/accel.yaml"),
                str(work / RES / "identify/gyro.yaml"), str(work / RES / "identify/accel.yaml"),
                {"a": 20.0, "b": 20.0}, {"a": None, "b": ""}, str(out), "stim300",
                path_kf_gyro=str(work / RES / "kf/stim300/gyro.yaml"), path_kf_accel=str(with_line))
    data = yaml.safe_load(out.read_text())
    assert data["refused"] is True and "narrowband" in data["reason"]
    assert "f0 0.47 Hz" in out.read_text()
    with pytest.raises(ValueError, match="accelerometer_noise_density"):
        read_kalibr(out)
    from imupipe.stages.summary import summary_text

    text = summary_text({"kalibr": [str(out)]}, ["gyro", "accel"], ["stim300"], "tiny")
    flags = [ln for ln in text.splitlines() if ln.startswith("- FLAG kalibr export")]
    assert len(flags) == 1 and "refused" in flags[0] and "narrowband" in flags[0]


def test_kalibr_refuses_datasets_of_different_rates(tiny_run, tmp_path):
    work, _ = tiny_run
    kalibr = _script("kalibr")
    # refused in the file, naming each rate (the run goes on: one Kalibr file holds one IMU rate)
    kalibr.main(*(str(work / RES / p) for p in ("bound/stim300/gyro.yaml", "bound/stim300/accel.yaml",
                                                 "identify/gyro.yaml", "identify/accel.yaml")),
                {"a": 20.0, "b": 100.0}, {}, str(tmp_path / "k.yaml"), "stim300",
                path_kf_gyro=str(work / RES / "kf/stim300/gyro.yaml"),
                path_kf_accel=str(work / RES / "kf/stim300/accel.yaml"))
    data = yaml.safe_load((tmp_path / "k.yaml").read_text())
    assert data["refused"] is True and "differ in sample rate (a: 20 Hz, b: 100 Hz)" in data["reason"]
    assert "accelerometer_noise_density" not in data and "set kalibr.update_rate_hz" in data["reason"]
    # the config names the rate to export at (an outside evaluation: records at 100 / 50 Hz got no Kalibr file, and
    # "one configuration per rate" gives two models of one IMU): written at that rate, the comment saying so; a rate
    # no dataset has is refused naming the key
    for named, written in ((20.0, True), (50.0, False)):
        kalibr.main(*(str(work / RES / p) for p in ("bound/stim300/gyro.yaml", "bound/stim300/accel.yaml",
                                                     "identify/gyro.yaml", "identify/accel.yaml")),
                    {"a": 20.0, "b": 100.0}, {}, str(tmp_path / "k.yaml"), "stim300",
                    path_kf_gyro=str(work / RES / "kf/stim300/gyro.yaml"),
                    path_kf_accel=str(work / RES / "kf/stim300/accel.yaml"), update_rate_hz=named)
        text = (tmp_path / "k.yaml").read_text()
        data = yaml.safe_load(text)
        if written:
            assert data["update_rate"] == 20.0 and data["accelerometer_noise_density"] > 0
            assert ("update_rate 20 Hz as the config names it (kalibr.update_rate_hz), of datasets at a 20 Hz, "
                    "b 100 Hz") in text
        else:
            assert data["refused"] is True and "kalibr.update_rate_hz 50: not the rate of any dataset" in data["reason"]


def test_summary_is_printed_on_the_terminal_after_a_run(tiny_copy):
    # the summary job re-run alone (its output removed) ends with the summary on the terminal (onsuccess);
    # Snakemake runs no handler when it has nothing to do
    work, config = tiny_copy
    (work / RES / "summary.md").unlink()
    proc = snakemake(work, "--quiet", "rules", "host", "reason", config=config, snakefile=work / "Snakefile")
    out = proc.stdout + proc.stderr
    assert "imupipe run summary: tiny" in out and "**Verdict:**" in out
    assert "FLAG" in out or "FAIL" in out


def test_a_failed_run_says_so_on_the_terminal(tmp_path):
    # a truth model that the simulation job cannot read: the first jobs fail, the error handler says so and
    # where the logs are
    from workflow_helpers import TINY, copy_checkout

    work = copy_checkout(tmp_path / "checkout")
    (work / "config" / "truth" / "broken.yaml").write_text("gyro: [not, a, model]\n")
    cfg = yaml.safe_load(TINY.read_text())
    cfg["simulation"]["truth"] = "config/truth/broken.yaml"
    config = work / "broken.yaml"
    config.write_text(yaml.safe_dump(cfg))
    proc = snakemake(work, "--quiet", "rules", "host", "reason", config=config, snakefile=work / "Snakefile",
                     check=False, timeout=300)
    assert proc.returncode != 0
    out = proc.stdout + proc.stderr
    assert "RUN FAILED" in out and "logs/tiny/" in out
