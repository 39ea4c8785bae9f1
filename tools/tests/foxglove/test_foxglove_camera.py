"""`penelope foxglove` in front of the demo with a camera (`config/demo-camera.toml`): per camera,
`/<camera>/image` (foxglove.CompressedImage), `/<camera>/calibration`
(foxglove.CameraCalibration), `/<camera>/annotations` (foxglove.ImageAnnotations) and
`/<camera>/force` (penelope.AlignedForce), each frame's annotations and force stamped with the
frame's capture instant, the force the one measured then (residual skew under a frame period)."""

from __future__ import annotations

import base64
import json
import math
from typing import Iterator

import jsonschema
import pytest

from conftest import REPO, FoxgloveClient, System

WAIT_S = 90.0
FRAMES = 20
CAMERA_DEMO = REPO / "config" / "demo-camera.toml"


@pytest.fixture
def camera_demo(penelope_bin: str) -> Iterator[System]:
    s = System(penelope_bin, [], [], system=CAMERA_DEMO)
    yield s
    s.stop()


def stamp_ns(m: dict) -> int:
    return m["timestamp"]["sec"] * 1_000_000_000 + m["timestamp"]["nsec"]


def percentile(values, p: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, math.ceil(p * len(ordered)) - 1))]


def test_camera_channels_are_advertised_and_each_frames_annotations_carry_its_capture_stamp(
        camera_demo: System):
    client = FoxgloveClient(camera_demo.url)
    try:
        images = lambda: [c for c in client.channels.values()  # noqa: E731
                          if c["schemaName"] == "foxglove.CompressedImage"]
        client.pump_until(lambda: images(), WAIT_S, "a camera's image channel")
        topic = images()[0]["topic"]
        assert topic.endswith("/image"), topic
        camera = topic[:-len("/image")]
        expected = {f"{camera}/image": "foxglove.CompressedImage",
                    f"{camera}/calibration": "foxglove.CameraCalibration",
                    f"{camera}/annotations": "foxglove.ImageAnnotations",
                    f"{camera}/force": "penelope.AlignedForce"}
        client.pump_until(lambda: all(client.channel(t) for t in expected), WAIT_S,
                          "the camera's four channels")
        for t, name in expected.items():
            c = client.channel(t)
            assert c["schemaName"] == name, (t, c["schemaName"])
            assert json.loads(c["schema"])["title"] == name
        subs = {t: client.subscribe(t) for t in expected}
        client.pump_until(
            lambda: all(len(client.messages.get(subs[t], [])) >= FRAMES for t in expected),
            WAIT_S, f"{FRAMES} frames with their calibration, annotations and force")
        got = {t: client.messages[subs[t]] for t in expected}
        schemas = {t: json.loads(client.channel(t)["schema"]) for t in expected}
        for t in expected:
            for _, m in got[t][:2] + got[t][-2:]:
                jsonschema.validate(m, schemas[t])
            # Every message's time is its capture stamp.
            for log_time, m in got[t]:
                assert log_time == stamp_ns(m), (t, log_time, m["timestamp"])
        image_stamps = [stamp_ns(m) for _, m in got[f"{camera}/image"]]
        assert base64.b64decode(got[f"{camera}/image"][0][1]["data"])[:2] == b"\xff\xd8"
        # Each frame's annotations carry its capture stamp, and the force arrow.
        annotated = {stamp_ns(m): m for _, m in got[f"{camera}/annotations"]}
        common = [s for s in image_stamps if s in annotated]
        assert len(common) >= len(image_stamps) - 3, (len(common), len(image_stamps))
        with_arrow = [s for s in common if annotated[s]["points"]]
        assert len(with_arrow) >= len(common) // 2, "most frames show the force arrow"
        for s in common:
            m = annotated[s]
            assert all(stamp_ns(x) == s for x in m["points"] + m["texts"] + m["circles"])
            assert "the hand" in m["texts"][0]["text"] or m["texts"][0]["text"] == "no force yet"
        # The force sample is the one measured at the capture instant.
        periods = [b - a for a, b in zip(image_stamps, image_stamps[1:]) if b > a]
        frame_period = percentile(periods, 0.5)
        forces = [m for _, m in got[f"{camera}/force"]]
        # The first frames may be older than the robot's first sample (its subscription opens
        # with the camera's): they say so ("oldest") and are left out, a few at most.
        leading = next((k for k, m in enumerate(forces) if m["how"] != "oldest"), len(forces))
        assert leading <= 5, f"{leading} frames before the robot's first sample"
        assert all(m["how"] in ("interpolated", "nearest") for m in forces[leading:])
        residual = [abs(m["residual_skew_ms"]) * 1e6 for m in forces[leading:]]
        unaligned = [abs(m["unaligned_skew_ms"]) * 1e6 for _, m in got[f"{camera}/force"]
                     if m["unaligned_skew_ms"] is not None]
        print(f"{len(image_stamps)} frames ({leading} before the first sample), period {frame_period / 1e6:.1f} ms; residual skew "
              f"p50 {percentile(residual, 0.5) / 1e6:.2f} ms p99 {percentile(residual, 0.99) / 1e6:.2f}"
              f" ms; unaligned p50 {percentile(unaligned, 0.5) / 1e6:.1f} ms; operator skew "
              f"{got[f'{camera}/force'][-1][1]['operator_skew_ms']} ms")
        assert percentile(residual, 0.99) < frame_period
    finally:
        client.close()
