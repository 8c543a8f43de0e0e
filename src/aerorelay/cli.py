"""Command-line interface: ``aerorelay validate|info|run|compare|bench``."""

from __future__ import annotations

import contextlib
import math
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import NoReturn

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from . import api
from .api import CampaignBusyError, OutputBusyError, OutputError, Scenario, ScenarioError, StudyError, load_scenario
from .flight.names import check_ros_namespace
from .planning.plugins import PluginError
from .planning.plugins import load as load_plugins
from .planning.plugins import resolve as resolve_plugin

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Communications-aware aerial relay under jamming.")
console = Console()
err_console = Console(stderr=True, soft_wrap=True)

EXIT_BAD_INPUT = 2
EXIT_UNSAFE = 3  # the run finished but the relay left its workspace or flipped (metrics.json: unsafe, unsafe_reason)
EXIT_FELL_BACK = 4  # safe, but a relay's controller did not fly it (metrics.json: exit_status fell_back, fell_back_reason)
QUICK_BUDGET_MIN = 5.0  # reproduce --quick: minutes of estimated wall time (experiments/budget.py)
_PLUGINS: list[str] = []  # --plugin: users' planner modules, imported before the command (and by a campaign's workers)


@app.callback()
def _plugins(plugin: list[str] = typer.Option(None, "--plugin", help="a module (or .py file) of your planners, imported "
                                               "before the command (register_planner / register_network_planner at "
                                               "import); reproduce's workers import it too; repeatable",
                                               show_default=False)) -> None:
    """Communications-aware aerial relay under jamming."""
    _PLUGINS[:] = plugin or []
    try:
        load_plugins([resolve_plugin(p) for p in _PLUGINS])
    except PluginError as exc:
        err_console.print(f"[bold red]error[/] {escape(str(exc))}", highlight=False)
        raise typer.Exit(EXIT_BAD_INPUT) from None


def _load_or_exit(path: Path, sets: list[str] | None = None, unsets: list[str] | None = None,
                  options: dict | None = None) -> Scenario:
    """The scenario file with the ``--set`` items, then the command-line ``options`` that were given (dotted keys,
    None: not given; ``--planner``, ``--variant``, ``--duration``, ...), applied and the ``--unset`` keys removed before
    it is validated (as ``load_scenario(set=..., unset=...)``: a file valid only with an option's value loads with
    it): exit 2 naming what is wrong."""
    try:
        updates = {**parse_sets(sets), **{k: v for k, v in (options or {}).items() if v is not None}}
    except ScenarioError as exc:
        _fail(str(exc))
    try:
        return load_scenario(path, set=updates, unset=list(unsets or []))
    except ScenarioError as exc:
        err_console.print(f"[bold red]invalid scenario[/] {path}:")
        for line in str(exc).splitlines():
            err_console.print(f"  {line}", markup=False, highlight=False)
        raise typer.Exit(EXIT_BAD_INPUT) from None


def _check_out(out: Path, kind: str) -> None:
    """``--out`` checked before any work: a named error and exit 2 when it cannot take the output."""
    try:
        api.check_output(out, kind)
    except OutputError as exc:
        _fail(str(exc))


def _fail(message: str) -> NoReturn:
    err_console.print(f"[bold red]error[/] {escape(message)}", highlight=False)
    raise typer.Exit(EXIT_BAD_INPUT)


def _check_duration(duration: float | None) -> None:
    """``--duration`` of a flight or a vehicle: None (the default) or a finite number of seconds > 0."""
    if duration is not None and not (math.isfinite(duration) and duration > 0):
        _fail(f"--duration must be a finite number of seconds > 0, got {duration:g}")


def _check_url(url: str | None, option: str) -> None:
    """A MAVLink URL option checked before anything is contacted (form, port range, a port in use)."""
    if url is None:
        return
    try:
        api.check_mavlink_url(url, option)
    except ValueError as exc:
        _fail(str(exc))


SET_HELP = ("override a scenario field, e.g. --set controller.mu=0.3 (repeatable; values in TOML syntax; applied before "
            "the file is validated)")
UNSET_HELP = "remove a field of the file, e.g. --unset jammer.position (repeatable; before the file is validated)"


def parse_sets(items: list[str] | None) -> dict:
    """``--set`` items as dotted keys -> values; a malformed item exits 2 naming it."""
    try:
        return api.parse_sets(items)
    except ScenarioError as exc:
        _fail(str(exc))


@app.command()
def validate(
    scenario: Path = typer.Argument(..., help="scenario TOML file", show_default=False),
    set_: list[str] = typer.Option(None, "--set", help=SET_HELP, show_default=False),
    unset: list[str] = typer.Option(None, "--unset", help=UNSET_HELP, show_default=False),
):
    """Validate a scenario and print it fully resolved (every default spelled out)."""
    sc = _load_or_exit(scenario, set_, unset)
    print(f"# {scenario}: valid")
    if sc.channel.outage_threshold is None:
        print(f"# channel.outage_threshold (unset) resolves to {sc.channel.outage:g} {sc.channel.capacity_unit}")
    for line in api.derived_values(sc):
        print(f"# {line}")
    for field, local in sc.wgs84_resolved:  # written at lat/lon: what they are in the local frame
        shown = [round(float(v), 4) for v in local] if not isinstance(local[0], list) else \
            [[round(float(v), 4) for v in point] for point in local]
        print(f"# {field}_wgs84 resolves to {field} = {shown} m (ENU at geo.origin)")
    if (b := sc.buildings_resolved) is not None:
        print(f"# buildings.geojson {b['file']}: {b['footprints']} footprints, {b['kept']} within reach "
              f"({b['left_out']} left out), {b['prisms']} convex prisms (the obstacles named building<i>)")
    print(sc.to_toml())


def model_summary(sc: Scenario) -> Table:
    """A table of the derived physical quantities of a scenario (hover, allocation, channel at t=0)."""
    try:
        budget: dict[str, float] | None = api.link_budget(sc)  # the paper's Gamma_21, Gamma_10
    except ScenarioError:  # a network's start is said hop by hop (api.link_budget_lines)
        budget = None
    t = Table(title=f"model summary: {sc.name}", show_header=True)
    t.add_column("quantity")
    t.add_column("value", justify="right")
    for r in api.relay_summaries(sc):  # every relay's own platform, limits and antenna
        name = str(r["name"])
        t.add_row(f"{name}: platform", str(r["platform"]))
        t.add_row(f"{name}: rotors / max axis tilt", f"{r['rotors']} ({r['layout']}) / {r['max_axis_tilt_deg']:.1f} deg")
        t.add_row(f"{name}: allocation rank [F; M]", str(r["allocation_rank"]))
        t.add_row(f"{name}: hover speeds (Hz)", ", ".join(f"{h:.2f}" for h in r["hover_hz"]))  # type: ignore[attr-defined]
        t.add_row(f"{name}: hover shaft power (W)", f"{r['hover_shaft_power_w']:.1f}")
        t.add_row(f"{name}: speed limit / governor (m/s)", f"{r['speed_m_s']:g} / {r['governor_speed_m_s']:g}")
        t.add_row(f"{name}: antenna", str(r["antenna"]))
    if budget is not None:
        t.add_row("Gamma_21 at t=0", f"{budget['gamma_21']:.4f}")
        t.add_row("Gamma_10 at t=0", f"{budget['gamma_10']:.4f}")
        t.add_row("end-to-end capacity C at t=0", f"{budget['capacity']:.4f}")
        t.add_row("mutual alignment at t=0", f"{budget['mutual_alignment']:.3f} (mu = {sc.controller.mu})")
    else:
        t.add_row("relays / sources / routes", f"{len(sc.relay_list)} / {len(sc.source_list)} / {len(sc.route_list)}")
        if sc.standby_names:
            t.add_row("spares (standby)", ", ".join(sc.standby_names))
        if sc.base_stations is not None:
            t.add_row("base stations", ", ".join(sc.base_station_names))
        if sc.has_handover:
            t.add_row("handover: margin (dB) / dwell (s)", f"{sc.network.handover_margin_db:g} / {sc.network.handover_dwell_s:g}")
    t.add_row("jammers", str(len(sc.jammer_configs)))
    if budget is not None:
        t.add_row("interference / noise at t=0: relay, BS (dB)", f"{budget['inr_relay_db']:.1f}, {budget['inr_bs_db']:.1f}")
    t.add_row("mission length (s)", f"{sc.duration_s:g}")
    return t


