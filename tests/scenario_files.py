"""A scenario written as TOML text in a test, loaded as a user's file is (``ar.load_scenario``: data, physics and the
parts' checks, file paths relative to its folder)."""

from pathlib import Path

import aerorelay as ar


def scenario_from_text(folder: Path, text: str, name: str = "scenario.toml"):
    path = Path(folder) / name
    path.write_text(text)
    return ar.load_scenario(path)
