"""imupipe.readers: round trips for every format on tiny generated files, one test per bad-input
class (the error must name the culprit), and the real ADIS16405 record."""

import dataclasses
import math
import warnings

import numpy as np
import pytest

from imupipe.readers import (
    SHEET_COLUMNS,
    DataError,
    GapWarning,
    Recording,
    parse_axis_map,
    read_dataset,
    read_dataset_row,
    sheet_row_to_kwargs,
)

G0 = 9.80665  # m/s^2 per g
DEG = math.pi / 180.0  # rad per degree
RATE = 100.0  # Hz
N = 64  # samples of the tiny files

ALL_KEYS = [(s, a) for s in ("gyro", "accel") for a in ("x", "y", "z")]
NAMES = {("gyro", "x"): "wx", ("gyro", "y"): "wy", ("gyro", "z"): "wz"} | {
    ("accel", "x"): "ax",
    ("accel", "y"): "ay",
    ("accel", "z"): "az",
}
UNITS = {"gyro": "deg/s", "accel": "g"}
SI = {"gyro": DEG, "accel": G0}  # SI factor of UNITS


@pytest.fixture
def signals(rng):
    """Six channels in file units (deg/s, g) on the ADIS16405's quantisation steps, plus time (s)."""
    gyro = np.round(rng.normal(0.0, 0.5, (N, 3)) / 0.05) * 0.05
    accel = np.round((rng.normal(0.0, 0.01, (N, 3)) + [0.0, 0.0, -1.0]) / 0.00333) * 0.00333
    data = {("gyro", a): gyro[:, i] for i, a in enumerate("xyz")} | {
        ("accel", a): accel[:, i] for i, a in enumerate("xyz")
    }
    return data, np.arange(N) / RATE


def write_csv(path, columns, delimiter=",", header=True, comment=None):
    """Write ``{name: 1-D array}`` as a text table; returns the path."""
    names = list(columns)
    lines = [comment] if comment else []
    if header:
        lines.append(delimiter.join(names))
    table = np.column_stack([columns[n] for n in names])
    lines += [delimiter.join(repr(float(v)) for v in row) for row in table]
    path.write_text("\n".join(lines) + "\n")
    return path


def csv_columns(signals):
    data, t = signals
    return {"t": t} | {NAMES[k]: data[k] for k in ALL_KEYS}


def assert_si(rec, data, keys=ALL_KEYS):
    assert list(rec) == keys
    for key in keys:
        assert rec[key].dtype == np.float64
        np.testing.assert_allclose(rec[key], data[key] * SI[key[0]], rtol=1e-15, atol=0)
        assert rec.units[key] == ("rad/s" if key[0] == "gyro" else "m/s^2")


