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

import numpy as np

from imupipe.readers._common import *  # noqa: F403
from imupipe.readers._common import _Raw, _blank, _chname, _default_specs, _resolve, _time_factor, Key, _ROS_FIELDS, _SI_UNITS


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
    source = "header" if _blank(time_column) else str(time_column).strip().lower()
    if source not in ("header", "bag"):
        raise DataError(
            f"{where}: time_column {time_column!r} for a bag must be 'header' (message stamps) or 'bag'"
        )
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
        paths = {k: str(v).split(".") for k, v in specs.items()}
        values: dict[Key, list[float]] = {k: [] for k in specs}
        stamps: list[int] = []
        messages = reader.messages(connections=conns)
        while True:
            try:
                conn, bag_ns, raw = next(messages)
                msg = reader.deserialize(raw, conn.msgtype)
            except StopIteration:
                break
            except Exception as exc:  # rosbags' reader and deserializer errors on a corrupt bag
                raise DataError(
                    f"{where}: message {len(stamps)} (0-based) on {topic!r} cannot be read (truncated or corrupt "
                    f"file?): {exc}"
                ) from exc
            if source == "header":
                stamps.append(int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec))
            else:
                stamps.append(int(bag_ns))
            for key, fields in paths.items():
                value = msg
                try:
                    for f in fields:
                        value = getattr(value, f)
                except AttributeError:
                    raise DataError(
                        f"{where}: {_chname(key)} field {specs[key]!r} not in sensor_msgs/Imu; fields: "
                        "angular_velocity.{x,y,z}, linear_acceleration.{x,y,z}"
                    ) from None
                values[key].append(float(value))
    finally:
        reader.close()
    if not stamps:
        raise DataError(f"{where}: topic {topic!r} holds no messages")
    ns = np.asarray(stamps, dtype=np.int64)
    return _Raw(
        data={k: np.asarray(v, dtype=np.float64) for k, v in values.items()},
        names={k: f"{topic}:{specs[k]}" for k in specs},
        time=(ns - ns[0]).astype(np.float64) * 1e-9,  # s after the first message: no loss of precision
        time_name=f"{topic} {'header.stamp' if source == 'header' else 'bag time'} (t from the first message)",
        default_units=dict(_SI_UNITS),  # sensor_msgs/Imu is SI by definition (REP 103/145)
        detail=f"topic {topic!r}",
    )


