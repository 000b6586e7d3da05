"""Files of the workflow: atomic writes, so that an interrupted or failed job leaves no half-written output.

Every writer creates a temporary file in the target's directory and renames it over the target
(:func:`os.replace`, atomic on POSIX within one file system): a reader sees either the old file or the
complete new one, never a partial file, and a killed job leaves at most a ``.tmp-*`` file that the
next run ignores and overwrites.

netCDF conventions (docs/architecture.md): every variable has ``long_name`` and ``units``; spectra
carry ``sidedness = "two-sided"``; files carry ``dataset``, ``sensor``, ``axis`` global attributes
where they apply.
"""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from pathlib import Path

__all__ = ["DuplicateKeyError", "atomic_path", "write_yaml_atomic", "write_text_atomic", "read_yaml",
           "write_series", "read_series", "remove_stale_temp", "DiskFullError", "TEMP_PREFIX", "plain"]

#: Prefix of the temporary files of :func:`atomic_path` (``.tmp-<name>-<random><suffix>``).
TEMP_PREFIX = ".tmp-"

#: Free space (bytes) below which a failed write is reported as a full disk even when the library that
#: wrote says something else (netCDF-4 reports ENOSPC as "NetCDF: HDF error").
DISK_FULL_BYTES = 1 << 20


class DiskFullError(OSError):
    """An output could not be written because its file system is full; the message names the output.

    ``errno`` is ENOSPC; ``str()`` is the message alone (no ``[Errno 28]`` prefix), as the user reads it."""

    def __str__(self) -> str:
        return self.strerror or super().__str__()


def _free_bytes(directory) -> int | None:
    try:
        st = os.statvfs(directory)
    except OSError:
        return None
    return st.f_bavail * st.f_frsize


def _stale_temps(path: Path) -> list[Path]:
    return [p for p in path.parent.glob(f"{TEMP_PREFIX}{path.name}-*") if p.is_file()]


def remove_stale_temp(root, older_than_s: float = 0.0) -> list[Path]:
    """Remove the temporary files (``.tmp-*``) that killed jobs left under `root`; return them.

    The workflow calls this once at start-up on its output folders (no job runs then). A job killed
    with SIGKILL cannot remove its temporary file; :func:`atomic_path` also removes those of its own
    target before it writes.

    Parameters
    ----------
    root : str or Path
        Folder searched recursively (a missing folder: nothing to do).
    older_than_s : float, optional
        Keep files modified in the last `older_than_s` seconds (s). Defaults to 0 (remove all).

    Returns
    -------
    list of Path
        Files removed.
    """
    import time

    root = Path(root)
    if not root.is_dir():
        return []
    now = time.time()
    removed = []
    for p in root.rglob(f"{TEMP_PREFIX}*"):
        with contextlib.suppress(FileNotFoundError):
            if p.is_file() and not p.is_symlink() and now - p.stat().st_mtime >= older_than_s:
                p.unlink()
                removed.append(p)
    return removed


@contextlib.contextmanager
def atomic_path(path):
    """Context manager yielding a temporary path next to `path`; renamed to `path` on success.

    On an exception the temporary file is removed and `path` is left untouched. Temporary files of the
    same target left by a killed earlier job are removed first. A write that fails for lack of space
    (``ENOSPC``, or any error while the file system has less than :data:`DISK_FULL_BYTES` free) raises
    :class:`DiskFullError` naming `path`.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        for stale in _stale_temps(path):
            with contextlib.suppress(FileNotFoundError):
                stale.unlink()
        fd, tmp = tempfile.mkstemp(prefix=f"{TEMP_PREFIX}{path.name}-", suffix=path.suffix, dir=path.parent)
        os.close(fd)
    except OSError as exc:
        _raise_if_disk_full(exc, path)
        raise
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; give the file the usual permissions
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(exc, Exception):
            _raise_if_disk_full(exc, path)
        raise


def _raise_if_disk_full(exc: BaseException, path: Path) -> None:
    """Re-raise `exc` as a DiskFullError naming `path` when it is (or looks like) a full file system."""
    if isinstance(exc, DiskFullError):
        return
    free = _free_bytes(path.parent if path.parent.exists() else Path("."))
    if getattr(exc, "errno", None) in (errno.ENOSPC, errno.EDQUOT) or (free is not None and free < DISK_FULL_BYTES):
        raise DiskFullError(
            errno.ENOSPC,
            f"disk full: no space left on the device writing {path} ({free if free is not None else '?'} bytes free; "
            f"the writer said: {exc}); free some space and run again",
        ) from exc


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_text_atomic(text: str, path) -> None:
    """Write `text` to `path` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def write_yaml_atomic(data, path, header: str | None = None) -> None:
    """Write plain data (dicts, lists, numbers, strings) as YAML, keys in insertion order, atomically.

    `header` lines are written first as ``#`` comments (units, provenance). Uses libyaml's safe dumper
    where PyYAML has it (the same text, ~5x faster), else the pure-Python one.
    """
    import yaml

    dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
    text = yaml.dump(data, Dumper=dumper, sort_keys=False, default_flow_style=False, width=110)
    if header:
        text = "".join(f"# {line}\n" for line in header.splitlines()) + text
    write_text_atomic(text, path)


