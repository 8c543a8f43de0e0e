"""Every script in examples/ runs (a short mission each) and prints what it promises."""

import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))


def test_the_python_api_guide_names_every_example():
    guide = (ROOT / "docs" / "guide" / "python-api.md").read_text()
    assert [p.name for p in EXAMPLES if f"`{p.name}`" not in guide] == []


def test_every_example_is_tested():
    assert {p.name for p in EXAMPLES} >= {"fly_nominal.py", "two_jammers_one_moving.py", "directional_jammer.py",
                                          "own_planner.py", "dask_sweep.py", "estimator_batch.py",
                                          "relay_chain.py", "two_sources.py"}


@pytest.mark.parametrize("script", EXAMPLES, ids=lambda p: p.name)
def test_example_runs(script, tmp_path):
    env = {**os.environ, "AERORELAY_EXAMPLE_DURATION": "1.0", "AERORELAY_EXAMPLE_OUT": str(tmp_path / "out"),
           "AERORELAY_EXAMPLE_BOUND": "0"}
    res = subprocess.run([sys.executable, str(script)], cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    assert "C_min" in res.stdout or "c_min" in res.stdout.lower(), res.stdout
    assert not re.search(r"\b(nan|inf)\b", res.stdout, re.IGNORECASE), res.stdout  # every printed number is one
    values = [float(v) for v in re.findall(r"C_min\s+([-+0-9.]+(?:e[-+]?\d+)?)", res.stdout)]
    assert all(math.isfinite(v) and v > 0 for v in values), res.stdout
    if script.name == "fly_nominal.py":  # the regression value of the nominal mission's first second
        assert values == [pytest.approx(1.294e-2, rel=1e-3)], res.stdout