@app.command()
def info(
    scenario: Path = typer.Argument(..., help="scenario TOML file", show_default=False),
    set_: list[str] = typer.Option(None, "--set", help=SET_HELP, show_default=False),
    unset: list[str] = typer.Option(None, "--unset", help=UNSET_HELP, show_default=False),
):
    """Print the scenario's derived model quantities: hover, allocation rank, initial link budget."""
    sc = _load_or_exit(scenario, set_, unset)
    console.print(model_summary(sc))
    t = Table(title=f"link budget at t=0 ({sc.channel.units} units, level attitudes, jammers at peak)", show_header=True)
    t.add_column("quantity")
    t.add_column("value", justify="right")
    for name, value in api.link_budget_lines(sc):
        t.add_row(name, value)
    console.print(t)


@app.command()
def run(
    scenario: Path = typer.Argument(..., help="scenario TOML file", show_default=False),
    out: Path = typer.Option(..., "--out", help="output folder (new, empty, or an earlier run folder, which is replaced)", show_default=False),
    variant: str = typer.Option(None, "--variant", help="constrained | unconstrained (overrides the scenario)", show_default=False),
    planner: str = typer.Option(None, "--planner", show_default=False,
                                help="trajectory_generator | isotropic | single_shot | capacity (overrides the scenario)"),
    duration: float = typer.Option(None, "--duration", help="simulate only this many seconds", show_default=False),
    no_figures: bool = typer.Option(False, "--no-figures", help="skip PNG/HTML figures"),
    no_bound: bool = typer.Option(False, "--no-bound", help="skip the capacity bound (computed once per scenario geometry, cached)"),
    set_: list[str] = typer.Option(None, "--set", help=SET_HELP, show_default=False),
    unset: list[str] = typer.Option(None, "--unset", help=UNSET_HELP, show_default=False),
    wait: bool = typer.Option(False, "--wait", help="wait for another run writing the same --out instead of refusing"),
):
    """Fly one closed-loop mission and write scenario.toml, timeseries.parquet, metrics.json, the
    capacity bound (bound.json, bound.parquet, efficiency in metrics.json) and figures."""
    sc = _load_or_exit(scenario, set_, unset, {"controller.variant": variant, "controller.planner": planner,
                                               "sim.duration_s": duration})
    _check_run(sc, out, figures=not no_figures, bound=not no_bound)
    try:
        with api.output_lock(out, wait=wait):  # one writer per folder, from before the flight until it is saved
            _check_run(sc, out, figures=not no_figures)  # again: we may have waited
            result = _fly(sc, no_bound)
            result.save(out, figures=not no_figures)
    except OutputBusyError as exc:
        _fail(str(exc))
    console.print(f"wrote {out}", markup=False, highlight=False)
    console.print(_metrics_table({"value": result.metrics}))
    for name, why in result.metrics.get("optional_outputs_failed", {}).items():
        err_console.print(f"[bold yellow]warning[/] {name} not written: {escape(str(why))} (the run is saved)", highlight=False)
    _exit_if_unsafe(result, "run")


def _check_run(sc: Scenario, out: Path, *, figures: bool, bound: bool = False) -> None:
    """The run's checks before flying (its size, its bound's, its output folder): exit 2 naming what fails."""
    try:
        api.check_run(sc, out, figures=figures, bound=bound)
    except (ScenarioError, OutputError) as exc:
        _fail(str(exc))


def _fly(sc: Scenario, no_bound: bool) -> api.Result:
    """The bound (unless ``no_bound``; cached per geometry), then the flight, with progress bars."""

    if not no_bound:  # computed once per scenario geometry (cached), with its own progress bar
        _bound_with_progress(sc)
    seconds, traces = api.flight_estimate(sc)
    if seconds > 60.0:  # long work says its estimate
        traced = f" ({traces} traces of its ray-traced channel)" if traces else ""
        err_console.print(f"flight: about {seconds / 60.0:.1f} min estimated here{traced} (sim.max_minutes = "
                          f"{sc.sim.max_minutes:g})", highlight=False)
    # no refresh thread: it would hold the GIL while the controller's C call returns and inflate
    # the measured step times; the bar is redrawn from the loop every 50 steps instead
    with _progress(f"{escape(sc.name)} \\[{sc.controller.variant}]", "steps", transient=False) as update:
        return api.simulate(sc, bound=not no_bound, progress=lambda k, n: update(k, n) if k % 50 == 0 or k == n else None)


def _say_bound_estimate(sc: Scenario) -> None:
    """Long work says its estimate: the bound's (``planning.bound_cost``), when above a few seconds, before it starts
    (a bound cached for this geometry takes none of it)."""
    cost = api.bound_estimate(sc)
    if 5.0 < cost.seconds <= 60.0 * sc.bound.max_minutes:  # above its limit, the bound's refusal says it
        ends = f" for {cost.combinations} combinations of base-station ends" if cost.combinations > 1 else ""
        err_console.print(f"capacity bound: about {cost.seconds / 60.0:.1f} min estimated here{ends} unless cached "
                          f"(bound.max_minutes = {sc.bound.max_minutes:g}; --no-bound skips it)", highlight=False)


def _bound_with_progress(sc: Scenario):
    """The scenario's capacity bound (cached by geometry), with a progress bar when computed."""

    _say_bound_estimate(sc)
    with _progress("capacity bound", "instants") as update:
        return api.bound(sc, progress=update)


PLAIN_PROGRESS_S = 10.0  # without a terminal, a progress line at most this often (and at the end)


@contextlib.contextmanager
def _progress(label: str, unit: str, *, transient: bool = True):
    """An ``update(done, total)`` for long work: a bar with the elapsed and remaining time on a terminal; without one
    (a log, a pipe, CI), where a bar prints nothing until the end, a plain line at most every ``PLAIN_PROGRESS_S``
    (a 48 min network bound printed nothing for its first 300 s)."""
    import time

    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    if not err_console.is_terminal:
        import threading

        t0, last, state = time.monotonic(), [-math.inf], [0, 0]
        lock, stop = threading.Lock(), threading.Event()

        def say(done: int, total: int) -> None:
            now = time.monotonic()
            last[0] = now
            elapsed = now - t0
            left = f", ~{elapsed / done * (total - done) / 60.0:.1f} min left" if 0 < done < total else ""
            of = f"{done}/{total}" if total else "starting,"
            err_console.print(f"{label}: {of} {unit}, {elapsed / 60.0:.1f} min{left}", highlight=False)

        def plain(done: int, total: int) -> None:
            with lock:
                state[:] = [done, total]
                if done >= total or time.monotonic() - last[0] >= PLAIN_PROGRESS_S:
                    say(done, total)

        def beat() -> None:  # a line every PLAIN_PROGRESS_S even while one step (a trace, a route) takes minutes
            while not stop.wait(PLAIN_PROGRESS_S / 4):
                with lock:
                    if time.monotonic() - last[0] >= PLAIN_PROGRESS_S:
                        say(*state)

        last[0] = t0
        heart = threading.Thread(target=beat, name="progress", daemon=True)
        heart.start()
        try:
            yield plain
        finally:
            stop.set()
            heart.join()
        return
    with Progress(TextColumn(label), BarColumn(), TextColumn(f"{{task.completed}}/{{task.total}} {unit}"), TimeElapsedColumn(),
                  TimeRemainingColumn(), console=err_console, transient=transient, auto_refresh=False) as prog:
        task = prog.add_task(unit, total=1)
        yield lambda done, total: prog.update(task, completed=done, total=total, refresh=True)


