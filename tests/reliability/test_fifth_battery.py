"""The fifth fault battery's cases (issue 77) on the newer surfaces: nothing of the user's overwritten (``--record``,
``export/``), run folders that re-open from anywhere, exports of runs with a spare that never flew or a damaged time
series. Each case: a named error or a correct result, no traceback, no file of the user's lost."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from aerorelay.cli import app

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()


def _csv_run(tmp_path: Path) -> Path:
    """A short run whose scenario names a CSV mission (copied into the run folder as mission.csv)."""
    t = np.linspace(0.0, 2.0, 21)
    path = np.c_[t, -3.04 + 0.2 * t, 5.79 + 0.0 * t, 1.72 + 0.3 * t]
    (tmp_path / "path.csv").write_text("t,px,py,pz\n" + "\n".join(",".join(f"{v:.6g}" for v in row) for row in path) + "\n")
    (tmp_path / "sc.toml").write_text('[mission]\ntrajectory_csv = "path.csv"\n[sim]\nduration_s = 0.3\n')
    r = runner.invoke(app, ["run", str(tmp_path / "sc.toml"), "--out", str(tmp_path / "run"), "--no-bound", "--no-figures"])
    assert r.exit_code == 0, r.output
    return tmp_path / "run"


def test_a_run_folder_re_opens_from_anywhere_after_it_moved(tmp_path, monkeypatch):
    """report and export of a run whose scenario names its copied mission.csv: from another working folder, and
    after the folder moved (they said "no such file: mission.csv" unless run from inside the folder)."""
    run = _csv_run(tmp_path)
    assert (run / "mission.csv").is_file()
    moved = tmp_path / "elsewhere" / "moved"
    moved.parent.mkdir()
    shutil.move(str(run), str(moved))
    monkeypatch.chdir(tmp_path / "elsewhere")
    for args in (["report", str(moved)], ["export", str(moved), "--format", "csv"]):
        r = runner.invoke(app, args)
        assert r.exit_code == 0, r.output
    assert (moved / "report.html").is_file() and (moved / "export" / "relay.csv").is_file()


def test_export_never_writes_through_a_link_or_over_a_file_in_its_place(tmp_path):
    run = _csv_run(tmp_path)
    users = tmp_path / "users"
    users.mkdir()
    (users / "relay.csv").write_text("mine\n")
    (run / "export").symlink_to(users)
    r = runner.invoke(app, ["export", str(run), "--format", "csv"])
    assert r.exit_code == 2 and "symbolic link" in r.output and "Traceback" not in r.output
    assert (users / "relay.csv").read_text() == "mine\n"  # the user's file untouched
    (run / "export").unlink()
    (run / "export").write_text("a file\n")
    r = runner.invoke(app, ["export", str(run), "--format", "csv"])
    assert r.exit_code == 2 and "a file is in the way" in " ".join(r.output.split()), r.output
    assert (run / "export").read_text() == "a file\n"


def test_an_export_of_a_damaged_time_series_names_the_missing_columns(tmp_path):
    run = _csv_run(tmp_path)
    df = pd.read_parquet(run / "timeseries.parquet")
    df.drop(columns=["relay.p_z"]).to_parquet(run / "timeseries.parquet")
    for fmt in ("csv", "plan", "kml"):
        r = runner.invoke(app, ["export", str(run), "--format", fmt, "--origin", "47.39,8.54,400"])
        assert r.exit_code == 2, r.output
        assert "relay.p_z" in r.output and "missing" in r.output and "Traceback" not in r.output


def test_codegen_record_never_replaces_a_file_it_did_not_write(tmp_path):
    mine = tmp_path / "notes.csv"
    mine.write_text("my notes\n")
    r = runner.invoke(app, ["codegen", str(ROOT / "scenarios" / "quad_x.toml"), "--out", str(tmp_path / "tree"),
                            "--record", str(mine), "--duration", "0.1", "--no-c-planner"])
    assert r.exit_code == 2 and "not a recording of controller steps this program wrote" in " ".join(r.output.split())
    assert mine.read_text() == "my notes\n" and not (tmp_path / "tree").exists()  # checked before any work
    link = tmp_path / "link.csv"
    link.symlink_to(mine)
    r = runner.invoke(app, ["codegen", str(ROOT / "scenarios" / "quad_x.toml"), "--out", str(tmp_path / "tree"),
                            "--record", str(link), "--duration", "0.1", "--no-c-planner"])
    assert r.exit_code == 2 and "symbolic link" in r.output
    # its own recording, made again, is replaced
    own = tmp_path / "calls.csv"
    for tree in ("t1", "t2"):
        r = runner.invoke(app, ["codegen", str(ROOT / "scenarios" / "quad_x.toml"), "--out", str(tmp_path / tree),
                                "--record", str(own), "--duration", "0.1", "--no-c-planner"])
        assert r.exit_code == 0, r.output
    assert own.read_text().startswith("step,") and os.path.getsize(str(own) + ".expected") > 0


def test_an_export_of_a_run_whose_spare_never_flew_skips_it_and_names_it_when_asked_for(tmp_path):
    data = (ROOT / "scenarios" / "chain_two_relays.toml").read_text()
    data = data.replace('[[sources]]', '[[relays]]\nname = "r3"\nstart = [2.0, 3.0, 1.0]\nstandby = true\n\n[[sources]]')
    data += "\n[platform.battery]\ncapacity_wh = 200.0\ngo_home = true\n\n[sim]\nduration_s = 0.3\n"
    (tmp_path / "spare.toml").write_text(data)
    r = runner.invoke(app, ["run", str(tmp_path / "spare.toml"), "--out", str(tmp_path / "run"), "--no-bound", "--no-figures"])
    assert r.exit_code == 0, r.output
    for fmt in ("geojson", "kml", "plan", "csv", "ulog"):
        r = runner.invoke(app, ["export", str(tmp_path / "run"), "--format", fmt, "--origin", "47.39,8.54,400"])
        assert r.exit_code == 0, (fmt, r.output)
    assert not (tmp_path / "run" / "export" / "r3.csv").exists()
    r = runner.invoke(app, ["export", str(tmp_path / "run"), "--format", "plan", "--relay", "r3", "--origin", "47.39,8.54,400"])
    assert r.exit_code == 2 and "'r3' never flew" in r.output


@pytest.mark.parametrize("args", [["compare", "{run}", "{tmp}"], ["compare", "{tmp}", "{run}"]])
def test_compare_against_a_folder_that_is_no_run_says_so(tmp_path, args):
    run = _csv_run(tmp_path)
    other = tmp_path / "other"
    other.mkdir()
    r = runner.invoke(app, [a.format(run=run, tmp=other) for a in args])
    assert r.exit_code == 2 and "not an aerorelay run folder" in r.output and "unit" not in r.output


def test_the_step_api_names_a_malformed_state_or_source_and_reads_a_state_by_name():
    import aerorelay as ar

    sc = ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml", set={"sim.duration_s": 1.0})
    ctrl = ar.controller(sc).one_relay()
    x = np.zeros(18)
    x[:3], x[12:] = [-6.95, 5.79, 1.72], 53.3
    src = ar.SourceState(np.array([-3.04, 5.79, 1.72]), np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match=r"a state by name has the parts p, eta, v, omega, Omega; missing eta"):
        ctrl.step(0.0, {"p": x[:3]}, src)
    with pytest.raises(ValueError, match=r"a source must be an aerorelay.SourceState"):
        ctrl.step(0.0, x, ((1, 2, 3), (0, 0, 0), (0, 0, 0)))
    with pytest.raises(ValueError, match="relay_states must map each name"):
        ctrl.network.step(0.0, x, {"source": src})
    named = {"p": x[:3], "eta": x[3:6], "v": x[6:9], "omega": x[9:12], "Omega": x[12:]}
    by_name = ar.controller(sc).one_relay().step(0.0, named, src)
    flat = ar.controller(sc).one_relay().step(0.0, x, src)
    assert np.array_equal(by_name.omega_dot_hz_s, flat.omega_dot_hz_s)  # the same state, the same command
    assert isinstance(ar.AutopilotLoop(ctrl), ar.AutopilotLoop)  # the one relay's controller, as before the network's


@pytest.mark.parametrize(("sets", "field"), [
    ({"wind.mean_m_s": [3.0, 0.0, 0.0], "wind.gust_w20_m_s": 10.0}, "wind.gust_w20_m_s"),
    ({"jammer.localization": "estimated", "jammer.inr_db_at_relay_start": 10.0, "jammer.localization_delay_s": 4.0},
     "jammer.localization_delay_s"),
])
def test_a_dormant_setting_is_refused_by_name(sets, field):
    """Both flew bit-identical flights with and without the setting (the gusts are off; an estimated jammer is known
    when the estimator finds it)."""
    import aerorelay as ar
    from aerorelay.config import ScenarioError

    with pytest.raises(ScenarioError, match=f"{field}: applies only where"):
        ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml", set=sets)


def test_a_list_item_out_of_range_says_how_the_items_are_numbered():
    r = runner.invoke(app, ["validate", str(ROOT / "scenarios" / "chain_two_relays.toml"), "--set", "relays.-1.start=[1, 2, 3]"])
    assert r.exit_code == 2 and "(numbered 0 to 1)" in r.output and "not a table" not in r.output


def _square(lon0: float, lat0: float, d: float) -> list:
    return [[lon0, lat0], [lon0 + d, lat0], [lon0 + d, lat0 + d], [lon0, lat0 + d], [lon0, lat0]]


def test_a_multipolygon_footprint_is_a_building_per_polygon_and_a_fifo_or_folder_is_named(tmp_path):
    """A valid MultiPolygon (two blocks of one feature) was refused as 'names must be unique'; a FIFO given as the
    footprint file blocked validate; a folder was a traceback."""
    import json

    import aerorelay as ar
    from aerorelay.config import ScenarioError

    origin = [47.3977, 8.5456, 488.0]
    lon, lat = origin[1] + 10.0 / 75_100.0, origin[0] - 3.0 / 111_200.0  # about 10 m east, 3 m south of the base station
    feature = {"type": "Feature", "properties": {"name": "twins", "height": 8.0},
               "geometry": {"type": "MultiPolygon", "coordinates": [[_square(lon, lat, 2e-5)], [_square(lon + 6e-5, lat, 2e-5)]]}}
    f = tmp_path / "twins.geojson"
    f.write_text(json.dumps({"type": "FeatureCollection", "features": [feature]}))
    sc = ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml",
                          set={"geo.origin": origin, "buildings.geojson": str(f), "buildings.margin_m": 0.2})
    names = [o.name for o in sc.obstacles]
    assert len(names) == 2 and len(set(names)) == 2, names
    fifo = tmp_path / "pipe.geojson"
    os.mkfifo(fifo)
    for bad, said in ((fifo, "FIFO"), (tmp_path, "a folder")):
        with pytest.raises(ScenarioError, match=f"buildings.geojson: .*{said}"):
            ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml", set={"geo.origin": origin, "buildings.geojson": str(bad)})


def test_a_gpx_point_whose_elevation_is_not_a_number_is_named():
    import tempfile

    from aerorelay.models.geo import read_gpx
    pts = "".join(f'<trkpt lat="47.3977" lon="{8.5456 + 1e-5 * k}"><ele>{"NaN" if k == 1 else 490}</ele>'
                  f"<time>2026-01-01T00:00:0{k}Z</time></trkpt>" for k in range(3))
    with tempfile.NamedTemporaryFile("w", suffix=".gpx", delete=False) as f:
        f.write(f'<?xml version="1.0"?><gpx version="1.1" creator="t"><trk><trkseg>{pts}</trkseg></trk></gpx>')
    with pytest.raises(ValueError, match=r"\.gpx: track 0 segment 0 point 1: <ele> nan is not a number"):
        read_gpx(f.name)
    os.unlink(f.name)


def test_a_cache_entry_whose_checksum_sidecar_holds_random_bytes_is_rebuilt_not_a_crash(tmp_path):
    from aerorelay.store.cache import entry_is_intact, publish_checked

    tmp = tmp_path / "entry.tmp"
    tmp.write_bytes(b"a cached trace")
    entry = tmp_path / "entry.npz"
    publish_checked(tmp, entry)
    assert entry_is_intact(entry)
    (tmp_path / "entry.npz.sha256").write_bytes(os.urandom(64) + b"\xff\xfe")
    assert not entry_is_intact(entry)  # not used: the caller traces again


def test_long_work_without_a_terminal_prints_a_line_while_one_step_takes_long(monkeypatch, capsys):
    """K = 16 and a 1e8-ray trace printed their estimate, then nothing for 300 s in a log: the plain progress printed
    only when the loop reported a step, and one step (a trace, the pre-flight route) took minutes."""
    import time

    from aerorelay import cli

    monkeypatch.setattr(cli, "PLAIN_PROGRESS_S", 0.2)
    with cli._progress("flight", "steps") as update:
        update(0, 10)
        time.sleep(1.0)  # one long step: no update for five periods
        update(10, 10)
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("flight:")]
    assert len(lines) >= 4 and lines[-1].startswith("flight: 10/10 steps"), lines


@pytest.mark.parametrize("scenario", ["nominal_tilted.toml", "chain_two_relays.toml"])
def test_a_source_that_jumps_a_kilometre_is_not_planned_on(scenario):
    """A 1 km jump of the source's reported position was planned on by one relay and by a chain alike: it is held as a
    relay state's jump is (its reach, StaleSettings.source_accel_max_m_s2), and the next report near where it was flies."""
    import aerorelay as ar

    sc = ar.load_scenario(ROOT / "scenarios" / scenario, set={"sim.duration_s": 1.0})
    ctrl = ar.controller(sc)  # the network's controller, for one relay too
    states = {}
    for r in sc.relay_list:
        x = np.zeros(12 + ctrl.relay(r.name).vehicle.n_rotors)
        x[:3], x[12:] = r.start, ctrl.relay(r.name).vehicle.hover_speeds()
        states[r.name] = x
    name = sc.source_list[0].name
    p0 = np.asarray(sc.source_list[0].mission.start, float)
    step = 0.015

    def src(p):
        return {name: ar.SourceState(np.asarray(p, float), np.zeros(3), np.zeros(3))}
    first = ctrl.step(0.0, states, src(p0))
    assert all(c.rejected is None for c in first.values())
    jumped = ctrl.step(step, states, src(p0 + [1000.0, 0.0, 0.0]))
    assert all(c.mode == "hold" and "source position jumped" in (c.rejected or "") for c in jumped.values())
    back = ctrl.step(2 * step, states, src(p0))
    assert all(c.rejected is None and c.mode == "nmpc" for c in back.values())
