"""The per-axis jobs write their netCDF files with netCDF4 alone (imupipe.io.write_series, Labelled.to_netcdf,
Stacked.to_netcdf) and the files read back as xarray's own to_netcdf of the same content would: every kind of
file (full-rate and decimated series with their segment attributes, whole and pooled PSD and Allan variance,
the per-sensor stack), compared with ``xarray.testing.assert_identical`` (values, dtypes, dimensions,
coordinates and every attribute). And none of the per-axis jobs imports xarray (about 0.7 s of CPU per job):
each workflow script's ``main`` run on a small axis in a fresh interpreter."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from imupipe.io import read_yaml, write_series, write_yaml_atomic
from imupipe.segments import Segments, pooled_allan, pooled_psd

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "workflow" / "scripts"
LABELS = {"dataset": "sim01", "sensor": "gyro", "axis": "x"}


def _assert_same_file(written, oracle: xr.Dataset, tmp_path) -> None:
    """`written` (a path) reads back identical to xarray's to_netcdf of `oracle` (netCDF4 engine)."""
    oracle.to_netcdf(tmp_path / "oracle.nc", engine="netcdf4")
    with xr.open_dataset(written) as a, xr.open_dataset(tmp_path / "oracle.nc") as b:
        a, b = a.load(), b.load()
    xr.testing.assert_identical(a, b)
    for name in a.variables:  # assert_identical compares values; the stored types must agree too
        assert a[name].dtype == b[name].dtype, name
        assert a[name].encoding.get("dtype") == b[name].encoding.get("dtype"), name
    assert a.attrs.keys() == b.attrs.keys()


@pytest.mark.parametrize("kind", ["series", "decimated_split", "cleaned"])
def test_series_file_reads_as_xarrays(tmp_path, rng, kind):
    # the attrs each job writes: ingest (labels, gap fill), decimate under split (int64 bounds, float starts),
    # outliers (an int count, a text rule, a float start); the variable's long_name taken out of the attrs
    x = 1e-4 * rng.standard_normal(5_000)
    attrs = {**LABELS, "source": "a.csv", "n_filled": 0, "long_name": "angular rate"}
    if kind == "decimated_split":
        seg = Segments(((0, 2_000), (2_000, 5_000)), 5_000, 1.0, (0.0, 2_400.0))
        attrs.update(seg.to_attrs(),
                     decimation="block average of 100 samples at 100 Hz within each of 2 segments")
    elif kind == "cleaned":
        attrs.update(outliers_removed=3, outlier_rule="|x - median| > 7 MAD", segment_start_s=12.5)
    write_series(tmp_path / "s.nc", x, rate_hz=1.0, units="rad/s", attrs={**attrs, "ignored": None})
    var_attrs = {"units": "rad/s", "long_name": attrs.pop("long_name")}
    oracle = xr.Dataset({"signal": ("sample", x, var_attrs)}, attrs={"rate_hz": 1.0, **attrs})
    _assert_same_file(tmp_path / "s.nc", oracle, tmp_path)


def _psd(y, seg):
    return pooled_psd(y, 1.0, seg, window_s=600.0, step_s=300.0, taper="hann", detrend="constant",
                      confidence=0.95, units="rad/s")


def _allan(y, seg):
    return pooled_allan(y, 10.0, seg, taus="octave", confidence=0.683, units="rad/s")


@pytest.mark.parametrize("kind", ["psd", "allan"])
@pytest.mark.parametrize("split", [False, True], ids=["whole", "segments"])
def test_curve_file_reads_as_xarrays(tmp_path, rng, kind, split):
    # the psd and allan jobs' files: the record's own curve, or pooled over segments (attrs of
    # imupipe.segments, segments_without_window for a segment shorter than a PSD window), with the labels the
    # jobs add
    n = 6_000
    y = rng.standard_normal(n)
    seg = (Segments(((0, 2_500), (2_600, 5_800), (5_900, 6_000)), n, 1.0 if kind == "psd" else 10.0,
                    (0.0, 260.0, 590.0)) if split else Segments.whole(n, 1.0 if kind == "psd" else 10.0))
    lab = _psd(y, seg) if kind == "psd" else _allan(y, seg)
    lab.attrs.update(LABELS, n_filled=2, filled_rows="10-11")
    if split:
        assert lab.attrs["n_record_segments"] == (2 if kind == "psd" else 3)
    lab.to_netcdf(tmp_path / "c.nc")
    _assert_same_file(tmp_path / "c.nc", lab.to_xarray(), tmp_path)


@pytest.mark.parametrize("join", ["exact", "outer"])
def test_stacked_psd_file_reads_as_xarrays_own(tmp_path, rng, join):
    # the stack job's PSD file (exact join: one frequency grid), written without xarray, against Stacked's
    # xarray form (test_labelled.py checks that form against xarray's own concat of the per-axis files)
    from imupipe.merge import Stacked

    paths = []
    for d in ("sim01", "sim02"):
        for a in ("x", "y"):
            lab = _psd(rng.standard_normal(3_000), Segments.whole(3_000, 1.0))
            lab.attrs.update(dataset=d, sensor="gyro", axis=a, n_samples=3_000)
            paths.append(tmp_path / f"{d}_{a}.nc")
            lab.to_netcdf(paths[-1])
    st = Stacked.from_axis_files(paths, join=join)
    st.set_included({"curves": [{"dataset": d, "axis": a, "included": (d, a) != ("sim02", "y")}
                                for d in ("sim01", "sim02") for a in ("x", "y")]})
    st.attrs["sensor"] = "gyro"
    st.to_netcdf(tmp_path / "gyro.nc")
    _assert_same_file(tmp_path / "gyro.nc", st.to_xarray(), tmp_path)