@app.command()
def codegen(
    scenario: Path = typer.Argument(..., help="scenario TOML file", show_default=False),
    out: Path = typer.Option(..., "--out", help="a new or empty folder for the C tree", show_default=False),
    relay: str = typer.Option(None, "--relay", help="the relay whose controller the tree is (required when the scenario has "
                              "several: one tree per relay)", show_default=False),
    prefix: str = typer.Option("ar", "--prefix", help="every C name of the tree begins with it (ar_step: PREFIX_step): "
                               "give each relay's tree its own to link several into one program"),
    record: Path = typer.Option(None, "--record", help="also fly the scenario and record the tree's relay's controller "
                                "steps here (replay's input; the Python commands in <record>.expected)",
                                show_default=False),
    fly: bool = typer.Option(False, "--fly", help="build the tree's shared library (make) and fly the scenario with its "
                             "commands for the tree's relay (the others on Python's), the Python controller beside it: "
                             "the flight's C_min and the largest difference (out/fly.json)"),
    c_planner: bool = typer.Option(True, "--c-planner/--no-c-planner", help="the paper's planner in the tree where the "
                                   "relay flies it (ar_plan: stage parameters from the source's and the jammers' states); "
                                   "without: the stage parameters always come from outside"),
    offboard: bool = typer.Option(False, "--offboard", help="the controller of the vehicle an autopilot flies (thrust "
                                  "along body z, as aerorelay fly plans), with an example program that flies a MAVLink "
                                  "vehicle in OFFBOARD through the library (tools/offboard.c: make -C OUT offboard) and "
                                  "world.csv (the source and jammers on the mission's clock, over --duration)"),
    duration: float = typer.Option(None, "--duration", help="with --record or --fly: simulate only this many seconds; "
                                   "with --offboard: the mission's length world.csv covers"),
    set_: list[str] = typer.Option(None, "--set", help=SET_HELP, show_default=False),
    unset: list[str] = typer.Option(None, "--unset", help=UNSET_HELP, show_default=False),
):
    """One relay's controller (the NMPC on the HPIPM engine, the supervisor's envelope, the fail-safe brake law;
    settings baked in; --relay NAME in a network) as a self-contained C99 library, with a Makefile, a CMake project and a replay
    program (see the tree's README.md)."""
    _check_duration(duration)
    sc = _load_or_exit(scenario, set_, unset)
    if duration is not None:
        sc = sc.with_updates({"sim.duration_s": duration})
    try:
        summary = api.codegen(sc, out, record=record, fly=fly, planner=c_planner, offboard=offboard, relay=relay,
                              prefix=prefix)
    except (ScenarioError, ValueError, FileExistsError, RuntimeError, OutputError) as exc:
        _fail(str(exc))
    planner_said = f"the paper's ({summary['prefix']}_plan)" if summary["planner"] else summary["no_planner_because"]
    console.print(f"wrote {out}: {len(summary['files'])} files (state {summary['nx']}, rotors {summary['nr']}, stage "
                  f"parameters {summary['n_params']} x {summary['horizon'] + 1}; planner: {planner_said}); build: "
                  f"make -C {out}" + (f"; the OFFBOARD example: make -C {out} offboard" if offboard else ""),
                  markup=False, highlight=False)
    if record is not None:
        console.print(f"recorded {summary['recorded']} controller steps in {record}", markup=False, highlight=False)
    if fly:
        f = summary["flown"]
        console.print(f"flown with the C library ({f['c_steps']} steps, {f['c_fallback_steps']} on the brake law): C_min "
                      f"{f['c_min']:.5g}, C_mean {f['c_mean']:.5g}, largest difference from Python's command "
                      f"{f['max_difference']:.2g} (relative), brake law disagreements {f['fallback_disagreements']}"
                      + (f"; stage parameters by the C planner, largest difference {f['max_parameter_difference']:.2g}"
                         if f["planned_in_c"] else "")
                      + (f"; UNSAFE: {f['unsafe_reason']}" if f["unsafe"] else ""), markup=False, highlight=False)
        if f["unsafe"]:
            raise typer.Exit(EXIT_UNSAFE)


@app.command()
def bound(
    scenario: Path = typer.Argument(..., help="scenario TOML file", show_default=False),
    out: Path = typer.Option(..., "--out", help="output folder: bound.json, bound.parquet, bound.png", show_default=False),
    set_: list[str] = typer.Option(None, "--set", help=SET_HELP, show_default=False),
    unset: list[str] = typer.Option(None, "--unset", help=UNSET_HELP, show_default=False),
):
    """The best link the physics allows on this scenario: static and path capacity bounds."""
    import json


    sc = _load_or_exit(scenario, set_, unset)
    _check_out(out, "bound")
    try:
        _say_bound_estimate(sc)
        with _progress("capacity bound", "instants") as update:
            summary = api.write_bound(sc, out, progress=update)
    except (OutputBusyError, ScenarioError) as exc:
        _fail(str(exc))
    t = Table(title=f"capacity bounds: {sc.name}")
    for c in ("bound", "mean C", "min C", "outage"):
        t.add_column(c, justify="right" if c != "bound" else "left")
    si = api.si
    names = ("static", "path_mean", "path_maxmin", "flyable_mean", "flyable_maxmin", "achieved", "flyable")  # those it has
    for name in (n for n in names if n in summary):
        s = summary[name]
        t.add_row(name, si(s["mean"], sc.channel.capacity_unit), si(s["min"], sc.channel.capacity_unit), f"{s['outage_fraction']:.1%}")
    console.print(t)
    console.print(f"resolution: {json.dumps(summary['resolution'])}", markup=False, highlight=False)
    console.print(f"wrote {out}", markup=False, highlight=False)


# an estimated jammer's rows: its final error beside the spread the estimator reported, when it first came within 1 m
ESTIMATION_KEYS = ("estimation_err_final_m", "estimation_std_final_m", "estimation_nees_final", "estimation_trusted_final",
                   "estimation_first_within_1m_s")
DIRECT_KEYS = ("c_min_direct", "c_mean_direct", "c_min_over_direct", "c_mean_over_direct")  # sim.baseline = "direct"
KEY_METRICS = (
    "c_min", "c_mean", *DIRECT_KEYS, "se_21_mean", "se_10_mean", "outage_fraction", "alignment_ok_fraction",
    "alignment_within_slack_fraction",
    "slack_active_fraction", "infeasible_fraction", "fallback_fraction", "solve_ms.mean", "solve_ms.p99",
    "feedback_ms.mean", "feedback_ms.p99", "position_error_mean_m",
    "distance_m", "energy_kJ", "motor_saturation_fraction", "rate_saturation_fraction", "final_z_m", "max_tilt_deg",
    "min_altitude_m", "box_violation_max_m", "safety_violations",
    "taylor_rel_err_max", "wall_s", "sim_s",
    "capacity_efficiency_mean", "capacity_efficiency_min", "bound.path_mean.mean", "bound.path_maxmin.min",
    "bound.path_mean.outage_fraction", "bound.static.mean", "capacity_efficiency_mean_flyable",
    "capacity_efficiency_min_flyable", "bound.flyable_mean.mean", "bound.flyable_maxmin.min",
    "bound.flyable.mean", "c_mean_before_loss", "c_mean_after_loss", "capacity_efficiency_mean_after_loss",
    # what a scenario's own features add (shown only where a run has them)
    "wind_speed_mean_m_s", "drag_accel_mean_m_s2", "observer_error_mean_m_s2", "obstacle_clearance_min_m",
    *ESTIMATION_KEYS, "separation_min_m", "telemetry_rejected_periods",
    "hold_fraction", "land_fraction", "soc_final_fraction", "battery_reserve_first_s", "went_home_at_s", "landed_at_s",
    "exit_status",
)


def _lookup(m: dict, key: str):
    """A dotted metric, or None where an older run folder does not have it."""
    try:
        return api.metric(m, key)
    except (KeyError, TypeError):
        return None


def unit_system(m: dict) -> str:
    """A run's unit system: metrics.json's ``unit_system`` (older runs: the paper's normalized units)."""
    return str(m.get("unit_system", "normalized"))


def _unit_of(key: str, capacity_unit: str) -> str:
    """The unit of a dotted key of KEY_METRICS (``bound.*`` capacities in the capacity's unit)."""
    if key.startswith("bound."):
        return "1" if key.endswith("outage_fraction") else capacity_unit
    return api.metric_unit(key.split(".")[0], capacity_unit) or ""