class DuplicateKeyError(ValueError):
    """A YAML mapping that gives one key twice (:func:`read_yaml`)."""


def _refuse_duplicate_keys(node, where: str) -> None:
    """Raise :class:`DuplicateKeyError` at the first mapping of the composed YAML `node` tree that gives a key twice,
    naming the file, the key's dotted path and both line numbers (1-based). YAML itself keeps the later value
    silently; a merge key ``<<`` is not a key of its own."""
    import yaml

    seen_nodes = set()
    todo = [(node, [])]
    while todo:
        n, path = todo.pop()
        if id(n) in seen_nodes:  # an alias: the anchored node is checked once
            continue
        seen_nodes.add(id(n))
        if isinstance(n, yaml.MappingNode):
            lines = {}
            for k, v in n.value:
                if isinstance(k, yaml.ScalarNode):
                    if k.tag == "tag:yaml.org,2002:merge":
                        continue
                    line = k.start_mark.line + 1
                    if k.value in lines:
                        dotted = ".".join([*map(str, path), k.value])
                        raise DuplicateKeyError(
                            f"{where}: key '{dotted}' is given twice, on line {lines[k.value]} and line {line} "
                            "(YAML would keep the later value silently); keep one")
                    lines[k.value] = line
                    todo.append((v, [*path, k.value]))
                else:
                    todo.append((v, path))
        elif isinstance(n, yaml.SequenceNode):
            todo += [(v, [*path, i]) for i, v in enumerate(n.value)]


def read_yaml(path):
    """Read a YAML file (safe loader; libyaml's where PyYAML has it, ~7x faster).

    A mapping that gives a key twice is refused (:class:`DuplicateKeyError`, a ValueError naming the file, the key
    and both lines): YAML keeps the later value silently, so a config or spec sheet edited twice would run with
    a value its author did not see. Every YAML file the project reads by hand goes through here."""
    import yaml

    with open(path) as fh:
        loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)(fh)
        try:
            node = loader.get_single_node()
            if node is None:
                return None
            _refuse_duplicate_keys(node, str(path))
            return loader.construct_document(node)
        finally:
            loader.dispose()


def write_series(path, x, *, rate_hz: float, units: str, attrs: dict | None = None, name: str = "signal") -> None:
    """Write one uniformly sampled channel (float64, SI) with its rate and units, atomically.

    Uses netCDF4 directly (importing xarray costs ~0.7 s per job). Variable `name` on dimension
    ``sample``; global attrs ``rate_hz`` (Hz) and everything in `attrs`.
    """
    import netCDF4
    import numpy as np

    x = np.asarray(x, dtype=np.float64)
    with atomic_path(path) as tmp:
        with netCDF4.Dataset(tmp, "w", format="NETCDF4") as nc:
            nc.createDimension("sample", x.size)
            v = nc.createVariable(name, "f8", ("sample",))
            v.units = units
            v.long_name = (attrs or {}).get("long_name", f"{name}")
            v[:] = x
            nc.rate_hz = float(rate_hz)
            for k, val in (attrs or {}).items():
                if k != "long_name" and val is not None:
                    nc.setncattr(k, val)


