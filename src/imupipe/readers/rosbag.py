"""ROS 1 / ROS 2 bags and MCAP files of sensor_msgs/Imu."""

from __future__ import annotations

import itertools
import math
import re
import warnings
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import logging
import struct
import time

import numpy as np

from imupipe.readers._common import *  # noqa: F403
from imupipe.readers._common import _Raw, _blank, _chname, _default_specs, _resolve, _time_factor, Key, _ROS_FIELDS, SI_UNITS

log = logging.getLogger(__name__)


def _load_rosbag(path, specs, topic, time_column, where) -> _Raw:
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError as exc:
        raise DataError(
            f"{where}: reading ROS bags / MCAP needs the rosbags package (pip install rosbags)"
        ) from exc
    if specs is None:
        specs = dict(_ROS_FIELDS)
    unknown = [k for k, v in specs.items() if str(v) not in _FIELD_OFFSETS]
    if unknown:
        k = unknown[0]
        raise DataError(
            f"{where}: {_chname(k)} field {specs[k]!r} not in sensor_msgs/Imu; fields: "
            "angular_velocity.{x,y,z}, linear_acceleration.{x,y,z}"
        )
    source = "header" if _blank(time_column) else str(time_column).strip().lower()
    if source not in ("header", "bag"):
        raise DataError(
            f"{where}: time_column {time_column!r} for a bag must be 'header' (message stamps) or 'bag'"
        )
    files = _mcap_files(Path(path))
    if files is not None:  # MCAP: read directly, ~10x faster than through the rosbags reader
        t0 = time.perf_counter()
        try:
            found, raws, bag_ns = _scan_mcap(files, topic, where)
        except (_Unsupported, struct.error, UnicodeDecodeError, IndexError, ValueError):
            files = None  # rosbags reads it (or names what is wrong with it)
        else:
            if raws:
                log.info("%s: reading %d sensor_msgs/Imu messages of %r (MCAP)", where, bag_ns.size, found)
                stamps, values = _decode_imu(raws, cdr=True, where=where, topic=found)
                order = np.argsort(bag_ns, kind="stable")
                if np.any(order != np.arange(order.size)):  # chunks out of log-time order
                    stamps, bag_ns = stamps[order], bag_ns[order]
                    values = {k: v[order] for k, v in values.items()}
                if source == "bag":
                    stamps = bag_ns
                log.info("%s: decoded %d messages of %r in %.2f s", where, bag_ns.size, found, time.perf_counter() - t0)
                return _imu_raw(values, stamps, specs, found, source)
            files = None
    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except Exception as exc:  # rosbags raises its own error classes on corrupt input
        raise DataError(f"{where}: not a readable ROS bag / MCAP file (empty or truncated?): {exc}") from exc
    try:
        imu = [c for c in reader.connections if c.msgtype.replace("/msg/", "/") == "sensor_msgs/Imu"]
        listing = ", ".join(sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})) or "none"
        if _blank(topic):
            topics = sorted({c.topic for c in imu})
            if len(topics) != 1:
                raise DataError(
                    f"{where}: {len(topics)} sensor_msgs/Imu topics; give `topic`; topics: {listing}"
                )
            topic = topics[0]
        conns = [c for c in reader.connections if c.topic == topic]
        if not conns:
            raise DataError(f"{where}: topic {topic!r} not found; topics: {listing}")
        if not all(c in imu for c in conns):
            raise DataError(f"{where}: topic {topic!r} carries {conns[0].msgtype}, not sensor_msgs/Imu")
        total = sum(int(getattr(c, "msgcount", 0) or 0) for c in conns)
        log.info("%s: reading %s sensor_msgs/Imu messages of %r", where, total or "the", topic)
        t0 = time.perf_counter()
        raws: list[bytes] = []
        bag_ns: list[int] = []
        keep_raw, keep_ns = raws.append, bag_ns.append
        try:
            for _, ns, raw in reader.messages(connections=conns):
                keep_raw(raw)
                keep_ns(ns)
        except Exception as exc:  # rosbags' reader errors on a corrupt bag
            raise DataError(
                f"{where}: message {len(raws)} (0-based) on {topic!r} cannot be read (truncated or corrupt "
                f"file?): {exc}"
            ) from exc
        if not raws:
            raise DataError(f"{where}: topic {topic!r} holds no messages")
        stamps, values = _decode_imu(raws, cdr=reader.is2, where=where, topic=topic)
        if source == "bag":
            stamps = np.asarray(bag_ns, dtype=np.int64)
        log.info("%s: decoded %d messages of %r in %.2f s", where, len(raws), topic, time.perf_counter() - t0)
    finally:
        reader.close()
    return _imu_raw(values, stamps, specs, topic, source)