# ---------------------------------------------------------------------------------------------
# round trips per format
# ---------------------------------------------------------------------------------------------
class TestCsv:
    def test_named_columns_with_time(self, tmp_path, signals):
        path = write_csv(tmp_path / "imu.csv", csv_columns(signals), comment="# static test, 100 Hz")
        rec = read_dataset(path, "csv", RATE, NAMES, UNITS, time_column="t")
        assert isinstance(rec, Recording)
        assert_si(rec, signals[0])
        assert rec.rate_hz == RATE
        assert rec.n_samples == N and rec.duration_s == pytest.approx(N / RATE)
        assert rec.segments == (dataclasses.replace(rec.segments[0], start=0, stop=N),)
        assert rec.columns[("gyro", "x")] == "'wx'"
        assert rec.file_units[("accel", "z")] == "g"
        assert rec.sensors == ("gyro", "accel")
        assert "imu.csv" in rec.source

    def test_a_name_without_its_bracketed_unit_finds_the_column(self, tmp_path, signals):
        # a header that states each column's unit ("wx [deg/s]", as imupipe init and the README suggest) read by the
        # bare names; a bare name that two columns share is refused naming both
        cols = {"t [s]": signals[1]} | {f"{NAMES[k]} [{UNITS[k[0]]}]": signals[0][k] for k in ALL_KEYS}
        path = write_csv(tmp_path / "imu.csv", cols)
        rec = read_dataset(path, "csv", RATE, NAMES, UNITS, time_column="t")
        assert_si(rec, signals[0])
        assert rec.columns[("gyro", "x")] == "'wx [deg/s]'"
        twice = write_csv(tmp_path / "twice.csv", cols | {"wx [rad/s]": signals[0][("gyro", "x")]})
        with pytest.raises(DataError, match=r"twice\.csv: gyro_x column 'wx' names 2 columns .*'wx \[deg/s\]', "
                                            r"'wx \[rad/s\]'\): give the full name"):
            read_dataset(twice, "csv", RATE, NAMES, UNITS, time_column="t")

    def test_no_header_whitespace_and_indices(self, tmp_path, signals):
        data, _ = signals
        path = write_csv(
            tmp_path / "imu.txt", {str(i): data[k] for i, k in enumerate(ALL_KEYS)}, " ", header=False
        )
        channels = {f"{s}_{a}": i for i, (s, a) in enumerate(ALL_KEYS)}
        rec = read_dataset(path, "txt", RATE, channels, UNITS, delimiter="space")
        assert_si(rec, data)

    def test_tab_delimiter_by_name_and_default_column_names(self, tmp_path, signals):
        data, _ = signals
        path = write_csv(tmp_path / "imu.tsv", {f"{s}_{a}": data[(s, a)] for s, a in ALL_KEYS}, "\t")
        rec = read_dataset(path, "auto", RATE, None, UNITS, delimiter="tab")
        assert_si(rec, data)

    def test_one_sensor_only(self, tmp_path, signals):
        path = write_csv(tmp_path / "imu.csv", csv_columns(signals))
        gyro = {k: v for k, v in NAMES.items() if k[0] == "gyro"}
        rec = read_dataset(path, "csv", RATE, gyro, {"gyro": "deg/s"})
        assert rec.sensors == ("gyro",)
        assert_si(rec, signals[0], keys=list(gyro))

    def test_axis_map_permutes_and_negates(self, tmp_path, signals):
        data, _ = signals
        path = write_csv(tmp_path / "imu.csv", csv_columns(signals))
        rec = read_dataset(path, "csv", RATE, NAMES, UNITS, axis_map="x:-y, y:x, z:-z")
        for sensor in ("gyro", "accel"):
            f = SI[sensor]
            np.testing.assert_array_equal(rec[sensor, "x"], -data[(sensor, "y")] * f)
            np.testing.assert_array_equal(rec[sensor, "y"], data[(sensor, "x")] * f)
            np.testing.assert_array_equal(rec[sensor, "z"], -data[(sensor, "z")] * f)
        assert rec.columns[("gyro", "x")] == "-'wy'"

    def test_time_in_ms_gives_the_rate_without_a_sheet_rate(self, tmp_path, signals):
        columns = csv_columns(signals) | {"t": signals[1] * 1e3}
        path = write_csv(tmp_path / "imu.csv", columns)
        rec = read_dataset(path, "csv", None, NAMES, UNITS, time_column="t", time_unit="ms")
        assert rec.rate_hz == pytest.approx(RATE, rel=1e-12)


    def test_header_units_agreeing_with_the_sheet_are_read(self, tmp_path, signals):
        data, t = signals
        cols = {"t [s]": t} | {f"{NAMES[k]} [{UNITS[k[0]]}]": data[k] for k in ALL_KEYS}
        names = {k: f"{NAMES[k]} [{UNITS[k[0]]}]" for k in ALL_KEYS}
        path = write_csv(tmp_path / "imu.csv", cols)
        # the sheet's unit spelled otherwise (dps = deg/s): the same factor, accepted
        rec = read_dataset(path, "csv", RATE, names, {"gyro": "dps", "accel": "g"}, time_column="t [s]")
        assert_si(rec, data)
        # no unit in the sheet: the header's is read (as a netCDF units attribute is)
        rec = read_dataset(path, "csv", RATE, names, None, time_column="t [s]")
        assert_si(rec, data)
        assert rec.file_units[("gyro", "x")] == "deg/s"

    def test_header_unit_contradicting_the_sheet_is_an_error(self, tmp_path, signals):
        """A header 'wx [deg/s]' under a sheet saying rad/s: read as rad/s, the data would be 57x too large (or, the
        other way round, 57x too small: a model that understates); refused, naming the file, column and both units."""
        data, t = signals
        cols = {"t": t} | {f"{NAMES[k]} [{UNITS[k[0]]}]": data[k] for k in ALL_KEYS}
        names = {k: f"{NAMES[k]} [{UNITS[k[0]]}]" for k in ALL_KEYS}
        path = write_csv(tmp_path / "imu.csv", cols)
        with pytest.raises(DataError, match=r"imu\.csv.*gyro_unit = 'rad/s' in the sheet but 'wx \[deg/s\]' states "
                                            r"'deg/s'"):
            read_dataset(path, "csv", RATE, names, {"gyro": "rad/s", "accel": "g"}, time_column="t")

    def test_a_bracketed_note_is_not_a_unit(self, tmp_path, signals):
        data, t = signals
        cols = {"t": t} | {f"{NAMES[k]} (filtered)": data[k] for k in ALL_KEYS}
        names = {k: f"{NAMES[k]} (filtered)" for k in ALL_KEYS}
        rec = read_dataset(write_csv(tmp_path / "imu.csv", cols), "csv", RATE, names, UNITS, time_column="t")
        assert_si(rec, data)