def _node_keys(runs: dict[str, dict]) -> list[str]:
    """Every route's and every relay's key metrics of the runs (any number of relays and sources: the same rows for
    one as for many; a relay's row shows where a network's relays differ, one relay's where its top-level value is)."""
    routes = sorted({s for m in runs.values() for s in m.get("routes", {})})
    relays = sorted({r for m in runs.values() for r in m.get("relays", {})})
    return ([f"routes.{s}.{q}" for s in routes for q in ("c_min", "c_mean")]
            + [f"relays.{r}.{q}" for r in relays for q in ("position_error_mean_m", "energy_kJ", "box_violation_max_m",
                                                          "solve_ms.mean", "solve_ms.p99", "fallback_fraction",
                                                          "infeasible_fraction", "soc_final_fraction",
                                                          "battery_reserve_first_s", "went_home_at_s", "landed_at_s",
                                                          "exit_status")]
            + ["fleet_solve_ms.mean", "fleet_solve_ms.p99", "bound.static.mean", "bound.achieved.mean",
               "capacity_efficiency_mean_achieved"])


def _metrics_table(runs: dict[str, dict], ratio: bool = False) -> Table:
    """Key metrics of runs of one unit system, each value with its unit (SI prefixes on bit/s, m, s, ...)."""
    si = api.si
    capacity_unit = "bit/s" if unit_system(next(iter(runs.values()))) == "physical" else "bit/s/Hz"
    t = Table(show_header=True)
    t.add_column("metric")
    for name in runs:
        t.add_column(name, justify="right")
    if ratio:
        t.add_column("ratio B/A", justify="right")
    for key in dict.fromkeys([*KEY_METRICS, *_node_keys(runs)]):
        vals = [_lookup(m, key) for m in runs.values()]
        if all(v is None for v in vals):
            continue  # a feature no run has (a bound, wind, losses, ...): no row of dashes
        if any(isinstance(v, str) for v in vals):
            t.add_row(key, *["-" if v is None else str(v) for v in vals], *(["-"] if ratio else []))
            continue
        generic = key.split(".", 2)[2] if key.startswith(("routes.", "relays.")) else key  # a node's metric: its quantity's unit
        unit = _unit_of(generic, capacity_unit)
        row = [key, *["-" if v is None else si(float(v), unit) for v in vals]]
        if ratio:
            a, b = vals
            if a is None or b is None:
                row.append("-")
            else:
                row.append(f"{b / a:.3g}" if a not in (0, 0.0) else ("inf" if b else "-"))
        t.add_row(*row)
    return t


@app.command()
def compare(
    run_a: Path = typer.Argument(..., help="first run folder (A)", show_default=False),
    run_b: Path = typer.Argument(..., help="second run folder (B)", show_default=False),
):
    """Print the key metrics of two runs side by side, with the ratio B/A."""
    runs = {}
    for d in (run_a, run_b):
        try:
            runs[str(d)] = api.read_metrics(d)
        except OutputError as exc:
            _fail(str(exc))
    systems = [unit_system(m) for m in runs.values()]
    if systems[0] != systems[1]:
        _fail(f"{run_a} is in {systems[0]} units (capacity in {'bit/s' if systems[0] == 'physical' else 'bit/s/Hz'}), "
              f"{run_b} in {systems[1]} units: their ratio would mean nothing; compare runs of one unit system "
              "(channel.units)")
    console.print(f"A = {run_a}\nB = {run_b}", markup=False, highlight=False)
    console.print(_metrics_table(dict(zip(("A", "B"), runs.values(), strict=False)), ratio=True))


@app.command()
def bench(
    scenario: Path = typer.Argument(..., help="scenario TOML file, e.g. scenarios/nominal_tilted.toml", show_default=False),
    duration: float = typer.Option(None, "--duration", help="simulate only this many seconds", show_default=False),
    variant: str = typer.Option(None, "--variant", help="constrained | unconstrained (overrides the scenario)", show_default=False),
    planner: str = typer.Option(None, "--planner", show_default=False,
                                help="trajectory_generator | isotropic | single_shot | capacity (overrides the scenario)"),
    control_rate_hz: float = typer.Option(None, "--control-rate-hz", help="controller rate (overrides sim.control_rate_hz)", show_default=False),
    ipopt_points: int = typer.Option(None, "--ipopt-points", min=0, show_default=False,
                                     help="states at which a full IPOPT solve is timed (default 3; not with --backend c)"),
    json_out: Path = typer.Option(None, "--json", help="also write the figures to this JSON file", show_default=False),
    backend: str = typer.Option("hpipm", "--backend", help="QP route: hpipm (compiled engine), casadi (casadi.conic), or "
                                "c: the first relay's controller as the C tree of aerorelay codegen (HPIPM engine, these "
                                "solver options baked in) against the Python one on the same mission, alternating, pinned"),
    rounds: int = typer.Option(None, "--rounds", min=1, max=20, show_default=False,
                               help="--backend c: rounds of Python then C (default 3); --chain: rounds of the counts in turn (default 1)"),
    condense: int = typer.Option(0, "--condense", min=0, help="hpipm backend: partial condensing to this many stages (0: none)"),
    qp_solver: str = typer.Option("hpipm", "--qp-solver", help="casadi backend: the casadi.conic plugin"),
    tol: float = typer.Option(1e-3, "--tol", help="QP complementarity tolerance (HPIPM)"),
    warm_start: str = typer.Option("primal_dual", "--warm-start", help="hpipm backend: none, primal or primal_dual"),
    iter_max: int = typer.Option(None, "--iter-max", min=1, show_default=False,
                                 help="QP interior-point iteration cap (default: the scenario's, 50 unless [controller.capacity] qp_iter_max)"),
    accept_tol: float = typer.Option(None, "--accept-tol", min=0.0, show_default=False,
                                     help="hpipm backend: use a capped QP whose primal residuals are <= this (0: never; "
                                          "default: the scenario's)"),
    simd: bool = typer.Option(True, "--simd/--no-simd", help="hpipm backend: AVX2 BLASFEO kernels where the CPU has them"),
    feedback: str = typer.Option(None, "--feedback", show_default=False,
                                 help="solve | sensitivity (default: sensitivity on the uncondensed hpipm engine)"),
    set_: list[str] = typer.Option(None, "--set", help=SET_HELP, show_default=False),
    unset: list[str] = typer.Option(None, "--unset", help=UNSET_HELP, show_default=False),
    chain: str = typer.Option(None, "--chain", show_default=False,
                              help="relay counts, e.g. 1,2,4,8,16: the scenario's network replaced by a generated long chain "
                                   "of each count (experiments.chains; its other settings kept), each relay's step and the "
                                   "fleet's timed per count"),
    chain_length: float = typer.Option(250.0, "--chain-length", help="--chain: the chain's length, m"),
):
    """Time the controller on a mission: preparation vs feedback phase, planner, percentiles, deadline misses, IPOPT ratio."""
    if chain is not None:
        _bench_chains(scenario, chain, chain_length, json_out, set_, unset,
                      {"sim.duration_s": duration, "controller.variant": variant, "controller.planner": planner,
                       "sim.control_rate_hz": control_rate_hz},
                      dict(backend=backend, condensed_horizon=condense, qp_solver=qp_solver, tol_comp=tol,
                           warm_start=warm_start, simd_kernels=simd, feedback=feedback, iter_max=iter_max,
                           accept_tol=accept_tol), refused={"--ipopt-points": ipopt_points, "--rounds": rounds})
        return
    sc = _load_or_exit(scenario, set_, unset, {"sim.duration_s": duration, "controller.variant": variant,
                                               "controller.planner": planner, "sim.control_rate_hz": control_rate_hz})
    if backend == "c":
        if ipopt_points is not None:
            _fail("--ipopt-points: the C bench times the C tree's step only (no IPOPT); leave it out with --backend c")
        _bench_c(sc, rounds if rounds is not None else 3, json_out, condensed_horizon=condense, tol_comp=tol,
                 warm_start=warm_start, simd_kernels=simd, feedback=feedback, iter_max=iter_max, accept_tol=accept_tol)
        return
    if rounds is not None:
        _fail(f"--rounds applies to --backend c (Python against the C tree), not to --backend {backend}")
    ipopt_points = 3 if ipopt_points is None else ipopt_points
    try:
        settings = api.solver_settings(sc, backend=backend, condensed_horizon=condense, qp_solver=qp_solver, tol_comp=tol,
                                 warm_start=warm_start, simd_kernels=simd, feedback=feedback, iter_max=iter_max,
                                 accept_tol=accept_tol)
    except ValueError as exc:
        _fail(str(exc))
    res = api.bench(sc, settings, ipopt_points=ipopt_points)
    # the same tables for one relay and for K: the slowest relay's step in detail, then each relay's and the fleet's
    t = Table(title=f"bench: {res['scenario']}, {res['steps']} steps, {res['sim_s']:.1f} s simulated; the slowest relay, "
                    f"{res['slowest_relay']!r}")
    t.add_column("timing (ms)")
    for c in ("mean", "p50", "p95", "p99", "max"):
        t.add_column(c, justify="right")
    for key in ("preparation_ms", "feedback_ms", "step_ms", "planner_ms", "step_with_planner_ms", "estimator_ms",
                "step_with_planner_and_estimator_ms", "ipopt_ms"):
        if key in res:
            t.add_row(key.removesuffix("_ms"), *[f"{res[key][c]:.3f}" for c in ("mean", "p50", "p95", "p99", "max")])
    console.print(t)
    it = res["qp_iterations"]
    console.print(f"QP route: {res['route']}; IPM iterations per step: mean {it['mean']:.2f}, p99 {it['p99']:.0f}, "
                  f"max {it['max']}", markup=False, highlight=False)
    console.print(f"the slowest relay's steps over 2 ms (500 Hz): {res['misses_at_500Hz']}", markup=False, highlight=False)
    _print_fleet_bench(res)
    gcs = res["garbage_collections"]
    console.print("garbage collections during the flight (young / middle / full): "
                  + " / ".join(f"{n} (longest {ms:.2f} ms)" for n, ms in zip(gcs["collections"], gcs["max_ms"], strict=True)),
                  markup=False, highlight=False)
    if res["planner_preflight_s"] > 0:
        console.print(f"planner's pre-flight route: {res['planner_preflight_s']:.2f} s before take-off", markup=False, highlight=False)
    if "ipopt_over_rti_mean" in res:
        console.print(f"full IPOPT solve / RTI step (means): x{res['ipopt_over_rti_mean']:.0f} "
                      f"(IPOPT converged {res['ipopt_converged']})", markup=False, highlight=False)
    if json_out is not None:
        json_out.write_text(api.strict_json_text(res))


