"""Labelled arrays on one dimension: what :func:`imupipe.allan_variance` and :func:`imupipe.psd` compute,
before they become an :class:`xarray.Dataset`.

The public functions return ``Labelled.to_xarray()``. The workflow's full-rate jobs write
``Labelled.to_netcdf()`` instead, with netCDF4 alone: importing xarray costs ~0.4 s and ~50 MB per
process, more than the numerical work of an axis (docs/architecture.md). Both give the same file:
an index coordinate variable named like the dimension, other coordinates listed in each data
variable's CF ``coordinates`` attribute (xarray reads them back as coordinates), every variable with
its attrs (``long_name``, ``units``), and the global attrs.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Labelled", "stack_curves"]


class Labelled(NamedTuple):
    """Variables on one dimension `dim`, each ``name -> (values, attrs)``.

    `coords` holds the index coordinate (named `dim`) first, then any other coordinates on `dim`;
    `data_vars` the data variables; `attrs` the global attributes (str, int, float; None is skipped).
    """

    dim: str
    coords: dict
    data_vars: dict
    attrs: dict

    def to_xarray(self):
        """The :class:`xarray.Dataset` (imports xarray)."""
        import xarray as xr

        return xr.Dataset(
            data_vars={k: (self.dim, v, dict(a)) for k, (v, a) in self.data_vars.items()},
            coords={k: (self.dim, v, dict(a)) for k, (v, a) in self.coords.items()},
            attrs={k: v for k, v in self.attrs.items() if v is not None},
        )

    def to_netcdf(self, path) -> None:
        """Write to netCDF-4 at `path` atomically (:func:`imupipe.io.atomic_path`), without xarray."""
        import netCDF4

        from imupipe.io import atomic_path

        n = len(next(iter(self.coords.values()))[0])
        aux = " ".join(k for k in self.coords if k != self.dim)
        with atomic_path(path) as tmp:
            with netCDF4.Dataset(tmp, "w", format="NETCDF4") as nc:
                nc.createDimension(self.dim, n)
                for name, (values, attrs) in {**self.coords, **self.data_vars}.items():
                    a = np.asarray(values)
                    if a.shape != (n,):
                        raise ValueError(f"variable {name!r} has shape {a.shape}, dimension {self.dim!r} is {n}")
                    var = nc.createVariable(name, a.dtype.str.lstrip("<>=|"), (self.dim,))
                    var.setncatts({k: v for k, v in attrs.items() if v is not None})
                    if aux and name in self.data_vars:
                        var.coordinates = aux
                    var[:] = a
                nc.setncatts({k: v for k, v in self.attrs.items() if v is not None})


def stack_curves(da, dim: str):
    """(C, n) float64 array and labels of an xarray.DataArray with dimension `dim` (``frequency`` or
    ``tau``): every other dimension (e.g. ``dataset``, ``axis``) stacked into curves labelled
    ``"dataset=..., axis=..."``; a DataArray on `dim` alone is one curve, ``"curve 0"``."""
    other = [d for d in da.dims if d != dim]
    if not other:
        return np.asarray(da.values, dtype=np.float64)[None, :], ["curve 0"]
    st = da.stack(curve=other).transpose("curve", dim)
    labels = []
    for idx in st.indexes["curve"]:
        idx = idx if isinstance(idx, tuple) else (idx,)
        labels.append(", ".join(f"{d}={v}" for d, v in zip(other, idx)))
    return np.asarray(st.values, dtype=np.float64), labels
