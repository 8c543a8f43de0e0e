"""The campaign report opened in a real headless Chromium: it loads, logs no console error, and
every figure decodes. Needs Debian's chromium (``.ci/run`` installs it); skipped elsewhere unless
``AERORELAY_REQUIRE_BROWSER=1`` (set by CI), which turns a missing browser into a failure."""

import os
import shutil
from pathlib import Path

import pytest

from aerorelay.experiments.campaign import load_manifest, run_campaign
from aerorelay.experiments.study import expand, find_studies
from aerorelay.report.html import render_report
from aerorelay.report.summary import summarize

from ..experiments.test_campaign import ROOT, TINY

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.fixture()
def browser():
    if CHROMIUM is None:
        if os.environ.get("AERORELAY_REQUIRE_BROWSER") == "1":
            pytest.fail("chromium is required (AERORELAY_REQUIRE_BROWSER=1) but not installed")
        pytest.skip("no chromium on this machine (apt-get install chromium)")
    try:
        from playwright import sync_api
    except ImportError:
        if os.environ.get("AERORELAY_REQUIRE_BROWSER") == "1":
            pytest.fail("playwright is required (AERORELAY_REQUIRE_BROWSER=1) but not installed (pip install playwright)")
        pytest.skip("playwright is not installed (the dev extra has it)")
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox", "--disable-gpu",
                              "--disable-background-networking", "--disable-component-update", "--no-first-run"])
        yield b
        b.close()


@pytest.mark.parametrize("seeds", [1, 3])
def test_report_opens_cleanly_in_headless_chromium(tmp_path, browser, seeds):
    """One seed: the 3D view of the runs renders. Three seeds of a run with CSI noise (a deterministic run
    flies one seed): the distribution over seeds is drawn (issue 48, item 4)."""
    from dask.distributed import Client, LocalCluster

    studies_dir = tmp_path / "studies"
    studies_dir.mkdir()
    tiny = TINY if seeds == 1 else TINY.replace("[[runs]]", f"seeds = {seeds}\n\n[[runs]]", 1).replace(
        '"sim.duration_s" = 0.3', '"sim.duration_s" = 0.3, "perturbations.csi_noise_m" = 0.05')
    (studies_dir / "tiny.toml").write_text(tiny)
    study = find_studies(studies_dir)[0]
    specs = expand(study, ROOT)
    out = tmp_path / "campaign"
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0") as cl, Client(cl) as c:
        run_campaign(specs, out, client=c)
    report = out / "report.html"
    report.write_text(render_report(summarize([study], specs, out), [study], specs, out, load_manifest(out)))

    page = browser.new_page(viewport={"width": 1280, "height": 900})
    errors = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(Path(report).resolve().as_uri())
    page.wait_for_load_state("load")
    images = page.eval_on_selector_all("img", "els => els.map(e => [e.complete, e.naturalWidth])")
    assert len(images) >= 2
    assert all(done and width > 0 for done, width in images), images
    assert "two short runs" in page.inner_text("body")
    spread = page.eval_on_selector_all("img[alt='C_min and mean C over seeds, per run']", "els => els.map(e => e.naturalWidth)")
    assert len(spread) == (seeds >= 3) and all(w > 0 for w in spread)  # the distribution over seeds drawn
    assert page.eval_on_selector_all(".js-plotly-plot", "els => els.length") == (seeds == 1)  # the 3D view rendered
    assert errors == []
    # a reader at 1280 px never scrolls sideways: not the page, not a table inside it
    scroll, width = page.evaluate("[document.documentElement.scrollWidth, document.documentElement.clientWidth]")
    assert scroll <= width
    assert page.evaluate("Array.from(document.querySelectorAll('.wide')).filter(e => e.scrollWidth > e.clientWidth + 1).length") == 0
    assert page.eval_on_selector_all("details", "els => els.length") >= 1  # the other columns on demand