class TestNumpy:
    def test_npy_columns_by_index_with_time(self, tmp_path, signals):
        data, t = signals
        np.save(tmp_path / "imu.npy", np.column_stack([t] + [data[k] for k in ALL_KEYS]))
        channels = {k: i + 1 for i, k in enumerate(ALL_KEYS)}
        rec = read_dataset(tmp_path / "imu.npy", "npy", RATE, channels, UNITS, time_column=0)
        assert_si(rec, data)
        assert rec.columns[("gyro", "x")] == "column 1"

    def test_npy_structured_by_field_name(self, tmp_path, signals):
        data, _ = signals
        arr = np.zeros(N, dtype=[(NAMES[k], "f8") for k in ALL_KEYS])
        for k in ALL_KEYS:
            arr[NAMES[k]] = data[k]
        np.save(tmp_path / "imu.npy", arr)
        assert_si(read_dataset(tmp_path / "imu.npy", "npy", RATE, NAMES, UNITS), data)

    def test_npz_arrays_by_name(self, tmp_path, signals):
        data, t = signals
        np.savez(tmp_path / "imu.npz", time=t, **{NAMES[k]: data[k] for k in ALL_KEYS})
        rec = read_dataset(tmp_path / "imu.npz", "npz", RATE, NAMES, UNITS, time_column="time")
        assert_si(rec, data)

    def test_npz_matrix_variable(self, tmp_path, signals):
        data, _ = signals
        np.savez(tmp_path / "imu.npz", imu=np.column_stack([data[k] for k in ALL_KEYS]), other=np.ones(3))
        channels = {k: i for i, k in enumerate(ALL_KEYS)}
        rec = read_dataset(tmp_path / "imu.npz", "npz", RATE, channels, UNITS, variable="imu")
        assert_si(rec, data)
        assert "variable 'imu'" in rec.source


class TestNetcdf:
    @staticmethod
    def write(path, data, t, units=True):
        import netCDF4

        with netCDF4.Dataset(path, "w") as ds:
            ds.createDimension("time", len(t))
            tv = ds.createVariable("time", "f8", ("time",))
            tv[:] = t * 1e3
            tv.units = "milliseconds since 2021-11-01 00:00:00"
            for k in ALL_KEYS:
                v = ds.createVariable(NAMES[k], "f8", ("time",))
                v[:] = data[k]
                if units:
                    v.units = UNITS[k[0]]
        return path

    def test_variables_and_units_from_the_file(self, tmp_path, signals):
        data, t = signals
        path = self.write(tmp_path / "imu.nc", data, t)
        rec = read_dataset(path, "netcdf", RATE, NAMES, None, time_column="time")
        assert_si(rec, data)
        assert rec.file_units[("gyro", "x")] == "deg/s"

    def test_sheet_unit_contradicting_the_file_is_an_error(self, tmp_path, signals):
        path = self.write(tmp_path / "imu.nc", *signals)
        with pytest.raises(
            DataError, match=r"gyro_unit = 'rad/s' in the sheet but 'wx' states 'deg/s'"
        ):
            read_dataset(path, "netcdf", RATE, NAMES, {"gyro": "rad/s", "accel": "g"})


def write_r_matrix(path, matrix, colnames, *, freq=None, name="imu", rds=False):
    """An R numeric matrix with column names (and the imudata ``freq`` attribute), as .rda or .rds."""
    from rdata.conversion.to_r import ConverterFromPythonToR, build_r_list, build_r_object
    from rdata.parser import RObjectType
    from rdata.unparser import unparse_file

    conv = ConverterFromPythonToR()
    attrs = {"dim": np.array(matrix.shape, dtype=np.int32), "dimnames": [None, np.array(colnames)]}
    if freq is not None:
        attrs["freq"] = np.array([float(freq)])
    obj = build_r_object(
        RObjectType.REAL, value=np.ravel(matrix, order="F"), attributes=conv.convert_to_r_attributes(attrs)
    )
    file_type = "rds" if rds else "rda"
    top = obj if rds else build_r_list([(conv.convert_to_r_sym(name), obj)])
    base = conv.convert_to_r_data({"x": 1.0} if not rds else 1.0, file_type=file_type)
    unparse_file(path, dataclasses.replace(base, object=top), file_type=file_type, compression="xz")
    return path


ADIS_NAMES = {("gyro", a): f"Gyro. {a.upper()}" for a in "xyz"} | {
    ("accel", a): f"Accel. {a.upper()}" for a in "xyz"
}


