"""Cases of the fourth fault battery (issue 61) that each failed before their fix, as tests."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from aerorelay.cli import app
from tests.rt_marks import needs_rt

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()


def test_bench_of_a_network_with_a_spare_that_never_flies_times_the_others():
    """``aerorelay bench relay_shifts.toml`` was an IndexError: its spare waits on the ground, nothing timed."""
    r = runner.invoke(app, ["bench", str(ROOT / "scenarios" / "relay_shifts.toml"), "--duration", "1"])
    assert r.exit_code == 0, r.output
    assert "r1: step" in r.output and "spare never flew" in r.output


def test_one_file_that_is_no_study_does_not_hide_the_others(tmp_path):
    """One non-UTF-8 file in a studies folder crashed ``reproduce --list`` and every study (UnicodeDecodeError)."""
    studies = tmp_path / "experiments"
    studies.mkdir()
    (tmp_path / "scenarios").symlink_to(ROOT / "scenarios")
    (studies / "01_nominal.toml").write_text((ROOT / "experiments" / "01_nominal.toml").read_text())
    (studies / "zz_latin1.toml").write_bytes("name = 'caf\u00e9'\n".encode("latin-1"))
    r = runner.invoke(app, ["reproduce", "--list", "--studies-dir", str(studies)])
    assert r.exit_code == 0, r.output
    assert "nominal" in r.output and "zz_latin1.toml" in r.output and "not UTF-8" in r.output
    r = runner.invoke(app, ["reproduce", "--studies-dir", str(studies), "--out", str(tmp_path / "c")])  # all: named
    assert r.exit_code == 2 and "zz_latin1.toml: not UTF-8 text" in r.output


def test_special_files_are_refused_at_once_wherever_a_path_is_read(tmp_path):
    """A FIFO as a run folder's metrics.json blocked export and compare; a symlink loop as the scenario or as --out
    was a traceback; a FIFO or a folder as a mission CSV was 'no such file'."""
    import os

    import aerorelay as ar
    from aerorelay.config import ScenarioError

    loop_a, loop_b = tmp_path / "a", tmp_path / "b"
    loop_a.symlink_to(loop_b)
    loop_b.symlink_to(loop_a)
    r = runner.invoke(app, ["validate", str(loop_a)])
    assert r.exit_code == 2 and "a symlink loop" in r.output
    r = runner.invoke(app, ["run", str(ROOT / "scenarios" / "nominal_tilted.toml"), "--out", str(loop_a), "--duration", "0.1",
                            "--no-bound", "--no-figures"])
    assert r.exit_code == 2 and "--out" in r.output and "a symlink loop" in r.output
    fifo = tmp_path / "mission.csv"
    os.mkfifo(fifo)
    try:
        ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml", set={"mission.trajectory_csv": str(fifo)})
        raise AssertionError("a FIFO as a mission CSV was read")
    except ScenarioError as exc:
        assert "mission.trajectory_csv" in str(exc) and "a FIFO" in str(exc)
    run = tmp_path / "run"
    r = runner.invoke(app, ["run", str(ROOT / "scenarios" / "nominal_tilted.toml"), "--out", str(run), "--duration", "0.1",
                            "--no-bound", "--no-figures"])
    assert r.exit_code == 0, r.output
    (run / "metrics.json").unlink()
    os.mkfifo(run / "metrics.json")
    for args in (["export", str(run)], ["compare", str(run), str(run)]):
        r = runner.invoke(app, args)
        assert r.exit_code == 2 and "metrics.json: a FIFO" in r.output, (args, r.output)


def test_the_network_bounds_estimate_counts_every_combination_of_base_station_ends():
    """8 stations x 2 sources ending at 'any' were 64 combinations bounded one by one, estimated as one (1.6 min
    said, nothing for 300 s). The estimate is the one combination's times their number (each bounded on its own)."""
    import aerorelay as ar
    from aerorelay.assembly.parts import bound_cost

    sc = ar.load_scenario(ROOT / "scenarios" / "relay_shifts.toml")  # one route to "any" of 2 base stations
    one = bound_cost(sc.with_updates({"network.routes": [["inspector", "r1", "r2", sc.base_station_names[0]]]}))
    both = bound_cost(sc)
    assert both.combinations == 2 and one.combinations == 1
    assert both.seconds == 2 * one.seconds


