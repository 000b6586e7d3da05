"""The netCDF4-only writer of the workflow's full-rate jobs gives the same file content as xarray."""

import numpy as np
import pytest
import xarray as xr

from imupipe.allan import _allan_variance
from imupipe.spectra import _psd


@pytest.mark.parametrize("kind", ["allan", "psd"])
def test_netcdf4_writer_reads_back_identical_to_xarray(tmp_path, rng, kind):
    x = rng.standard_normal(20_000)
    lab = (_allan_variance(x, 10.0, taus="octave", units="rad/s") if kind == "allan"
           else _psd(x, 10.0, window_s=200.0, step_s=100.0, units="rad/s"))
    lab.attrs["dataset"] = "d1"
    lab.to_netcdf(tmp_path / "a.nc")
    lab.to_xarray().to_netcdf(tmp_path / "b.nc", engine="netcdf4")
    with xr.open_dataset(tmp_path / "a.nc") as a, xr.open_dataset(tmp_path / "b.nc") as b:
        xr.testing.assert_identical(a.load(), b.load())
        assert set(a.coords) == set(lab.coords)  # auxiliary coordinates come back as coordinates


def test_shape_mismatch_is_refused(tmp_path):
    from imupipe.labelled import Labelled

    lab = Labelled("tau", {"tau": (np.arange(3.0), {"units": "s"})}, {"avar": (np.ones(2), {})}, {})
    with pytest.raises(ValueError, match="avar"):
        lab.to_netcdf(tmp_path / "x.nc")
    assert not list(tmp_path.iterdir())  # nothing half-written


@pytest.mark.parametrize("backend", ["numpy", "auto"])
def test_in_place_integration_gives_the_same_allan_variance(tmp_path, rng, backend):
    # the workflow reads a record into buf[1:] and integrates it in place (no second copy): same AV, bit for bit
    from imupipe.io import read_series, write_series

    x = 9.81 + 1e-3 * rng.standard_normal(50_001)
    write_series(tmp_path / "s.nc", x, rate_hz=10.0, units="m/s^2")
    ref = _allan_variance(x, 10.0, taus="octave", backend=backend)
    y, rate, _ = read_series(tmp_path / "s.nc", pad_front=1)
    assert y.base is not None and y.base.size == x.size + 1 and np.array_equal(y, x)
    got = _allan_variance(y, rate, taus="octave", backend=backend, theta_buffer=y.base)
    np.testing.assert_array_equal(got.data_vars["avar"][0], ref.data_vars["avar"][0])


def _xarray_stack(paths, join):
    """The oracle: the same stacking with xarray (open each file, drop auxiliary coordinates, n_samples as a
    variable, concat on axis then dataset with the given join)."""
    by_dataset, first = {}, None
    for path in paths:
        with xr.open_dataset(path) as ds:
            ds = ds.load()
        dataset, axis, n = ds.attrs["dataset"], ds.attrs["axis"], ds.attrs["n_samples"]
        first = first or dict(ds.attrs)
        ds = ds.reset_coords(drop=True)
        ds["n_samples"] = xr.DataArray(int(n), attrs={"long_name": "samples in the record", "units": "1"})
        ds["rate_hz"] = xr.DataArray(float(ds.attrs["rate_hz"]),  # per curve (records of different rates)
                                     attrs={"long_name": "sampling rate of the curve's record", "units": "Hz"})
        ds.attrs = {}
        by_dataset.setdefault(dataset, []).append(ds.expand_dims({"axis": [axis]}))
    per_dataset = [xr.concat(v, dim="axis", join=join).sortby("axis") for v in by_dataset.values()]
    out = xr.concat(per_dataset, dim=xr.DataArray(list(by_dataset), dims="dataset", name="dataset"), join=join)
    out.attrs = {k: v for k, v in first.items() if k not in ("dataset", "sensor", "axis", "n_samples")}
    out["dataset"].attrs["long_name"] = "dataset"
    out["axis"].attrs["long_name"] = "sensor axis"
    return out


def test_per_sensor_file_is_xarrays_stack_and_reads_the_same_without_xarray(tmp_path, rng):
    # what collect writes and bound/identify/figures read, both with netCDF4 alone: xarray reads the file as
    # its own concat of the per-axis files (a shorter record's missing taus NaN, the integer noise type then
    # float), and Stacked reads every variable, coordinate, attribute and flag as xarray does
    from imupipe.merge import Stacked

    paths = []
    for d, n in (("long", 40_000), ("short", 10_000)):
        for a in ("z", "x", "y"):
            lab = _allan_variance(rng.standard_normal(n), 10.0, taus="octave", units="rad/s")
            lab.attrs.update(dataset=d, axis=a, sensor="gyro", n_samples=n)
            paths.append(tmp_path / f"{d}_{a}.nc")
            lab.to_netcdf(paths[-1])
    summary = {"curves": [{"dataset": d, "axis": a, "included": (d, a) != ("short", "y")}
                          for d in ("long", "short") for a in ("x", "y", "z")]}
    stacked = Stacked.from_axis_files(paths, join="outer")
    stacked.set_included(summary)
    stacked.to_netcdf(tmp_path / "gyro.nc")

    oracle = _xarray_stack(paths, "outer")
    oracle["included"] = xr.DataArray([[1, 1, 1], [1, 0, 1]], dims=("dataset", "axis"),
                                      attrs={"long_name": "curve used by the bound (stationarity.on_fail)",
                                             "units": "1"})
    with xr.open_dataset(tmp_path / "gyro.nc") as written:
        xr.testing.assert_identical(written.load(), oracle)
    xr.testing.assert_identical(stacked.to_xarray(), oracle)

    st = Stacked(tmp_path / "gyro.nc")
    assert st.datasets == ["long", "short"] and st.axes == ["x", "y", "z"]
    np.testing.assert_array_equal(st["tau"], oracle.tau.values)
    assert st.attrs == oracle.attrs
    for name in ("avar", "avar_lower", "edf", "alpha", "n_samples"):
        for d in st.datasets:
            for a in st.axes:
                np.testing.assert_array_equal(st.at(name, d, a), oracle[name].sel(dataset=d, axis=a).values)
    for name in ("avar", "alpha"):  # the integer noise type too: NaN where the record has no such tau
        assert np.isnan(st.at(name, "short", "x")[-1]) and np.isfinite(st.at(name, "long", "x")[-1])
    assert ("short", "y") in st.curves() and ("short", "y") not in st.curves(included_only=True)
    assert len(st.curves(included_only=True)) == 5
    with pytest.raises(KeyError, match="no variable 'psd'"):
        st["psd"]
    with pytest.raises(ValueError, match="not a per-sensor file"):
        Stacked(paths[0])


def test_exact_join_refuses_different_grids(tmp_path, rng):
    from imupipe.merge import Stacked

    paths = []
    for d, n in (("a", 20_000), ("b", 10_000)):
        lab = _psd(rng.standard_normal(n), 10.0, window_s=200.0 if d == "a" else 100.0, step_s=100.0, units="rad/s")
        lab.attrs.update(dataset=d, axis="x", n_samples=n)
        paths.append(tmp_path / f"{d}.nc")
        lab.to_netcdf(paths[-1])
    with pytest.raises(ValueError, match="do not share one grid.*b.nc"):
        Stacked.from_axis_files(paths, join="exact")
    one = Stacked.from_axis_files(paths[:1], join="exact")
    assert one.variables["psd"][0].shape == (1, 1, one["frequency"].size)
