"""The modelling stages of the workflow: outliers and spectral lines per full-rate axis (their files, the
`remove` policy feeding the cleaned series to allan, decimate and lines), checked on the shared tiny run, on
dry runs and on the stage scripts run on records with a known truth (injected spikes and sinusoids)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

pytest.importorskip("snakemake", reason="the workflow tests need snakemake (pip install -e '.[test]')")

from imupipe.io import read_series, write_series  # noqa: E402
from imupipe.lines import Line  # noqa: E402

from workflow_helpers import RES, ROOT, dry_run_jobs, snakemake, stage_script as _script  # noqa: E402

DATASETS, SENSORS, AXES = ("sim01", "sim02"), ("gyro", "accel"), ("x", "y", "z")
SI = {"gyro": "rad/s", "accel": "m/s^2"}


def _changed(work, config, name, **sections):
    cfg = yaml.safe_load(config.read_text())
    for key, value in sections.items():
        cfg[key] = {**cfg.get(key, {}), **value}
    path = work / f"changed_{name}.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def _series(tmp_path, x, rate, sensor="accel", axis="x", name="series.nc"):
    path = tmp_path / name
    write_series(path, x, rate_hz=rate, units=SI[sensor],
                 attrs={"dataset": "rec", "sensor": sensor, "axis": axis, "long_name": f"{sensor} {axis}"})
    return str(path)


class TestFilesOfTheTinyRun:
    def test_outlier_report_per_axis(self, tiny_run):
        # simulated Gaussian noise: the expected false count per axis (k = 7, 108000 samples) is ~1e-3, so more
        # than 2 on an axis would be a Poisson(1e-3) event of probability < 2e-10: the rule or its input is wrong
        work, _ = tiny_run
        for d in DATASETS:
            for s in SENSORS:
                for a in AXES:
                    rep = yaml.safe_load((work / RES / "outliers" / d / s / f"{a}.yaml").read_text())
                    assert (rep["dataset"], rep["sensor"], rep["axis"]) == (d, s, a)
                    assert rep["policy"] == "warn" and rep["threshold"] == 7.0
                    assert rep["n_samples"] == 108000  # 1.5 h at 20 Hz
                    assert rep["expected_false_gaussian"] < 0.01
                    assert rep["n_outliers"] <= 2 and len(rep["indices"]) == rep["n_outliers"]
                    assert rep["units"]["max_abs_deviation"] == SI[s]
                    assert rep["effect"]["units"]["avar_tau0_before"] == f"({SI[s]})^2"
                    assert rep["effect"]["tau0_s"] == pytest.approx(1 / 20.0)
                    if rep["n_outliers"] == 0:
                        assert rep["effect"]["avar_ratio"] == 1.0

    def test_lines_file_per_axis(self, tiny_run):
        # the simulated truth has no line: with the family-wise level alpha = 0.01 per series, 12 series give at
        # most 0.12 false lines on average; 3 or more would be a binomial(12, 0.01) event of probability 2e-4
        work, _ = tiny_run
        total = 0
        for d in DATASETS:
            for s in SENSORS:
                for a in AXES:
                    res = yaml.safe_load((work / RES / "lines" / d / s / f"{a}.yaml").read_text())
                    assert (res["dataset"], res["sensor"], res["axis"]) == (d, s, a)
                    assert res["rate_hz"] == 20.0 and res["resolution_hz"] == pytest.approx(0.002)
                    assert res["n_segments"] == 10  # 108000 samples / (20 Hz / 0.002 Hz)
                    assert res["units"]["power"] == f"({SI[s]})^2" and res["units"]["frequency_hz"] == "Hz"
                    assert res["n_lines"] == len(res["lines"])
                    total += res["n_lines"]
        assert total <= 2


class TestDag:
    def test_warn_policy_change_reruns_the_reports_alone(self, tiny_run):
        work, config = tiny_run
        jobs = dry_run_jobs(work, config=_changed(work, config, "k", outliers={"k": 6.0}))
        assert jobs == {"outliers": 12, "summary": 1, "integrity": 1, "all": 1}  # the run's verdict is the last job: after every output

    def test_a_burst_scan_setting_reruns_the_line_search_under_warn(self, tiny_run):
        # the lines job fills the bursts its own scan finds (imupipe.stages.outliers.line_search_series), with the
        # events settings as params: a burst setting re-runs it (and what reads the lines), outliers.k above does not
        work, config = tiny_run
        jobs = dry_run_jobs(work, config=_changed(work, config, "burst_k", events={"burst_k": 8.0}))
        assert jobs["outliers"] == 12 and jobs["lines"] == 12

    def test_remove_policy_feeds_the_cleaned_series(self, tiny_run):
        # with `remove` the full-rate stages read results/<name>/cleaned/ (the outliers job's second output)
        work, config = tiny_run
        changed = _changed(work, config, "remove", outliers={"policy": "remove"})
        out = snakemake(work, "-n", config=changed, snakefile=work / "Snakefile").stdout
        for rule in ("allan", "decimate", "lines"):
            block = out.split(f"rule {rule}:", 1)[1].split("\n\n", 1)[0]
            assert f"input: {RES}/cleaned/" in block, (rule, block)
        jobs = dry_run_jobs(work, config=changed)
        assert {"outliers", "allan", "decimate", "lines", "psd", "stationarity", "identify", "bound"} <= set(jobs)
        assert "ingest" not in jobs and "simulate" not in jobs


class TestScripts:
    def test_remove_counts_injected_spikes_and_restores_the_white_noise(self, tmp_path, rng):
        # 50 spikes of 50 sigma in 200000 white samples (at least 3 blocks apart): every spike is counted and
        # nothing else (expected false count at k = 7 ~ 2e-3). The cleaned AV(tau0) differs from the spike-free
        # record's only through the 50 replaced samples (block medians, no noise): relative change ~ 50/2e5 =
        # 2.5e-4 plus the diffs they take part in (x2), far inside the 1 % that the issue asks of N.
        n, rate, sigma = 200_000, 100.0, 0.01
        clean = sigma * rng.standard_normal(n)
        idx = np.sort(rng.choice(np.arange(100, n - 100, 300), size=50, replace=False))
        spiky = clean.copy()
        spiky[idx] += 50 * sigma * rng.choice([-1.0, 1.0], size=50)
        path = _series(tmp_path, spiky, rate)
        report, cleaned = tmp_path / "report.yaml", tmp_path / "cleaned.nc"
        _script("outliers").main(path_series=path, policy="remove", k=7.0, window_samples=100, max_indices=20,
                                 path_report=str(report), path_cleaned=str(cleaned))
        rep = yaml.safe_load(report.read_text())
        assert rep["n_outliers"] == 50
        assert rep["indices"] == idx[:20].tolist() and rep["indices_truncated"] is True
        x, r, attrs = read_series(cleaned)
        assert r == rate and attrs["units"] == "m/s^2" and attrs["outliers_removed"] == 50
        av_clean = 0.5 * np.mean(np.diff(clean) ** 2)
        assert rep["effect"]["avar_tau0_after"] == pytest.approx(0.5 * np.mean(np.diff(x) ** 2), rel=1e-12)
        assert math.sqrt(rep["effect"]["avar_tau0_after"] / av_clean) == pytest.approx(1.0, abs=0.01)
        # before: each spike adds (50 sigma)^2 to two squared differences: AV(tau0) grows by 50 * 2500 sigma^2 / n
        assert rep["effect"]["avar_tau0_before"] / av_clean == pytest.approx(1 + 50 * 2500 / n, rel=0.05)

    def test_warn_keeps_the_data_and_states_the_effect(self, tmp_path, rng):
        x = 0.01 * rng.standard_normal(50_000)
        x[[1000, 20000]] += 1.0
        report = tmp_path / "report.yaml"
        with pytest.warns(UserWarning, match="2 outlier"):
            _script("outliers").main(path_series=_series(tmp_path, x, 100.0), policy="warn", k=7.0,
                                     window_samples=100, max_indices=100, path_report=str(report))
        rep = yaml.safe_load(report.read_text())
        assert rep["n_outliers"] == 2 and rep["indices"] == [1000, 20000]
        # each spike of A = 100 sigma adds A^2 to two squared differences: AV(tau0) = sigma^2 (1 + 2 * 2 A^2 /
        # (2 n sigma^2)) = 1.4 sigma^2 before, sigma^2 after. Spread: the AV estimate's own relative error
        # (~sqrt(3/n) = 0.8 %) largely cancels in the ratio; the spike-noise cross terms (sd 4 A sigma sqrt(2)
        # per spike against 2 n sigma^2) give ~0.6 %: 3 % is 5 sd
        assert rep["effect"]["avar_ratio"] == pytest.approx(1 / 1.4, rel=0.03)

    def test_fail_names_the_file(self, tmp_path, rng):
        x = 0.01 * rng.standard_normal(10_000)
        x[500] = 5.0
        path = _series(tmp_path, x, 100.0)
        with pytest.raises(ValueError, match=r"series\.nc.*1 outlier.*outliers\.policy"):
            _script("outliers").main(path_series=path, policy="fail", k=7.0, window_samples=100, max_indices=10,
                                     path_report=str(tmp_path / "r.yaml"))
        assert not (tmp_path / "r.yaml").exists()

    def test_lines_file_rebuilds_the_injected_line(self, tmp_path, rng):
        # 2000 s at 100 Hz, white 0.01 u per sample, a 0.5634 Hz sinusoid of amplitude 1.7e-3 u (about 50x the
        # floor at 0.01 Hz resolution; the library's detection test derives the 10 % amplitude tolerance)
        rate, n, f0, amp = 100.0, 200_000, 0.5634, 1.7e-3
        t = np.arange(n) / rate
        x = 0.01 * rng.standard_normal(n) + amp * np.cos(2 * np.pi * f0 * t + 0.3)
        out = tmp_path / "lines.yaml"
        _script("lines").main(path_series=_series(tmp_path, x, rate), resolution_hz=0.01, alpha=0.01,
                              floor_window_bins=51, path_lines=str(out))
        res = yaml.safe_load(out.read_text())
        assert res["n_lines"] == 1 and res["label"] == "rec/accel/x"
        line = Line(**res["lines"][0])
        assert abs(line.frequency_hz - f0) < res["resolution_hz"]
        assert line.amplitude == pytest.approx(amp, rel=0.10)
        assert res["units"]["amplitude"] == "m/s^2"

    def test_lines_resolution_too_fine_names_the_key(self, tmp_path, rng):
        path = _series(tmp_path, rng.standard_normal(1000), 10.0)
        with pytest.raises(ValueError, match=r"series\.nc.*lines\.resolution_hz"):
            _script("lines").main(path_series=path, resolution_hz=0.001, alpha=0.01, floor_window_bins=51,
                                  path_lines=str(tmp_path / "l.yaml"))


@pytest.fixture(scope="module")
def mixed_run(tmp_path_factory):
    """Two recordings of different length and rate through the workflow up to the global bounds (the files the
    tests below read, and every stage before them: per-axis stages, lines, merges, identification): 0.5 h at
    20 Hz ("short", its three gyro axes one and the same simulated record) and 0.75 h at 25 Hz ("long"), drawn
    from the tiny config's true model; PSD windows of 15 min (the short record holds one at 7.5 min spacing)."""
    from imupipe.simulate import simulate
    from imupipe.specsheet import load_spec
    from workflow_helpers import copy_checkout, tiny_config

    work = copy_checkout(tmp_path_factory.mktemp("mixed") / "checkout")
    truth = load_spec(ROOT / "config" / "truth" / "stim300_like.yaml").models
    cols = [f"{s}_{a}" for s in SENSORS for a in AXES]
    rows = []
    for i, (name, hours, rate) in enumerate((("short", 0.5, 20.0), ("long", 0.75, 25.0))):
        n = int(hours * 3600 * rate)
        data = np.column_stack([simulate(truth[s], n, rate, rng=100 * i + j) for j, s in enumerate(
            [s for s in SENSORS for _ in AXES])])
        if name == "short":
            data[:, 1] = data[:, 2] = data[:, 0]  # the same record on gyro x, y and z
        path = work / f"{name}.csv"
        np.savetxt(path, data, delimiter=",", header=",".join(cols), comments="")
        rows.append([name, str(path), f"{rate:g}", "rad/s", "m/s^2", "yes", *cols])
    sheet = work / "datasets.tsv"
    # simulated noise only, no gravity in the accel channels: the sheet says so (gravity_removed)
    head = ["dataset", "path", "rate_hz", "gyro_unit", "accel_unit", "gravity_removed", *cols]
    sheet.write_text("\n".join("\t".join(r) for r in [head, *rows]) + "\n")
    config = tiny_config(work, datasets=str(sheet), simulation=None,
                         psd={"window_s": 900.0, "step_s": 450.0, "taper": "hann", "detrend": "constant",
                              "confidence": 0.95})
    snakemake(work, "--until", "bound", config=config, snakefile=work / "Snakefile")
    return work, config