def test_two_relays_on_one_vehicle_are_refused_before_arming():
    """Two relays' --mavlink on one vehicle were flown, then 'unsafe' without the cause."""
    chain = str(ROOT / "scenarios" / "chain_two_relays.toml")
    r = runner.invoke(app, ["fly", chain, "--mavlink", "r1=udpout:127.0.0.1:14541", "--mavlink", "r2=udpout:127.0.0.1:14541"])
    assert r.exit_code == 2 and "relays 'r1' and 'r2' on one vehicle (udpout:127.0.0.1:14541)" in r.output, r.output


@needs_rt
def test_a_scene_file_not_found_says_where_it_looked():
    """A scene given with --set is found from the working folder, one in the file beside the file: the error said
    only "does not exist"."""
    import pytest

    import aerorelay as ar
    from aerorelay.config import ScenarioError

    with pytest.raises(ScenarioError, match=r"scene file 'nowhere\.xml': no such file \(looked for /.*nowhere\.xml; "):
        ar.load_scenario(ROOT / "scenarios" / "street_canyon_traced.toml", set={"channel.propagation.scene": "nowhere.xml"})


@needs_rt
def test_a_truncated_or_foreign_scene_file_is_refused_at_load(tmp_path):
    """A truncated or binary scene XML, or a GPX file as a scene, validated and then crashed the run at its first
    trace."""
    import pytest

    import aerorelay as ar
    from aerorelay.config import ScenarioError

    cut = tmp_path / "cut.xml"
    cut.write_text('<scene version="2.1.0"><shape type="ply" id="wall"><string name="filename"')
    gpx = tmp_path / "track.xml"
    gpx.write_text('<?xml version="1.0"?><gpx version="1.1"><trk/></gpx>')
    for f, said in ((cut, "not well-formed XML"), (gpx, "its root element is <gpx>")):
        with pytest.raises(ScenarioError, match=said):
            ar.load_scenario(ROOT / "scenarios" / "street_canyon_traced.toml", set={"channel.propagation.scene": str(f)})


def test_a_closed_tcp_port_is_named_not_a_traceback():
    """``--mavlink tcp:`` to a closed port was a ConnectionRefusedError traceback (left from the third battery)."""
    import pytest

    from aerorelay.flight.mavlink import MavlinkUrlError, connect

    with pytest.raises(MavlinkUrlError, match=r"'tcp:127\.0\.0\.1:9': cannot connect"):  # a ValueError: `fly` exits 2
        connect("tcp:127.0.0.1:9", system=1, component=1)


def test_the_paper_s_one_relay_keeps_the_separation_its_verdict_checks(tmp_path):
    """The one-relay capacity planner under a sector base station pointed up toward the tower flew 1.01 m from the
    inspection drone, inside the 1.05 m separation the verdict checks (exit 3): its goal kept the clearance, its
    tracking did not. Every relay's NMPC now keeps the separation from every other vehicle, one relay's too."""
    import json

    out = tmp_path / "run"
    r = runner.invoke(app, ["run", str(ROOT / "scenarios" / "nominal_coplanar.toml"), "--out", str(out), "--planner", "capacity",
                            "--duration", "7", "--no-figures", "--no-bound", "--set", 'antenna.bs_pattern="cosine"',
                            "--set", "antenna.bs_azimuth_deg=110", "--set", "antenna.bs_g_max=10", "--set", "antenna.bs_exponent=4",
                            "--set", "antenna.bs_tilt_deg=-20"])
    m = json.loads((out / "metrics.json").read_text())
    assert r.exit_code == 0, r.output
    assert m["exit_status"] == "complete" and m["separation_min_m"] >= 1.05, m["separation_min_m"]


def test_a_network_s_summary_shows_its_jammer_estimate(tmp_path):
    """A chain that estimates its jammer printed no estimation rows (and one relay's summary asked for a metric
    by a name metrics.json never had): the final error, the reported spread, its NEES and whether the planners
    trust it are shown."""
    r = runner.invoke(app, ["run", str(ROOT / "scenarios" / "chain_two_relays.toml"), "--out", str(tmp_path / "run"),
                            "--duration", "3", "--no-figures", "--no-bound", "--set", 'jammer.localization="estimated"'])
    assert r.exit_code == 0, r.output
    for row in ("estimation_err_final_m", "estimation_std_final_m", "estimation_nees_final", "estimation_trusted_final"):
        assert row in r.output, row