def _imu_raw(values, ns, specs, topic, source) -> _Raw:
    values = {k: values[str(v)] for k, v in specs.items()}
    return _Raw(
        data=values,
        names={k: f"{topic}:{specs[k]}" for k in specs},
        time=(ns - ns[0]).astype(np.float64) * 1e-9,  # s after the first message: no loss of precision
        time_name=f"{topic} {'header.stamp' if source == 'header' else 'bag time'} (t from the first message)",
        default_units=dict(SI_UNITS),  # sensor_msgs/Imu is SI by definition (REP 103/145)
        detail=f"topic {topic!r}",
    )


# sensor_msgs/Imu after the header: orientation (4 float64), orientation_covariance (9),
# angular_velocity (3), angular_velocity_covariance (9), linear_acceleration (3), its covariance (9)
_FIELD_OFFSETS = {
    **{f"angular_velocity.{a}": 8 * (13 + i) for i, a in enumerate(AXES)},
    **{f"linear_acceleration.{a}": 8 * (25 + i) for i, a in enumerate(AXES)},
}
_BODY_BYTES = 8 * 37


def _gather(buf: np.ndarray, offsets: np.ndarray, dtype: str, stride: int = 0) -> np.ndarray:
    """Values of `dtype` at byte `offsets` of `buf` (one per message).

    With ``stride`` > 0 (all messages of that length and ``offsets`` equally spaced by it, the usual case
    of one frame_id) a strided view of the byte matrix, else one fancy-indexing gather.
    """
    size = np.dtype(dtype).itemsize
    if stride and offsets.size and np.all(offsets - offsets[0] == np.arange(offsets.size) * stride):
        first = int(offsets[0])
        rows = np.lib.stride_tricks.as_strided(buf[first:], shape=(offsets.size, size), strides=(stride, 1))
        return np.ascontiguousarray(rows).view(dtype).ravel()
    idx = offsets[:, None] + np.arange(size)
    return np.ascontiguousarray(buf[idx]).view(dtype).ravel()


