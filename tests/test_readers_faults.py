"""imupipe.readers: the bad-input classes of the inputs issue, each refused with a message naming the file and
the column/row or the config key and what was expected, or (wrongly refused before) accepted with the right
numbers. Catalogue: docs/inputs.md."""

import gzip
import math
import os
import time
import warnings

import numpy as np
import pytest

from imupipe.readers import (
    GRAVITY_WINDOW,
    PLAUSIBLE_SI,
    ConfigError,
    DataError,
    GapWarning,
    check_against_config,
    check_gravity,
    check_sheet_header,
    gravity_removed,
    probe,
    probe_row,
    read_channel,
    read_dataset,
    read_dataset_row,
    snap_rate,
    validate_dataset_name,
)

DEG = math.pi / 180.0
G0 = 9.80665
N = 600


@pytest.fixture
def table(rng):
    """Six noisy channels (deg/s, g) and a time column (s) at 100 Hz."""
    gyro = rng.normal(0.0, 0.5, (N, 3))
    accel = rng.normal(0.0, 0.01, (N, 3)) + [0.0, 0.0, -1.0]
    return np.column_stack([np.arange(N) / 100.0, gyro, accel])


NAMES = ["t", "wx", "wy", "wz", "ax", "ay", "az"]
CHANNELS = dict(zip(["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"], NAMES[1:]))
UNITS = {"gyro": "deg/s", "accel": "g"}


def write_csv(path, table, header=NAMES, fmt="%.17g"):
    lines = [",".join(header)] if header is not None else []
    lines += [",".join(fmt % v for v in row) for row in table]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_nc(path, table, units=UNITS):
    import netCDF4

    with netCDF4.Dataset(path, "w") as ds:
        ds.createDimension("time", len(table))
        tv = ds.createVariable("t", "f8", ("time",))
        tv[:] = table[:, 0]
        tv.units = "s"
        for i, name in enumerate(NAMES[1:], start=1):
            v = ds.createVariable(name, "f8", ("time",))
            v[:] = table[:, i]
            unit = units["gyro" if i <= 3 else "accel"]
            if unit is not None:
                v.units = unit
    return path