def test_a_too_long_name_is_named_without_dumping_it():
    """A jammer's name had no length or character rule (its log columns are ``jam_<name>_x``), and an error quoted
    whatever input it was given, whole."""
    long = "y" * 300
    r = runner.invoke(app, ["validate", str(ROOT / "scenarios" / "two_jammers.toml"), "--set", f'jammers.0.name="{long}"'])
    assert r.exit_code == 2 and "jammers.0.name: String should have at most 32 characters" in r.output
    assert "(302 characters)" in r.output and long not in r.output
    r = runner.invoke(app, ["validate", str(ROOT / "scenarios" / "two_jammers.toml"), "--set", 'jammers.0.name="south west"'])
    assert r.exit_code == 2 and "jammers.0.name: String should match pattern" in r.output


def test_reproduce_list_names_the_extra_a_study_needs(monkeypatch):
    """Without Sionna RT the ray-traced study is listed with the extra to install, the others as runnable: the
    message said "pip install 'aerorelay'" (the console read "[rt]" as a style and dropped it)."""
    import aerorelay.models.raytrace as rtm

    def missing():
        raise rtm.RayTracingUnavailable(f"{rtm.RT_EXTRA} (No module named 'sionna')")

    monkeypatch.setattr(rtm, "sionna_rt", missing)
    r = runner.invoke(app, ["reproduce", "--list"])
    assert r.exit_code == 0, r.output
    flat = " ".join(r.output.replace("│", " ").split())
    assert "aerorelay[rt]" in flat and "cannot run here" in flat
    assert "nominal" in flat and "network" in flat


def test_a_track_too_long_to_read_is_refused_by_its_size_before_it_is_read(tmp_path):
    """A 3,000,000-row straight-line CSV was read for 150 s (1.6 GB) and refused as 'ill-posed'; a mission file
    is now counted before it is read: its rows (a CSV) and its size (any track), each limit named."""
    from aerorelay.models.mission import MAX_TRACK_ROWS

    f = tmp_path / "long.csv"
    n = MAX_TRACK_ROWS + 100
    f.write_bytes(b"t,px,py,pz\n" + b"".join(b"%d,%d,0,5\n" % (k, k) for k in range(n)))
    r = runner.invoke(app, ["validate", str(ROOT / "scenarios" / "nominal_tilted.toml"), "--set", f'mission.trajectory_csv="{f}"'])
    assert r.exit_code == 2, r.output
    assert f"{n:,} rows, more than a mission file is read ({MAX_TRACK_ROWS:,}" in " ".join(r.output.split())


@needs_rt
def test_a_traced_flight_too_long_for_its_limit_is_refused_before_it_starts(tmp_path):
    """A traced flight at rays_per_source = 1e8 ran unbounded with no estimate: 188 traces of ~100 s each. Its
    estimate (the closed loop and every trace, in proportion to the rays) is refused above sim.max_minutes, naming
    what to change, from the CLI and from Python, before any work."""
    import aerorelay as ar
    from aerorelay.config import ScenarioError

    r = runner.invoke(app, ["run", str(ROOT / "scenarios" / "munich_roof.toml"), "--out", str(tmp_path / "run"), "--no-bound",
                            "--set", "channel.propagation.rays_per_source=100000000"])
    assert r.exit_code == 2, r.output
    flat = " ".join(r.output.split())
    assert "sim.max_minutes: this flight would take about 314 min here (188 traces" in flat and "rays_per_source" in flat
    assert not (tmp_path / "run").exists()
    sc = ar.load_scenario(ROOT / "scenarios" / "munich_roof.toml", set={"channel.propagation.rays_per_source": 100_000_000})
    with pytest.raises(ScenarioError, match="sim.max_minutes"):
        ar.simulate(sc, bound=False)
    assert ar.api.flight_estimate(sc.with_updates({"sim.max_minutes": 400.0}))[1] == 188


def test_long_work_shows_its_progress_without_a_terminal(tmp_path, monkeypatch):
    """A 48 min network bound printed nothing for 300 s where its output was not a terminal (a log, CI): a bar
    draws nothing there until the end. Without a terminal a plain line says how far the work is, at most every
    10 s and at the end, for the bound and for the flight."""
    monkeypatch.setenv("AERORELAY_CACHE", str(tmp_path / "cache"))  # the bound computed here, not found cached
    r = runner.invoke(app, ["run", str(ROOT / "scenarios" / "nominal_tilted.toml"), "--out", str(tmp_path / "run"),
                            "--duration", "1", "--no-figures", "--set", "bound.dt_s=0.4"])
    assert r.exit_code == 0, r.output
    assert "capacity bound: 3/3 instants" in r.output and "nominal_tilted [constrained]: 67/67 steps" in r.output