class TestRdata:
    def test_rda_matrix_with_column_names_and_freq(self, tmp_path, signals):
        data, _ = signals
        matrix = np.column_stack([data[k] for k in ALL_KEYS])
        path = write_r_matrix(tmp_path / "imu.rda", matrix, [ADIS_NAMES[k] for k in ALL_KEYS], freq=RATE)
        rec = read_dataset(path, "rda", None, ADIS_NAMES, UNITS)
        assert_si(rec, data)
        assert rec.rate_hz == RATE  # from the R attribute freq
        assert "object 'imu'" in rec.source

    def test_rds_matrix(self, tmp_path, signals):
        data, _ = signals
        matrix = np.column_stack([data[k] for k in ALL_KEYS])
        path = write_r_matrix(tmp_path / "imu.rds", matrix, [ADIS_NAMES[k] for k in ALL_KEYS], rds=True)
        assert_si(read_dataset(path, "rds", RATE, ADIS_NAMES, UNITS), data)

    def test_rda_named_list_among_several_objects(self, tmp_path, signals):
        import rdata

        data, _ = signals
        path = tmp_path / "imu.rda"
        rdata.write_rda(path, {"imu": {NAMES[k]: data[k] for k in ALL_KEYS}, "note": "static"})
        assert_si(read_dataset(path, "auto", RATE, NAMES, UNITS, variable="imu"), data)
        with pytest.raises(DataError, match=r"2 objects in the file; give `variable`, one of 'imu', 'note'"):
            read_dataset(path, "auto", RATE, NAMES, UNITS)
        with pytest.raises(DataError, match=r"object 'imu2' not found; available: 'imu', 'note'"):
            read_dataset(path, "auto", RATE, NAMES, UNITS, variable="imu2")

    def test_freq_attribute_disagreeing_with_the_sheet(self, tmp_path, signals):
        matrix = np.column_stack([signals[0][k] for k in ALL_KEYS])
        path = write_r_matrix(tmp_path / "imu.rda", matrix, [ADIS_NAMES[k] for k in ALL_KEYS], freq=200.0)
        with pytest.raises(
            DataError, match=r"rate_hz = 100 Hz in the sheet but the file says 200 Hz \(R attribute freq\)"
        ):
            read_dataset(path, "rda", RATE, ADIS_NAMES, UNITS)


class TestRosbag:
    """sensor_msgs/Imu in ROS 2 (sqlite3 and MCAP) and ROS 1 bags written with rosbags' writers."""

    @staticmethod
    def write(path, data, stamps_ns, kind="ros2", topic="/imu", extra_topic=True, frame_ids=("imu",)):
        pytest.importorskip("rosbags")
        from rosbags.typesys import Stores, get_typestore

        ros1 = kind == "ros1"
        ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
        T = ts.types
        Imu, Header, Time = (
            T["sensor_msgs/msg/Imu"],
            T["std_msgs/msg/Header"],
            T["builtin_interfaces/msg/Time"],
        )
        Vec, Quat = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
        String = T["std_msgs/msg/String"]
        serialize = ts.serialize_ros1 if ros1 else ts.serialize_cdr

        def message(i):
            stamp = Time(sec=int(stamps_ns[i] // 10**9), nanosec=int(stamps_ns[i] % 10**9))
            header = (
                Header(seq=i, stamp=stamp, frame_id=frame_ids[i % len(frame_ids)])
                if ros1
                else Header(stamp=stamp, frame_id=frame_ids[i % len(frame_ids)])
            )
            return Imu(
                header=header,
                orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=np.zeros(9),
                angular_velocity=Vec(**{a: float(data[("gyro", a)][i]) for a in "xyz"}),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=Vec(**{a: float(data[("accel", a)][i]) for a in "xyz"}),
                linear_acceleration_covariance=np.zeros(9),
            )

        if ros1:
            from rosbags.rosbag1 import Writer

            writer = Writer(path)
        else:
            from rosbags.rosbag2 import StoragePlugin, Writer

            plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
            writer = Writer(path, version=9, storage_plugin=plugin)
        with writer:
            conn = writer.add_connection(topic, Imu.__msgtype__, typestore=ts)
            other = (
                writer.add_connection("/status", String.__msgtype__, typestore=ts) if extra_topic else None
            )
            for i in range(len(stamps_ns)):
                writer.write(conn, int(stamps_ns[i]) + 1000, serialize(message(i), Imu.__msgtype__))
                if other is not None and i == 0:
                    writer.write(other, int(stamps_ns[i]), serialize(String(data="ok"), String.__msgtype__))
        return path

    @pytest.fixture
    def si_signals(self, signals):
        data, _ = signals
        return {k: v * SI[k[0]] for k, v in data.items()}, 1_700_000_000 * 10**9 + np.arange(N) * 10_000_000

    @pytest.mark.parametrize("kind", ["ros2", "mcap", "ros1"])
    def test_round_trip(self, tmp_path, si_signals, kind):
        data, stamps = si_signals
        path = self.write(tmp_path / ("imu.bag" if kind == "ros1" else "imu"), data, stamps, kind)
        if kind == "mcap":  # the bare .mcap file, without the rosbag2 metadata.yaml
            path = next(path.glob("*.mcap"))
        rec = read_dataset(path, "auto", RATE)
        assert list(rec) == ALL_KEYS
        for k in ALL_KEYS:
            np.testing.assert_array_equal(rec[k], data[k])
        assert rec.file_units[("gyro", "x")] == "rad/s"
        assert "topic '/imu'" in rec.source

    @pytest.mark.parametrize("frame_ids", [("imu",), ("imu", "imu_link_long_name")])
    def test_bulk_decode_equals_the_deserialiser(self, tmp_path, si_signals, frame_ids, monkeypatch):
        """The numpy decoder over the raw CDR bytes gives rosbags' deserialised values, also when frame_id
        lengths (and so the padding) differ between messages; the direct MCAP reader the same as rosbags'."""
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        from imupipe.readers import rosbag as rb

        data, stamps = si_signals
        path = self.write(tmp_path / "imu", data, stamps, "mcap", frame_ids=frame_ids)
        with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            conns = [c for c in reader.connections if c.topic == "/imu"]
            msgs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns)]
        topic, _, log_ns = rb._scan_mcap(rb._mcap_files(path), None, str(path))  # the direct path applies
        assert topic == "/imu" and log_ns.size == len(msgs)
        direct = read_dataset(path, "rosbag")
        monkeypatch.setattr(rb, "_mcap_files", lambda p: None)  # through rosbags' reader instead
        via_rosbags = read_dataset(path, "rosbag")
        for a in "xyz":
            want = np.array([getattr(m.angular_velocity, a) for m in msgs])
            np.testing.assert_array_equal(direct["gyro", a], want)
            np.testing.assert_array_equal(via_rosbags["gyro", a], want)
            want = np.array([getattr(m.linear_acceleration, a) for m in msgs])
            np.testing.assert_array_equal(direct["accel", a], want)
        np.testing.assert_array_equal(direct.segments[0].t_stop, (stamps[-1] - stamps[0]) * 1e-9)

    @pytest.mark.parametrize("kind", ["ros2", "mcap"])
    def test_probe_reads_the_index(self, tmp_path, si_signals, kind):
        from imupipe.readers import probe

        path = self.write(tmp_path / "imu", *si_signals, kind)
        meta = probe(path, "rosbag", topic="/imu")
        assert (meta.n_samples, meta.rate_hz, meta.rate_from) == (N, RATE, "timestamps")

    def test_unknown_topic_lists_the_topics(self, tmp_path, si_signals):
        path = self.write(tmp_path / "imu", *si_signals)
        with pytest.raises(
            DataError, match=r"topic '/imu0' not found; topics: /imu \(sensor_msgs/msg/Imu\), /status"
        ):
            read_dataset(path, "rosbag", RATE, topic="/imu0")
        with pytest.raises(DataError, match=r"topic '/status' carries std_msgs/msg/String"):
            read_dataset(path, "rosbag", RATE, topic="/status")

    def test_header_stamp_gap(self, tmp_path, si_signals):
        data, stamps = si_signals
        stamps = stamps.copy()
        stamps[40:] += 50_000_000  # 50 ms lost after message 39
        path = self.write(tmp_path / "imu", data, stamps)
        with pytest.raises(
            DataError, match=r"timestamp gap of 0.06 s between row 39 \(0-based\).*and row 40"
        ):
            read_dataset(path, "rosbag", RATE)