class TestRecordsOfDifferentLengthAndRate:
    def test_bounded_with_per_curve_rate(self, mixed_run):
        import netCDF4

        work, _ = mixed_run
        for sensor in SENSORS:
            with netCDF4.Dataset(work / RES / "allan" / f"{sensor}.nc") as nc:
                datasets = [str(v) for v in nc.variables["dataset"][:]]
                rates = np.asarray(nc.variables["rate_hz"][:])
                assert nc.variables["rate_hz"].units == "Hz"
            assert rates.shape == (2, 3)
            expect = {"short": 20.0, "long": 25.0}
            for i, d in enumerate(datasets):
                assert np.all(rates[i] == expect[d]), (d, rates[i])
            ident = yaml.safe_load((work / RES / "identify" / f"{sensor}.yaml").read_text())
            assert ident["rate_hz"] == {f"{d}/{a}": expect[d] for d in datasets for a in AXES}
            assert ident["n_samples"]["short/x"] == 36000 and ident["n_samples"]["long/x"] == 67500
            assert {c["label"]: c["rate_hz"] for c in ident["pooling"]["per_curve"]} == ident["rate_hz"]
            for key in ("model", "model_selected", "upper_envelope_model", "selection", "fit", "slope_line"):
                assert key in ident
            assert ident["adequacy"]["pooled"]["p_value"] is not None
            assert set(ident["adequacy"]["per_curve"]) == set(ident["rate_hz"])
            bound = yaml.safe_load((work / RES / "bound" / "stim300" / f"{sensor}.yaml").read_text())
            assert bound["psd_bounded"] is True and bound["n_curves"] == 6

    def test_identical_axes_identical_verdicts(self, mixed_run):
        # the null draws are seeded from the record, not the axis name: the one record on three axes gets one
        # verdict, p-value, Monte Carlo error and number of draws
        work, _ = mixed_run
        verdicts = [yaml.safe_load((work / RES / "stationarity" / "short" / "gyro" / f"{a}.yaml").read_text())
                    for a in AXES]
        keys = ("stationary", "p_value", "p_value_mc_se", "n_sim_run", "closeness", "close_to_level")
        assert all(k in verdicts[0] for k in keys)
        for v in verdicts[1:]:
            assert {k: v[k] for k in keys} == {k: verdicts[0][k] for k in keys}
            assert v["calibrated"]["ks_statistic"] == verdicts[0]["calibrated"]["ks_statistic"]
        lines = [yaml.safe_load((work / RES / "lines" / "short" / "gyro" / f"{a}.yaml").read_text())["lines"]
                 for a in AXES]
        assert lines[0] == lines[1] == lines[2]

    def test_identical_rerun(self, mixed_run, tmp_path):
        # the stochastic stages re-run on the run's own inputs (seeded bootstrap and pooling test, record-seeded
        # null) write byte-identical files
        work, config = mixed_run
        cfg = {**yaml.safe_load((ROOT / "config" / "config.yaml").read_text()), **yaml.safe_load(config.read_text())}
        st, idn = cfg["stationarity"], cfg["identify"]
        res = work / RES
        again = tmp_path / "verdict.yaml"
        _script("stationarity").main(
            path_decimated=str(res / "decimated/long/accel/z.nc"), path_allan=str(res / "allan/long/accel/z.nc"),
            n_segments=st["n_segments"], alpha=st["alpha"], test=st["test"], n_sim=st["n_sim"],
            n_sim_max=st.get("n_sim_max", 1599), close_z=st.get("close_z", 2.0), path_out=str(again))
        assert again.read_bytes() == (res / "stationarity/long/accel/z.yaml").read_bytes()
        again = tmp_path / "identify.yaml"
        _script("identify").main(
            path_allan=str(res / "allan/gyro.nc"), components=idn["components"], n_gm=idn["n_gm"],
            n_boot=idn["n_boot"], confidence=idn["confidence"], significance=idn["significance"],
            relevance=idn["relevance"], adequacy_level=idn.get("adequacy_level", 0.01),
            pooling_level=idn.get("pooling_level", 0.01), pooling_n_boot=idn.get("pooling_n_boot", 99),
            filter_rate_hz=cfg["application"]["filter_rate_hz"], outage_s=cfg["application"]["outage_s"], truth=None,
            span_s=float(cfg["verify"]["fix_s"]) + float(cfg["application"]["outage_s"]),
            path_out=str(again), sensor="gyro")
        assert again.read_bytes() == (res / "identify/gyro.yaml").read_bytes()


