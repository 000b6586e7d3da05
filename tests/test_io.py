"""imupipe.io: atomic writes leave no temporary file behind, stale ones are removed, a full disk is named."""

import errno
import os

import pytest

import imupipe.io as io
from imupipe.io import DiskFullError, atomic_path, remove_stale_temp, write_text_atomic


def test_write_replaces_and_leaves_no_temp(tmp_path):
    target = tmp_path / "out" / "bound.yaml"
    write_text_atomic("a: 1\n", target)
    write_text_atomic("a: 2\n", target)
    assert target.read_text() == "a: 2\n"
    assert sorted(p.name for p in target.parent.iterdir()) == ["bound.yaml"]


def test_next_write_removes_the_temp_of_a_killed_job(tmp_path):
    target = tmp_path / "bound.yaml"
    stale = tmp_path / ".tmp-bound.yaml-abc123.yaml"  # what SIGKILL during atomic_path leaves
    stale.write_text("half")
    other = tmp_path / ".tmp-table.md-xyz.md"  # another target's: not this writer's business
    other.write_text("half")
    write_text_atomic("ok\n", target)
    assert not stale.exists() and other.exists()


def test_cleanup_helper_removes_every_temp_under_a_folder(tmp_path):
    (tmp_path / "a" / "b").mkdir(parents=True)
    temps = [tmp_path / "a" / ".tmp-x.nc-1.nc", tmp_path / "a" / "b" / ".tmp-y.yaml-2.yaml"]
    for p in temps:
        p.write_text("")
    keep = tmp_path / "a" / "x.nc"
    keep.write_text("")
    assert sorted(remove_stale_temp(tmp_path)) == sorted(temps)
    assert keep.exists() and not any(p.exists() for p in temps)
    assert remove_stale_temp(tmp_path / "missing") == []


def test_enospc_names_the_output(tmp_path):
    target = tmp_path / "bound.nc"
    with pytest.raises(DiskFullError, match=r"no space left on the device writing .*bound\.nc"):
        with atomic_path(target) as tmp:
            tmp.write_text("partial")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert list(tmp_path.iterdir()) == []  # neither the target nor a temporary file


def test_library_error_on_a_full_disk_is_named(tmp_path, monkeypatch):
    """netCDF-4 reports ENOSPC as "NetCDF: HDF error": with no free space the write is named as a full disk."""
    monkeypatch.setattr(io, "_free_bytes", lambda d: 0)
    with pytest.raises(DiskFullError, match=r"writing .*x\.nc \(0 bytes free; the writer said: NetCDF: HDF error\)"):
        with atomic_path(tmp_path / "x.nc"):
            raise RuntimeError("NetCDF: HDF error")


def test_other_errors_pass_unchanged(tmp_path):
    with pytest.raises(ValueError, match="boom"):
        with atomic_path(tmp_path / "x.nc"):
            raise ValueError("boom")
    assert list(tmp_path.iterdir()) == []


def test_plain_turns_numpy_into_yaml_types():
    import math

    import numpy as np
    import yaml

    from imupipe.io import plain

    obj = {1: np.float64(0.5), "a": (np.int32(3), np.bool_(True)), "b": np.array([1.0, np.nan]),
           "c": {"d": np.float32(np.inf), "e": "text", "f": None}}
    out = plain(obj)
    assert out == {"1": 0.5, "a": [3, True], "b": [1.0, None], "c": {"d": None, "e": "text", "f": None}}
    assert type(out["a"][0]) is int and type(out["a"][1]) is bool and type(out["1"]) is float
    yaml.safe_dump(out)  # raises on any numpy type left
    kept = plain(obj, nonfinite_to_none=False)
    assert math.isnan(kept["b"][1]) and kept["c"]["d"] == math.inf