def _bench_chains(base: Path, counts: str, length_m: float, json_out: Path | None, sets, unsets, options: dict,
                  solver: dict, refused: dict) -> None:
    """``aerorelay bench --chain 1,2,4,8``: generated long chains of each count, each relay's step and the fleet's."""
    rounds = refused.pop("--rounds") or 1
    for opt, value in refused.items():
        if value is not None:
            _fail(f"{opt}: not with --chain (a chain bench times every relay's RTI step and the fleet's)")
    if unsets:
        _fail("--unset: not with --chain (the chain writes its network anew; --set changes the rest)")
    if solver["backend"] == "c":
        _fail("--backend c: not with --chain (the C tree is one relay's controller)")
    try:
        ks = [int(v) for v in counts.split(",") if v.strip()]
    except ValueError:
        _fail(f"--chain: relay counts separated by commas, e.g. 1,2,4,8,16; got {counts!r}")
    if not ks or any(not 1 <= k <= 16 for k in ks) or len(set(ks)) != len(ks):
        _fail(f"--chain: distinct relay counts in 1..16, e.g. 1,2,4,8,16; got {counts!r}")
    updates = {**api.parse_sets(sets or []), **{k: v for k, v in options.items() if v is not None}}
    try:
        res = api.bench_chains(base, ks, length_m, updates=updates, rounds=rounds,
                               settings_of=lambda sc: api.solver_settings(sc, **solver),
                               say=lambda s: console.print(s, markup=False, highlight=False))
    except (ScenarioError, ValueError) as exc:
        _fail(str(exc))
    t = Table(title=f"bench --chain: generated chains over {length_m:g} m ({res['machine']}); ms")
    for c in ("round", "K", "relay step", "worst relay mean / p99", "worst / one's", "brake law / failed QPs",
              "planner", "one computer mean / p99", "a computer each mean / p99"):
        t.add_column(c, justify="right")
    for i, k, c in ((i, k, c) for i, r in enumerate(res["rounds"]) for k, c in r.items()):
        one, own = c["fleet_step_one_computer_ms"], c["fleet_step_own_computers_ms"]
        t.add_row(str(i + 1), k, f"{c['relay_step_mean_ms']:.3f}", f"{c['relay_step_worst_mean_ms']:.3f} / {c['relay_step_worst_p99_ms']:.3f}",
                  f"{c['relay_step_over_one']:.2f}" if "relay_step_over_one" in c else "-",
                  f"{c['fallback_fraction_max']:.1%} / {c['qp_failure_fraction_max']:.1%}", f"{c['planner_ms']['mean']:.3f}",
                  f"{one['mean']:.2f} / {one['p99']:.2f}", f"{own['mean']:.2f} / {own['p99']:.2f}")
    console.print(t)
    if json_out is not None:
        json_out.write_text(api.strict_json_text(res))


def _bench_c(sc, rounds: int, json_out: Path | None, **solver) -> None:
    """``aerorelay bench --backend c``: the first relay's step in Python and as the C tree, alternating, pinned."""
    try:
        settings = api.solver_settings(sc, backend="hpipm", **solver)
        res = api.bench_c(sc, settings, rounds=rounds, say=lambda s: console.print(s, markup=False, highlight=False))
    except (ValueError, RuntimeError, ScenarioError) as exc:
        _fail(str(exc))
    stats = ("mean", "p50", "p95", "p99", "max")
    t = Table(title=f"bench --backend c: {res['scenario']}, {res['steps']} steps, {rounds} rounds, pinned to core "
                    f"{res['pinned_core']}")
    t.add_column("timing (ms)")
    for c in stats:
        t.add_column(c, justify="right")
    for i, r in enumerate(res["rounds"]):
        for key, label in (("python_step_ms", "Python step"), ("python_preparation_ms", "  preparation"),
                           ("python_feedback_ms", "  feedback"), ("c_step_ms", "C step (ar_step)"),
                           ("c_preparation_ms", "  preparation"), ("c_feedback_ms", "  feedback")):
            t.add_row(f"{i + 1}: {label}", *[f"{r[key][c]:.3f}" for c in stats])
    console.print(t)
    ratios = "; ".join(f"{r['c_step_ms']['mean'] / r['python_step_ms']['mean']:.2f} / "
                       f"{r['c_step_ms']['p99'] / r['python_step_ms']['p99']:.2f}" for r in res["rounds"])
    console.print(f"C step over Python step (mean / p99), per round: {ratios}; brake-law steps: {res['fallback_steps']}; "
                  f"BLASFEO's AVX2 kernels: {'yes' if res['simd'] else 'no'}", markup=False, highlight=False)
    if json_out is not None:
        json_out.write_text(api.strict_json_text(res))


def _print_fleet_bench(res: dict) -> None:
    """``aerorelay bench`` of any network (one relay too): each relay's step, the planner's and the fleet's."""
    stats = ("mean", "p50", "p95", "p99", "max")
    t = Table(title="each relay and the fleet")
    t.add_column("timing (ms)")
    for c in stats:
        t.add_column(c, justify="right")
    rows = [(f"{name}: {key.removesuffix('_ms')}", r[key]) for name, r in res["relays"].items()
            for key in ("preparation_ms", "feedback_ms", "step_ms") if key in r]  # a spare that never flew: none
    rows += [("fleet planner", res["planner_ms"]), ("fleet, one computer", res["fleet_step_one_computer_ms"]),
             ("fleet, a computer per relay", res["fleet_step_own_computers_ms"])]
    for label, v in rows:
        t.add_row(label, *[f"{v[c]:.3f}" for c in stats])
    console.print(t)
    shares = ", ".join(f"{n} {r['fallback_fraction']:.1%} / {r['qp_failure_fraction']:.1%}" for n, r in res["relays"].items()
                       if "fallback_fraction" in r)
    console.print(f"brake law / failed QPs, share of each relay's steps: {shares}", markup=False, highlight=False)
    misses = ", ".join(f"{n} {r.get('deadline_misses', 'never flew')}" for n, r in res["relays"].items())
    console.print(f"wall {res['wall_s']:.1f} s for {res['sim_s']:.1f} s simulated (x{res['real_time_factor']:.2f} real time); "
                  f"deadline misses vs {res['control_period_ms']:g} ms period: per relay {misses}; fleet on one computer "
                  f"{res['deadline_misses_one_computer']}, a computer per relay {res['deadline_misses_own_computers']}; "
                  f"QP failures: {res['qp_failures']}; fail-safe episodes: {res['fallback_episodes']}", markup=False, highlight=False)


