"""Independent random streams per purpose (models/streams.py), checked against numpy's own
SeedSequence.spawn and for overlaps between purposes and between consecutive seeds."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from aerorelay.models.propagation import LargeScaleRealization, PathGain, RmaAvPathGain
from aerorelay.models.streams import PURPOSES, generator, stream


@given(st.integers(0, 2**32))
def test_a_stream_is_numpys_spawned_child(seed):
    children = np.random.SeedSequence(seed).spawn(len(PURPOSES))
    for k, purpose in enumerate(PURPOSES):
        want = np.random.default_rng(children[k]).random(4)
        np.testing.assert_array_equal(generator(seed, purpose).random(4), want)


@given(st.integers(0, 10_000))
def test_no_two_purposes_of_this_or_the_next_seed_share_draws(seed):
    draws = {(s, p): generator(s, p).random(8) for s in (seed, seed + 1) for p in PURPOSES}
    for a, b in itertools.combinations(draws, 2):
        assert not np.allclose(draws[a], draws[b]), (a, b)


def test_the_old_offsets_overlapped_and_the_streams_do_not():
    """``seed + 1`` (fading) of run s was run s+1's closed-loop stream: with the streams they differ."""
    old_fading_run0 = np.random.default_rng(0 + 1).random(4)
    old_csi_run1 = np.random.default_rng(1).random(4)
    np.testing.assert_array_equal(old_fading_run0, old_csi_run1)
    assert not np.allclose(generator(0, "fading").random(4), generator(1, "csi").random(4))


def test_the_los_states_and_the_shadowing_field_draw_from_their_own_streams():
    rma = LargeScaleRealization(RmaAvPathGain(carrier_hz=2.4e9), 3, std_db=0.0, decorrelation_m=10.0, seed=7)
    np.testing.assert_array_equal(rma.u, generator(7, "los").uniform(size=3))
    shadow = LargeScaleRealization(PathGain(), 3, std_db=4.0, decorrelation_m=10.0, seed=7)
    first = np.random.default_rng(stream(7, "shadowing")).standard_normal((3, 3, 256))
    assert np.all(np.sign(shadow.field.omega) == np.sign(first))  # omega = z / (d sqrt(chi2)): the same normals


def test_an_unknown_purpose_is_named():
    with pytest.raises(ValueError, match="random stream 'weather'"):
        stream(0, "weather")