# ---------------------------------------------------------------------------------------------
# silently wrong before
# ---------------------------------------------------------------------------------------------
class TestSilentlyWrong:
    def test_numeric_pandas_header_is_a_header(self, tmp_path, table):
        """`DataFrame.to_csv(index=False)` of an unnamed frame writes a header 0,1,2,...: not sample 0."""
        path = write_csv(tmp_path / "imu.csv", table, header=[str(i) for i in range(7)])
        channels = {k: i for i, k in enumerate(CHANNELS, start=1)}
        rec = read_dataset(path, "csv", 100.0, channels, UNITS, time_column=0)
        assert rec.n_samples == N
        np.testing.assert_allclose(rec["gyro", "x"], table[:, 1] * DEG, rtol=1e-15)

    def test_numeric_first_line_is_a_header_when_the_sheet_names_columns(self, tmp_path, table):
        path = write_csv(tmp_path / "imu.csv", table, header=["5", "6", "7", "8", "9", "10", "11"])
        channels = {k: str(i + 5) for i, k in enumerate(CHANNELS, start=1)} | {"gyro_x": "6x"}
        with pytest.raises(DataError, match=r"imu\.csv: gyro_x column '6x' not found; available: '5', '6'"):
            read_dataset(path, "csv", 100.0, channels, UNITS)

    def test_netcdf_units_contradicting_the_sheet(self, tmp_path, table):
        path = write_nc(tmp_path / "imu.nc", table, {"gyro": "deg s-1", "accel": "m s-2"})
        with pytest.raises(DataError, match=r"imu\.nc: gyro_unit = 'rad/s' in the sheet but 'wx' states 'deg s-1'"):
            read_dataset(path, "netcdf", 100.0, CHANNELS, {"gyro": "rad/s", "accel": "m/s^2"})

    def test_netcdf_unparseable_units_refused_naming_file_and_variable(self, tmp_path, table):
        path = write_nc(tmp_path / "imu.nc", table, {"gyro": "furlongs per fortnight", "accel": "m s-2"})
        with pytest.raises(DataError, match=r"imu\.nc: variable 'wx' units attribute: unknown unit 'furlongs per fortnight'"):
            read_dataset(path, "netcdf", 100.0, CHANNELS, {"gyro": "rad/s", "accel": "m/s^2"})

    @pytest.mark.parametrize("sheet_unit", [None, "from_file"])
    def test_netcdf_cf_units_from_the_file(self, tmp_path, table, sheet_unit):
        path = write_nc(tmp_path / "imu.nc", table, {"gyro": "deg s-1", "accel": "m s-2"})
        units = {"gyro": sheet_unit, "accel": sheet_unit}
        rec = read_dataset(path, "netcdf", 100.0, CHANNELS, units)
        np.testing.assert_allclose(rec["gyro", "y"], table[:, 2] * DEG, rtol=1e-15)  # 57x if ignored
        np.testing.assert_array_equal(rec["accel", "z"], table[:, 6])

    def test_from_file_without_a_units_attribute(self, tmp_path, table):
        path = write_nc(tmp_path / "imu.nc", table, {"gyro": None, "accel": "m s-2"})
        with pytest.raises(DataError, match=r"imu\.nc: gyro_unit = 'from_file' but gyro_x \(variable 'wx'\) has no units"):
            read_dataset(path, "netcdf", 100.0, CHANNELS, {"gyro": "from_file", "accel": "from_file"})

    def test_duplicated_column_header_in_the_sheet(self, tmp_path):
        sheet = tmp_path / "datasets.tsv"
        sheet.write_text("dataset\tpath\tgyro_x\tgyro_y\tgyro_z\tgyro_x\nd1\timu.csv\twx\twy\twz\taz\n")
        with pytest.raises(DataError, match=r"datasets\.tsv', line 1: duplicated column header 'gyro_x' in columns 3, 6"):
            check_sheet_header(sheet)

    def test_two_channels_from_one_column(self, tmp_path, table):
        path = write_csv(tmp_path / "imu.csv", table)
        with pytest.raises(DataError, match=r"imu\.csv: gyro_x and accel_z both name column 'wx'"):
            read_dataset(path, "csv", 100.0, CHANNELS | {"accel_z": "wx"}, UNITS)

    def test_duplicated_column_header_in_the_data_file(self, tmp_path, table):
        path = write_csv(tmp_path / "imu.csv", table, header=["t", "wx", "wy", "wz", "ax", "ay", "wx"])
        with pytest.raises(DataError, match=r"imu\.csv: line 1: duplicated column header 'wx' \(columns \[1, 6\]\)"):
            read_dataset(path, "csv", 100.0, dict(gyro_x="wx", gyro_y="wy"), UNITS)

    def test_file_changed_while_read(self, tmp_path, table, monkeypatch):
        import imupipe.readers.core as core

        path = write_csv(tmp_path / "imu.csv", table)
        original = core._load_text

        def load_then_append(*args, **kwargs):
            raw = original(*args, **kwargs)
            with open(path, "a") as fh:  # another process still writing the file
                fh.write("6.0,1,1,1,1,1,1\n")
            return raw

        monkeypatch.setattr(core, "_load_text", load_then_append)
        with pytest.raises(DataError, match=r"imu\.csv: changed while it was read \(size \d+ -> \d+ bytes"):
            read_dataset(path, "csv", 100.0, CHANNELS, UNITS)

    def test_file_torn_while_read_names_the_change_not_the_row(self, tmp_path, table, monkeypatch):
        """A logger rewriting the file mid-read leaves the reader a torn last row: the message says the file
        changed (the parse error is chained), not only that a line is malformed."""
        import imupipe.readers.core as core

        path = write_csv(tmp_path / "imu.csv", table)
        original = core._load_text

        def rewrite_then_load(*args, **kwargs):
            text = path.read_text()
            path.write_text(text[: len(text) // 2])  # cut inside a row
            return original(*args, **kwargs)

        monkeypatch.setattr(core, "_load_text", rewrite_then_load)
        with pytest.raises(DataError, match=r"imu\.csv: changed while it was read \(size \d+ -> \d+ bytes") as info:
            read_dataset(path, "csv", 100.0, CHANNELS, UNITS)
        assert isinstance(info.value.__cause__, DataError) and "line" in str(info.value.__cause__)


# ---------------------------------------------------------------------------------------------
# crashes or hangs before: a parametrised table (error type, message naming file, column/row, expectation)
# ---------------------------------------------------------------------------------------------
def _csv_with(value, column, row):
    def make(tmp_path, table):
        t = table.copy()
        t[row, column] = value
        return write_csv(tmp_path / "imu.csv", t), {}

    return make


def _fifo(tmp_path, table):
    path = tmp_path / "imu.npy"
    os.mkfifo(path)
    return path, {"format": "npy", "channels": {"gyro_x": 1}}


def _loop(tmp_path, table):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    a.symlink_to(b)
    b.symlink_to(a)
    return a, {}


def _gzip_csv(tmp_path, table):
    plain = write_csv(tmp_path / "plain.csv", table)
    path = tmp_path / "imu.csv"
    path.write_bytes(gzip.compress(plain.read_bytes()))
    return path, {}


def _subnormal(tmp_path, table):
    t = table.copy()
    t[:, 1:4] = table[:, 1:4] * 1e-308  # deg/s -> ~1e-310 rad/s: squares underflow to 0
    return write_csv(tmp_path / "imu.csv", t), {}


def _broken_link(tmp_path, table):
    path = tmp_path / "imu.csv"
    path.symlink_to(tmp_path / "gone.csv")
    return path, {}


FAULTS = [
    # id, maker, message regex (file, column/row, what was expected)
    ("gyro_1e300", _csv_with(1e300, 2, 17), r"imu\.csv: gyro_y \(column 'wy'\) has a sample of 1\.74533e\+298 rad/s at row 17 \(0-based\), line 19 .*\|x\| <= 1000 rad/s"),
    ("accel_2000g", _csv_with(2000.0, 6, 3), r"imu\.csv: accel_z \(column 'az'\) has a sample of 19613\.3 m/s\^2 at row 3 \(0-based\), line 5 .*\|x\| <= 10000 m/s\^2"),
    ("gyro_inf", _csv_with(np.inf, 1, 5), r"imu\.csv: gyro_x \(column 'wx'\) has a non-finite sample \(inf\) at row 5 \(0-based\), line 7"),
    ("subnormal", _subnormal, r"imu\.csv: gyro_x \(column 'wx'\): the largest sample is .* its square underflows float64: expected a channel scale >= 1e-150"),
    ("fifo", _fifo, r"imu\.npy: is a FIFO \(named pipe\), not a regular file; refused"),
    ("symlink_loop", _loop, r"a\.csv: symbolic link loop"),
    ("broken_symlink", _broken_link, r"imu\.csv: broken symbolic link \(its target '.*gone\.csv' is missing\)"),
    ("gzip_csv", _gzip_csv, r"imu\.csv: is gzip-compressed, not a text file \(decompress it first, e.g\. gunzip\)"),
]


@pytest.mark.parametrize("maker, message", [f[1:] for f in FAULTS], ids=[f[0] for f in FAULTS])
def test_fault_table(tmp_path, table, maker, message):
    path, extra = maker(tmp_path, table)
    kwargs = {"format": "csv", "rate_hz": 100.0, "channels": CHANNELS, "units": UNITS, "time_column": "t"}
    kwargs.update(extra)
    if kwargs["format"] == "npy":
        kwargs.pop("time_column")
    t0 = time.monotonic()
    with pytest.raises(DataError, match=message):
        read_dataset(path, **kwargs)
    assert time.monotonic() - t0 < 5.0  # refused at once (a FIFO would block forever in open())


def test_plausible_limits_are_si():
    # 1e3 rad/s ~ 57 300 deg/s (14x the widest MEMS range); 1e4 m/s^2 ~ 1020 g
    assert PLAUSIBLE_SI["gyro"] / DEG > 4000 * 10 and PLAUSIBLE_SI["accel"] / G0 > 1000


# ---------------------------------------------------------------------------------------------
# wrongly refused before
# ---------------------------------------------------------------------------------------------
class TestTimestamps:
    @pytest.mark.parametrize("rate", [128.0, 300.0])
    def test_integer_millisecond_stamps(self, tmp_path, table, rate):
        n = 3000
        t_ms = np.floor(np.arange(n) * 1000.0 / rate)  # a ms clock read at each sample
        data = np.resize(table, (n, 7))
        data[:, 0] = t_ms
        path = write_csv(tmp_path / "imu.csv", data)
        rec = read_dataset(path, "csv", rate, CHANNELS, UNITS, time_column="t", time_unit="ms")
        assert rec.rate_hz == rate and rec.n_samples == n
        # without the sheet's rate, the mean interval gives it: (n-1) / (t_last - t_first) within 1 ms / span
        inferred = read_dataset(path, "csv", None, CHANNELS, UNITS, time_column="t", time_unit="ms")
        assert inferred.rate_hz == rate

    def test_jittered_stamps_with_rate_left_empty(self, tmp_path, table, rng):
        n = 4000
        t = np.arange(n) / 2.0 + rng.normal(0.0, 0.02, n)  # 2 Hz, 20 ms rms jitter
        data = np.resize(table, (n, 7))
        data[:, 0] = t
        path = write_csv(tmp_path / "imu.csv", data)
        rec = read_dataset(path, "csv", None, CHANNELS, UNITS, time_column="t")
        assert rec.rate_hz == 2.0  # the mean 2.000x Hz snapped: decimation to 1 Hz needs the integer ratio
        check_against_config(rec, decimate_rate_hz=1.0, dataset="jitter")

    def test_snap_rate(self):
        assert snap_rate(2.00035) == 2.0
        assert snap_rate(124.998) == 125.0
        assert snap_rate(0.50004) == 0.5
        assert snap_rate(99.5) == 99.5  # 0.5 % off 100 Hz: a real rate, not a clock error


class TestGapFill:
    def phone_log(self, tmp_path, table, drops):
        keep = np.setdiff1d(np.arange(N), drops)
        data = table[keep].copy()
        data[:, 4] = data[:, 0] * 0.1  # accel_x a straight line in t: interpolation must be exact
        return write_csv(tmp_path / "phone.csv", data), data

    def test_five_single_sample_drops_filled(self, tmp_path, table):
        drops = [50, 120, 121 + 80, 333, 480]
        path, data = self.phone_log(tmp_path, table, drops)
        rec = read_dataset(path, "csv", 100.0, CHANNELS, UNITS, time_column="t", gap_policy="fill")
        assert rec.n_samples == N and rec.n_filled == 5 and len(rec.filled) == 5
        assert [g.n_missing for g in rec.filled] == [1] * 5
        assert [g.row for g in rec.filled] == [49, 118, 198, 329, 475]  # file rows before each gap
        np.testing.assert_allclose(rec["accel", "x"], np.arange(N) / 100.0 * 0.1 * G0, rtol=1e-12, atol=1e-15)
        for d in drops:  # a gyro sample in a gap: the mean of its two neighbours
            assert rec["gyro", "z"][d] == pytest.approx(0.5 * (table[d - 1, 3] + table[d + 1, 3]) * DEG, rel=1e-12)

    def test_jittered_stamps_are_not_gaps_and_real_drops_are(self, tmp_path, table, rng):
        # 10 ms rms stamp jitter at 10 Hz (an outside evaluation's record): intervals longer than 1.5 periods
        # occur (P = 2e-4 each, 3.5 sd of an interval), and the per-interval rule read each as a gap (fill
        # inserted a sample in each, fail refused the record). A late stamp leaves the grid phase of its
        # neighbours in place; a drop moves every later stamp by a period (grid_shift: 6.6 sd apart here).
        from imupipe.readers.intervals import intervals_above

        n, period = 36_000, 0.1
        stamps = np.arange(n) * period + rng.normal(0.0, 0.01, n)
        assert intervals_above(stamps, 1.5 * period).size >= 3  # the old rule's false gaps are there
        data = np.resize(table, (n, 7))
        data[:, 0] = stamps
        clean = write_csv(tmp_path / "jitter.csv", data)
        for policy in ("fail", "split", "fill"):
            rec = read_dataset(clean, "csv", 10.0, CHANNELS, UNITS, time_column="t", gap_policy=policy)
            assert rec.n_samples == n and rec.n_filled == 0 and len(rec.segments) == 1, policy
        # uniform jitter of +-0.35 periods (rms 0.2), the rate left empty: the long intervals the next stamps make up
        # stay in the mean rate (left out, 10 Hz read as 10.31 Hz and 436 gaps), and none is a gap
        uniform = data.copy()
        uniform[:, 0] = np.arange(n) * period + rng.uniform(-0.35, 0.35, n) * period
        rec = read_dataset(write_csv(tmp_path / "uniform.csv", uniform), "csv", None, CHANNELS, UNITS,
                           time_column="t", gap_policy="fill")
        assert rec.rate_hz == 10.0 and rec.n_filled == 0 and rec.n_samples == n
        drops = [5000, 12_000, 12_001, 30_000]  # two single drops and a double one
        keep = np.setdiff1d(np.arange(n), drops)
        dropped = write_csv(tmp_path / "dropped.csv", data[keep])
        rec = read_dataset(dropped, "csv", 10.0, CHANNELS, UNITS, time_column="t", gap_policy="fill")
        assert [(g.row, g.n_missing) for g in rec.filled] == [(4999, 1), (11_998, 2), (29_996, 1)]
        assert rec.n_samples == n

    def test_a_stamp_stepping_back_within_the_jitter_is_jitter_and_a_clock_set_back_is_not(self, tmp_path, table,
                                                                                           rng):
        # Gaussian stamp jitter of 15 % of a period steps back about once in 2 h at 10 Hz (an outside evaluation):
        # every gap_policy refused the record. Here one pair of neighbours 0.6 periods late and 0.5 early (4 and 3.3
        # sd of the jitter, within 5) makes an interval of -0.1 periods; a drop elsewhere must still be found.
        n, period = 36_000, 0.1
        stamps = np.arange(n) * period + rng.normal(0.0, 0.15 * period, n)
        stamps[20_000] = 20_000.6 * period
        stamps[20_001] = 20_000.5 * period
        data = np.resize(table, (n, 7))
        data[:, 0] = stamps
        keep = np.setdiff1d(np.arange(n), [5000])
        path = write_csv(tmp_path / "back.csv", data[keep])
        for policy in ("fail", "split", "fill"):
            with pytest.warns(GapWarning, match=r"back\.csv: \d+ timestamp\(s\) in 't' step back or repeat within the "
                                                r"stamps' jitter .* the first at row \d+"):
                if policy == "fail":
                    with pytest.raises(DataError, match=r"timestamp gap .* row 4999"):  # the drop, not the step back
                        read_dataset(path, "csv", 10.0, CHANNELS, UNITS, time_column="t", gap_policy=policy)
                    continue
                rec = read_dataset(path, "csv", 10.0, CHANNELS, UNITS, time_column="t", gap_policy=policy)
            if policy == "fill":
                assert [(g.row, g.n_missing) for g in rec.filled] == [(4999, 1)] and rec.n_samples == n
            else:
                assert [s.n for s in rec.segments] == [5000, n - 5001]
        # the same jitter with the clock set back by five periods, or a row written twice: the stamps after sit
        # on another grid, which no jitter explains
        back = data.copy()
        back[20_001:, 0] -= 5 * period
        with pytest.raises(DataError, match=r"not increasing: .* row 20001 .* [45]\.\d+ periods earlier on the sample "
                                            r"grid .*a clock set back"):
            read_dataset(write_csv(tmp_path / "set_back.csv", back), "csv", 10.0, CHANNELS, UNITS, time_column="t")
        twice = np.insert(data, 20_000, data[20_000], axis=0)
        with pytest.raises(DataError, match=r"duplicate timestamp .* row 20000 .* row 20001 .* 1\.\d+ periods earlier"):
            read_dataset(write_csv(tmp_path / "twice.csv", twice), "csv", 10.0, CHANNELS, UNITS, time_column="t")

    def test_a_drop_beside_a_jittered_stamp_is_found(self, tmp_path, table, rng):
        # an outside evaluation (0.15-period stamp jitter at 20 Hz): a drop beside a late stamp made two neighbouring
        # intervals long (1.52 and 1.64 periods) and split its grid shift between them (0.28 and 0.39, each below
        # half a period): not filled, not counted, no warning. The run of long intervals is now tested as one.
        n, period, d = 36_000, 0.1, 20_000
        stamps = (np.arange(n) + rng.normal(0.0, 0.15, n)) * period
        stamps[d - 2 : d + 2] = (np.array([d - 2, d - 1, d, d + 1]) + [-0.08, 0.52, 0.0, 0.08]) * period
        data = np.resize(table, (n, 7))
        data[:, 0] = stamps
        kept = np.delete(data, d, axis=0)  # the sample at d dropped: intervals of 1.60 and 1.56 periods around d - 1
        dt = np.diff(kept[:, 0]) / period
        assert dt[d - 2] > 1.5 and dt[d - 1] > 1.5
        rec = read_dataset(write_csv(tmp_path / "beside.csv", kept), "csv", 10.0, CHANNELS, UNITS, time_column="t",
                           gap_policy="fill")
        (gap,) = rec.filled
        assert gap.n_missing == 1 and abs(gap.row - (d - 1)) <= 1 and rec.n_samples == n  # placed within a row

    def test_heavy_stamp_jitter_with_drops_is_filled_not_refused(self, tmp_path, table):
        # an outside evaluation: Gaussian stamp jitter of 0.25 periods at 10 Hz with 8 single and double drops was
        # refused under gap_policy fill ("longer than the fill limit" for an interval of 1.76 periods): the check
        # after filling read an interval beside a filled drop as a gap. A gap within the fill limit found only after
        # filling is not one (the fill's own search looked for those): 16 of 40 such records refused before, none
        # now; the samples counted within 3 of the 12 dropped (the stamps resolve single drops only roughly here)
        n, period = 72_000, 0.1
        rng = np.random.default_rng([31, 0])
        stamps = (np.arange(n) + rng.normal(0.0, 0.25, n)) * period
        drops = np.sort(rng.choice(np.arange(100, n - 100), 8, replace=False))
        keep = np.ones(n, bool)
        for j, i in enumerate(drops):
            keep[i : i + 1 + j % 2] = False  # single and double drops
            if j % 4 == 1:
                stamps[i - 1] += 0.45 * period  # a late stamp before the drop
        data = np.resize(table, (n, 7))
        data[:, 0] = stamps
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", GapWarning)
            rec = read_dataset(write_csv(tmp_path / "heavy.csv", data[keep]), "csv", None, CHANNELS, UNITS,
                               time_column="t", gap_policy="fill")
        assert rec.rate_hz == 10.0 and abs(rec.n_samples - n) <= 3 and rec.n_filled >= 9

    def test_a_wandering_clock_fills_no_jitter_and_says_what_it_cannot_resolve(self, tmp_path, table, rng):
        # intervals jittering by 25 % rms, each on its own (the phase wanders): about 1 interval in 40 is longer than
        # 1.5 periods, and fill inserted a sample in each (an outside evaluation, at 20 %: 251 made-up samples). The
        # grid shift moves with the walk, so a long interval is a gap only beyond 5 robust sds of the intervals
        # (1.25 periods above one): a 3-sample drop is found, a single one cannot be told from the jitter, and a
        # GapWarning says so
        n, period = 36_000, 0.1
        steps = 1.0 + 0.25 * np.clip(rng.standard_normal(n - 1), -3.5, 3.5)  # clipped: time keeps increasing
        stamps = np.concatenate([[0.0], np.cumsum(period * steps)])
        data = np.resize(table, (n, 7))
        data[:, 0] = stamps
        keep = np.setdiff1d(np.arange(n), [9000, 9001, 9002])
        path = write_csv(tmp_path / "wander.csv", data[keep])
        with pytest.warns(GapWarning, match=r"wander\.csv: the timestamps jitter .* gaps of fewer than 2 samples"):
            rec = read_dataset(path, "csv", 10.0, CHANNELS, UNITS, time_column="t", gap_policy="fill")
        # the count is the interval's: 4 periods of 25 % jitter each span 4 +- 0.5 periods, so 3 +- 1 samples
        (gap,) = rec.filled
        assert gap.row == 8999 and abs(gap.n_missing - 3) <= 1 and rec.n_samples == n - 3 + gap.n_missing

    def test_gap_longer_than_the_fill_limit_fails_or_splits(self, tmp_path, table):
        drops = list(range(100, 120)) + [300]
        path, _ = self.phone_log(tmp_path, table, drops)
        kw = dict(time_column="t", gap_policy="fill", fill_max_s=0.05)
        with pytest.raises(DataError, match=r"phone\.csv: timestamp gap of 0\.21 s between row 99 \(0-based\)") as info:
            read_dataset(path, "csv", 100.0, CHANNELS, UNITS, **kw)
        # the short gap was filled already: the refusal names the long-gap policy, not gap_policy fill again
        assert "longer than the fill limit" in str(info.value) and "long_gap_policy='split'" in str(info.value)
        with pytest.warns(GapWarning, match=r"1 timestamp gap"):
            rec = read_dataset(path, "csv", 100.0, CHANNELS, UNITS, **kw, long_gap_policy="split")
        assert rec.n_filled == 1 and rec.n_samples == N - 120  # rows 120..599 plus the one filled

    def test_sheet_row_fill_columns(self, tmp_path, table):
        path, _ = self.phone_log(tmp_path, table, [10])
        row = {"dataset": "phone", "path": str(path), "rate_hz": 100, "time_column": "t", "gap_policy": "fill",
               "fill_max_samples": 2.0, **CHANNELS, "gyro_unit": "deg/s", "accel_unit": "g"}
        assert read_dataset_row(row).n_filled == 1
        with pytest.raises(DataError, match=r"dataset 'phone': fill_max_samples = 1\.5 is not an integer number of samples"):
            read_dataset_row(row | {"fill_max_samples": 1.5})

    @pytest.mark.parametrize("policy", ["fill", "fail", "split"])
    def test_sheet_rate_twice_the_timestamps_is_refused_not_filled(self, tmp_path, table, policy):
        # issue 19: a 100 Hz record stated as 200 Hz had every interval a "gap"; fill inserted a sample in
        # each (50 % of the record made up), fail spoke only of gaps. Now the sheet's rate is checked against
        # the timestamps' mean rate (found as when rate_hz is empty) before any gap handling.
        path = write_csv(tmp_path / "imu.csv", table)
        row = {"dataset": "imu", "path": str(path), "rate_hz": 200, "time_column": "t", "gap_policy": policy,
               **CHANNELS, "gyro_unit": "deg/s", "accel_unit": "g"}
        with pytest.raises(DataError) as info:
            read_dataset_row(row)
        msg = str(info.value)
        assert str(path) in msg and "rate_hz = 200 Hz" in msg and "mean rate of 100 Hz" in msg
        assert "correct rate_hz, or leave it empty" in msg and "timestamp gap" not in msg
        # the rate left empty: inferred from the same timestamps, nothing filled
        rec = read_dataset_row(row | {"rate_hz": None})
        assert rec.rate_hz == 100.0 and rec.n_filled == 0 and rec.n_samples == N

    def test_fill_may_make_up_at_most_fill_max_fraction(self, tmp_path, table):
        # 10 single-sample drops leave 590 file samples: filling inserts 10 / 590 = 1.69 % > 1 % (default)
        drops = list(range(30, 600, 57))
        assert len(drops) == 10
        path, _ = self.phone_log(tmp_path, table, drops)
        row = {"dataset": "phone", "path": str(path), "rate_hz": 100, "time_column": "t", "gap_policy": "fill",
               **CHANNELS, "gyro_unit": "deg/s", "accel_unit": "g"}
        with pytest.raises(DataError) as info:
            read_dataset_row(row)
        msg = str(info.value)
        assert str(path) in msg and "fill_max_fraction = 0.01" in msg and "insert 10 samples in 10 gap(s)" in msg
        assert read_dataset_row(row | {"fill_max_fraction": 0.02}).n_filled == 10  # 1.69 % <= 2 %
        with pytest.raises(DataError, match=r"phone\.csv: fill_max_fraction = 1\.5; expected a fraction"):
            read_dataset_row(row | {"fill_max_fraction": 1.5})
        with pytest.raises(DataError, match=r"dataset 'phone': fill_max_fraction = 'some' is not a number"):
            read_dataset_row(row | {"fill_max_fraction": "some"})


class TestGravity:
    """Issue 19: accel declared m/s^2 for data in g passed every check and made everything 9.8x too small."""

    def test_tilted_static_imu_passes_at_any_attitude(self, rng):
        # |g| on Earth 9.780 .. 9.832 m/s^2 (equator, poles) at any tilt: |f| = |g| whatever the rotation
        for g in (9.780, 9.832):
            for _ in range(20):
                u = rng.normal(size=3)
                assert check_gravity(g * u / np.linalg.norm(u), "m/s^2", "imu.csv") == pytest.approx(g, rel=1e-12)

    def test_window_edges(self):
        lo, hi = GRAVITY_WINDOW
        for ratio, ok in ((lo * (1 + 1e-9), True), (hi * (1 - 1e-9), True), (lo * (1 - 1e-6), False),
                          (hi * (1 + 1e-6), False)):
            f = [0.0, 0.0, -ratio * G0]
            if ok:
                check_gravity(f, "g", "imu.csv")
            else:
                with pytest.raises(DataError, match="accel_unit"):
                    check_gravity(f, "g", "imu.csv")
        # every confusion of two accepted accel units (ratio >= 9.80665) lands outside the window
        assert hi * (1 / lo) < 9.80665 / 1.0 and 1 / 9.80665 < lo

    def test_g_data_declared_si_names_file_key_magnitudes_and_the_unit(self, tmp_path, table):
        # the table is in g (accel z = -1 + noise): read as m/s^2, the mean specific force is ~1 m/s^2
        path = write_csv(tmp_path / "imu.csv", table)
        rec = read_dataset(path, "csv", 100.0, CHANNELS, {"gyro": "deg/s", "accel": "m/s^2"}, time_column="t")
        means = [float(np.mean(rec["accel", a])) for a in "xyz"]
        magnitude = float(np.linalg.norm(means))
        with pytest.raises(DataError) as info:
            check_gravity(means, "m/s^2", f"{path} (dataset 'imu')")
        msg = str(info.value)
        assert msg.startswith(f"{path} (dataset 'imu'): accel_unit = 'm/s^2'")
        assert f"magnitude of {magnitude:.4g} m/s^2 = {magnitude / G0:.4g} g" in msg
        assert "accel_unit = 'g' would make it" in msg and "gravity_removed: yes" in msg
        # declared g, the same file passes
        rec = read_dataset(path, "csv", 100.0, CHANNELS, UNITS, time_column="t")
        check_gravity([float(np.mean(rec["accel", a])) for a in "xyz"], "g", str(path))

    def test_mg_data_declared_g_proposes_mg(self):
        with pytest.raises(DataError, match=r"magnitude 1000 g: accel_unit = 'mg' would make it 1 g"):
            check_gravity([0.0, 0.0, -1000.0 * G0], "g", "imu.csv")

    def test_gravity_removed_cell(self):
        assert gravity_removed("yes") and gravity_removed("True") and gravity_removed(1)
        assert not gravity_removed(None) and not gravity_removed("") and not gravity_removed("no")
        assert not gravity_removed(float("nan"))
        with pytest.raises(DataError, match=r"dataset 'x': gravity_removed = 'maybe'; expected yes or no"):
            gravity_removed("maybe", where="dataset 'x'")


# ---------------------------------------------------------------------------------------------
# start-up checks: names, probe, config
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "name, reason",
    [("..", "relative directory"), (".", "relative directory"), ("", "is empty"), ("a/b", "path separator"),
     ("/", "path separator"), ("a b", "characters other than"), ("-x", "characters other than")],
)
def test_bad_dataset_names(name, reason):
    with pytest.raises(DataError, match=rf"dataset name {name!r} .*{reason}"):
        validate_dataset_name(name)


def test_good_dataset_name():
    assert validate_dataset_name("adis_run-1.v2") == "adis_run-1.v2"


class TestProbe:
    def test_probe_matches_the_full_read(self, tmp_path, table):
        csv = write_csv(tmp_path / "imu.csv", table)
        nc = write_nc(tmp_path / "imu.nc", table)
        npy = tmp_path / "imu.npy"
        np.save(npy, table)
        npz = tmp_path / "imu.npz"
        np.savez(npz, **{n: table[:, i] for i, n in enumerate(NAMES)})
        for path, fmt in ((csv, "csv"), (nc, "netcdf"), (npy, "npy"), (npz, "npz")):
            tcol = 0 if fmt == "npy" else "t"
            meta = probe(path, fmt, None, time_column=tcol)
            assert (meta.n_samples, meta.rate_hz, meta.rate_from) == (N, 100.0, "timestamps"), fmt
            assert meta.duration_s == pytest.approx(N / 100.0)

    def test_probe_row_and_config_check_name_the_key(self, tmp_path, table):
        path = write_csv(tmp_path / "imu.csv", table)
        meta = probe_row({"dataset": "short", "path": str(path), "rate_hz": 100.0})
        assert meta.dataset == "short" and meta.channels == tuple(NAMES)
        with pytest.raises(ConfigError, match=r"dataset 'short' lasts 6 s .* shorter than config key psd\.window_s = 25200 s"):
            check_against_config(meta, window_s=25200.0)
        with pytest.raises(ConfigError, match=r"config key decimate\.rate_hz = 3 Hz does not divide the rate of dataset 'short' \(100 Hz"):
            check_against_config(meta, decimate_rate_hz=3.0)
        with pytest.raises(ConfigError, match=r"dataset 'short': 6 decimated samples .* stationarity\.n_segments = 4 \(need >= 3 per segment"):
            check_against_config(meta, decimate_rate_hz=1.0, n_segments=4)
        check_against_config(meta, window_s=5.0, decimate_rate_hz=1.0, n_segments=2)  # fits


def test_read_channel_equals_read_dataset(tmp_path, table):
    path = write_nc(tmp_path / "imu.nc", table)
    full = read_dataset(path, "netcdf", 100.0, CHANNELS, None, axis_map="x:-y,y:x,z:z")
    one = read_channel(("gyro", "x"), path, "netcdf", rate_hz=100.0, channels=CHANNELS, axis_map="x:-y,y:x,z:z")
    assert list(one) == [("gyro", "x")] and one.columns[("gyro", "x")] == "-'wy'"
    np.testing.assert_array_equal(one["gyro", "x"], full["gyro", "x"])


def test_bag_row_needs_no_channel_columns():
    from imupipe.readers import missing_channel_columns

    assert missing_channel_columns({"dataset": "b", "path": "imu.mcap"}, ["gyro", "accel"]) == []
    assert missing_channel_columns({"path": "x.csv", "gyro_x": "wx", "gyro_y": "wy"}, ["gyro"]) == ["gyro_z"]


def test_too_short_names_the_config_key(tmp_path, table):
    path = write_csv(tmp_path / "imu.csv", table)
    with pytest.raises(DataError, match=r"imu\.csv: record lasts 6 s .* shorter than the 25200 s needed \(psd\.window_s\)"):
        read_dataset(path, "csv", 100.0, CHANNELS, UNITS, min_duration_s=25200.0, min_duration_key="psd.window_s")


def test_mcap_chunks_of_equal_messages_decode_as_blocks(tmp_path, rng):
    """A bag large enough for several MCAP chunks: the chunks of equal-length records are read as one array
    view each (the fast path), and the values equal what rosbags' own reader and deserialiser give."""
    pytest.importorskip("rosbags")
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    from imupipe.readers import rosbag as rb

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    Imu = T["sensor_msgs/msg/Imu"]
    n = 6000  # x 324 bytes: ~1.9 MB, more than one chunk of rosbags' MCAP writer
    w = rng.normal(0.0, 0.01, (n, 3))
    path = tmp_path / "imu"
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as wr:
        conn = wr.add_connection("/imu", Imu.__msgtype__, typestore=ts)
        for i in range(n):
            ns = 10**18 + i * 5_000_000  # 200 Hz
            msg = Imu(
                T["std_msgs/msg/Header"](T["builtin_interfaces/msg/Time"](ns // 10**9, ns % 10**9), "imu_link"),
                T["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0), np.zeros(9),
                T["geometry_msgs/msg/Vector3"](*w[i]), np.zeros(9),
                T["geometry_msgs/msg/Vector3"](*(w[i] + [0.0, 0.1 * i / n, 9.8])), np.zeros(9),
            )
            wr.write(conn, ns, ts.serialize_cdr(msg, Imu.__msgtype__))
    _, blocks, _ = rb._scan_mcap(rb._mcap_files(path), None, str(path))
    assert any(isinstance(b, np.ndarray) and b.shape[0] > 1 for b in blocks)
    rec = read_dataset(path, "rosbag")
    with AnyReader([path], default_typestore=ts) as reader:
        msgs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()]
    np.testing.assert_array_equal(rec["gyro", "y"], [m.angular_velocity.y for m in msgs])
    np.testing.assert_array_equal(rec["accel", "y"], [m.linear_acceleration.y for m in msgs])
    assert rec.rate_hz == 200.0 and rec.n_samples == n


@pytest.mark.parametrize("layout", ["plain", "comments_on_top", "no_final_newline", "blank_lines", "no_header", "comment_inside"])
def test_probe_counts_text_rows_like_the_reader(tmp_path, table, layout):
    header = None if layout == "no_header" else NAMES
    text = write_csv(tmp_path / "imu.csv", table, header=header).read_text()
    if layout == "comments_on_top":
        text = "# logger v2\n\n# rate 100 Hz\n" + text
    elif layout == "no_final_newline":
        text = text.rstrip("\n")
    elif layout == "blank_lines":
        text = text + "\n\n"
    elif layout == "comment_inside":
        lines = text.splitlines()
        text = "\n".join(lines[:100] + ["# operator note"] + lines[100:]) + "\n"
    path = tmp_path / "imu.csv"
    path.write_text(text)
    tcol = 0 if header is None else "t"
    channels = {k: i for i, k in enumerate(CHANNELS, start=1)} if header is None else CHANNELS
    full = read_dataset(path, "csv", None, channels, UNITS, time_column=tcol)
    meta = probe(path, "csv", None, time_column=tcol, channels=channels)
    assert (meta.n_samples, meta.rate_hz) == (full.n_samples, full.rate_hz) == (N, 100.0)


class TestFirstHourMessages:
    """Inputs a new user's first hour produced, each refused naming the culprit or accepted (docs/inputs.md)."""

    @pytest.mark.parametrize("sep, found", [(",", "commas"), (";", "semicolons")])
    def test_sheet_not_tab_separated(self, tmp_path, sep, found):
        sheet = tmp_path / "datasets.tsv"
        sheet.write_text(sep.join(["dataset", "path", "rate_hz"]) + "\n" + sep.join(["d1", "imu.csv", "100"]) + "\n")
        with pytest.raises(DataError, match=rf"datasets\.tsv', line 1: not tab-separated \(found {found}"):
            check_sheet_header(sheet)

    def test_sheet_unknown_column_named_with_the_allowed_ones(self, tmp_path):
        sheet = tmp_path / "datasets.tsv"
        sheet.write_text("# lab records\ndataset\tpath\tnotes\tgyro_unit\nd1\timu.csv\tbench 2\tdeg/s\n")
        with pytest.raises(DataError) as exc:
            check_sheet_header(sheet)
        msg = str(exc.value)
        assert "line 2: unknown column 'notes' (column 3); allowed columns: dataset, path, format, rate_hz" in msg
        assert "long_gap_policy" in msg and "'#' comment line" in msg
        ok = tmp_path / "ok.tsv"
        ok.write_text("dataset\tpath\tgyro_unit\t\t\nd1\timu.csv\tdeg/s\t\t\n")  # trailing tabs: fine
        assert check_sheet_header(ok) == ["dataset", "path", "gyro_unit", "", ""]

    @pytest.mark.parametrize("clock, time_unit_hint, fix", [
        # stamps whose mean rate is 0.85 % above 100 Hz (a fast clock), rate_hz empty: 100.8 Hz is read (snapped to
        # 1e-3), which 1 Hz does not divide; the fix is the nominal rate in the sheet, not decimate.rate_hz
        (1.0 / 1.0085, None, r"0\.80 % above 100 Hz: if 100 Hz is the record's nominal rate, set rate_hz: 100"),
        # stamps counting ms, read as s: 0.1 Hz; read as ms 100 Hz, which 1 Hz divides
        (1e3, None, r"read as ms the timestamps give 100 Hz: if the time column counts ms, set time_unit: ms"),
    ])
    def test_a_rate_decimation_cannot_divide_names_the_sheet_fix(self, tmp_path, table, clock, time_unit_hint, fix):
        t = table.copy()
        t[:, 0] = t[:, 0] * clock
        path = write_csv(tmp_path / "imu.csv", t)
        meta = probe_row({"dataset": "lab", "path": str(path), "time_column": "t"})
        assert meta.rate_from == "timestamps"
        with pytest.raises(ConfigError, match=r"decimate\.rate_hz = 1 Hz does not divide the rate of dataset 'lab'.*"
                           + fix):
            check_against_config(meta, decimate_rate_hz=1.0)
        # a rate the sheet gives is the user's statement: no guess added
        meta = probe_row({"dataset": "lab", "path": str(path), "time_column": "t", "rate_hz": 100.85})
        with pytest.raises(ConfigError) as exc:
            check_against_config(meta, decimate_rate_hz=1.0)
        assert "set rate_hz" not in str(exc.value) and "time_unit" not in str(exc.value)

    @pytest.mark.parametrize("header_too", [True, False])
    def test_csv_with_a_trailing_comma_on_every_line_is_read(self, tmp_path, table, header_too):
        path = tmp_path / "imu.csv"
        lines = [",".join(NAMES) + ("," if header_too else "")]
        lines += [",".join("%.17g" % v for v in row) + "," for row in table]
        path.write_text("\n".join(lines) + "\n")
        rec = read_dataset(path, "csv", 100.0, CHANNELS, UNITS, time_column="t")
        np.testing.assert_allclose(rec["gyro", "y"], table[:, 2] * DEG, rtol=1e-15)
        assert rec.n_samples == N
        # a value in the trailing column is data without a header: refused, naming the line
        lines[5] = lines[5] + "7"
        path.write_text("\n".join(lines) + "\n")
        with pytest.raises(DataError, match=r"imu\.csv: line 6 has too many fields \(8, expected 7\)"):
            read_dataset(path, "csv", 100.0, CHANNELS, UNITS, time_column="t")

    def test_windows_path_hint(self, tmp_path):
        with pytest.raises(DataError, match=r"file not found \(the path has backslashes, a Windows path\? .*"
                                            r"write 'data/imu\.csv'"):
            read_dataset("data\\imu.csv", "csv", 100.0, CHANNELS, UNITS)
        with pytest.raises(DataError, match=r"nope\.csv: file not found$"):
            read_dataset(tmp_path / "nope.csv", "csv", 100.0, CHANNELS, UNITS)

    @pytest.mark.parametrize("unit, factor", [("ms", 1e-3), ("ns", 1e-9)])
    def test_stamps_in_another_unit_than_read_name_time_unit(self, tmp_path, table, unit, factor):
        # ms or ns stamps with rate_hz 100 and no time_unit said "correct rate_hz": the rate is right, the unit not
        stamped = table.copy()
        stamped[:, 0] = np.round(stamped[:, 0] / factor)
        path = write_csv(tmp_path / "imu.csv", stamped)
        with pytest.raises(DataError) as info:
            read_dataset(path, "csv", 100.0, CHANNELS, UNITS, time_column="t")
        msg = str(info.value)
        assert f"read as s give a mean rate of {100 * factor:.6g} Hz" in msg
        assert f"read as {unit} they give 100 Hz: the time column counts {unit}, set time_unit: {unit}" in msg
        assert "correct rate_hz" not in msg
        rec = read_dataset(path, "csv", 100.0, CHANNELS, UNITS, time_column="t", time_unit=unit)
        assert rec.rate_hz == 100.0
        # a rate no unit explains keeps the rate_hz advice
        with pytest.raises(DataError, match="correct rate_hz, or leave it empty"):
            read_dataset(path, "csv", 120.0, CHANNELS, UNITS, time_column="t", time_unit=unit)