def _studies_epilog() -> str:
    """The studies of the default studies folder, one per line with its title (read as TOML, not validated:
    ``--list`` validates and counts their runs)."""
    folder = api.default_studies_dir()
    lines = []
    for f in sorted(folder.glob("*.toml")) if folder.is_dir() else []:
        try:
            data = tomllib.loads(f.read_text())
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
            continue
        if isinstance(data.get("name"), str):
            lines.append(f"{data['name']}: {data.get('title', '')}")
    return ("Studies in " + str(folder) + ":\n\n" + "\n\n".join(lines)) if lines else ""


@contextlib.contextmanager
def _campaign_bar(label: str, field: str):
    """A campaign's progress bar on stderr (runs done of all, time, the last run's ``record[field]`` and status):
    yields ``started(n_runs)`` and ``progress(done, total, record)`` (``run_campaign``'s callback)."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    cols = (TextColumn(label), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(), TextColumn("{task.description}"))
    with Progress(*cols, console=err_console) as prog:
        task = prog.add_task("", total=1)

        def progress(done, total, rec):
            prog.update(task, completed=done, description="" if rec is None else f"{rec[field]}: {rec['status']}")

        yield (lambda n_runs: prog.update(task, total=n_runs)), progress


@app.command(epilog=_studies_epilog())
def reproduce(
    studies: list[str] = typer.Argument(None, help="study names (default: all in the studies folder)", show_default=False),
    out: Path = typer.Option(None, "--out", help="campaign folder (re-running the same command resumes it); required "
                             "unless --list", show_default=False),
    quick: bool = typer.Option(False, "--quick", help="fewer Monte Carlo seeds, shorter missions where the study allows"),
    list_: bool = typer.Option(False, "--list", help="print every study of the studies folder with its title and run count, "
                               "then exit"),
    scheduler: str = typer.Option(None, "--scheduler", help="address of an existing dask scheduler (default: local cluster)", show_default=False),
    studies_dir: Path = typer.Option(None, "--studies-dir", help="folder of study TOML files (default: experiments/)", show_default=False),
    workers: int = typer.Option(None, "--workers", min=1, help="local cluster size (default: one per core)", show_default=False),
    wait: bool = typer.Option(False, "--wait", help="wait for another campaign running in the same folder instead of refusing"),
    budget_min: float = typer.Option(None, "--budget-min", min=0.0, show_default=False,
                                     help="keep only the runs whose estimated wall time fits in this many minutes (default with "
                                          "--quick: 5; 0: no budget); what is left out is listed"),
):
    """Run the paper's experiments as a campaign on dask, then write report.html and summary.json
    (`aerorelay reproduce --list` names the studies)."""

    folder = studies_dir or api.default_studies_dir()
    if list_:
        try:
            listed = api.list_studies(folder, quick=quick)
        except StudyError as exc:
            _fail(str(exc))
        t = Table(title=f"studies in {folder}" + (" (--quick)" if quick else ""))
        for c in ("study", "runs", "title"):
            t.add_column(c, justify="right" if c == "runs" else "left")
        for name, title, runs in listed:  # a title may quote "pip install 'aerorelay[rt]'": not a style
            t.add_row(escape(name), "-" if runs is None else str(runs), escape(title))
        console.print(t)
        return
    if out is None:
        _fail("--out: a campaign folder is required (or --list)")
    _check_out(out, "campaign")

    try:
        with _campaign_bar("campaign", "key") as (started, progress):
            def on_start(n_runs, n_studies):
                started(n_runs)
                console.print(f"{n_runs} runs in {n_studies} studies -> {out}", markup=False, highlight=False)

            budget = QUICK_BUDGET_MIN if budget_min is None and quick else budget_min
            rep = api.reproduce(studies or None, out=out, quick=quick, studies_dir=folder, scheduler=scheduler, workers=workers,
                                plugins=_PLUGINS,
                                progress=progress, on_start=on_start, wait=wait,
                                budget_s=budget * 60.0 if budget else None)
    except (StudyError, CampaignBusyError, OutputError) as exc:
        _fail(str(exc))
    except KeyboardInterrupt:
        n = api.finished_runs(out)
        err_console.print(f"interrupted: {n} finished runs are kept in {out} (partial report: {out / 'report.html'}); "
                          "run the same command to resume", markup=False)
        raise typer.Exit(130) from None
    summary, res, meta = rep.summary, rep.campaign, rep.summary["campaign"]
    for notice in meta.get("notices", []):
        err_console.print(f"[bold yellow]note[/] {notice}", highlight=False)
    t = Table(title="the paper's claims on our numbers")
    t.add_column("claim")
    t.add_column("verdict")
    t.add_column("evidence")
    for c in summary["claims"]:
        t.add_row(c["claim"], {True: "holds", False: "does not hold", None: "not evaluated"}[c["holds"]], c["evidence"])
    console.print(t)
    console.print(f"ran {res.ran} runs ({meta['runs_failed']} failed), skipped {res.skipped} finished ones, "
                  f"wall {res.wall_s:.0f} s; report: {out / 'report.html'}", markup=False, highlight=False)
    if meta.get("runs_unsafe"):
        err_console.print(f"{meta['runs_unsafe']} unsafe run(s): listed in the report, their numbers not used", markup=False)
    if meta["runs_failed"] or meta.get("runs_unsafe"):
        raise typer.Exit(1)


@app.command()
def design(
    scenario: Path = typer.Argument(..., help="scenario TOML file (its mission, jammers, base stations, workspace)",
                                    show_default=False),
    out: Path = typer.Option(..., "--out", help="the design's folder (a campaign: re-running the command resumes it)",
                             show_default=False),
    relays: str = typer.Option("1-3", "--relays", help="the relay counts to try: 'A-B', 'K' or 'A,B,C' (1-16; the direct "
                               "link, no relay, is in every design)"),
    schedule: list[str] = typer.Option(["tdma"], "--schedule", help="a schedule to try (network.schedule: tdma, "
                                       "spatial_reuse, full_duplex); repeat for several"),
    by: str = typer.Option("c_mean", "--by", help="what 'best flown' means: c_mean or c_min"),
    bound: bool = typer.Option(True, "--bound/--no-bound", help="each point's capacity bound (its upper bound and flyable "
                               "path) beside its flight"),
    duration: float = typer.Option(None, "--duration", help="fly only this many seconds of the mission", show_default=False),
    scheduler: str = typer.Option(None, "--scheduler", help="address of an existing dask scheduler (default: local cluster)",
                                  show_default=False),
    workers: int = typer.Option(None, "--workers", min=1, help="local cluster size (default: one per core)", show_default=False),
    wait: bool = typer.Option(False, "--wait", help="wait for another campaign running in the same folder instead of refusing"),
    set_: list[str] = typer.Option(None, "--set", help=SET_HELP, show_default=False),
    unset: list[str] = typer.Option(None, "--unset", help=UNSET_HELP, show_default=False),
):
    """How many relays a mission needs, under which schedule: for each relay count (placed by the tool on the line from
    the base station toward the source) and schedule, capacity-seeking relays flown with their bound and against the
    direct link; design.json, design.png and the recommended design as recommended.toml."""
    from .experiments.design import parse_relays

    _check_duration(duration)
    sc = _load_or_exit(scenario, set_, unset)
    if duration is not None:
        sc = sc.with_updates({"sim.duration_s": duration})
    try:
        counts = parse_relays(relays)
    except ValueError as exc:
        _fail(str(exc))
    _check_out(out, "campaign")
    try:
        with _campaign_bar("design", "group") as (started, progress):
            def on_start(n_runs, estimate_s):
                started(n_runs)
                console.print(f"{n_runs} design points (relays {', '.join(map(str, counts))}; {', '.join(schedule)}) -> {out}; "
                              f"estimated {estimate_s / 60.0:.1f} min here", markup=False, highlight=False)

            summary = api.design(sc, out, relays=counts, schedules=schedule, bound=bound, by=by, scheduler=scheduler,
                                 workers=workers, progress=progress, on_start=on_start, wait=wait)
    except (ScenarioError, ValueError, CampaignBusyError, OutputError) as exc:
        _fail(str(exc))
    unit = sc.channel.capacity_unit
    t = Table(title=f"design: {by} per relay count and schedule ({unit})")
    for c in ("relays", "schedule", f"flown {by}", "bound (upper mean)", "flyable mean", "exit"):
        t.add_column(c, justify="left" if c in ("schedule", "exit") else "right")
    if summary["direct"] is not None:
        t.add_row("0", "direct link", api.si(float(summary["direct"][by]), unit), "-", "-", "-")
    for p in summary["points"]:
        f, b = p.get("flown") or {}, p.get("bound") or {}
        t.add_row(str(p["relays"]), p["schedule"], "-" if f.get(by) is None else api.si(float(f[by]), unit),
                  "-" if b.get("upper_mean") is None else api.si(float(b["upper_mean"]), unit),
                  "-" if b.get("flyable_mean") is None else api.si(float(b["flyable_mean"]), unit),
                  str(f.get("exit_status", p["status"])))
    console.print(t)
    rec = summary["recommended"]
    console.print(f"recommended: {rec.get('relays')} relays" + (f", {rec['schedule']}" if rec.get("schedule") else "")
                  + f" ({rec['why']}); {out / 'design.json'}, {out / 'design.png'}"
                  + (f", {out / 'recommended.toml'}" if rec.get("schedule") else ""), markup=False, highlight=False)
    if summary["missing"]:
        err_console.print(f"{len(summary['missing'])} design point(s) did not fly: {', '.join(summary['missing'])}", markup=False)
        raise typer.Exit(1)


@app.command()
def export(
    run_dir: Path = typer.Argument(..., help="a run folder (aerorelay run --out, or a campaign's runs/<study>/<run>/seed<k>)", show_default=False),
    fmt: str = typer.Option("mcap", "--format", help="mcap: run.mcap with Foxglove's schemas; csv (per vehicle: ENU, NED, "
                            "lat/lon/alt, attitude), plan (per relay: a QGroundControl mission), geojson or kml (every "
                            "vehicle's track), ulog (per relay: a PX4 ULog): into the folder's export/"),
    relay: str = typer.Option(None, "--relay", help="that relay only (csv, plan, geojson, kml, ulog)", show_default=False),
    origin: str = typer.Option(None, "--origin", help="lat_deg,lon_deg,alt_m of the run's local frame (default: its "
                               "scenario's [geo] origin; plan, geojson and kml need one)", show_default=False),
):
    """Write a run's flight for Foxglove (mcap), autopilots (plan, ulog) and GIS tools (geojson, kml, csv)."""
    where = None
    if origin is not None:
        try:
            where = tuple(float(v) for v in origin.split(","))
        except ValueError:
            _fail(f"--origin: three numbers lat_deg,lon_deg,alt_m, got {origin!r}")
        if len(where) != 3:
            _fail(f"--origin: three numbers lat_deg,lon_deg,alt_m, got {origin!r}")
    try:
        paths = api.export(run_dir, fmt, relay=relay, origin=where)  # type: ignore[arg-type]
    except (OutputError, ValueError) as exc:
        _fail(str(exc))
    if fmt == "mcap":
        console.print(f"wrote {paths[0]} (open it in Foxglove and import the folder's foxglove_layout.json: its panels "
                      "name this run's series)", markup=False, highlight=False)
        return
    for p in paths:
        console.print(f"wrote {p}", markup=False, highlight=False)