# ----------------------------------------------------------------------------------------------------------
# the jobs' imports: each per-axis script's main in a fresh interpreter, the heavy modules it loaded
# ----------------------------------------------------------------------------------------------------------
RUN = """
import json, runpy, sys
script, kwargs = sys.argv[1], json.loads(sys.argv[2])
runpy.run_path(script, run_name="job")["main"](**kwargs)
print(json.dumps([m for m in ("xarray", "pandas", "matplotlib", "scipy.special") if m in sys.modules]))
"""


def _job(script: str, **kwargs) -> list:
    out = subprocess.run([sys.executable, "-c", RUN, str(SCRIPTS / f"{script}.py"), json.dumps(kwargs)],
                         capture_output=True, text=True, env={"OPENBLAS_NUM_THREADS": "1", "PATH": ""})
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.splitlines()[-1])


@pytest.fixture(scope="module")
def axis_files(tmp_path_factory):
    """One full-rate axis (2 h at 10 Hz, white noise plus a slow random walk) and its decimated series."""
    d = tmp_path_factory.mktemp("axis")
    rng = np.random.default_rng(31)
    x = 1e-3 * rng.standard_normal(72_000) + 1e-6 * np.cumsum(rng.standard_normal(72_000))
    write_series(d / "series.nc", x, rate_hz=10.0, units="rad/s", attrs=LABELS)
    _job("decimate", path_series=str(d / "series.nc"), rate_hz=1.0, path_decimated=str(d / "decimated.nc"))
    return d


# modules each job may load; scipy.special stays in psd, allan and lines (chi-squared and gamma quantiles of
# non-integer degrees of freedom: docs/performance.md, issue 31) and in outliers (the events' t quantiles)
JOBS = {
    "decimate": (dict(path_series="series.nc", rate_hz=1.0, path_decimated="decimated2.nc"), set()),
    "psd": (dict(path_decimated="decimated.nc", window_s=1800.0, step_s=900.0, taper="hann",
                 detrend="constant", confidence=0.95, path_psd="psd.nc"), {"scipy.special"}),
    "allan": (dict(path_series="series.nc", taus="octave", confidence=0.683, path_allan="allan.nc"),
              {"scipy.special"}),
    "lines": (dict(path_series="series.nc", resolution_hz=0.01, alpha=0.01, floor_window_bins=51,
                   path_lines="lines.yaml"), {"scipy.special"}),
    "outliers": (dict(path_series="series.nc", policy="remove", k=7.0, window_samples=100, max_indices=10,
                      path_report="outliers.yaml", path_cleaned="cleaned.nc", events={"policy": "warn"}),
                 {"scipy.special"}),
}


@pytest.mark.parametrize("script", list(JOBS))
def test_per_axis_job_loads_no_xarray(axis_files, script):
    kwargs, allowed = JOBS[script]
    kwargs = {k: str(axis_files / v) if k.startswith("path_") else v for k, v in kwargs.items()}
    loaded = set(_job(script, **kwargs))
    assert loaded <= allowed, f"{script} job loads {sorted(loaded - allowed)}"
    inputs = ("path_series",) if script == "decimate" else ("path_series", "path_decimated")
    assert all(Path(v).is_file() for k, v in kwargs.items() if k.startswith("path_") and k not in inputs)
    if script in ("psd", "allan"):  # the job's file as xarray reads it: labelled, units on every variable
        with xr.open_dataset(kwargs[f"path_{script}"]) as ds:
            assert {k: ds.attrs[k] for k in LABELS} == LABELS
            assert all("units" in ds[v].attrs for v in ds.variables)


def test_stack_job_loads_no_xarray(axis_files, tmp_path):
    _job("psd", path_decimated=str(axis_files / "decimated.nc"), window_s=1800.0, step_s=900.0, taper="hann",
         detrend="constant", confidence=0.95, path_psd=str(tmp_path / "x.nc"))
    write_yaml_atomic({"curves": [{"dataset": "sim01", "axis": "x", "included": True}]},
                      tmp_path / "summary.yaml")
    loaded = _job("stack", curves=[str(tmp_path / "x.nc")], path_summary=str(tmp_path / "summary.yaml"),
                  join="exact", path_out=str(tmp_path / "gyro.nc"), sensor="gyro")
    assert "xarray" not in loaded and read_yaml(tmp_path / "summary.yaml")["curves"][0]["included"]
    with xr.open_dataset(tmp_path / "gyro.nc") as ds:
        assert ds.attrs["sensor"] == "gyro" and ds["included"].values.tolist() == [[1]]