# ---------------------------------------------------------------------------------------------
# bad inputs: one test per class, the error names the culprit
# ---------------------------------------------------------------------------------------------
class TestBadInputs:
    @pytest.fixture
    def csv(self, tmp_path, signals):
        return write_csv(tmp_path / "imu.csv", csv_columns(signals))

    def edit_line(self, path, line, text):
        """Replace 1-based ``line`` of a text file."""
        lines = path.read_text().splitlines()
        lines[line - 1] = text
        path.write_text("\n".join(lines) + "\n")
        return path

    def test_missing_file(self, tmp_path):
        with pytest.raises(DataError, match=r"nothere\.csv: file not found"):
            read_dataset(tmp_path / "nothere.csv", "csv", RATE, NAMES, UNITS)

    def test_empty_file(self, tmp_path):
        (tmp_path / "empty.csv").write_text("")
        with pytest.raises(DataError, match=r"empty\.csv: file is empty"):
            read_dataset(tmp_path / "empty.csv", "csv", RATE, NAMES, UNITS)

    def test_header_only(self, tmp_path):
        (tmp_path / "imu.csv").write_text("t,wx,wy,wz\n")
        with pytest.raises(DataError, match=r"imu\.csv: no data rows after line 1"):
            read_dataset(tmp_path / "imu.csv", "csv", RATE, {"gyro_x": "wx"}, UNITS)

    def test_truncated_last_row_names_the_line(self, csv):
        lines = csv.read_text().splitlines()
        csv.write_text(
            "\n".join(lines) + "\n" + lines[-1][: lines[-1].rindex(",")]
        )  # no newline, a field short
        with pytest.raises(DataError, match=rf"imu\.csv: line {N + 2} has too few fields \(6, expected 7\)"):
            read_dataset(csv, "csv", RATE, NAMES, UNITS)

    def test_non_numeric_field_names_line_and_column(self, csv):
        self.edit_line(csv, 5, "0.03,0.1,oops,0.2,0.0,0.0,-1.0")
        with pytest.raises(DataError, match=r"line 5, column 'wy': non-numeric value 'oops'"):
            read_dataset(csv, "csv", RATE, NAMES, UNITS)

    def test_unknown_column_lists_the_available_ones(self, csv):
        with pytest.raises(
            DataError, match=r"gyro_y column 'wq' not found; available: 't', 'wx', 'wy', 'wz', 'ax'"
        ):
            read_dataset(csv, "csv", RATE, NAMES | {("gyro", "y"): "wq"}, UNITS)

    @pytest.mark.parametrize("bad", ["nan", "inf", "-inf"])
    def test_non_finite_sample_names_channel_row_and_line(self, csv, bad):
        self.edit_line(csv, 5, f"0.03,0.1,0.2,0.3,{bad},0.0,-1.0")
        with pytest.raises(
            DataError, match=r"accel_x \(column 'ax'\) has a non-finite sample .* row 3 \(0-based\), line 5"
        ):
            read_dataset(csv, "csv", RATE, NAMES, UNITS)

    def test_duplicate_timestamp(self, tmp_path, signals):
        columns = csv_columns(signals)
        columns["t"] = columns["t"].copy()
        columns["t"][4] = columns["t"][3]
        path = write_csv(tmp_path / "imu.csv", columns)
        with pytest.raises(
            DataError, match=r"duplicate timestamp in 't': row 3 \(0-based\), line 5 and row 4"
        ):
            read_dataset(path, "csv", RATE, NAMES, UNITS, time_column="t")

    def test_mostly_duplicate_timestamps_named_when_filling_by_seconds(self, tmp_path, signals):
        """gap_policy fill with fill_max_s and no rate needs the median interval: with most stamps duplicated it
        is 0; the duplicates are named first (not a division by zero)."""
        columns = csv_columns(signals)
        columns["t"] = columns["t"][np.arange(N) // 3 * 3]  # each stamp three times: 2/3 of the intervals 0
        path = write_csv(tmp_path / "imu.csv", columns)
        n_dup = int(np.count_nonzero(np.diff(columns["t"]) == 0))
        with pytest.raises(DataError, match=rf"duplicate timestamp in 't': row 0 .* \({n_dup} duplicates in all\)"):
            read_dataset(path, "csv", None, NAMES, UNITS, time_column="t", gap_policy="fill", fill_max_s=1.0)

    def test_time_going_backwards(self, tmp_path, signals):
        columns = csv_columns(signals)
        columns["t"] = columns["t"].copy()
        columns["t"][[10, 11]] = columns["t"][[11, 10]]
        path = write_csv(tmp_path / "imu.csv", columns)
        with pytest.raises(
            DataError, match=r"not increasing: t = 0.1 s at row 11 .* after t = 0.11 s at row 10"
        ):
            read_dataset(path, "csv", RATE, NAMES, UNITS, time_column="t")

    def test_gap_fails_by_default(self, tmp_path, signals):
        columns = csv_columns(signals)
        columns["t"] = columns["t"] + np.where(np.arange(N) >= 20, 0.5, 0.0)
        path = write_csv(tmp_path / "imu.csv", columns)
        with pytest.raises(
            DataError, match=r"timestamp gap of 0.51 s between row 19 .* \(t = 0.19 s\) and row 20"
        ):
            read_dataset(path, "csv", RATE, NAMES, UNITS, time_column="t")

    def test_gap_split_keeps_the_longest_segment_and_warns(self, tmp_path, signals):
        data, _ = signals
        columns = csv_columns(signals)
        columns["t"] = columns["t"] + np.where(np.arange(N) >= 20, 0.5, 0.0)
        path = write_csv(tmp_path / "imu.csv", columns)
        with pytest.warns(
            GapWarning, match=r"1 timestamp gap\(s\).*row 19.*Kept the longest of 2 segments: rows 20\.\.63"
        ):
            rec = read_dataset(path, "csv", RATE, NAMES, UNITS, time_column="t", gap_policy="split")
        assert [(s.start, s.stop) for s in rec.segments] == [(0, 20), (20, N)]
        assert rec.selected == 1 and rec.n_samples == N - 20
        assert rec.segments[1].t_start == pytest.approx(0.7)
        np.testing.assert_array_equal(rec["gyro", "x"], data[("gyro", "x")][20:] * DEG)
        np.testing.assert_array_equal(rec.segment(0)[("gyro", "x")], data[("gyro", "x")][:20] * DEG)

    def test_sheet_rate_disagreeing_with_timestamps(self, tmp_path, signals):
        path = write_csv(tmp_path / "imu.csv", csv_columns(signals))
        with pytest.raises(
            DataError, match=r"rate_hz = 102 Hz but the timestamps \('t'\) give a mean rate of 100 Hz"
        ):
            read_dataset(path, "csv", 102.0, NAMES, UNITS, time_column="t")
        read_dataset(path, "csv", 100.5, NAMES, UNITS, time_column="t")  # within 1 %

    def test_mean_rate_beyond_one_percent(self, tmp_path, signals):
        # every 4th interval 5 ms long (not a gap): median interval 10 ms, mean 10.125 ms -> 98.77 Hz
        dt = np.where(np.arange(1, N) % 4 == 0, 0.0105, 0.01)
        columns = csv_columns(signals) | {"t": np.concatenate([[0.0], np.cumsum(dt)])}
        path = write_csv(tmp_path / "imu.csv", columns)
        with pytest.raises(
            DataError, match=r"rate_hz = 100 Hz but the timestamps \('t'\) give a mean rate of 98\.82"
        ):
            read_dataset(path, "csv", RATE, NAMES, UNITS, time_column="t")

    def test_too_short_for_the_requested_duration(self, csv):
        with pytest.raises(
            DataError, match=r"record lasts 0.64 s \(64 samples at 100 Hz\), shorter than the 10 s needed"
        ):
            read_dataset(csv, "csv", RATE, NAMES, UNITS, min_duration_s=10.0)
        assert read_dataset(csv, "csv", RATE, NAMES, UNITS, min_duration_s=0.64).n_samples == N

    def test_constant_channel(self, tmp_path, signals):
        columns = csv_columns(signals) | {"ay": np.full(N, 0.00333)}
        path = write_csv(tmp_path / "imu.csv", columns)
        with pytest.raises(
            DataError, match=r"accel_y \(column 'ay'\) is constant \(0.00333 in all 64 samples\)"
        ):
            read_dataset(path, "csv", RATE, NAMES, UNITS)

    def test_unknown_unit(self, csv):
        with pytest.raises(DataError, match=r"gyro_unit: unknown unit 'furlong/s' for gyro"):
            read_dataset(csv, "csv", RATE, NAMES, {"gyro": "furlong/s", "accel": "g"})

    def test_accel_unit_given_for_gyro_is_unknown(self, csv):
        with pytest.raises(DataError, match=r"gyro_unit: unknown unit 'm/s\^2' for gyro"):
            read_dataset(csv, "csv", RATE, NAMES, {"gyro": "m/s^2", "accel": "g"})

    def test_missing_unit(self, csv):
        with pytest.raises(DataError, match=r"accel_unit missing for accel_x"):
            read_dataset(csv, "csv", RATE, NAMES, {"gyro": "deg/s"})

    def test_rate_unknown(self, csv):
        with pytest.raises(DataError, match=r"sample rate unknown: give rate_hz"):
            read_dataset(csv, "csv", None, NAMES, UNITS)

    def test_unknown_format_and_extension(self, csv, tmp_path):
        with pytest.raises(DataError, match=r"unknown format 'xls'"):
            read_dataset(csv, "xls", RATE, NAMES, UNITS)
        (tmp_path / "imu.xyz").write_text("1\n")
        with pytest.raises(DataError, match=r"imu\.xyz: cannot tell the format from the extension '\.xyz'"):
            read_dataset(tmp_path / "imu.xyz", "auto", RATE, NAMES, UNITS)

    def test_bad_gap_policy(self, csv):
        with pytest.raises(DataError, match=r"gap_policy 'interpolate' not one of"):
            read_dataset(csv, "csv", RATE, NAMES, UNITS, gap_policy="interpolate")

    @pytest.mark.parametrize(
        ("text", "message"),
        [
            ("x:y,y:y,z:z", "permutation"),
            ("x:-w,y:x,z:z", "other than x, y, z"),
            ("x:y,x:x,z:z", "given twice"),
        ],
    )
    def test_bad_axis_map(self, csv, text, message):
        with pytest.raises(DataError, match=rf"axis_map '{text}'.*{message}"):
            read_dataset(csv, "csv", RATE, NAMES, UNITS, axis_map=text)

    @pytest.mark.parametrize("suffix", [".npy", ".npz", ".nc", ".rda", ".mcap"])
    def test_truncated_binary_file(self, tmp_path, signals, suffix):
        data, t = signals
        path = tmp_path / f"imu{suffix}"
        if suffix == ".npy":
            np.save(path, np.column_stack([data[k] for k in ALL_KEYS]))
        elif suffix == ".npz":
            np.savez(path, **{NAMES[k]: data[k] for k in ALL_KEYS})
        elif suffix == ".nc":
            TestNetcdf.write(path, data, t)
        elif suffix == ".rda":
            write_r_matrix(
                path, np.column_stack([data[k] for k in ALL_KEYS]), [ADIS_NAMES[k] for k in ALL_KEYS]
            )
        else:
            bag = TestRosbag.write(
                tmp_path / "bag", {k: v * SI[k[0]] for k, v in data.items()}, (t * 1e9).astype(int), "mcap"
            )
            path.write_bytes(next(bag.glob("*.mcap")).read_bytes())
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
        channels = {k: i for i, k in enumerate(ALL_KEYS)} if suffix == ".npy" else None
        channels = ADIS_NAMES if suffix == ".rda" else channels
        channels = NAMES if suffix in (".npz", ".nc") else channels
        with pytest.raises(DataError, match=rf"imu\{suffix}: .*(empty or truncated|too few|non-finite)"):
            read_dataset(path, "auto", RATE, channels, UNITS if suffix != ".mcap" else None)


# ---------------------------------------------------------------------------------------------
# the dataset sheet
# ---------------------------------------------------------------------------------------------
class TestSheetRow:
    def row(self, **cells):
        row = dict.fromkeys(SHEET_COLUMNS, "")
        row |= {
            "dataset": "bench",
            "path": "imu.csv",
            "format": "csv",
            "rate_hz": "100",
            "gyro_unit": "deg/s",
            "accel_unit": "g",
            "time_column": "t",
        }
        row |= {f"{s}_{a}": NAMES[(s, a)] for s, a in ALL_KEYS}
        return row | cells

    def test_row_maps_onto_read_dataset(self, tmp_path, signals):
        write_csv(tmp_path / "imu.csv", csv_columns(signals))
        rec = read_dataset_row(self.row(), base_dir=tmp_path)
        assert_si(rec, signals[0])
        assert rec.rate_hz == RATE
        # a gyro-only dataset (blank accel cells, as pandas gives them) with a rotated frame
        blank = {f"accel_{a}": float("nan") for a in "xyz"} | {"accel_unit": float("nan")}
        rec = read_dataset_row(self.row(axis_map="x:y,y:-x,z:z", **blank), base_dir=tmp_path)
        assert rec.sensors == ("gyro",)
        np.testing.assert_allclose(rec["gyro", "y"], -signals[0][("gyro", "x")] * DEG)

    def test_blank_cells_are_absent_and_numbers_are_parsed(self):
        kwargs = sheet_row_to_kwargs(
            self.row(accel_x="", accel_y=None, accel_z=float("nan"), gyro_z=2.0, delimiter=" ")
        )
        assert kwargs["rate_hz"] == 100.0
        assert kwargs["channels"][("gyro", "z")] == 2
        assert ("accel", "x") not in kwargs["channels"]
        assert "delimiter" not in kwargs  # a blank cell; a whitespace-separated file is delimiter=space

    def test_bad_rate_names_the_dataset(self):
        with pytest.raises(DataError, match=r"dataset 'bench': rate_hz = '100Hz' is not a number"):
            sheet_row_to_kwargs(self.row(rate_hz="100Hz"))

    def test_min_duration_passes_through(self, tmp_path, signals):
        write_csv(tmp_path / "imu.csv", csv_columns(signals))
        with pytest.raises(DataError, match=r"shorter than the 3600 s needed"):
            read_dataset_row(self.row(), base_dir=tmp_path, min_duration_s=3600.0)


def test_parse_axis_map():
    assert parse_axis_map("x:-y,y:x,z:z") == {"x": (-1, "y"), "y": (1, "x"), "z": (1, "z")}
    assert parse_axis_map(None) == {"x": (1, "x"), "y": (1, "y"), "z": (1, "z")}
    assert parse_axis_map({"x": "z", "y": "+y", "z": "-x"}) == {"x": (1, "z"), "y": (1, "y"), "z": (-1, "x")}


# ---------------------------------------------------------------------------------------------
# the real ADIS16405 record (../shared/data)
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="session")
def adis_imu1(shared_data):
    """imu1 read once per session (xz-compressed 3 MB .rda, about 1 s)."""
    path = shared_data / "adis16405" / "raw" / "adis_16405_imu1.rda"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the real file must read without any warning
        return read_dataset(
            path, "rda", 100.0, ADIS_NAMES, {"gyro": "deg/s", "accel": "g"}, min_duration_s=5000.0
        )