class TestPerAxisIdentification:
    """The identification's per-axis rule (imupipe.stages.identify.selected_and_envelope, also the pooled path's): the selection's
    kept components refitted with imupipe.identify.refit_selected, so a random walk the selection dropped keeps
    its upper limit in the axis's envelope (the per-axis bounds read it)."""

    def test_dropped_random_walk_keeps_its_upper_limit_per_axis(self):
        from imupipe.allan import allan_variance
        from imupipe.identify import fit_allan

        from imupipe.stages import identify as mod

        rate, n = 10.0, 72000  # 2 h at 10 Hz: white 1e-3 u/sqrt(Hz) plus a GM (sigma 5e-4 u, T 20 s), no random walk
        rng = np.random.default_rng(7)
        phi = math.exp(-1.0 / (rate * 20.0))
        e = 5e-4 * math.sqrt(1 - phi * phi) * rng.standard_normal(n)
        g = np.empty(n)
        g[0] = 5e-4 * rng.standard_normal()
        for k in range(1, n):
            g[k] = phi * g[k - 1] + e[k]
        x = 1e-3 * math.sqrt(rate) * rng.standard_normal(n) + g
        av = allan_variance(x, rate, taus="octave", units="rad/s")
        ok = np.isfinite(av["avar"].values) & np.isfinite(av["edf"].values)
        tau, avar, edf = av["tau"].values[ok], av["avar"].values[ok], av["edf"].values[ok]
        curves = [("d/x", tau, avar, edf, n, rate, "x")]
        kw = dict(n_boot=20, confidence=0.95, dt=1.0 / rate, record_rate_hz=[rate], n_samples=[n])
        full = fit_allan([tau], [avar], [edf], components=("white", "gauss_markov", "random_walk"), n_gm=1,
                         rng=1, **{**kw, "n_boot": 0})
        selection = {"kept": ["white", "gauss_markov"], "dropped": ["random_walk"]}
        sel, env = mod.selected_and_envelope(full, selection, curves, kw, 0.95, 1200.0)
        assert sel.params["random_walk"] == 0.0 and sel.intervals["random_walk"][1] > 0
        assert env.random_walk > 0
        assert "random walk" in sel.interval_kind["random_walk"]
        # the former per-axis rule (a fit of the kept components only) had no random walk at all in the envelope
        only_kept = fit_allan([tau], [avar], [edf], components=("white", "gauss_markov"), n_gm=1, rng=1, **kw)
        assert mod.envelope(only_kept, selection["kept"], curves, 0.95, 1200.0).random_walk == 0.0


    def test_each_axis_records_its_joint_band(self):
        # where the pooling test rejects one model, each axis's joint band is recorded (at the identification's
        # level): the auto bound's envelope candidate is built on them only when every one is a joint band
        from imupipe.allan import allan_variance
        from imupipe.stages import identify as mod

        rate, n, rng = 10.0, 36000, np.random.default_rng(11)
        curves = []
        for axis, white in (("x", 1e-3), ("y", 2e-3), ("z", 1e-3)):
            av = allan_variance(white * math.sqrt(rate) * rng.standard_normal(n), rate, taus="octave", units="rad/s")
            ok = np.isfinite(av["avar"].values) & np.isfinite(av["edf"].values)
            curves.append((f"d/{axis}", av["tau"].values[ok], av["avar"].values[ok], av["edf"].values[ok], n, rate,
                           axis))
        kw = dict(n_boot=40, confidence=0.95, dt=1.0 / rate, record_rate_hz=[rate] * 3, n_samples=[n] * 3)
        selection = {"kept": ["white"], "dropped": []}
        per = mod._per_axis(curves, ("white",), 1, selection, kw, 0.95, 1200.0, 5, envelope_kind="joint")
        for axis in "xyz":
            band = per[axis]["upper_envelope_joint"]
            assert band["confidence"] == pytest.approx(0.95, rel=1e-12), band
            assert not band.get("note") and band["worst_ratio_to_band"] is not None
        # the marginal kind records no band
        assert "upper_envelope_joint" not in mod._per_axis(curves, ("white",), 1, selection, kw, 0.95, 1200.0, 5)["x"]


