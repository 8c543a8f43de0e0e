"""run.mcap read back with the mcap reader: Foxglove schemas, topics, message counts, the time
series' values equal to the parquet's, and frame rotations equal to the logged attitudes."""

import json

import numpy as np
import pytest
from mcap.reader import make_reader
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

import aerorelay as ar
from aerorelay.cli import app
from aerorelay.models.geometry import rotation_zyx
from aerorelay.report.mcap_export import numeric_columns, quaternion_xyzw


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("mcap") / "run"
    sc = ar.load_scenario("scenarios/moving_jammer.toml", set={"sim.duration_s": 1.5})
    res = ar.simulate(sc)
    res.save(out)
    return out, res


def test_schemas_topics_and_counts(run):
    out, res = run
    n = len(res.timeseries)
    with open(out / "run.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    topics = {c.topic: (summary.schemas[c.schema_id].name, summary.statistics.channel_message_counts[cid])
              for cid, c in summary.channels.items()}
    assert topics["/tf"] == ("foxglove.FrameTransforms", n)
    assert topics["/scene"] == ("foxglove.SceneUpdate", (n + 4) // 5)
    assert topics["/scene/static"] == ("foxglove.SceneUpdate", 1)
    assert topics["/timeseries"] == ("aerorelay.Timeseries", n)


def test_timeseries_values_equal_the_parquet(run):
    out, res = run
    df = res.timeseries
    cols = numeric_columns(df)
    with open(out / "run.mcap", "rb") as f:
        rows = [(msg.log_time, json.loads(msg.data)) for _, ch, msg in make_reader(f).iter_messages(topics=["/timeseries"])]
    assert len(rows) == len(df)
    for k in (0, len(df) // 2, len(df) - 1):
        log_time, row = rows[k]
        assert log_time == round(df["t"].iloc[k] * 1e9)
        for c in cols:
            assert row[c] == pytest.approx(float(df[c].iloc[k]), rel=1e-12, abs=1e-300), c


@pytest.mark.parametrize("eta", [(0.1, -0.2, 0.3), (1.0, 0.5, -2.0), (0.0, 0.0, np.pi)])
def test_quaternion_is_the_zyx_rotation(eta):
    R = Rotation.from_quat(quaternion_xyzw(*eta)).as_matrix()  # scipy: (x, y, z, w)
    np.testing.assert_allclose(R, rotation_zyx(np.array(eta)), atol=1e-12)


def test_export_command_for_a_run_without_mcap(run, tmp_path):
    out, _ = run
    (out / "run.mcap").unlink()
    res = CliRunner().invoke(app, ["export", str(out), "--format", "mcap"])
    assert res.exit_code == 0 and (out / "run.mcap").stat().st_size > 0, res.output
    bad = CliRunner().invoke(app, ["export", str(tmp_path)])
    assert bad.exit_code == 2 and "not an aerorelay run folder" in bad.output


def test_a_fleets_mcap_has_every_vehicle_and_every_hop(tmp_path):
    """Counts from the summary; frame and entity names read from the protobuf bytes (strings are
    stored as they are), the time series as JSON."""
    import re

    sc = ar.load_scenario("scenarios/two_sources.toml", set={"sim.duration_s": 0.5})
    res = ar.simulate(sc)
    res.save(tmp_path / "run")
    n = len(res.timeseries)
    first: dict[str, bytes] = {}
    with open(tmp_path / "run" / "run.mcap", "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        counts = {c.topic: summary.statistics.channel_message_counts[cid] for cid, c in summary.channels.items()}
        for _schema, channel, message in reader.iter_messages(topics=["/tf", "/scene", "/timeseries"]):
            first.setdefault(channel.topic, message.data)
    assert counts["/tf"] == n and counts["/timeseries"] == n and counts["/scene"] == (n + 4) // 5
    assert all(name.encode() in first["/tf"] for name in ("r1", "r2", "north", "south"))
    links = set(re.findall(rb"link_[a-z0-9]+_[a-z0-9]+", first["/scene"]))
    assert links == {b"link_north_r1", b"link_r1_r2", b"link_r2_bs", b"link_south_r1"}
    assert json.loads(first["/timeseries"])["capacity"] == pytest.approx(float(res.timeseries["capacity"].iloc[0]))
