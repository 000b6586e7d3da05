"""Stack per-axis results into one labelled Dataset per sensor type: dims (dataset, axis, <coord>)."""

from __future__ import annotations

__all__ = ["Stacked", "stack_axis_files", "included_flags"]

_PER_FILE = ("dataset", "sensor", "axis", "n_samples", "n_samples_used")


def stack_axis_files(paths, join: str = "exact"):
    """Open per-(dataset, axis) netCDF files (global attrs ``dataset`` and ``axis``) and stack them.

    Parameters
    ----------
    paths : sequence of str
        Files of one sensor type, each with one index coordinate (``frequency`` or ``tau``).
    join : {"exact", "outer"}
        ``exact``: every file must share the coordinate (PSDs of one configuration); ``outer``:
        union, missing entries NaN (AV grids of records of different lengths).

    Returns
    -------
    xarray.Dataset
        Variables with dims (dataset, axis, coord), their attrs kept; per-file record lengths as the
        variable ``n_samples`` (dataset, axis); global attrs of the first file, minus per-file ones.
    """
    import numpy as np
    import xarray as xr

    by_dataset: dict[str, list] = {}
    first_attrs = None
    for path in paths:
        with xr.open_dataset(path) as ds:
            ds = ds.load()
        dataset, axis = ds.attrs.get("dataset"), ds.attrs.get("axis")
        if dataset is None or axis is None:
            raise ValueError(f"{path}: global attributes 'dataset' and 'axis' are required")
        if first_attrs is None:
            first_attrs = dict(ds.attrs)
        n = ds.attrs.get("n_samples")
        ds = ds.reset_coords(drop=True)
        if n is not None:
            ds["n_samples"] = xr.DataArray(int(n), attrs={"long_name": "samples in the record", "units": "1"})
        ds.attrs = {}
        by_dataset.setdefault(str(dataset), []).append(ds.expand_dims({"axis": [str(axis)]}))
    if not by_dataset:
        raise ValueError("no files to stack")
    try:
        per_dataset = [xr.concat(v, dim="axis", join=join).sortby("axis") for v in by_dataset.values()]
        out = xr.concat(per_dataset, dim=xr.DataArray(list(by_dataset), dims="dataset", name="dataset"), join=join)
    except ValueError as exc:
        raise ValueError(f"files do not share one grid ({exc}); check that every dataset uses the same "
                         "decimation rate and PSD window") from None
    for name in out.data_vars:
        # an integer variable (the noise type alpha) that the outer join padded with NaN: stored as float
        # with NaN rather than cast back to its integer dtype (NaN has no integer value)
        var = out[name]
        stored_as_int = np.dtype(var.encoding.get("dtype", "f8")).kind in "iu"
        if var.dtype.kind == "f" and stored_as_int and np.isnan(var.values).any():
            var.encoding.pop("dtype", None)
    out.attrs = {k: v for k, v in first_attrs.items() if k not in _PER_FILE}
    out["dataset"].attrs["long_name"] = "dataset"
    out["axis"].attrs["long_name"] = "sensor axis"
    return out


def included_flags(summary: dict, ds):
    """Boolean DataArray (dataset, axis): curve used by the bound (stationarity summary's ``included``)."""
    import numpy as np
    import xarray as xr

    flags = xr.DataArray(np.zeros((ds.sizes["dataset"], ds.sizes["axis"]), dtype=bool),
                         coords={"dataset": ds.dataset, "axis": ds.axis}, dims=("dataset", "axis"))
    for c in summary["curves"]:
        flags.loc[{"dataset": c["dataset"], "axis": c["axis"]}] = bool(c["included"])
    flags.attrs = {"long_name": "curve used by the bound (stationarity.on_fail)", "units": "1"}
    return flags.astype("i1")


class Stacked:
    """A per-sensor-type file of :func:`stack_axis_files` (``results/spectra/{sensor}.nc``,
    ``results/allan/{sensor}.nc``) read with netCDF4 alone, for the jobs that only read it: importing
    xarray costs ~0.35 s per process, a third of a bound job.

    Attributes
    ----------
    datasets, axes : list of str
        The ``dataset`` and ``axis`` coordinates, in file order.
    coords : dict
        Every 1-D coordinate variable (``frequency`` in Hz, ``tau`` in s, ...) as a float64 array.
    attrs : dict
        Global attributes (``rate_hz``, ``taper``, ...).
    variables : dict
        ``name -> (values, dims, attrs)`` of every other variable, values as stored (floats NaN where
        missing, the same as xarray's decoding of the ``_FillValue = NaN`` these files carry).
    """

    def __init__(self, path):
        import netCDF4
        import numpy as np

        self.path = str(path)
        with netCDF4.Dataset(self.path) as nc:
            nc.set_auto_mask(False)
            self.attrs = {k: nc.getncattr(k) for k in nc.ncattrs()}
            names = {"dataset", "axis"}
            missing = names - set(nc.variables)
            if missing:
                raise ValueError(f"{self.path}: no {', '.join(sorted(missing))} coordinate: not a per-sensor file")
            self.datasets = [str(v) for v in nc.variables["dataset"][:]]
            self.axes = [str(v) for v in nc.variables["axis"][:]]
            self.coords, self.variables = {}, {}
            for name, var in nc.variables.items():
                if name in names:
                    continue
                attrs = {k: var.getncattr(k) for k in var.ncattrs() if k != "_FillValue"}
                if var.dimensions == (name,):
                    self.coords[name] = np.asarray(var[:], dtype=np.float64)
                else:
                    self.variables[name] = (np.asarray(var[:]), tuple(var.dimensions), attrs)

    def _variable(self, name):
        if name not in self.variables:
            raise KeyError(f"{self.path}: no variable {name!r} (has {sorted(self.variables)})")
        return self.variables[name]

    def __getitem__(self, name):
        """Values of a variable (all its dimensions) or of a coordinate."""
        if name in self.coords:
            return self.coords[name]
        return self._variable(name)[0]

    def at(self, name, dataset, axis):
        """A variable at one (dataset, axis): the curve on its last dimension, or a scalar; a variable
        without the dataset/axis dimensions is returned whole."""
        values, dims, _ = self._variable(name)
        index = tuple(self.datasets.index(dataset) if d == "dataset" else self.axes.index(axis) if d == "axis"
                      else slice(None) for d in dims)
        return values[index]

    def curves(self, included_only=False):
        """(dataset, axis) of every curve in file order; with `included_only`, those whose ``included``
        flag is set."""
        return [(d, a) for d in self.datasets for a in self.axes
                if not included_only or int(self.at("included", d, a))]