class TestDominatingModel:
    """models.dominating_model: the envelope the bound reads when the axes are identified apart."""

    def test_dominates_every_model_and_touches_the_extremes(self):
        from imupipe.models import dominating_model
        from imupipe.models import NoiseModel

        models = [NoiseModel(white=1e-3, gauss_markov=((2e-4, 10.0),), random_walk=1e-6),
                  NoiseModel(white=1.4e-3, gauss_markov=((1e-4, 300.0),), flicker=5e-5),
                  NoiseModel(white=0.9e-3)]
        env = dominating_model(models)
        f = np.logspace(-6, 2, 2001)
        for m in models:
            # every component dominates its counterpart: the sum dominates everywhere (float rounding only)
            assert np.all(env.psd(f) >= m.psd(f) * (1 - 1e-12))
        assert env.white == 1.4e-3 and env.random_walk == 1e-6 and env.flicker == 5e-5
        (s, T), = env.gauss_markov
        # the GM's two asymptotes are the largest of the terms': 2 sigma^2 T (f -> 0), 2 sigma^2 / T / (2 pi f)^2
        assert s * s * T == pytest.approx(max(2e-4**2 * 10.0, 1e-4**2 * 300.0), rel=1e-12)
        assert s * s / T == pytest.approx(max(2e-4**2 / 10.0, 1e-4**2 / 300.0), rel=1e-12)

    def test_one_model_is_its_own_envelope(self):
        from imupipe.models import dominating_model
        from imupipe.models import NoiseModel

        m = NoiseModel(white=1e-3, gauss_markov=((2e-4, 10.0), (1e-4, 500.0)), random_walk=1e-6)
        env = dominating_model([m])
        assert env.white == m.white and env.random_walk == m.random_walk
        assert np.allclose(env.gauss_markov, m.gauss_markov, rtol=1e-12, atol=0)


