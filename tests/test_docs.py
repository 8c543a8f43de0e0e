"""The documentation cannot drift from the code: the scenario reference is generated from the
schema (every field with its type, default, unit, range and description; a field without a
description fails the build) and the README stays a front door."""

import re
import sys
from pathlib import Path

import pytest

from aerorelay.config import Scenario

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "docs" / "_ext"))
import scenario_reference  # noqa: E402


def _leaf_fields(model, prefix=""):
    from aerorelay.config.errors import _submodel

    for name, info in model.model_fields.items():
        sub = _submodel(info.annotation)
        yield prefix + name, info
        if sub is not None:
            yield from _leaf_fields(sub, f"{prefix}{name}.")


def test_every_schema_field_is_in_the_reference_with_its_description():
    text = scenario_reference.render()
    for key, info in _leaf_fields(Scenario):
        name = key.split(".")[-1]
        assert f"| `{name}` |" in text, key
        if info.description:
            assert " ".join(info.description.split())[:40].replace("|", "\\|") in text, key


def test_the_committed_scenario_reference_is_the_schemas():
    """The reference is in the repository (its links work in a clone before any docs build) and is
    what the schema renders: a field changed without regenerating it fails here."""
    committed = (ROOT / "docs" / "reference" / "scenario.md").read_text()
    assert committed == scenario_reference.render(), (
        "docs/reference/scenario.md is stale: make docs (or python -c \"import sys; sys.path.insert(0, 'docs/_ext'); "
        "import scenario_reference as s; open('docs/reference/scenario.md', 'w').write(s.render())\") rewrites it")


def test_the_committed_study_reference_is_the_schemas():
    """Issue 48 (item 3): the study files' reference, generated like the scenario's, committed and current."""
    committed = (ROOT / "docs" / "reference" / "study.md").read_text()
    assert committed == scenario_reference.render_study(), (
        "docs/reference/study.md is stale: python -c \"import sys; sys.path.insert(0, 'docs/_ext'); import scenario_reference "
        "as s; open('docs/reference/study.md', 'w').write(s.render_study())\" rewrites it")
    for name in ("base", "grid", "seeds", "claims", "ranking"):
        assert f"| `{name}` |" in committed


def test_a_field_without_a_description_fails_the_build(monkeypatch):
    from sphinx.errors import ExtensionError

    from aerorelay.config import WorldConfig

    monkeypatch.setattr(WorldConfig.model_fields["ground_z_m"], "description", None)
    with pytest.raises(ExtensionError, match="world.ground_z_m"):
        scenario_reference.render()


def test_units_come_from_the_field_name_or_its_description():
    assert scenario_reference._unit("decorrelation_m", "") == "m"
    assert scenario_reference._unit("omega_dot_max_hz_s", "") == "Hz/s"
    assert scenario_reference._unit("position", "m, world (the start when moving)") == "m"
    assert scenario_reference._unit("forget_s", "time constant") == "s"
    assert scenario_reference._unit("exponent", "n of the sin^n pattern") == ""


def test_the_readme_is_a_front_door():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) < 150
    text = "\n".join(lines[:30])
    assert "make run" in text and "make test" in text
    for link in [part.split(")")[0] for part in "\n".join(lines).split("](")[1:]]:
        if not link.startswith("http"):
            assert (ROOT / link.split("#")[0]).exists(), link


LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)")


def _anchors(md: Path) -> set[str]:
    """The heading anchors MyST makes (``myst_heading_anchors = 3``: levels 1-3), GitHub's slug rule."""
    out = set()
    for line in md.read_text().splitlines():
        m = re.match(r"^(#{1,3})\s+(.*)$", line)
        if m:
            text = re.sub(r"[`*_]", "", m.group(2)).strip().lower()
            out.add(re.sub(r"\s", "-", re.sub(r"[^\w\s-]", "", text)))
    return out


def test_every_relative_link_in_the_docs_and_the_readme_resolves():
    """Issue 48 (item 7): every relative link in docs/ and the README names a file that exists (in a clone,
    before any docs build) and, with ``#anchor``, a heading of that page."""
    pages = [p for p in (ROOT / "docs").rglob("*.md") if "_build" not in p.parts] + [ROOT / "README.md"]
    broken = []
    for page in pages:
        for target in LINK.findall(page.read_text()):
            if re.match(r"^[a-z]+:", target) or target.startswith("#") and not target[1:]:
                continue  # a web address, mailto
            path, _, anchor = target.partition("#")
            dest = page if not path else (page.parent / path).resolve()
            if not dest.exists():
                broken.append(f"{page.relative_to(ROOT)}: {target} (no such file)")
            elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
                broken.append(f"{page.relative_to(ROOT)}: {target} (no such heading)")
    assert not broken, "\n".join(broken)
    anchors = _anchors(ROOT / "docs" / "results" / "networks.md")  # the checker sees headings, and only them
    assert {"the-network-bound", "timing-a-fleet"} <= anchors and "the-network-bounds" not in anchors