@app.command("report")
def report_cmd(
    out: Path = typer.Argument(..., help="a campaign folder (aerorelay reproduce --out) or one run folder (aerorelay run --out)",
                               show_default=False),
    studies_dir: Path = typer.Option(None, "--studies-dir", show_default=False,
                                     help="folder of study TOML files (default: the one the campaign ran with, else experiments/)"),
):
    """Render report.html (and a campaign's summary.json) from a campaign's finished runs (partial studies
    marked), or from one run folder."""
    if api.is_run_folder(out):
        try:
            path = api.report_run(out)
        except OutputError as exc:
            _fail(str(exc))
        console.print(f"report: {path}", markup=False, highlight=False)
        return
    try:
        summary = api.report(out, studies_dir=studies_dir)
    except StudyError as exc:
        _fail(str(exc))
    meta = summary["campaign"]
    console.print(f"{meta['runs_finished']} of {meta['runs_total']} runs finished; report: {out / 'report.html'}",
                  markup=False, highlight=False)


@app.command()
def sitl(
    scenario: Path = typer.Argument(..., help="scenario TOML file (the vehicle starts at its relay's start)", show_default=False),
    listen: str = typer.Option("udpin:127.0.0.1:14540", "--listen", help="MAVLink URL the vehicle listens on"),
    duration: float = typer.Option(None, "--duration", help="stop after this many seconds (default: run until Ctrl-C)",
                                   show_default=False),
    airframe: str = typer.Option("pointmass", "--airframe", help="pointmass (an ideal autopilot on a point mass) | plant "
                                 "(aerorelay's own plant for the scenario's platform under a multirotor autopilot's cascade) | "
                                 "rotorpy (RotorPy's Hummingbird quadrotor with its SE(3) and attitude controllers, in the "
                                 "scenario's [wind]; pip install 'aerorelay[rotorpy]')"),
    source: bool = typer.Option(False, "--source", help="be the inspection drone instead: fly the scenario's source mission "
                                "as MAVLink system 2 (for aerorelay fly --source-mavlink)"),
    relay: str = typer.Option(None, "--relay", help="a network's relay by name: start at its start as MAVLink system 1 + "
                              "its index (one sitl per relay, each on its own --listen)", show_default=False),
):
    """Run the in-repo MAVLink vehicle in real time: PX4's offboard subset (heartbeats, arming, modes, the
    offboard rules and timeout, position and attitude telemetry) on an ideal point-mass autopilot, aerorelay's own
    plant under a multirotor autopilot's cascade, or RotorPy's quadrotor; or, with --source, the inspection drone.
    For tests and demos of `aerorelay fly`: it tests the protocol, not PX4."""
    sc = _load_or_exit(scenario)
    _check_duration(duration)
    _check_url(listen, "--listen")
    if airframe not in ("pointmass", "plant", "rotorpy"):
        _fail(f"--airframe must be pointmass, plant or rotorpy, got {airframe!r}")
    try:
        api.relay_index(sc, relay)
    except ValueError as exc:
        _fail(str(exc))
    frame = api.plant_airframe(sc, relay) if airframe == "plant" else None
    if airframe == "rotorpy":
        try:
            frame = api.rotorpy_airframe(sc, relay=relay)  # RotorPy: an optional extra, imported when the airframe is made
        except ImportError as exc:
            _fail(f"--airframe rotorpy needs RotorPy (pip install 'aerorelay[rotorpy]'): {exc}")
    who = "the source, system 2" if source else airframe + (f", relay {relay}" if relay else "")
    console.print(f"vehicle ({who}) listening on {listen} (Ctrl-C stops)", markup=False, highlight=False)
    try:
        api.sitl(sc, listen, duration, airframe=frame, source=source, relay=relay)
    except KeyboardInterrupt:
        pass


