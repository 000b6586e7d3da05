"""Stack per-axis results into one labelled file per sensor type: dims (dataset, axis, <coord>).

Read and written with netCDF4 alone (:class:`Stacked`): importing xarray costs ~0.3 s per process, more than
the stacking itself. :meth:`Stacked.to_xarray` gives the same content as an :class:`xarray.Dataset`.
"""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["Stacked"]

# (the last five: a curve analysed over the segments of its record, imupipe.segments.CURVE_ATTRS)
_PER_FILE = ("dataset", "sensor", "axis", "n_samples", "n_samples_used", "n_filled", "filled_rows",
             "n_samples_analysed", "n_record_segments", "record_segments", "segments_method", "segments_without_window")
_RATE_ATTRS = {"long_name": "sampling rate of the curve's record", "units": "Hz"}
_INCLUDED_ATTRS = {"long_name": "curve used by the bound (stationarity.on_fail)", "units": "1"}
_LABEL_ATTRS = {"dataset": {"long_name": "dataset"}, "axis": {"long_name": "sensor axis"}}


class _AxisFile(NamedTuple):
    path: str
    dataset: str
    axis: str
    dim: str  # the one dimension, e.g. "tau" or "frequency"
    index: object  # its coordinate values, float64
    index_attrs: dict
    data: dict  # name -> (values, attrs) of the data variables on dim
    attrs: dict  # global attributes


def _read_axis_file(path) -> _AxisFile:
    """A per-axis file: its data variables on its one dimension; auxiliary coordinates (``m``, ``n_terms``)
    are dropped."""
    import netCDF4
    import numpy as np

    with netCDF4.Dataset(path) as nc:
        nc.set_auto_mask(False)
        attrs = {k: nc.getncattr(k) for k in nc.ncattrs()}
        dataset, axis = attrs.get("dataset"), attrs.get("axis")
        if dataset is None or axis is None:
            raise ValueError(f"{path}: global attributes 'dataset' and 'axis' are required")
        if len(nc.dimensions) != 1:
            raise ValueError(f"{path}: one dimension expected, found {list(nc.dimensions)}")
        dim = next(iter(nc.dimensions))
        if dim not in nc.variables:
            raise ValueError(f"{path}: no coordinate variable {dim!r}")
        aux = {c for v in nc.variables.values() for c in getattr(v, "coordinates", "").split()}
        data = {}
        for name, var in nc.variables.items():
            if name == dim or name in aux or var.dimensions != (dim,):
                continue
            data[name] = (np.asarray(var[:]), {k: var.getncattr(k) for k in var.ncattrs()
                                               if k not in ("_FillValue", "coordinates")})
        index = nc.variables[dim]
        return _AxisFile(str(path), str(dataset), str(axis), dim, np.asarray(index[:], dtype=np.float64),
                         {k: index.getncattr(k) for k in index.ncattrs() if k != "_FillValue"}, data, attrs)


