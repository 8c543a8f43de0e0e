"""Command-line interface: ``aerorelay validate|info|run|compare|bench``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from .config import Scenario, ScenarioError, load_scenario

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Communications-aware aerial relay under jamming.")
console = Console()
err_console = Console(stderr=True, soft_wrap=True)

EXIT_BAD_INPUT = 2


def _load_or_exit(path: Path) -> Scenario:
    try:
        return load_scenario(path)
    except ScenarioError as exc:
        err_console.print(f"[bold red]invalid scenario[/] {path}:")
        for line in str(exc).splitlines():
            err_console.print(f"  {line}", markup=False, highlight=False)
        raise typer.Exit(EXIT_BAD_INPUT) from None


@app.command()
def validate(scenario: Path = typer.Argument(..., help="scenario TOML file")):
    """Validate a scenario and print it fully resolved (every default spelled out)."""
    sc = _load_or_exit(scenario)
    print(f"# {scenario}: valid")
    print(sc.to_toml())


def model_summary(sc: Scenario) -> Table:
    """A table of the derived physical quantities of a scenario (hover, allocation, channel at t=0)."""
    from .sim.initial import initial_link_budget

    veh = sc.platform.vehicle()
    F, M = veh.allocation()
    hover = veh.hover_speeds()
    budget = initial_link_budget(sc)
    t = Table(title=f"model summary: {sc.name}", show_header=True)
    t.add_column("quantity")
    t.add_column("value", justify="right")
    t.add_row("rotors / tilt", f"{veh.n_rotors} / {sc.platform.tilt_deg:g} deg")
    t.add_row("allocation rank [F; M]", str(np.linalg.matrix_rank(np.vstack([F, M]))))
    t.add_row("hover speeds (Hz)", ", ".join(f"{h:.2f}" for h in hover))
    t.add_row("hover shaft power (W)", f"{veh.shaft_power(hover):.1f}")
    t.add_row("Gamma_21 at t=0", f"{budget['gamma_21']:.4f}")
    t.add_row("Gamma_10 at t=0", f"{budget['gamma_10']:.4f}")
    t.add_row("end-to-end capacity C at t=0", f"{budget['capacity']:.4f}")
    t.add_row("mutual alignment at t=0", f"{budget['mutual_alignment']:.3f} (mu = {sc.controller.mu})")
    t.add_row("mission length (s)", f"{sc.duration_s:g}")
    return t


@app.command()
def info(scenario: Path = typer.Argument(..., help="scenario TOML file")):
    """Print the scenario's derived model quantities: hover, allocation rank, initial link budget."""
    sc = _load_or_exit(scenario)
    console.print(model_summary(sc))


if __name__ == "__main__":  # pragma: no cover
    app()