class TestPerAxisExport:
    def test_contract_and_kf_give_each_axis_its_own_model_only_when_its_contract_holds(self, tmp_path):
        """The contract and kf scripts on a bound file with per-axis models (two datasets, gyro x of white
        density 1e-4 and z of 2e-4 rad/s/sqrt(Hz), bounded per axis by imupipe.bound.bound_by_axis and verified
        by imupipe.verify.verification_stage): x's own contract holds, so the KF file's per_axis x carries x's
        own white noise; z's Allan total check is given a shortfall (ratio 0.6 at tau = 0.02 s), so z's contract
        names it and the KF file gives z the global model. The global contract stays bounded (the global model
        covers both axes)."""
        from imupipe.bound import bound_by_axis, bound_psd
        from imupipe.io import plain
        from imupipe.specsheet import load_spec
        from imupipe.spectra import psd
        from imupipe.verify import verification_stage

        rng = np.random.default_rng(5)
        spec_path = ROOT / "config" / "specs" / "stim300.yaml"
        spec = load_spec(spec_path).models["gyro"]
        curves = {}
        for d in ("d1", "d2"):
            for ax, N in (("x", 1e-4), ("z", 2e-4)):
                ds = psd(N * rng.standard_normal(7200), 1.0, window_s=3600.0, step_s=3600.0)
                f, curves[f"{d}/{ax}"] = ds.frequency.values, ds.psd.values
        kw = dict(dt=1.0, keep=("white",), span_s=180.0)
        glob = bound_psd(f, np.array(list(curves.values())), spec, **kw)
        per = bound_by_axis(f, curves, spec, **kw)
        ok_allan = {"components": {}, "total": {"passed": True}, "passed": True}
        short = {"components": {}, "passed": False,
                 "total": {"passed": False, "worst_ratio": 0.6, "curve": "d1/z", "tau_s": 0.02,
                           "shortfalls": [{"curve": "d1/z", "tau_s": 0.02, "ratio": 0.6}], "tau_band_s": [0.01, 180.0]}}

        def bound_doc(res, allan):
            b = res.to_dict(sensor="gyro")
            b["psd_bounded"] = b.pop("bounded")
            return {**b, "spec_name": "STIM-300", "n_curves": 4, "allan_check": allan,
                    "allan_check_passed": allan["passed"]}

        def ver(res):
            return verification_stage(res.model, "gyro", spec=spec, fix_s=60.0, outage_s=120.0, reduce=False)[0]

        bound = {**bound_doc(glob, ok_allan), "per_axis_models": {
            "x": {**bound_doc(per["x"][1], ok_allan), "curves": per["x"][0], "upper_envelope": None},
            "z": {**bound_doc(per["z"][1], short), "curves": per["z"][0], "upper_envelope": None}}}
        verify = {**ver(glob), "per_axis_models": {ax: ver(per[ax][1]) for ax in ("x", "z")}}
        paths = {k: tmp_path / f"{k}.yaml" for k in ("bound", "verify", "contract", "kf")}
        paths["bound"].write_text(yaml.safe_dump(plain(bound)))
        paths["verify"].write_text(yaml.safe_dump(plain(verify)))
        _script("contract").contract(str(paths["bound"]), str(paths["verify"]), str(spec_path), str(paths["kf"]),
                                     "fail", str(paths["contract"]), "gyro")
        con = yaml.safe_load(paths["contract"].read_text())
        assert con["bounded"] is True and con["failed_checks"] == []
        px, pz = con["per_axis_models"]["x"], con["per_axis_models"]["z"]
        assert px["bounded"] and px["exported_in_kf"] and px["curves"] == ["d1/x", "d2/x"]
        assert px["inflation_scope"]["dropped_from_exported_model"] == []  # reduce=False: the bound is exported
        assert not pz["bounded"] and not pz["exported_in_kf"]
        assert [(c["check"], c["curve"], c["tau_s"], c["worst_ratio"]) for c in pz["failed_checks"]] == \
            [("allan_total", "d1/z", 0.02, 0.6)]
        _script("kf").main(str(paths["bound"]), str(paths["verify"]), str(paths["contract"]), 1.0, 120.0,
                           str(paths["kf"]), "gyro")
        kf = yaml.safe_load(paths["kf"].read_text())
        assert kf["per_axis"]["x"]["model"] == "own" and kf["per_axis"]["z"]["model"] == "global"
        assert kf["per_axis"]["x"]["parameters"]["white"] == pytest.approx(per["x"][1].model.white, rel=1e-12)
        assert kf["per_axis"]["z"]["parameters"]["white"] == pytest.approx(glob.model.white, rel=1e-12)
        # the axes differ: x's own white noise is below the global one (set by z, density twice x's). Each bound N^2
        # is the largest of 3600 two-window Welch ordinates (Gamma(2, 1/2) in units of the PSD): between 4.3 and 9.05
        # except with probability 1e-3 each, so N_x/N_global <= sqrt(9.05 / (4 x 4.3)) = 0.725
        assert per["x"][1].model.white < 0.75 * glob.model.white


