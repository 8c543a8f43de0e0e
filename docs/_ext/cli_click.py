"""The CLI as a click command, for sphinx-click's reference (typer builds it from ``aerorelay.cli.app``)."""

from typer.main import get_command

from aerorelay.cli import app

command = get_command(app)