@app.command()
def fly(
    scenario: Path = typer.Argument(..., help="scenario TOML file", show_default=False),
    mavlink: list[str] = typer.Option(..., "--mavlink", help="the autopilot's MAVLink URL (e.g. udpout:127.0.0.1:14540); a "
                                      "network: one per relay as NAME=URL, repeated (--mavlink r1=udpout:127.0.0.1:14541 "
                                      "--mavlink r2=udpout:127.0.0.1:14542)", show_default=False),
    arm: bool = typer.Option(False, "--arm", help="arm the vehicle (never without this flag)"),
    setpoint: str = typer.Option("position", "--setpoint", help="position (SET_POSITION_TARGET_LOCAL_NED with velocity and "
                                 "acceleration feed-forward) | attitude (SET_ATTITUDE_TARGET)"),
    duration: float = typer.Option(None, "--duration", help="fly this many seconds (default: the mission's length)",
                                   show_default=False),
    out: Path = typer.Option(None, "--out", help="write the flight's run folder here (timeseries.parquet, metrics.json, "
                             "figures, run.mcap, flight.parquet: the bridge's log)", show_default=False),
    source_mavlink: list[str] = typer.Option(None, "--source-mavlink", help="read the source (inspection drone) as a second "
                                             "MAVLink system on this URL (default: its mission file); a network: NAME=URL per "
                                             "source read so, repeated", show_default=False),
    source_system: int = typer.Option(None, "--source-system", min=1, max=255, help="the source's MAVLink system id "
                                      "(default: any on --source-mavlink)", show_default=False),
    source_origin: str = typer.Option("0,0,0", "--source-origin", help="where the source's local frame's origin lies in the "
                                      "scenario's world, x,y,z m ENU"),
):
    """Fly the scenario's controller on MAVLink autopilots in OFFBOARD, one per relay (--mavlink NAME=URL each; one
    relay: its URL alone): wait for their heartbeats, stream setpoints, arm only with --arm, ask for OFFBOARD, step
    the controller every period; a vehicle on stale telemetry holds, then lands and leaves the network; hand back to a
    hold at the end or on Ctrl-C."""
    sc = _load_or_exit(scenario)
    if setpoint not in ("position", "attitude"):
        _fail(f"--setpoint must be position or attitude, got {setpoint!r}")
    _check_duration(duration)
    names = [r.name for r in sc.relay_list]
    urls = _named_urls(mavlink, names, "--mavlink", "relay")
    if set(urls) != set(names):
        _fail(f"--mavlink: no vehicle for the relays {sorted(set(names) - set(urls))} (one NAME=URL per relay)")
    sources = _named_urls(source_mavlink or [], [s.name for s in sc.source_list], "--source-mavlink", "source")
    shared = sorted(set(urls.values()) & set(sources.values()))
    if shared:
        _fail(f"--source-mavlink: {shared[0]} is a relay's vehicle too (--mavlink): a source is another vehicle")
    try:
        origin = tuple(float(v) for v in source_origin.split(","))
    except ValueError:
        origin = ()
    if len(origin) != 3 or not all(math.isfinite(v) for v in origin):
        _fail(f"--source-origin must be three finite numbers x,y,z (m, ENU), got {source_origin!r}")
    done = _flown(lambda: api.fly(sc, urls, arm=arm, setpoint=setpoint, duration_s=duration, out=out, source_url=sources or None,
                                  source_system=source_system, source_origin=origin), out, "the vehicles were")
    if done is None:
        return
    result, df = done
    flown = df[~df["mode"].isin(["stream", "wait", "ended"])] if len(df) else df
    per = ", ".join(f"{n}: {int((flown['relay'] == n).sum()) if len(flown) else 0}" for n in names)
    nmpc = int((flown["mode"] == "nmpc").sum()) if len(flown) else 0
    console.print(f"control periods flown per relay ({per}; {nmpc} by the NMPC)" + (f"; run folder: {out}" if out else ""),
                  markup=False, highlight=False)
    if result is not None and result.metrics.get("lost_in_flight"):
        console.print("left the network: " + ", ".join(f"{e['relay']} at {e['t_s']:.2f} s" for e in result.metrics["lost_in_flight"]),
                      markup=False, highlight=False)
    _exit_if_unsafe(result)


def _named_urls(given: list[str], names: list[str], option: str, what: str) -> dict[str, str]:
    """``option``'s values by name: NAME=URL each, NAME one of ``names``; one plain URL is the one ``what``'s when there
    is one. Exits 2 naming the option on anything else."""
    out: dict[str, str] = {}
    for value in given:
        name, sep, url = value.partition("=")
        if not sep or "://" in name or ":" in name:  # a plain URL (udpout:host:port) has no NAME=
            if len(names) != 1 or len(given) != 1:
                _fail(f"{option} {value!r}: the scenario has {what}s {', '.join(names)}: give one NAME=URL per {what}")
            name, url = names[0], value
        elif name not in names:
            _fail(f"{option} {value!r}: NAME must be one of the scenario's {what}s: {', '.join(names)}")
        if name in out:
            _fail(f"{option}: {what} {name!r} given twice")
        _check_url(url, f"{option} {name}=" if sep else option)
        same = [n for n, u in out.items() if u == url]
        if same:  # one vehicle flown by two controllers: refused before anything is armed
            _fail(f"{option}: {what}s {same[0]!r} and {name!r} on one vehicle ({url}): one URL per {what}")
        out[name] = url
    return out


def _flown(fly: Callable[[], tuple], out: Path | None, who: str) -> tuple | None:
    """``fly()``'s flight and bridge log; a named error exits 2, Ctrl-C says where the flight is and gives None."""
    try:
        return fly()
    except (TimeoutError, OutputError, ScenarioError, ValueError) as exc:
        _fail(str(exc))
    except KeyboardInterrupt:
        console.print(f"interrupted: {who} asked to hold" + (f"; the flight is in {out}" if out else ""),
                      markup=False, highlight=False)
    return None


def _exit_if_unsafe(result, what: str = "flight") -> None:
    """Exit 3 when a run's or flight's metrics say it was unsafe or ended early, 4 when a relay's controller did not
    fly it (``fell_back``), naming why."""
    if result is None:
        return
    m = result.metrics
    if m.get("unsafe"):
        err_console.print(f"[bold red]unsafe {what}[/]: {escape(str(m['unsafe_reason']))} (exit {EXIT_UNSAFE})",
                          highlight=False)
        raise typer.Exit(EXIT_UNSAFE)
    if m.get("fell_back"):
        err_console.print(f"[bold yellow]{what} fell back[/]: {escape(str(m['fell_back_reason']))} (exit {EXIT_FELL_BACK})",
                          highlight=False)
        raise typer.Exit(EXIT_FELL_BACK)


@app.command()
def ros(
    scenario: Path = typer.Argument(..., help="scenario TOML file", show_default=False),
    relay: str = typer.Option(None, "--relay", help="the one relay's topic namespace (/<relay>/odom, /<relay>/setpoint; "
                              "default: its name in the scenario)", show_default=False),
    source: str = typer.Option(None, "--source", help="the one source's topic namespace (/<source>/odom; default: its name)",
                               show_default=False),
    duration: float = typer.Option(None, "--duration", help="stop after this many seconds (default: until Ctrl-C)", show_default=False),
    out: Path = typer.Option(None, "--out", help="write the flight's run folder here (timeseries.parquet, metrics.json, "
                             "figures, run.mcap)", show_default=False),
):
    """Run the scenario's controller as one ROS 2 node (the optional extra: pip install 'aerorelay[ros]'): subscribes
    nav_msgs/Odometry of every relay and source, each under its name in the scenario (/<relay>/odom, /<source>/odom),
    publishes trajectory_msgs/MultiDOFJointTrajectory setpoints per relay (/<relay>/setpoint) and the network's link
    state (/network/link) every control period."""
    sc = _load_or_exit(scenario)
    relays, sources = [r.name for r in sc.relay_list], [s.name for s in sc.source_list]
    topics: dict[str, str] = {}
    try:
        for flag, given, names in (("--relay", relay, relays), ("--source", source, sources)):
            if given is None:
                continue
            if len(names) != 1:
                raise ValueError(f"{flag}: renames the scenario's one {flag[2:]}; its {flag[2:]}s ({', '.join(names)}) are "
                                 "their topics' namespaces")
            topics[names[0]] = check_ros_namespace(given, flag)
        for n in (*relays, *sources):
            check_ros_namespace(topics.get(n, n), "a relay's or source's name")
    except ValueError as exc:
        _fail(str(exc))
    _check_duration(duration)
    try:
        from .flight import ros_node  # the optional extra: imported only here
    except ImportError as exc:
        _fail(f"the ROS 2 node needs the ros extra (pip install 'aerorelay[ros]'): {exc}")
    ends = ", ".join(f"/{topics.get(r, r)}/odom -> /{topics.get(r, r)}/setpoint" for r in relays)
    console.print(f"ROS 2 node: {ends}; sources " + ", ".join(f"/{topics.get(s, s)}/odom" for s in sources) + "; /network/link",
                  markup=False, highlight=False)
    try:
        node, result = api.ros(sc, ros_node.spin, duration, out=out, topics=topics)
    except OutputError as exc:
        _fail(str(exc))
    except KeyboardInterrupt:
        return
    console.print(f"{len(node.commands)} control periods stepped" + (f"; run folder: {out}" if out else ""),
                  markup=False, highlight=False)
    _exit_if_unsafe(result)


if __name__ == "__main__":  # pragma: no cover
    app()