def test_start_up_refuses_a_filter_rate_the_replay_cannot_run_and_the_renamed_keys(tiny_run):
    """The verification runs at application.filter_rate_hz (one filter rate: no warning of two rates any more); a
    filter rate that does not divide the records' rate: refused before any job, naming the key and the record (the
    verify job would otherwise stop mid-run on the replay); a filter faster than the decimation: the replay reads
    the full-rate series; a renamed key: refused naming the new one."""
    work, config = tiny_run
    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())  # the defaults the tiny config keeps
    for key, value in yaml.safe_load(config.read_text()).items():
        cfg[key] = {**cfg[key], **value} if isinstance(value, dict) and isinstance(cfg.get(key), dict) else value
    base = cfg["application"]["filter_rate_hz"]
    assert base == cfg["decimate"]["rate_hz"]  # the tiny run's rates agree
    same = snakemake(work, "-n", config=config)
    assert "imupipe warning" not in same.stderr
    faster = _changed(work, config, "fast_verify", application={"filter_rate_hz": base * 3})
    proc = snakemake(work, "-n", config=faster, check=False)
    assert proc.returncode != 0
    rate = cfg["simulation"]["record_rate_hz"]
    assert (f"record rate {rate:g} Hz is not a whole multiple of application.filter_rate_hz = {base * 3} Hz"
            in proc.stdout + proc.stderr)
    # 10 Hz on the 20 Hz records decimated to 1 Hz for the bound: the verify jobs read the full-rate series
    fast = _changed(work, config, "fast_filter", application={"filter_rate_hz": rate / 2})
    proc = snakemake(work, "-n", "--forcerun", "verify", "--verbose", config=fast)
    verify_inputs = proc.stdout.split("rule verify:", 1)[1].split("output:", 1)[0]
    assert "/series/" in verify_inputs and "/decimated/" not in verify_inputs, verify_inputs
    # a fix rate that is not a whole fraction of the filter rate: refused before any job, naming both keys
    odd_fix = _changed(work, config, "odd_fix", verify={"fix_rate_hz": base / 2.5})
    proc = snakemake(work, "-n", config=odd_fix, check=False)
    assert proc.returncode != 0
    assert (f"verify.fix_rate_hz = {base / 2.5} Hz must divide application.filter_rate_hz = {base} Hz"
            in proc.stdout + proc.stderr)
    # the old keys: refused by name at start-up, the new key suggested
    old = _changed(work, config, "old_keys", verify={"filter_rate_hz": base})
    proc = snakemake(work, "-n", config=old, check=False)
    assert proc.returncode != 0 and "verify.filter_rate_hz is no longer a key" in proc.stdout + proc.stderr


