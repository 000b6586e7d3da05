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


def test_per_sensor_file_reads_the_same_without_xarray(tmp_path, rng):
    # what collect writes (xarray) and bound/identify/figures read (netCDF4 alone): every variable of
    # every curve, the coordinates, the global attrs and the included flags agree with xarray's reading;
    # a shorter record's missing taus (outer join) come back NaN in both
    from imupipe.io import write_netcdf_atomic
    from imupipe.merge import Stacked, included_flags, stack_axis_files

    paths = []
    for d, n in (("long", 40_000), ("short", 10_000)):
        for a in ("x", "y", "z"):
            lab = _allan_variance(rng.standard_normal(n), 10.0, taus="octave", units="rad/s")
            lab.attrs.update(dataset=d, axis=a, sensor="gyro", n_samples=n)
            paths.append(tmp_path / f"{d}_{a}.nc")
            lab.to_netcdf(paths[-1])
    ds = stack_axis_files(paths, join="outer")
    summary = {"curves": [{"dataset": d, "axis": a, "included": (d, a) != ("short", "y")}
                          for d in ("long", "short") for a in ("x", "y", "z")]}
    ds["included"] = included_flags(summary, ds)
    write_netcdf_atomic(ds, tmp_path / "gyro.nc")

    st = Stacked(tmp_path / "gyro.nc")
    with xr.open_dataset(tmp_path / "gyro.nc") as ref:
        ref = ref.load()
        assert st.datasets == list(ref.dataset.values) and st.axes == list(ref.axis.values)
        np.testing.assert_array_equal(st["tau"], ref.tau.values)
        assert st.attrs == ref.attrs
        for name in ("avar", "avar_lower", "edf", "alpha", "n_samples"):
            for d in st.datasets:
                for a in st.axes:
                    np.testing.assert_array_equal(st.at(name, d, a), ref[name].sel(dataset=d, axis=a).values)
    for name in ("avar", "alpha"):  # the integer noise type too: NaN where the record has no such tau
        assert np.isnan(st.at(name, "short", "x")[-1]) and np.isfinite(st.at(name, "long", "x")[-1])
    assert ("short", "y") in st.curves() and ("short", "y") not in st.curves(included_only=True)
    assert len(st.curves(included_only=True)) == 5
    with pytest.raises(KeyError, match="no variable 'psd'"):
        st["psd"]
    with pytest.raises(ValueError, match="not a per-sensor file"):
        Stacked(paths[0])
