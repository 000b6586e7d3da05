"""One orchestration: the workflow (the shared tiny run, `tiny_run`) and the one-call API
(:func:`imupipe.noise_model`) on the same records with the same settings give the same identification
(selection, selected model, upper envelope), the same stationarity marks (the curves bounded at their noisiest
stretch), the same bound and the same Kalman-filter matrices.

Two runs: the shared tiny run, whose axes pool (one model per sensor type), and the tiny configuration on
recordings whose gyro x differs from y and z (`axes_run`: the pooling test rejects one model, so the per-axis
identification, bounds, verifications, contracts and KF matrices are compared too). The records are the run's
own full-rate series (results/tiny/series/...), the curves its stacked Allan file includes, in its order; the
settings are the configuration's over config/config.yaml's defaults.
Both paths call the same library functions on the same numbers (the YAML files in between write floats by
repr, so the round trip is exact): the tolerance, 1e-12 relative, only allows for a different order of
floating-point sums, not for a different rule.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml

pytest.importorskip("snakemake", reason="the workflow tests need snakemake (pip install -e '.[test]')")

from workflow_helpers import RES, ROOT  # noqa: E402

RTOL = 1e-12
KF_MATRICES = ("F", "G", "Qc", "Phi", "Qd", "P0")


def _config(config_path):
    """The tiny configuration over the defaults of config/config.yaml (one level of sections merged)."""
    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    for key, value in yaml.safe_load(config_path.read_text()).items():
        cfg[key] = {**cfg[key], **value} if isinstance(value, dict) and isinstance(cfg.get(key), dict) else value
    return cfg


@pytest.fixture(scope="module")
def axes_run(tmp_path_factory):
    """The tiny configuration on a dataset sheet whose gyro x differs from y and z (two gyro recordings of 1.5 h
    at 20 Hz drawn from the tiny config's true model, x scaled by 3): the pooling test rejects one model, so the
    per-axis identification, bounds, verifications, contracts and KF matrices run. The gyro alone (the only
    sensor compared on this run: `both`), up to its KF file and contract (the files compared). (folder, config)."""
    from imupipe.simulate import simulate
    from imupipe.specsheet import load_spec
    from workflow_helpers import copy_checkout, snakemake, tiny_config

    work = copy_checkout(tmp_path_factory.mktemp("axes") / "checkout")
    truth = load_spec(ROOT / "config" / "truth" / "stim300_like.yaml").models
    cols = [f"gyro_{a}" for a in "xyz"]
    rows = []
    for i in range(2):
        rate, n = 20.0, int(1.5 * 3600 * 20.0)
        data = np.column_stack([simulate(truth["gyro"], n, rate, rng=300 + 10 * i + j) for j in range(len(cols))])
        data[:, 0] *= 3.0  # gyro x: every component 3 x the others'
        path = work / f"rec{i}.csv"
        np.savetxt(path, data, delimiter=",", header=",".join(cols), comments="")
        rows.append([f"rec{i}", str(path), f"{rate:g}", "rad/s", *cols])
    sheet = work / "datasets.tsv"
    head = ["dataset", "path", "rate_hz", "gyro_unit", *cols]
    sheet.write_text("\n".join("\t".join(r) for r in [head, *rows]) + "\n")
    config = tiny_config(work, datasets=str(sheet), simulation=None, sensors=["gyro"])
    snakemake(work, "--until", "kf", config=config, snakefile=work / "Snakefile")  # kf reads the contract
    return work, config


@pytest.fixture(scope="module", params=[("tiny", "gyro"), ("tiny", "accel"), ("axes differ", "gyro")],
                ids=["tiny-gyro", "tiny-accel", "axes_differ-gyro"])
def both(request):
    """(sensor, workflow files, API result) of one sensor type of one run (the shared tiny run, or
    :func:`axes_run`)."""
    from imupipe.api import noise_model
    from imupipe.io import read_series, read_yaml
    from imupipe.merge import Stacked

    run, sensor = request.param
    work, config_path = request.getfixturevalue("tiny_run" if run == "tiny" else "axes_run")
    cfg = _config(config_path)
    res = work / RES
    spec_name = cfg["specs"][0]
    records, rates = {}, set()
    for d, a in Stacked(res / "allan" / f"{sensor}.nc").curves(included_only=True):
        x, rate, _ = read_series(res / "series" / d / sensor / f"{a}.nc")
        records[f"{d}/{a}"] = np.array(x, dtype=np.float64)
        rates.add(float(rate))
    assert len(rates) == 1 and records
    idn, app, b, ver = cfg["identify"], cfg["application"], cfg["bound"], cfg["verify"]
    api = noise_model(
        records, rates.pop(), sensor, work / cfg["spec_dir"] / f"{spec_name}.yaml",
        decimate_hz=cfg["decimate"]["rate_hz"], window_s=cfg["psd"]["window_s"], step_s=cfg["psd"]["step_s"],
        taper=cfg["psd"]["taper"], detrend=cfg["psd"]["detrend"], psd_confidence=cfg["psd"]["confidence"],
        taus=cfg["allan"]["taus"], allan_confidence=cfg["allan"]["confidence"],
        components=idn["components"], n_gm=idn["n_gm"], n_boot=idn["n_boot"], fit_confidence=idn["confidence"],
        significance=idn["significance"], relevance=idn["relevance"], adequacy_level=idn["adequacy_level"],
        pooling_level=idn["pooling_level"], pooling_n_boot=idn["pooling_n_boot"],
        fit_tau_min_samples=idn.get("fit_tau_min_samples"), max_bias_time_s=idn.get("max_bias_time_s"),
        filter_rate_hz=app["filter_rate_hz"], outage_s=app["outage_s"],
        mode=b["mode"], bound_confidence=b["confidence"], bands_per_decade=b["bands_per_decade"],
        lines_policy=cfg["lines"]["policy"][sensor], lines_resolution_hz=cfg["lines"]["resolution_hz"],
        lines_alpha=cfg["lines"]["alpha"], lines_floor_window_bins=cfg["lines"]["floor_window_bins"],
        lines_scales=tuple(cfg["lines"].get("scales", [1])),
        lines_low_band_resolution_hz=cfg["lines"].get("low_band_resolution_hz"), fix_s=ver["fix_s"],
        fix_rate_hz=ver.get("fix_rate_hz"),
        sigma_fix=ver["sigma_fix_m"] if sensor == "accel" else ver["sigma_fix_rad"], reduce=ver["reduce"],
        replay_z=ver["replay_z"], truth=work / cfg["simulation"]["truth"] if cfg.get("simulation") else None,
        stationarity={k: cfg["stationarity"][k] for k in ("n_segments", "alpha", "test", "n_sim", "n_sim_max",
                                                          "close_z")})
    files = {"identify": read_yaml(res / "identify" / f"{sensor}.yaml"),
             "bound": read_yaml(res / "bound" / spec_name / f"{sensor}.yaml"),
             "kf": read_yaml(res / "kf" / spec_name / f"{sensor}.yaml"),
             "contract": read_yaml(res / "contract" / spec_name / f"{sensor}.yaml")}
    return sensor, files, api


def test_axes_differ_run_takes_the_per_axis_path(axes_run):
    from imupipe.io import read_yaml

    res = axes_run[0] / RES
    ident = read_yaml(res / "identify" / "gyro.yaml")
    assert ident["pooling"]["consistent"] is False and set(ident["per_axis"]) == {"x", "y", "z"}
    assert read_yaml(res / "bound" / "stim300" / "gyro.yaml")["per_axis_models"]


def _flat(model: dict) -> dict:
    """name -> value of a NoiseModel dict (GM and narrowband terms numbered), for a per-parameter comparison."""
    from imupipe.models import NoiseModel

    d = NoiseModel.from_dict({k: v for k, v in model.items() if k in (
        "white", "gauss_markov", "random_walk", "flicker", "quantization", "ramp", "narrowband")}).to_dict()
    out = {k: float(d[k]) for k in ("white", "random_walk", "flicker", "quantization", "ramp")}
    for i, g in enumerate(d["gauss_markov"]):
        out |= {f"gm{i}_sigma": g["sigma"], f"gm{i}_T": g["T"]}
    for i, n in enumerate(d.get("narrowband") or []):
        out |= {f"nb{i}_{k}": float(v) for k, v in n.items()}
    return out


def _same_model(name, got: dict, want: dict):
    g, w = _flat(got), _flat(want)
    assert set(g) == set(w), f"{name}: parameters {sorted(g)} (API) vs {sorted(w)} (workflow)"
    diff = {k: (g[k], w[k]) for k in w if not np.isclose(g[k], w[k], rtol=RTOL, atol=0.0)}
    assert not diff, f"{name} differs (API, workflow): {diff}"


def test_same_selection(both):
    sensor, files, api = both
    sel = files["identify"]["selection"]
    assert list(api.selection["kept"]) == list(sel["kept"])
    assert list(api.selection["dropped"]) == list(sel["dropped"])


def test_same_selected_model_and_envelope(both):
    sensor, files, api = both
    _same_model(f"{sensor} model_selected", api.selected.model.to_dict(), files["identify"]["model_selected"])
    _same_model(f"{sensor} upper envelope", api.upper.to_dict(), files["bound"]["upper_envelope"])


def test_same_bound(both):
    sensor, files, api = both
    _same_model(f"{sensor} bound", api.bound.to_dict(sensor=sensor)["bound"], files["bound"]["bound"])
    per_api, per_file = api.records["bound"]["per_axis_models"], files["bound"]["per_axis_models"]
    assert (per_api is None) == (per_file is None), f"{sensor}: per-axis models in one path only"
    for ax in per_file or {}:
        _same_model(f"{sensor} per-axis bound {ax}", per_api[ax]["bound"], per_file[ax]["bound"])


def test_same_verdict_and_export(both):
    sensor, files, api = both
    con = files["contract"]
    assert {k: api.contract[k] for k in ("bounded", "verified")} == {k: con[k] for k in ("bounded", "verified")}
    assert [f["check"] for f in api.contract["failed_checks"]] == [f["check"] for f in con["failed_checks"]]
    for key in ("bounded", "reduction", "states", "export"):
        assert api.kf[key] == files["kf"][key], f"{sensor}: the KF file's {key} differs"
    per_api, per_file = api.contract["per_axis_models"], con["per_axis_models"]
    assert (per_api is None) == (per_file is None)
    for ax in per_file or {}:
        assert per_api[ax]["bounded"] == per_file[ax]["bounded"]
        assert per_api[ax]["exported_in_kf"] == per_file[ax]["exported_in_kf"]


def test_same_kf_matrices(both):
    sensor, files, api = both
    assert list(api.kf["states"]) == list(files["kf"]["states"]), f"{sensor}: KF states differ"
    errors = {}
    kfs = [("", api.kf, files["kf"])] + [(f"per_axis {ax} ", api.kf["per_axis"][ax], k)
                                         for ax, k in (files["kf"]["per_axis"] or {}).items()]
    for (where, got_kf, want_kf), name in ((k, n) for k in kfs for n in KF_MATRICES):
        got, want = np.array(got_kf[name], dtype=float), np.array(want_kf[name], dtype=float)
        assert got.shape == want.shape, f"{sensor} {name}: shape {got.shape} (API) vs {want.shape} (workflow)"
        # relative to the matrix's scale: an entry that is 0 in one is 0 (to 1e-12 of the largest) in the other
        scale = float(np.max(np.abs(want))) or 1.0
        errors[where + name] = float(np.max(np.abs(got - want))) / scale
    bad = {k: f"{v:.3g}" for k, v in errors.items() if v > RTOL}
    assert not bad, f"{sensor}: max |API - workflow| / max |workflow| of {bad}"
