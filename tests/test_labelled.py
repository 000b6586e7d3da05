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
