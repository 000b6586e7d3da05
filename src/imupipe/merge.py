"""Stack per-axis results into one labelled Dataset per sensor type: dims (dataset, axis, <coord>)."""

from __future__ import annotations

__all__ = ["stack_axis_files", "included_flags"]

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