def _decode_imu(raws: list, *, cdr: bool, where: str, topic: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Header stamps (ns) and the six rate fields of serialised sensor_msgs/Imu messages, in bulk.

    Layouts: ROS 2 CDR (4-byte encapsulation header, then ``stamp.sec`` int32, ``stamp.nanosec`` uint32,
    ``frame_id`` (uint32 length incl. NUL, bytes), padding to 8 bytes counted from the end of the
    encapsulation header, 37 float64); ROS 1 (``seq``, ``stamp.secs``, ``stamp.nsecs`` uint32,
    ``frame_id`` (uint32 length, bytes), 37 float64, no padding). The frame_id length is read per message,
    so messages of different frame ids decode together. Every message's length is checked against the
    layout: a message that does not fit is named. `raws` holds one bytes-like object per message, or
    2-D uint8 arrays of equal-length messages (one per row).
    """
    if any(isinstance(e, np.ndarray) for e in raws):  # blocks of equal-length messages (direct MCAP reader)
        lengths = np.concatenate(
            [np.full(e.shape[0], e.shape[1]) if isinstance(e, np.ndarray) else [len(e)] for e in raws]
        ).astype(np.int64)
    else:
        lengths = np.fromiter(map(len, raws), dtype=np.int64, count=len(raws))
    n = lengths.size
    starts = np.zeros(n, dtype=np.int64)
    np.cumsum(lengths[:-1], out=starts[1:])
    buf = np.frombuffer(b"".join(raws), dtype=np.uint8)
    stride = int(lengths[0]) if np.all(lengths == lengths[0]) else 0  # one message size: strided views
    g = lambda offsets, dtype: _gather(buf, offsets, dtype, stride)  # noqa: E731
    short = np.flatnonzero(lengths < 16)
    if short.size:
        i = int(short[0])
        raise DataError(f"{where}: message {i} (0-based) on {topic!r} is {lengths[i]} bytes: too short for sensor_msgs/Imu")
    if cdr:
        kind = buf[starts + 1]
        if not np.all(kind == kind[0]) or kind[0] not in (0, 1):
            i = int(np.flatnonzero(kind != kind[0])[0]) if not np.all(kind == kind[0]) else 0
            raise DataError(f"{where}: message {i} (0-based) on {topic!r}: unsupported CDR encapsulation {int(kind[i])}")
        e = "<" if kind[0] == 1 else ">"
        base = 4
        sec = g(starts + base, f"{e}i4").astype(np.int64)
        nsec = g(starts + base + 4, f"{e}u4").astype(np.int64)
        strlen = g(starts + base + 8, f"{e}u4").astype(np.int64)
        pos = base + 12 + strlen
        body = base + ((pos - base + 7) // 8) * 8
    else:
        e = "<"
        sec = g(starts + 4, "<u4").astype(np.int64)
        nsec = g(starts + 8, "<u4").astype(np.int64)
        strlen = g(starts + 12, "<u4").astype(np.int64)
        body = 16 + strlen
    bad = np.flatnonzero(body + _BODY_BYTES > lengths)
    if bad.size:
        i = int(bad[0])
        raise DataError(
            f"{where}: message {i} (0-based) on {topic!r} is {lengths[i]} bytes, shorter than a sensor_msgs/Imu "
            f"with a {strlen[i]}-byte frame_id ({body[i] + _BODY_BYTES} bytes): truncated or another type"
        )
    values = {name: g(starts + body + off, f"{e}f8").astype(np.float64) for name, off in _FIELD_OFFSETS.items()}
    return sec * 1_000_000_000 + nsec, values


# --- MCAP, read directly ---------------------------------------------------------------------
# The MCAP container (https://mcap.dev/spec): magic b"\x89MCAP0\r\n", then records of opcode (uint8),
# length (uint64 LE) and content; strings are uint32 length + UTF-8, byte arrays uint64 length + bytes.
_MCAP_MAGIC = b"\x89MCAP0\r\n"
_OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK = 0x03, 0x04, 0x05, 0x06


class _Unsupported(Exception):
    """An MCAP feature the direct reader does not handle: the caller falls back to rosbags."""


def _mcap_files(path: Path) -> list[Path] | None:
    if path.is_file():
        return [path] if path.suffix.lower() == ".mcap" else None
    files = sorted(path.glob("*.mcap"))
    others = [p for p in path.iterdir() if p.suffix.lower() in (".db3", ".bag")]
    return files if files and not others else None


def _string(buf, pos):
    (n,) = struct.unpack_from("<I", buf, pos)
    return bytes(buf[pos + 4 : pos + 4 + n]).decode("utf-8"), pos + 4 + n


def _decompress(kind: str, data: bytes, size: int) -> bytes:
    if kind == "":
        return data
    if kind == "lz4":
        import lz4.frame

        return lz4.frame.decompress(data)
    if kind == "zstd":
        try:
            from compression import zstd  # Python >= 3.14
        except ImportError:
            try:
                from backports import zstd  # what rosbags depends on
            except ImportError:
                raise _Unsupported("zstd") from None
        return zstd.decompress(data)
    raise _Unsupported(kind)


def _scan_mcap(files: list[Path], topic: str | None, where: str):
    """(topic, messages, log times ns) of the sensor_msgs/Imu channel of MCAP files, in file order.

    Reads the file once: schema and channel records at the top level or in chunks, message records of
    the selected channel sliced out of each (decompressed) chunk: a chunk of equal-length message records
    of the wanted channel as one 2-D array view, else one tight loop per record (struct.unpack_from); no
    deserialisation. The caller sorts by log time (MCAP does not require chunks in time order).
    """
    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, int, str]] = {}
    raws: list[bytes] = []
    times: list[int] = []
    wanted: set[int] = set()

    def records(buf, pos, end, top):
        nonlocal wanted
        unpack = struct.unpack_from
        keep_raw, keep_t = raws.append, times.append
        if not top and end - pos > 9 and buf[pos] == _OP_MESSAGE and wanted:
            # a chunk of message records of one length (the usual case): one numpy view, no loop
            stride = 9 + unpack("<Q", buf, pos + 1)[0]
            if (end - pos) % stride == 0 and stride > 31:
                rows = np.frombuffer(buf, dtype=np.uint8)[pos:end].reshape(-1, stride)
                same = np.all(rows[:, 0] == _OP_MESSAGE) and np.all(
                    np.ascontiguousarray(rows[:, 1:9]).view("<u8").ravel() == stride - 9
                )
                cids = np.ascontiguousarray(rows[:, 9:11]).view("<u2").ravel()
                if same and np.all(np.isin(cids, list(wanted))):
                    keep_raw(np.ascontiguousarray(rows[:, 31:]))
                    times.extend(np.ascontiguousarray(rows[:, 15:23]).view("<u8").ravel().tolist())
                    return
        while pos + 9 <= end:
            op = buf[pos]
            (length,) = unpack("<Q", buf, pos + 1)
            body = pos + 9
            if body + length > end:
                raise DataError(
                    f"{where}: not a readable MCAP file (empty or truncated?): a record at byte {pos} runs "
                    f"{body + length - end} bytes past the end{' of its chunk' if not top else ''}"
                )
            pos = body + length
            if op == _OP_MESSAGE:
                cid, _, log_time = unpack("<HIQ", buf, body)
                if cid in wanted:
                    keep_raw(buf[body + 22 : pos])
                    keep_t(log_time)
            elif op == _OP_CHUNK and top:
                kind, p = _string(buf, body + 28)
                (size,) = unpack("<Q", buf, p)
                data = _decompress(kind, bytes(buf[p + 8 : p + 8 + size]), unpack("<Q", buf, body + 16)[0])
                records(memoryview(data), 0, len(data), False)
            elif op == _OP_SCHEMA:
                (sid,) = unpack("<H", buf, body)
                name, _ = _string(buf, body + 2)
                schemas[sid] = name
            elif op == _OP_CHANNEL:
                cid, sid = unpack("<HH", buf, body)
                name, p = _string(buf, body + 4)
                encoding, _ = _string(buf, p)
                channels[cid] = (name, sid, encoding)
                is_imu = schemas.get(sid, "").replace("/msg/", "/") == "sensor_msgs/Imu"
                if is_imu and (_blank(topic) or name == topic):
                    if encoding != "cdr":
                        raise _Unsupported(f"message encoding {encoding}")
                    wanted = wanted | {cid}

    for file in files:
        with open(file, "rb") as fh:
            data = fh.read()
        if not data.startswith(_MCAP_MAGIC):
            raise _Unsupported("not an MCAP file")
        if not data.endswith(_MCAP_MAGIC) or len(data) < 2 * len(_MCAP_MAGIC):
            raise DataError(f"{file}: not a readable MCAP file (empty or truncated?): no closing magic bytes")
        end = len(data) - len(_MCAP_MAGIC)
        records(memoryview(data), len(_MCAP_MAGIC), end, True)
    imu_topics = sorted({channels[c][0] for c in wanted})
    if len(imu_topics) != 1:
        raise _Unsupported("topic selection")  # rosbags names the topics in its message
    return imu_topics[0], raws, np.asarray(times, dtype=np.int64)
