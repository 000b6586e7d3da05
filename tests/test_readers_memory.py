"""Readers stream one channel: the values equal the whole-array reading at every block boundary, and reading
one channel of a wide record raises the process's peak memory by about one channel, not the record.

The block sizes are patched small (a few rows) so that a few hundred samples cross many block boundaries,
Fortran-ordered and structured arrays included. The memory test runs each read in a fresh interpreter and
compares its peak resident set (``VmHWM``, Linux) before and after the read; the allowance over the one
channel (8 n bytes) is derived from the block sizes (see ALLOWANCE_MB)."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import imupipe.readers.arrays as arrays
import imupipe.readers.netcdf as ncmod
import imupipe.readers.text as text
from imupipe.readers import read_channel, read_dataset

RATE = 100.0  # Hz
N = 301  # samples: not a multiple of any patched block size
KEYS = [("gyro", "x"), ("gyro", "y"), ("accel", "z")]
UNITS = {"gyro": "rad/s", "accel": "m/s^2"}


@pytest.fixture
def table(rng):
    """Time (s) and three channels in SI, columns t, gyro_x, gyro_y, accel_z."""
    t = np.arange(N) / RATE
    return np.column_stack([t, rng.normal(0, 1e-3, N), rng.normal(0, 1e-3, N), rng.normal(-9.8, 1e-2, N)])


@pytest.fixture(autouse=True)
def small_blocks(monkeypatch):
    monkeypatch.setattr(arrays, "READ_ROWS", 7)
    monkeypatch.setattr(ncmod, "READ_CHUNK", 11)
    monkeypatch.setattr(text, "READ_LINES", 13)


def _check(rec, table, with_time=True):
    for i, key in enumerate(KEYS, start=1):
        np.testing.assert_array_equal(rec[key], table[:, i])
    assert rec.rate_hz == RATE


@pytest.mark.parametrize("order", ["C", "F"])
def test_npy_streamed_columns(tmp_path, table, order):
    path = tmp_path / "imu.npy"
    np.save(path, np.asarray(table, order=order))
    assert np.load(path, mmap_mode="r").flags.f_contiguous == (order == "F")
    channels = {k: i for i, k in enumerate(KEYS, start=1)}
    _check(read_dataset(path, "npy", RATE, channels, UNITS, time_column=0), table)
    one = read_channel(("gyro", "y"), path, "npy", rate_hz=RATE, channels=channels, units=UNITS, time_column=0)
    np.testing.assert_array_equal(one["gyro", "y"], table[:, 2])


def test_npy_structured_streamed(tmp_path, table):
    arr = np.zeros(N, dtype=[("t", "<f8"), ("wx", ">f4"), ("wy", "<f8"), ("az", "<f8")])
    for i, name in enumerate(arr.dtype.names):
        arr[name] = table[:, i]
    path = tmp_path / "imu.npy"
    np.save(path, arr)
    rec = read_dataset(path, "npy", RATE, dict(zip(KEYS, ["wx", "wy", "az"])), UNITS, time_column="t")
    expected = table.copy()
    expected[:, 1] = table[:, 1].astype(">f4")  # the file holds float32: the reader widens it exactly
    _check(rec, expected)


@pytest.mark.parametrize("order", ["C", "F"])
def test_npz_matrix_streamed(tmp_path, table, order):
    path = tmp_path / "imu.npz"
    np.savez_compressed(path, imu=np.asarray(table, order=order), other=np.ones(3))
    channels = {k: i for i, k in enumerate(KEYS, start=1)}
    _check(read_dataset(path, "npz", RATE, channels, UNITS, variable="imu", time_column=0), table)


def test_netcdf_streamed_with_fill_values_and_matrix(tmp_path, table):
    import netCDF4

    path = tmp_path / "imu.nc"
    with netCDF4.Dataset(path, "w") as ds:
        ds.createDimension("sample", N)
        ds.createDimension("col", 4)
        for i, name in enumerate(["t", "wx", "wy", "az"]):
            v = ds.createVariable(name, "f8", ("sample",), fill_value=-999.0)
            v[:] = table[:, i]
        m = ds.createVariable("imu", "f8", ("sample", "col"))
        m[:] = table
    names = dict(zip(KEYS, ["wx", "wy", "az"]))
    _check(read_dataset(path, "netcdf", RATE, names, UNITS, time_column="t", time_unit="s"), table)
    channels = {k: i for i, k in enumerate(KEYS, start=1)}
    _check(read_dataset(path, "netcdf", RATE, channels, UNITS, variable="imu"), table)
    with netCDF4.Dataset(path, "a") as ds:  # a masked sample in the last, partial block becomes NaN
        ds.variables["wy"][N - 2] = np.ma.masked
    assert np.isnan(ncmod._read_float64(netCDF4.Dataset(path).variables["wy"]))[N - 2]
    with pytest.raises(Exception, match=r"gyro_y .* non-finite sample \(nan\) at row 299"):
        read_dataset(path, "netcdf", RATE, names, UNITS)


def test_csv_streamed_with_comments_and_blank_lines(tmp_path, table):
    lines = ["# a comment line", "t,wx,wy,az"]
    for i, row in enumerate(table):
        lines.append(",".join(repr(float(v)) for v in row) + ("  # note" if i % 17 == 0 else ""))
        if i % 29 == 0:
            lines += ["", "# another comment"]
    path = tmp_path / "imu.csv"
    path.write_text("\n".join(lines))  # no newline after the last row
    names = dict(zip(KEYS, ["wx", "wy", "az"]))
    _check(read_dataset(path, "csv", RATE, names, UNITS, time_column="t"), table)
    one = read_channel("accel_z", path, "csv", rate_hz=RATE, channels=names, units=UNITS)
    np.testing.assert_array_equal(one["accel", "z"], table[:, 3])


def test_csv_time_scaled_in_place_and_a_shared_column_kept(tmp_path, table):
    """The time column is scaled to s in place, unless a channel reads the same column (that stays in its own
    unit): time in ms also read as a channel."""
    ms = table[:100].copy()  # 0 .. 990 ms: within the gyro's plausible range when read as a channel
    ms[:, 0] = np.arange(100) * 10.0  # ms at 100 Hz
    path = tmp_path / "imu.csv"
    np.savetxt(path, ms, delimiter=",", header="t,wx,wy,az", comments="", fmt="%.17g")
    rec = read_dataset(path, "csv", RATE, {("gyro", "x"): "t", ("gyro", "y"): "wy"}, UNITS, time_column="t",
                       time_unit="ms")
    np.testing.assert_array_equal(rec["gyro", "x"], ms[:, 0])  # the column as read, not scaled by 1e-3
    assert rec.rate_hz == RATE
    alone = read_dataset(path, "csv", RATE, {("gyro", "y"): "wy"}, UNITS, time_column="t", time_unit="ms")
    np.testing.assert_array_equal(alone["gyro", "y"], ms[:, 2])
    assert alone.rate_hz == RATE


def _old_nominal_rate(t, rate, gap_factor):
    """The whole-array rule the block-wise one replaces (np.diff, np.median, masked np.sum)."""
    dt = np.diff(t)
    guess = 1.0 / float(np.median(dt)) if rate is None else rate
    ok = dt <= gap_factor / guess
    mean_rate = float(np.count_nonzero(ok) / np.sum(dt, where=ok)) if ok.any() else guess
    if rate is None:
        ok = dt <= gap_factor / mean_rate
        mean_rate = float(np.count_nonzero(ok) / np.sum(dt, where=ok)) if ok.any() else mean_rate
    return (rate if rate is not None else mean_rate), mean_rate


def _clocks(rng):
    """Timestamps (s) with gaps and duplicates at and around the edges of 256-interval blocks: a jittered
    128 Hz clock, a 300 Hz clock stamped in whole ms (many equal intervals: ties at the median), both with an
    even and an odd number of intervals."""
    jitter = np.cumsum(rng.uniform(0.9, 1.1, 20_001) / 128.0)
    for i in (255, 256, 511, 767, 12_800):  # gaps ending at, starting at and straddling block edges
        jitter[i:] += 0.05 + 0.01 * rng.uniform()
    ms = np.floor(np.arange(30_000) / 300.0 * 1e3) / 1e3
    ms[4096:] += 0.02
    return {"jitter odd": jitter, "jitter even": jitter[:-1], "ms even": ms, "ms odd": ms[:-1]}


@pytest.mark.parametrize("block", [129, 256, 1000])
def test_interval_statistics_blockwise_equal_whole_array(monkeypatch, rng, block):
    """Every block-wise interval statistic equals the whole-array NumPy expression to the last bit, on records
    whose gaps and duplicates sit at block edges (blocks of 129, 256 and 1000 intervals: the pairwise sum's
    recursion is followed across them; a block-by-block sum, or a median of block medians, differs in the last
    bits or more)."""
    from imupipe.readers import intervals as iv
    from imupipe.readers.core import _nominal_rate

    monkeypatch.setattr(iv, "INTERVAL_BLOCK", block)
    for name, t in _clocks(rng).items():
        dt = np.diff(t)
        assert iv.median_interval(t) == np.median(dt), name
        for limit in (1.5 / 128.0, 1.5 / 300.0, 1e-3):
            gaps = iv.intervals_above(t, limit)
            np.testing.assert_array_equal(gaps, np.flatnonzero(dt > limit))
            ok = dt <= limit
            assert iv.sum_between(t, gaps) == (np.count_nonzero(ok), np.sum(dt, where=ok)), (name, limit)
        np.testing.assert_array_equal(iv.intervals(t, gaps), dt[gaps])
        for rate in (None, 128.0, 300.0):
            assert _nominal_rate(t, rate, 1.5) == _old_nominal_rate(t, rate, 1.5), (name, rate)
        assert iv.first_nonpositive(t) is None
    t = np.arange(3000) / 100.0
    t[block : block + 2] = t[block - 1]  # duplicates on either side of one edge and after another
    t[2 * block + 1] = t[2 * block]
    t[2500] = t[2400]  # a step back
    dt = np.diff(t)
    assert iv.first_nonpositive(t) == np.flatnonzero(dt <= 0)[0] == block - 1
    assert iv.count_zero(t) == np.count_nonzero(dt == 0) == 3


@pytest.mark.parametrize("move_block", [1, 7, 1 << 16])
def test_fill_grows_in_place_equal_to_interp(monkeypatch, rng, move_block):
    """Gap filling inserts the samples in place (the owning array is resized, its rows moved from the end in
    blocks) and equals, bit for bit, np.interp over the whole filled record's fractional row positions (what
    the filling computed before), signed zeros included; a view is copied into a new array, with the same
    values, and the row map names file rows and inserted samples."""
    from imupipe.readers import core

    monkeypatch.setattr(core, "MOVE_BLOCK", move_block)
    n = 200
    table = np.column_stack([np.arange(n) / RATE + rng.uniform(-1e-4, 1e-4, n), rng.normal(0, 1e-3, n)])
    table[40:43, 1] = [-0.0, -0.0, 0.0]  # signed zeros at a gap's edges survive as np.interp keeps them
    gaps = np.array([0, 40, 41, 57, 130, n - 2])
    missing = np.array([1, 3, 1, 2, 1, 4])
    pieces, cuts = [], [0, *(gaps + 1), n]
    for g, (a, b) in enumerate(zip(cuts[:-1], cuts[1:])):
        pieces.append(np.arange(a, b, dtype=np.float64))
        if g < len(gaps):
            k = int(missing[g])
            pieces.append(b - 1 + np.arange(1, k + 1) / (k + 1))
    pos = np.concatenate(pieces)
    for col in range(2):
        expected = np.interp(pos, np.arange(n, dtype=np.float64), table[:, col])
        owned = table[:, col].copy()
        grown = core._insert_filled(owned, gaps, missing)
        assert grown is owned and grown.tobytes() == expected.tobytes()
        view = table[:, col]  # a strided view: copied
        copied = core._insert_filled(view, gaps, missing)
        assert copied is not view and copied.tobytes() == expected.tobytes()
        np.testing.assert_array_equal(view, table[:, col])
    file_row = core._filled_row_map(gaps, missing)
    assert [file_row(r) for r in range(len(pos))] == [int(p) if p == int(p) else -1 for p in pos]


def test_csv_bad_row_in_a_later_block_is_named(tmp_path, table):
    rows = [",".join(repr(float(v)) for v in row) for row in table]
    rows[200] += ",1.0"  # one field too many, far past the first block
    path = tmp_path / "imu.csv"
    path.write_text("t,wx,wy,az\n" + "\n".join(rows) + "\n")
    with pytest.raises(Exception, match=r"line 202 has too many fields \(5, expected 4\)"):
        read_dataset(path, "csv", RATE, dict(zip(KEYS, ["wx", "wy", "az"])), UNITS, time_column="t")


# ---------------------------------------------------------------------------------------------------------
# peak memory of reading one channel of a wide record
# ---------------------------------------------------------------------------------------------------------
N_BIG = 1 << 22  # rows: one float64 channel = 33.5 MB
N_TEXT = 1 << 19  # text rows (writing text is slow): one channel = 4.2 MB
#: Allowed peak beyond the channel's 8 n bytes (MB). Binary: one block of 2**16 rows x 4 columns of float64
#: (2.1 MB) read as bytes and as the column being copied, zlib's buffers for npz, netCDF-4's slab of 2**18
#: samples with its mask and unmasked copy (~4.5 MB); text: one block of 2**14 lines (~270 B per line as
#: Python strings, parser buffers and the parsed floats: ~4.5 MB); plus ~4 MB for the allocator's arenas and
#: page rounding: 10 MB. Reading the whole record instead (what the readers did) costs 4 x 8 n bytes (npy:
#: the mapped file's pages; npz, text: the table), or 2 x 8 n for netCDF-4: over the bound with these n.
ALLOWANCE_MB = {"npy": 10.0, "npz": 10.0, "netcdf": 10.0, "csv": 10.0}

_PROBE = textwrap.dedent(
    """
    import sys
    import numpy as np
    from imupipe.readers import read_channel
    def status(key):
        for line in open("/proc/self/status"):
            if line.startswith(key):
                return int(line.split()[1]) * 1024
    path, small, fmt = sys.argv[1:4]
    kw = dict(rate_hz=100.0, channels={"gyro_x": sys.argv[4]}, units={"gyro": "rad/s"})
    if len(sys.argv) > 5:
        kw["variable"] = sys.argv[5]
    read_channel("gyro_x", small, fmt, **kw)  # imports and first-call costs paid before the baseline
    before = status("VmRSS")
    assert status("VmHWM") - before < 64 << 20
    x = read_channel("gyro_x", path, fmt, **kw)["gyro", "x"]
    print(status("VmHWM") - max(before, 0), x.size)
    """
)


def _write(path, data, fmt):
    if fmt == "npy":
        np.save(path, data)
        return "1", None
    if fmt == "npz":
        np.savez(path, imu=data)
        return "1", "imu"
    if fmt == "netcdf":
        import netCDF4

        with netCDF4.Dataset(path, "w") as ds:
            ds.createDimension("sample", len(data))
            for i in range(data.shape[1]):
                ds.createVariable(f"c{i}", "f8", ("sample",))[:] = data[:, i]
        return "c1", None
    np.savetxt(path, data, delimiter=",", header="c0,c1,c2,c3", comments="", fmt="%.6g")
    return "c1", None


@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="needs Linux /proc/self/status (VmHWM)")
@pytest.mark.parametrize("fmt,suffix", [("npy", ".npy"), ("npz", ".npz"), ("netcdf", ".nc"), ("csv", ".csv")])
def test_one_channel_costs_one_channel(tmp_path, rng, fmt, suffix):
    n = N_TEXT if fmt == "csv" else N_BIG
    data = rng.normal(0.0, 1e-3, (n, 4))
    path, small = tmp_path / f"big{suffix}", tmp_path / f"small{suffix}"
    col, variable = _write(path, data, fmt)
    _write(small, data[:1000], fmt)
    del data
    args = [sys.executable, "-c", _PROBE, str(path), str(small), fmt, col] + ([variable] if variable else [])
    out = subprocess.run(args, capture_output=True, text=True, check=True, env=dict(os.environ, OPENBLAS_NUM_THREADS="1"))
    rise, size = map(int, out.stdout.split())
    assert size == n
    assert rise <= 8 * n + ALLOWANCE_MB[fmt] * 2**20, f"{fmt}: peak rose {rise / 2**20:.1f} MB for a {8 * n / 2**20:.1f} MB channel"