def test_contract_says_the_inflation_is_the_bounds_and_which_states_the_export_dropped(tmp_path):
    """The contract's `inflation` is bound/spec of the bound's model; when the verified reduction drops a state (here
    a GM of sigma 1e-9 rad/s, T = 5 s, which no check needs) the exported `model` lacks it. The contract keeps the
    `inflation` key and adds `inflation_scope` (the dropped states and a statement), its header says so, and the run
    summary states it under the inflation table. Without a reduction the scope says the exported model is the
    bound's."""
    from imupipe.io import plain
    from imupipe.models import NoiseModel
    from imupipe.summary import render_summary
    from imupipe.verify import verification_stage

    spec_path = ROOT / "config" / "specs" / "stim300.yaml"
    truth = NoiseModel(white=1e-4, gauss_markov=((5e-5, 300.0),), random_walk=1e-6)
    big = NoiseModel(white=1.2e-4, gauss_markov=((6e-5, 300.0), (1e-9, 5.0)), random_walk=1.2e-6)
    bound = {"spec_name": "STIM-300", "mode": "raw", "n_curves": 1, "psd_bounded": True, "margin": 1.2,
             "spec_margin": 1.1, "all_frequency_margin": 1.1, "allan_check_passed": True,
             "allan_check": {"components": {}, "total": {"passed": True}, "passed": True},
             "bound": big.to_dict(), "inflation": {"N": 1.2, "sigma_1": 1.2, "T_1": 1.0, "sigma_2": None, "T_2": None,
                                                    "K": 1.2}}
    docs = {}
    for reduce in (True, False):
        ver = verification_stage(big, "gyro", spec=truth, upper=truth, fix_s=300.0, outage_s=900.0, reduce=reduce)[0]
        paths = {k: tmp_path / f"{k}_{reduce}.yaml" for k in ("bound", "verify", "contract")}
        paths["bound"].write_text(yaml.safe_dump(plain(bound)))
        paths["verify"].write_text(yaml.safe_dump(plain(ver)))
        _script("contract").contract(str(paths["bound"]), str(paths["verify"]), str(spec_path), "kf.yaml", "fail",
                                     str(paths["contract"]), "gyro")
        docs[reduce] = (yaml.safe_load(paths["contract"].read_text()), paths["contract"].read_text())
    (con, text), (whole, _) = docs[True], docs[False]
    assert con["model_reduced"] and len(con["model"]["gauss_markov"]) == 1  # the T = 5 s GM is not exported
    assert con["inflation"] == bound["inflation"]  # the key its readers read is unchanged
    scope = con["inflation_scope"]
    assert scope["of"] == "bound" and scope["dropped_from_exported_model"] == ["gauss_markov T=5 s"]
    assert "BEFORE the verified reduction" in scope["statement"] and "gauss_markov T=5 s" in scope["statement"]
    assert "inflation: bound/spec per parameter of the BOUND's" in text.replace("\n# ", " ")
    assert not whole["model_reduced"] and whole["inflation_scope"]["dropped_from_exported_model"] == []
    assert "which is the exported model (no state dropped)" in whole["inflation_scope"]["statement"]
    summary = render_summary({"gyro": {"bound": con}})
    assert f"- the table above: {scope['statement']}" in summary
    assert "- the table above" not in render_summary({"gyro": {"bound": whole}})


