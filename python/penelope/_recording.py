"""Reading a Penelope recording (MCAP, profile ``penelope``) into NumPy arrays, on the official
``mcap`` reader (Foxglove's, ``pip install mcap``: an optional dependency, imported on use)."""

from __future__ import annotations

import json
import os
from typing import Any, Dict, List, Union

import numpy as np
import numpy.typing as npt

#: One channel's arrays, by field.
Channel = Dict[str, npt.NDArray[Any]]

_CONTROLLERS = "/controllers/"
_LINKS = "/links/"
_JOINT_FIELDS = ("q", "qd", "effort")
_LINK_INTS = (
    "losses", "restorations", "samples_taken", "samples_dropped", "samples_missed", "refused",
    "trips",
)
_LINK_OPTIONAL_NS = (
    "clock_offset_ns", "round_trip_ns", "one_way_delay_ns", "jitter_ns", "last_heard_ns",
    "trip_p50_ns", "trip_p99_ns", "trip_max_ns",
)


def _f64(rows: List[Any]) -> npt.NDArray[np.float64]:
    return np.array(rows, dtype=np.float64)


def _optional(values: List[Any]) -> npt.NDArray[np.float64]:
    """Numbers that may be null, as floats with NaN for null."""
    return np.array([np.nan if v is None else float(v) for v in values], dtype=np.float64)


def _ticks(messages: List[Dict[str, Any]]) -> Channel:
    samples = [m["sample"] for m in messages]
    out: Channel = {
        "time_ns": np.array([s["time"] for s in samples], dtype=np.int64),
        "seq": np.array([s["seq"] for s in samples], dtype=np.int64),
        "state": np.array([s["state"] for s in samples], dtype=np.str_),
    }
    out["time"] = out["time_ns"].astype(np.float64) * 1e-9
    for k in _JOINT_FIELDS:
        out[k] = _f64([s[k] for s in samples])
    if all("tool_position" in s for s in samples):
        out["tool_position"] = _f64([s["tool_position"] for s in samples])
    for wrench, prefix in (("wrench", ""), ("commanded_wrench", "commanded_")):
        if all(wrench in s for s in samples):
            out[prefix + "force"] = _f64([s[wrench]["force"] for s in samples])
            out[prefix + "torque"] = _f64([s[wrench]["torque"] for s in samples])
    for k in ("port_energy", "channel_energy"):
        if all(k in s for s in samples):
            out[k] = _optional([s[k] for s in samples])
    if all("clutch" in m for m in messages):
        # null (no hand holds the robot) as -1, else 0 / 1.
        out["clutch"] = np.array(
            [-1 if m["clutch"] is None else int(m["clutch"]) for m in messages], dtype=np.int8
        )
    truths: List[Dict[str, Any]] = [m["truth"] for m in messages if m.get("truth") is not None]
    if truths and len(truths) == len(messages):
        for k in _JOINT_FIELDS:
            out["truth_" + k] = _f64(
                [t["joints"][{"q": "position", "qd": "velocity", "effort": "effort"}[k]]
                 for t in truths]
            )
    return out


def _links(messages: List[Dict[str, Any]]) -> Channel:
    out: Channel = {
        "time_ns": np.array([m["time_ns"] for m in messages], dtype=np.int64),
        "down": np.array([bool(m["down"]) for m in messages], dtype=np.bool_),
    }
    out["time"] = out["time_ns"].astype(np.float64) * 1e-9
    for k in _LINK_INTS:
        out[k] = np.array([m.get(k, 0) for m in messages], dtype=np.int64)
    for k in _LINK_OPTIONAL_NS:
        out[k] = _optional([m.get(k) for m in messages])
    out["heartbeat_loss"] = _f64([m.get("heartbeat_loss", 0.0) for m in messages])
    return out


def read_recording(path: Union[str, "os.PathLike[str]"]) -> Dict[str, Channel]:
    """Reads the recording at ``path`` into NumPy arrays, one dict per channel, by topic:

    - ``/controllers/<name>``: one row per control tick: ``time_ns`` and ``seq`` (int64),
      ``time`` (s), ``q``, ``qd``, ``effort`` (ticks x joints), ``tool_position`` (ticks x 3),
      ``force``, ``torque``, ``commanded_force``, ``commanded_torque`` (ticks x 3, base
      frame), ``state`` (strings), ``port_energy`` / ``channel_energy`` (NaN where the law has
      none), ``clutch`` (-1 no hand, 0 released, 1 held) and, behind a simulated board, the
      plant's ``truth_q``, ``truth_qd``, ``truth_effort``;
    - ``/links/<channel>``: one row per statistics record (``time_ns``, ``down``, the counts,
      the delays in ns with NaN while not estimated, ``heartbeat_loss``).

    Messages are taken in log-time order. Other topics (safety events, the 3D scene, the
    recorder's losses) are not arrays and are left out. Needs the ``mcap`` package."""
    from mcap.reader import make_reader

    per_topic: Dict[str, List[Dict[str, Any]]] = {}
    with open(os.fspath(path), "rb") as f:
        reader = make_reader(f)
        for _schema, channel, message in reader.iter_messages(log_time_order=True):
            topic = channel.topic
            if channel.message_encoding != "json":
                continue
            if topic.startswith(_CONTROLLERS) or topic.startswith(_LINKS):
                per_topic.setdefault(topic, []).append(json.loads(message.data))
    return {
        topic: (_ticks(msgs) if topic.startswith(_CONTROLLERS) else _links(msgs))
        for topic, msgs in per_topic.items()
    }