@pytest.mark.shared_data
class TestAdis16405:
    def test_shape_rate_and_units(self, adis_imu1):
        rec = adis_imu1
        assert list(rec) == ALL_KEYS
        assert rec.n_samples == 1_000_000 and rec.rate_hz == 100.0 and rec.duration_s == 10_000.0
        assert rec.source.endswith("(rdata, object 'adis_16405_imu1')")
        assert {rec.units[k] for k in ALL_KEYS} == {"rad/s", "m/s^2"}

    def test_first_samples_converted_to_si(self, adis_imu1):
        # first row of the R matrix: -0.05 -0.3 0.7 deg/s, -0.00666 0 -1.01565 g
        first = [adis_imu1[k][0] for k in ALL_KEYS]
        expected = [-0.05 * DEG, -0.3 * DEG, 0.7 * DEG, -0.00666 * G0, 0.0, -1.01565 * G0]
        np.testing.assert_allclose(first, expected, rtol=1e-12, atol=0)

    def test_quantisation_steps_survive_and_accel_z_is_minus_one_g(self, adis_imu1):
        gyro_steps = np.unique(np.round(np.diff(np.unique(adis_imu1["gyro", "x"])) / DEG, 6))
        assert gyro_steps[0] == pytest.approx(0.05)  # deg/s, the ADIS16405 gyro LSB
        assert adis_imu1["accel", "z"].mean() / G0 == pytest.approx(-1.016, abs=5e-4)

    def test_too_short_for_a_day(self, shared_data):
        path = shared_data / "adis16405" / "raw" / "adis_16405_imu2.rda"
        with pytest.raises(
            DataError, match=r"record lasts 10000 s \(1000000 samples at 100 Hz\), shorter than the 86400 s"
        ):
            read_dataset(
                path, "rda", 100.0, ADIS_NAMES, {"gyro": "deg/s", "accel": "g"}, min_duration_s=86400.0
            )