# -------------------------------------------------------------------------------------------------
# stage functions of the thin scripts, without a run


def test_stationarity_summary_stage_applies_on_fail():
    from imupipe.stages.stationarity import summary_stage

    def verdict(axis, ok):
        return {"dataset": "a", "axis": axis, "stationary": ok, "p_value": 0.5 if ok else 0.001, "test": "calibrated",
                "paper": {"stationary": ok}}

    both = [verdict("x", True), verdict("y", False)]
    warn = summary_stage(both, "warn", "gyro")
    assert [c["included"] for c in warn["curves"]] == [True, True] and warn["n_non_stationary"] == 1
    assert [c["included"] for c in summary_stage(both, "exclude", "gyro")["curves"]] == [True, False]
    with pytest.raises(ValueError, match=r"stationarity.on_fail = fail\): a/gyro/y \(p = 0.001\)"):
        summary_stage(both, "fail", "gyro")
    with pytest.raises(ValueError, match="every gyro record failed the stationarity test and on_fail = exclude"):
        summary_stage([verdict("y", False)], "exclude", "gyro")


def test_tables_stage_of_the_spec_sheet_itself_gives_ratio_one():
    # a bound equal to the spec sheet's own model: every parameter's bound/spec ratio is 1 (printed to 4 digits)
    import csv
    import io

    from imupipe.specsheet import load_spec
    from imupipe.stages.tables import tables_stage

    spec = load_spec(ROOT / "config" / "specs" / "stim300.yaml")
    bounds = {}
    for sensor, m in spec.models.items():
        bounds[sensor] = {"bound": {"white": m.white, "random_walk": m.random_walk,
                                    "gauss_markov": [{"sigma": s, "T": t} for s, t in m.gauss_markov]},
                          "mode": "raw", "margin": 1.25, "psd_bounded": True}
    out = tables_stage(spec, bounds)
    rows = list(csv.DictReader(io.StringIO(out["csv"])))
    assert rows and {r["sensor"] for r in rows} == set(spec.models)
    assert len(rows) == 8 and all(abs(float(r["ratio"]) - 1.0) < 1e-12 for r in rows)  # N, GM sigma, T, K of each
    assert out["markdown"].startswith(f"# {spec.name}: spec sheet vs bound (raw mode)")
    assert "<table" in out["html"] and "gyro 1.25" in out["markdown"]
    # the sensors' bounds from different modes: the title says whose is which (an outside evaluation read "auto
    # (smoothed), auto (envelope) mode")
    bounds["accel"] = {**bounds["accel"], "mode": "smoothed"}
    assert tables_stage(spec, bounds)["markdown"].startswith(
        f"# {spec.name}: spec sheet vs bound (mode: gyro raw, accel smoothed)")
    # a line the lines policy made a filter state is a row of the table (an outside evaluation found inflation.md
    # silent on the KF's line states): its sigma in the GM sigma's unit, 1e-4 rad/s = 20.63 deg/h, no spec value
    bounds["gyro"]["bound"]["narrowband"] = [{"sigma": 1e-4, "f0_hz": 12.0, "zeta": 0.002}]
    md = tables_stage(spec, bounds)["markdown"]
    assert "| gyro | line 1 sigma (12 Hz, damping 0.002) | deg/h | - | 20.63 | - |" in md
    # a line the bound gave no power (the default run's 16.9 Hz lines: sigma 0) is no state and no row
    bounds["gyro"]["bound"]["narrowband"] = [{"sigma": 0.0, "f0_hz": 16.9, "zeta": 6e-5},
                                             {"sigma": 1e-4, "f0_hz": 12.0, "zeta": 0.002}]
    md = tables_stage(spec, bounds)["markdown"]
    assert "16.9 Hz" not in md and "| gyro | line 1 sigma (12 Hz, damping 0.002) | deg/h | - | 20.63 | - |" in md