class Stacked:
    """Every curve of one sensor type: per-(dataset, axis) files stacked on (dataset, axis, <coord>)
    (``results/spectra/{sensor}.nc``, ``results/allan/{sensor}.nc``), read and written with netCDF4 alone.

    ``Stacked(path)`` reads a stacked file; :meth:`from_axis_files` stacks per-axis files;
    :meth:`to_netcdf` writes (every variable with its attrs, floats with ``_FillValue = NaN``, the
    ``dataset`` and ``axis`` coordinates as strings: xarray reads the file as the Dataset of
    :meth:`to_xarray`).

    Attributes
    ----------
    datasets, axes : list of str
        The ``dataset`` and ``axis`` coordinates, in file order.
    coords : dict
        Every 1-D coordinate variable (``frequency`` in Hz, ``tau`` in s, ...) as a float64 array.
    coord_attrs : dict
        Their attributes (``units``, ``long_name``).
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
            self.coords, self.coord_attrs, self.variables = {}, {}, {}
            for name, var in nc.variables.items():
                if name in names:
                    continue
                attrs = {k: var.getncattr(k) for k in var.ncattrs() if k not in ("_FillValue", "coordinates")}
                if var.dimensions == (name,):
                    self.coords[name] = np.asarray(var[:], dtype=np.float64)
                    self.coord_attrs[name] = attrs
                else:
                    self.variables[name] = (np.asarray(var[:]), tuple(var.dimensions), attrs)

    @classmethod
    def from_axis_files(cls, paths, join: str = "exact") -> "Stacked":
        """Stack per-(dataset, axis) files (global attrs ``dataset`` and ``axis``, one index coordinate such as
        ``frequency`` or ``tau``).

        Datasets in the order of `paths`, axes sorted. ``join="exact"``: every file must share the
        coordinate (PSDs of one configuration); ``"outer"``: the sorted union, missing entries NaN (AV grids
        of records of different lengths; an integer variable with a missing entry is stored as float with
        NaN, since NaN has no integer value). Per-file record lengths (global attr ``n_samples``) become
        the variable ``n_samples`` (dataset, axis), per-file rates (global attr ``rate_hz``, Hz) the variable
        ``rate_hz`` (dataset, axis; NaN where a curve is missing); global attrs are the first file's minus
        per-file ones (the global ``rate_hz`` is kept as the first file's for older readers: use
        :meth:`rate_of` for a curve's own rate).
        """
        import numpy as np

        if join not in ("exact", "outer"):
            raise ValueError(f"join must be 'exact' or 'outer', got {join!r}")
        files = [_read_axis_file(path) for path in paths]
        if not files:
            raise ValueError("no files to stack")
        dim = files[0].dim
        if any(f.dim != dim for f in files):
            raise ValueError(f"files do not share one dimension: {sorted({f.dim for f in files})}")
        if join == "exact":
            bad = [f.path for f in files if not np.array_equal(f.index, files[0].index)]
            if bad:
                raise ValueError(f"files do not share one grid ({dim} of {bad[0]} differs from {files[0].path}); "
                                 "check that every dataset uses the same decimation rate and PSD window")
            index = files[0].index
        else:
            index = np.unique(np.concatenate([f.index for f in files]))
        out = cls.__new__(cls)
        out.path = None
        out.datasets = list(dict.fromkeys(f.dataset for f in files))
        out.axes = sorted({f.axis for f in files})
        out.coords, out.coord_attrs = {dim: index}, {dim: files[0].index_attrs}
        out.attrs = {k: v for k, v in files[0].attrs.items() if k not in _PER_FILE}
        shape = (len(out.datasets), len(out.axes))
        values, attrs, dtypes = {}, {}, {}
        n_samples = np.full(shape, np.nan)
        rates = np.full(shape, np.nan)
        have = np.zeros(shape, dtype=bool)
        for f in files:
            i, j = out.datasets.index(f.dataset), out.axes.index(f.axis)
            if have[i, j]:
                raise ValueError(f"{f.path}: a second file for dataset {f.dataset!r}, axis {f.axis!r}")
            have[i, j] = True
            if f.attrs.get("n_samples") is not None:
                n_samples[i, j] = int(f.attrs["n_samples"])
            if f.attrs.get("rate_hz") is not None:
                rates[i, j] = float(f.attrs["rate_hz"])
            at = np.searchsorted(index, f.index)
            for name, (v, a) in f.data.items():
                if name not in values:
                    values[name] = np.full(shape + (index.size,), np.nan)
                    attrs[name], dtypes[name] = a, v.dtype
                values[name][i, j, at] = v
        out.variables = {}
        for name, v in values.items():
            integer = dtypes[name].kind in "iu" and not np.isnan(v).any()
            out.variables[name] = (v.astype(dtypes[name]) if integer else v, ("dataset", "axis", dim), attrs[name])
        if not np.isnan(n_samples).all():
            ns = n_samples.astype(np.int64) if not np.isnan(n_samples).any() else n_samples
            out.variables["n_samples"] = (ns, ("dataset", "axis"), {"long_name": "samples in the record", "units": "1"})
        if not np.isnan(rates).all():
            out.variables["rate_hz"] = (rates, ("dataset", "axis"), dict(_RATE_ATTRS))
        return out

    def set_included(self, summary: dict) -> None:
        """The ``included`` flag (dataset, axis), int8: a curve is used by the bound (``curves[*].included`` of
        the stationarity summary; a curve not in the summary is not)."""
        import numpy as np

        flags = np.zeros((len(self.datasets), len(self.axes)), dtype=np.int8)
        for c in summary["curves"]:
            if c["dataset"] in self.datasets and c["axis"] in self.axes:
                flags[self.datasets.index(c["dataset"]), self.axes.index(c["axis"])] = bool(c["included"])
        self.variables["included"] = (flags, ("dataset", "axis"), dict(_INCLUDED_ATTRS))

    def to_netcdf(self, path) -> None:
        """Write to netCDF-4 at `path` atomically (:func:`imupipe.io.atomic_path`)."""
        import netCDF4
        import numpy as np

        from imupipe.io import atomic_path

        with atomic_path(path) as tmp:
            with netCDF4.Dataset(tmp, "w", format="NETCDF4") as nc:
                for name, labels in (("dataset", self.datasets), ("axis", self.axes)):
                    nc.createDimension(name, len(labels))
                    var = nc.createVariable(name, str, (name,))
                    var.setncatts(_LABEL_ATTRS[name])
                    var[:] = np.array(labels, dtype=object)
                for name, values in self.coords.items():
                    nc.createDimension(name, values.size)
                    var = nc.createVariable(name, "f8", (name,), fill_value=np.nan)
                    var.setncatts(self.coord_attrs.get(name, {}))
                    var[:] = values
                for name, (values, dims, attrs) in self.variables.items():
                    values = np.asarray(values)
                    fill = np.nan if values.dtype.kind == "f" else None
                    var = nc.createVariable(name, values.dtype.str.lstrip("<>=|"), dims, fill_value=fill)
                    var.setncatts({k: v for k, v in attrs.items() if v is not None})
                    var[:] = values
                nc.setncatts({k: v for k, v in self.attrs.items() if v is not None})

    def to_xarray(self):
        """The same content as an :class:`xarray.Dataset` (imports xarray)."""
        import xarray as xr

        coords = {name: (name, labels, dict(_LABEL_ATTRS[name]))
                  for name, labels in (("dataset", self.datasets), ("axis", self.axes))}
        coords.update({k: (k, v, dict(self.coord_attrs.get(k, {}))) for k, v in self.coords.items()})
        return xr.Dataset({k: (dims, v, dict(a)) for k, (v, dims, a) in self.variables.items()}, coords=coords,
                          attrs=dict(self.attrs))

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

    def rate_of(self, dataset, axis) -> float:
        """Sampling rate of one curve's record, Hz: the per-curve variable ``rate_hz`` (dataset, axis) where the
        file has it, else the global attribute ``rate_hz`` (files stacked before the per-curve rate existed,
        whose curves all had the first file's rate)."""
        import math

        if "rate_hz" in self.variables:
            r = float(self.at("rate_hz", dataset, axis))
            if math.isfinite(r) and r > 0:
                return r
            raise ValueError(f"{self.path}: no rate_hz for dataset {dataset!r}, axis {axis!r}")
        if "rate_hz" not in self.attrs:
            raise ValueError(f"{self.path}: neither a rate_hz variable (dataset, axis) nor a rate_hz attribute")
        return float(self.attrs["rate_hz"])

    def curves(self, included_only=False):
        """(dataset, axis) of every curve in file order; with `included_only`, those whose ``included``
        flag is set."""
        return [(d, a) for d in self.datasets for a in self.axes
                if not included_only or int(self.at("included", d, a))]
