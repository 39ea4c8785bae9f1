"""`penelope demo`'s run.mcap read by an independent reader: the official `mcap` Python package
(Foxglove's), and each message checked against its channel's JSON Schema with `jsonschema`.

Checks: every channel has a schema, in `jsonschema`, that is a valid JSON Schema; every message
is JSON that its schema accepts; each controller's channel holds one message per control tick
(sequence numbers 1..N without a gap, log times one control period apart, N = duration x rate);
the summary's per-channel counts and the `recorder` metadata agree with the messages read."""

from __future__ import annotations

import json
import subprocess
from collections import defaultdict
from pathlib import Path

import jsonschema
from mcap.reader import make_reader

DURATION_S = 2
PERIOD_NS = 1_000_000  # the demo's control period (config/demo.toml: period_us = 1000)


def test_the_demos_mcap_file_opens_with_the_official_reader(
    penelope_bin: str, tmp_path: Path
) -> None:
    out = tmp_path / "demo"
    run = subprocess.run(
        [penelope_bin, "demo", "--sim-clock", "--duration", f"{DURATION_S}s", "--json",
         "--out", str(out)],
        capture_output=True, text=True, timeout=300,
    )
    assert run.returncode == 0, run.stderr
    path = out / "run.mcap"

    with path.open("rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        assert header.profile == "penelope"
        summary = reader.get_summary()
        assert summary is not None, "the file has a summary section"

        # Every channel has a schema, in JSON Schema, that is itself a valid schema.
        validators = {}
        for cid, channel in summary.channels.items():
            assert channel.schema_id != 0, f"{channel.topic} has no schema"
            schema = summary.schemas[channel.schema_id]
            assert schema.encoding == "jsonschema", channel.topic
            assert channel.message_encoding == "json", channel.topic
            document = json.loads(schema.data)
            jsonschema.Draft202012Validator.check_schema(document)
            validators[cid] = jsonschema.Draft202012Validator(document)
        topics = {c.topic for c in summary.channels.values()}
        assert {"/controllers/display", "/controllers/follow", "/safety", "/recorder"} <= topics

        counts: dict[str, int] = defaultdict(int)
        ticks: dict[str, list[tuple[int, int]]] = defaultdict(list)
        for _schema, channel, message in reader.iter_messages(log_time_order=False):
            value = json.loads(message.data)
            validators[channel.id].validate(value)
            counts[channel.topic] += 1
            if channel.topic.startswith("/controllers/"):
                sample = value["sample"]
                assert sample["time"] == message.log_time
                ticks[channel.topic].append((sample["seq"], message.log_time))
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}

    # One message per control tick per controller.
    expected = DURATION_S * 1_000_000_000 // PERIOD_NS
    for topic in ("/controllers/display", "/controllers/follow"):
        seqs = [s for s, _ in ticks[topic]]
        times = [t for _, t in ticks[topic]]
        assert len(seqs) == expected, topic
        assert seqs == list(range(seqs[0], seqs[0] + expected)), f"{topic}: a gap"
        assert all(b - a == PERIOD_NS for a, b in zip(times, times[1:])), topic

    # The summary's counts and the recorder's metadata agree with what was read.
    stats = summary.statistics
    assert stats is not None
    assert stats.message_count == sum(counts.values())
    for cid, channel in summary.channels.items():
        assert stats.channel_message_counts[cid] == counts[channel.topic], channel.topic
    recorder = metadata["recorder"]
    for name in ("display", "follow"):
        assert int(recorder[f"written.{name}"]) == counts[f"/controllers/{name}"]
        assert int(recorder[f"dropped.{name}"]) == 0
    assert "system" in metadata["run"], "the run record (for `penelope recording rerun`)"