def read_series(path, name: str = "signal", pad_front: int = 0):
    """Read a channel written by :func:`write_series`: (float64 array, rate_hz, attrs dict).

    With ``pad_front = p`` the samples are read, in chunks, into ``buf[p:]`` of a new float64 buffer of
    n + p elements and the returned array is that view (``x.base`` is the buffer): room for an in-place
    cumulative sum without a second copy of the record.
    """
    import netCDF4
    import numpy as np

    with netCDF4.Dataset(path) as nc:
        nc.set_auto_mask(False)
        if name not in nc.variables:
            raise KeyError(f"{path}: no variable {name!r} (has {sorted(nc.variables)})")
        v = nc.variables[name]
        if pad_front:
            n = v.shape[0]
            buf = np.empty(n + pad_front)
            step = 1 << 20
            for i in range(0, n, step):
                buf[pad_front + i : pad_front + min(n, i + step)] = v[i : i + step]
            x = buf[pad_front:]
        else:
            x = np.asarray(v[:], dtype=np.float64)
        attrs = {k: nc.getncattr(k) for k in nc.ncattrs()}
        attrs["units"] = getattr(v, "units", None)
        return x, float(nc.rate_hz), attrs


def run_job(main, log_path, **kwargs) -> None:
    """Run a workflow script's ``main(**kwargs)`` with its log at `log_path`.

    Warnings, log records and tracebacks go to the log. An input error (:class:`imupipe.readers.DataError`,
    :class:`imupipe.specsheet.SpecError`, :class:`imupipe.units.UnitError`, ``ValueError``) is written as
    one line ``imupipe error: <message>`` to the log and to the terminal, and the process exits with
    status 1, so the job fails and Snakemake removes its outputs; any other exception keeps its traceback.
    """
    import logging
    import sys
    import time
    import traceback

    terminal = sys.stderr
    Path(log_path).parent.mkdir(parents=True, exist_ok=True)
    log = open(log_path, "w", buffering=1)
    sys.stderr = log
    logging.basicConfig(level=logging.INFO, stream=log, format="%(asctime)s %(levelname)s %(message)s", force=True)
    logging.captureWarnings(True)
    t0 = time.perf_counter()
    try:
        main(**kwargs)
    except (ValueError, KeyError, FileNotFoundError, DiskFullError) as exc:
        traceback.print_exc(file=log)
        msg = f"imupipe error: {exc}"
        print(msg, file=log)
        print(msg, file=terminal)
        log.close()
        sys.exit(1)
    logging.info("done in %.3f s", time.perf_counter() - t0)


def plain(obj, *, nonfinite_to_none: bool = True):
    """Numpy containers and scalars -> plain Python, for YAML (``yaml.safe_dump`` takes no numpy types).

    Mappings become dicts with ``str`` keys, lists/tuples/arrays become lists (recursively), numpy booleans
    ``bool``, numpy integers ``int``, floats ``float``; a NaN or infinite float becomes ``None`` (YAML ``null``:
    "not available") unless `nonfinite_to_none` is False, when it stays a float (YAML ``.nan``/``.inf``).
    Anything else (str, None, Python ints and bools) is returned as it is.
    """
    import math

    import numpy as np

    if isinstance(obj, dict):
        return {str(k): plain(v, nonfinite_to_none=nonfinite_to_none) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v, nonfinite_to_none=nonfinite_to_none) for v in obj]
    if isinstance(obj, np.ndarray):
        return plain(obj.tolist(), nonfinite_to_none=nonfinite_to_none)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) or not nonfinite_to_none else None
    return obj


def merged_with_defaults(defaults: dict, given: dict) -> dict:
    """A partial configuration on top of the defaults, key by key inside each section.

    ``given``'s keys replace ``defaults``' ones; where both values are mappings the merge recurses, so a
    partial config keeps the default of every key it does not name. A sheet of recordings (``datasets``)
    given without ``simulation`` switches the default simulation off. Used by the workflow (``--configfile``
    on top of ``config/config.yaml``) and by ``imupipe check``, so both see the same configuration.
    """
    out = dict(defaults)
    for key, value in given.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merged_with_defaults(out[key], value)
        else:
            out[key] = value
    if given.get("datasets") and "simulation" not in given:
        out["simulation"] = None
    return out
