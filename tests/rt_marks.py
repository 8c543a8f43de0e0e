"""Whether Sionna RT (the optional ``rt`` extra) is here: ``needs_rt`` skips a test without it, unless CI
requires it (``AERORELAY_REQUIRE_RT=1``: then the test runs and fails, never skips silently)."""

from __future__ import annotations

import os

import pytest

from aerorelay.models import raytrace

try:
    raytrace.sionna_rt()
    MISSING = None
except raytrace.RayTracingUnavailable as exc:
    MISSING = str(exc)
SKIP_RT = MISSING is not None and os.environ.get("AERORELAY_REQUIRE_RT") != "1"
needs_rt = pytest.mark.skipif(SKIP_RT, reason=f"optional rt extra: {MISSING}")
