"""Ray-traced links (models/raytrace.py) against independent values: Friis in an empty scene, the
two-ray floor reflection with the half-space Fresnel coefficient of the floor's own material, the
analytic dipole link of ``models.radio.link_gain`` for the line of sight, reciprocity, the two-ray
delay spread. Needs the optional ``rt`` extra (CI requires it: ``AERORELAY_REQUIRE_RT=1``)."""

from __future__ import annotations

import numpy as np
import pytest

from aerorelay.models import raytrace
from aerorelay.models.antenna import DipolePattern, IsotropicPattern
from aerorelay.models.propagation import PathGain, wavelength_m
from aerorelay.models.radio import link_gain
from aerorelay.models.raytrace import RayTracer, RayTracingUnavailable, TraceSettings
from tests.rt_marks import needs_rt

F = 2.4e9
ISO = IsotropicPattern(1.0)
UP = np.array([0.0, 0.0, 1.0])


def test_a_missing_extra_is_named_with_the_llvm_library(monkeypatch):
    import builtins

    real = builtins.__import__

    def no_sionna(name, *a, **k):
        if name.startswith(("sionna", "mitsuba")):
            raise ImportError(f"No module named {name!r}")
        return real(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", no_sionna)
    with pytest.raises(RayTracingUnavailable, match=r"aerorelay\[rt\].*libllvm19"):
        raytrace.sionna_rt()


@needs_rt
def test_an_empty_scene_gives_friis():
    """(lambda / 4 pi d)^2 within 0.05 dB at 10, 50 and 300 m, one path, coherent = power sum."""
    tracer = RayTracer(TraceSettings("empty", F, max_depth=0))
    tx = np.array([[0.0, 0.0, 10.0]] * 3)
    rx = np.array([[10.0, 0.0, 10.0], [30.0, 40.0, 10.0], [0.0, 300.0, 40.0]])
    links = tracer.trace(tx, rx)
    d = np.linalg.norm(rx - tx, axis=1)
    friis = (wavelength_m(F) / (4 * np.pi * d)) ** 2
    got = links.gain(ISO, UP, ISO, UP)
    np.testing.assert_allclose(10 * np.log10(got / friis), 0.0, atol=0.05)
    np.testing.assert_array_equal(links.paths, [1, 1, 1])
    np.testing.assert_allclose(links.gain(ISO, UP, ISO, UP, coherent=False), got, rtol=1e-6)


@needs_rt
@pytest.mark.parametrize("heights", [(1.5, 1.0), (1.2, 2.5), (1.8, 1.8)])
def test_one_floor_reflection_is_the_fresnel_half_space_coefficient(heights):
    """``floor_wall`` (a 4 m x 4 m floor at z = 0, a wall in the plane x = 0 from z = 0.9 to 2.9 m): the wall
    blocks the line of sight between ends at x = -5 and 5 m at these heights, so the floor's specular
    reflection is the only path; with the floor's thickness set large (a half space) its amplitude over
    the unfolded path's free-space amplitude is the TM (vertical polarization) Fresnel coefficient of the
    floor's own permittivity and conductivity at the carrier, ``eps = eps_r - j sigma / (omega eps0)``."""
    tracer = RayTracer(TraceSettings("floor_wall", F, max_depth=1), cached=False)  # its material changed below
    floor = tracer.scene.objects["floor"].radio_material
    floor.thickness = 50.0
    h1, h2 = heights
    tx, rx = np.array([[-5.0, 0.0, h1]]), np.array([[5.0, 0.0, h2]])
    links = tracer.trace(tx, rx)
    assert links.paths[0] == 1
    eps = float(np.asarray(floor.relative_permittivity).ravel()[0]) - 1j * float(np.asarray(floor.conductivity).ravel()[0]) / (
        2 * np.pi * F * 8.8541878128e-12)
    d2 = np.hypot(10.0, h1 + h2)
    cos_i = (h1 + h2) / d2
    root = np.sqrt(eps - (1 - cos_i**2))
    gamma_tm = (eps * cos_i - root) / (eps * cos_i + root)
    amplitude = np.sqrt(links.gain(ISO, UP, ISO, UP)[0]) / (wavelength_m(F) / (4 * np.pi * d2))
    assert amplitude == pytest.approx(abs(gamma_tm), rel=5e-4)  # Sionna traces in float32 (1.1e-4 measured at the steepest)
    # the path leaves downward toward the floor and arrives from below it, mirrored
    np.testing.assert_allclose(links.departure[0, 0], np.array([10.0, 0.0, -(h1 + h2)]) / d2, atol=1e-5)
    np.testing.assert_allclose(links.arrival[0, 0], np.array([-10.0, 0.0, -(h1 + h2)]) / d2, atol=1e-5)


@needs_rt
def test_the_dipole_weighting_of_the_line_of_sight_is_the_analytic_link():
    """Random poses and axes: the traced line of sight weighed by our dipoles equals ``link_gain`` with
    the free-space path gain (eq. 6), float32 tracing aside (1e-4)."""
    rng = np.random.default_rng(4)
    tx = rng.uniform(-50, 50, (6, 3))
    rx = rng.uniform(-50, 50, (6, 3))
    b_tx = rng.normal(size=(6, 3))
    b_rx = rng.normal(size=(6, 3))
    b_tx /= np.linalg.norm(b_tx, axis=1, keepdims=True)
    b_rx /= np.linalg.norm(b_rx, axis=1, keepdims=True)
    dip = DipolePattern(1.0)
    got = RayTracer(TraceSettings("empty", F, max_depth=0)).trace(tx, rx).gain(dip, b_tx, dip, b_rx)
    want = np.array([float(link_gain(tx[i], b_tx[i], dip, rx[i], b_rx[i], dip, PathGain.free_space(F))) for i in range(6)])
    np.testing.assert_allclose(got, want, rtol=1e-4)


@needs_rt
def test_swapping_a_links_ends_gives_the_same_gain_and_the_frame_sits_where_it_is_told():
    """``simple_street_canyon``, reflections up to depth 2, dipoles at tilted axes: the link and its
    reverse (ends, patterns and axes swapped) have the same coherent gain; the scenario's frame moved by
    ``origin_m`` and turned by ``yaw_deg`` traces the same link where its ends land in the scene."""
    dip = DipolePattern(1.0)
    a, b = np.array([[-20.0, 3.0, 1.5]]), np.array([[25.0, -4.0, 20.0]])
    ax_a, ax_b = np.array([0.2, 0.1, 0.97]), np.array([-0.3, 0.0, 0.95])
    ax_a, ax_b = ax_a / np.linalg.norm(ax_a), ax_b / np.linalg.norm(ax_b)
    tracer = RayTracer(TraceSettings("simple_street_canyon", F, max_depth=2))
    forward = tracer.trace(a, b)
    backward = tracer.trace(b, a)
    assert forward.paths[0] > 1  # reflections off the canyon's walls
    g_f, g_b = forward.gain(dip, ax_a, dip, ax_b)[0], backward.gain(dip, ax_b, dip, ax_a)[0]
    assert g_f == pytest.approx(g_b, rel=1e-3)
    yaw = np.radians(30.0)
    Rz = np.array([[np.cos(yaw), -np.sin(yaw), 0.0], [np.sin(yaw), np.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    origin = np.array([5.0, -2.0, 0.0])
    moved = RayTracer(TraceSettings("simple_street_canyon", F, origin_m=tuple(origin), yaw_deg=30.0, max_depth=2))
    # the same scene points expressed in the moved frame: x = Rz^T (x_scene - origin)
    g_m = moved.trace((a - origin) @ Rz, (b - origin) @ Rz).gain(dip, ax_a @ Rz, dip, ax_b @ Rz)[0]
    assert g_m == pytest.approx(g_f, rel=1e-3)


@needs_rt
def test_the_two_ray_delay_spread():
    """Line of sight and one floor reflection (``floor_wall``, both ends on one side of the wall and below
    it): the RMS delay spread of two paths of powers w1, w2 and delays t1, t2 is
    ``sqrt(w1 w2) |t2 - t1| / (w1 + w2)``, the delays' difference the unfolded path's extra length over c."""
    tracer = RayTracer(TraceSettings("floor_wall", F, max_depth=1))
    tx, rx = np.array([[-1.5, -1.5, 0.5]]), np.array([[-1.0, 1.5, 0.3]])
    links = tracer.trace(tx, rx)
    v = links.valid[0]
    assert v.sum() == 2
    w = links.path_powers(ISO, UP, ISO, UP)[0, v]
    t = links.tau[0, v]
    want = np.sqrt(w[0] * w[1]) * abs(t[1] - t[0]) / (w[0] + w[1])
    assert links.delay_spread(ISO, UP, ISO, UP)[0] == pytest.approx(want, rel=1e-6)
    flat = np.hypot(0.5, 3.0)
    assert abs(t[1] - t[0]) == pytest.approx((np.hypot(flat, 0.8) - np.hypot(flat, 0.2)) / 299_792_458.0, rel=1e-3)


@needs_rt
def test_a_trace_is_kept_in_memory_and_on_disk_keyed_by_what_it_depends_on(tmp_path, monkeypatch):
    """The same links traced twice call the solver once; a new tracer (empty memory) reads them from the disk
    cache, equal; another carrier or another end is traced again."""
    monkeypatch.setenv("AERORELAY_CACHE", str(tmp_path))
    settings = TraceSettings("floor_wall", F, max_depth=1)
    tx, rx = np.array([[-1.5, -1.5, 0.5]]), np.array([[-1.0, 1.5, 0.3]])

    def counted(tracer):
        calls = []
        solver = tracer.solver
        tracer.solver = lambda *a, **k: calls.append(1) or solver(*a, **k)
        return calls

    first = RayTracer(settings)
    calls = counted(first)
    a = first.trace(tx, rx)
    first.trace(tx, rx)
    assert len(calls) == 1
    second = RayTracer(settings)
    calls = counted(second)
    b = second.trace(tx, rx)
    assert not calls
    np.testing.assert_array_equal(a.a, b.a)
    np.testing.assert_array_equal(a.arrival, b.arrival)
    second.trace(tx, rx + 0.1)
    assert len(calls) == 1
    other = RayTracer(TraceSettings("floor_wall", 3.5e9, max_depth=1))
    calls = counted(other)
    other.trace(tx, rx)
    assert len(calls) == 1


@needs_rt
def test_links_of_several_transmitters_are_each_traced_from_their_own_and_a_fixed_ends_links_once(tmp_path, monkeypatch):
    """Links of three transmitters in any order (one serving two receivers) each come out as Friis for their own ends,
    one solver call per transmitter, each asked with the settings' rays; a transmitter's links to the same receivers
    again (another order, other transmitters beside it) come from memory: only the new transmitter is traced."""
    monkeypatch.setenv("AERORELAY_CACHE", str(tmp_path))
    tracer = RayTracer(TraceSettings("empty", F, max_depth=0, rays_per_source=20_000))
    asked = []
    solver = tracer.solver
    tracer.solver = lambda *a, **k: asked.append(k["samples_per_src"]) or solver(*a, **k)
    A, B, C = [0.0, 0.0, 10.0], [50.0, 5.0, 3.0], [-20.0, 7.0, 30.0]
    tx = np.array([A, B, A, C])
    rx = np.array([[10.0, 0.0, 10.0], [30.0, 40.0, 10.0], [0.0, 300.0, 40.0], [30.0, 40.0, 10.0]])
    links = tracer.trace(tx, rx)
    friis = (wavelength_m(F) / (4 * np.pi * np.linalg.norm(rx - tx, axis=1))) ** 2
    np.testing.assert_allclose(10 * np.log10(links.gain(ISO, UP, ISO, UP) / friis), 0.0, atol=0.05)
    np.testing.assert_allclose(np.linalg.norm(links.departure[:, 0] - (rx - tx) / np.linalg.norm(rx - tx, axis=1)[:, None],
                                              axis=1), 0.0, atol=1e-5)
    assert asked == [20_000] * 3 and tracer.calls == 3
    D = [5.0, -9.0, 2.0]
    again = tracer.trace(np.array([D, A, A]), np.array([[0.0, 0.0, 1.0], [0.0, 300.0, 40.0], [10.0, 0.0, 10.0]]))
    assert tracer.calls == 4  # D's link only
    np.testing.assert_array_equal(again.a[1], links.a[2])
    np.testing.assert_array_equal(again.a[2], links.a[0])


@needs_rt
def test_the_coherent_sum_is_the_two_ray_field_with_the_carriers_phase():
    """Line of sight and the floor's reflection (``floor_wall`` as a half space, both ends on one side of the
    wall): the narrowband gain is ``|lambda/(4 pi d1) e^(-j k d1) + Gamma_TM lambda/(4 pi d2) e^(-j k d2)|^2``
    (the classic two-ray model with the floor's own Fresnel coefficient), written out here; the power sum
    is the two terms' squares added."""
    tracer = RayTracer(TraceSettings("floor_wall", F, max_depth=1), cached=False)
    floor = tracer.scene.objects["floor"].radio_material
    floor.thickness = 50.0
    eps = float(np.asarray(floor.relative_permittivity).ravel()[0]) - 1j * float(np.asarray(floor.conductivity).ravel()[0]) / (
        2 * np.pi * F * 8.8541878128e-12)
    lam, k = wavelength_m(F), 2 * np.pi / wavelength_m(F)
    for tx, rx in (((-1.5, -1.5, 0.5), (-1.0, 1.5, 0.3)), ((-1.8, 0.0, 0.6), (-0.2, 1.0, 0.7)), ((-1.0, -1.0, 0.4), (-1.2, 1.7, 0.45))):
        tx, rx = np.array(tx), np.array(rx)
        links = tracer.trace(tx[None], rx[None])
        assert links.paths[0] == 2 and links.los[0].sum() == 1
        flat = np.hypot(*(rx - tx)[:2])
        d1, d2 = np.linalg.norm(rx - tx), np.hypot(flat, tx[2] + rx[2])
        cos_i = (tx[2] + rx[2]) / d2
        root = np.sqrt(eps - (1 - cos_i**2))
        gamma = (eps * cos_i - root) / (eps * cos_i + root)
        field = lam / (4 * np.pi * d1) * np.exp(-1j * k * d1) + gamma * lam / (4 * np.pi * d2) * np.exp(-1j * k * d2)
        assert links.gain(ISO, UP, ISO, UP)[0] == pytest.approx(abs(field) ** 2, rel=2e-3)
        power = (lam / (4 * np.pi * d1)) ** 2 + abs(gamma) ** 2 * (lam / (4 * np.pi * d2)) ** 2
        assert links.gain(ISO, UP, ISO, UP, coherent=False)[0] == pytest.approx(power, rel=2e-3)


def _gamma_tm(eps, h_sum, flat):
    """The half-space TM (vertical polarization) Fresnel coefficient at the specular point of ends ``h_sum``
    apart in height (summed) and ``flat`` apart horizontally."""
    cos_i = h_sum / np.hypot(flat, h_sum)
    root = np.sqrt(eps - (1 - cos_i**2))
    return (eps * cos_i - root) / (eps * cos_i + root)


@needs_rt
def test_links_carried_to_moved_ends_match_tracing_them_again():
    """Ends moved by 5 cm, the traced links carried there (``TracedLinks.moved``) against a new trace: the line of
    sight exact (length, directions, power); the floor's reflection's delay to second order (within
    2 |dp|^2 / length over c); its coefficient held where it was traced, so its power is the new trace's
    times ``|Gamma(old angle)|^2 / |Gamma(new angle)|^2`` of the half-space Fresnel coefficient (written out
    here): what tracing below the control rate costs, the coefficient's change with the angle."""
    tracer = RayTracer(TraceSettings("floor_wall", F, max_depth=1), cached=False)
    floor = tracer.scene.objects["floor"].radio_material
    floor.thickness = 50.0
    eps = float(np.asarray(floor.relative_permittivity).ravel()[0]) - 1j * float(np.asarray(floor.conductivity).ravel()[0]) / (
        2 * np.pi * F * 8.8541878128e-12)
    tx0, rx0 = np.array([[-1.5, -1.5, 0.5]]), np.array([[-1.0, 1.5, 0.3]])
    tx1, rx1 = tx0 + [0.03, -0.04, 0.0], rx0 + [0.0, 0.03, 0.04]
    carried = tracer.trace(tx0, rx0).moved(tx0, rx0, tx1, rx1, F)
    fresh = tracer.trace(tx1, rx1)
    los_c, los_f = carried.los[0], fresh.los[0]
    ref_c, ref_f = carried.valid[0] & ~los_c, fresh.valid[0] & ~los_f
    assert los_c.sum() == los_f.sum() == 1 and ref_c.sum() == ref_f.sum() == 1
    np.testing.assert_allclose(carried.departure[0][los_c][0], (rx1 - tx1)[0] / np.linalg.norm(rx1 - tx1), atol=1e-12)
    assert carried.tau[0][los_c][0] == pytest.approx(np.linalg.norm(rx1 - tx1) / 299_792_458.0, rel=1e-12)
    assert np.abs(carried.a[0][los_c][0]) ** 2 == pytest.approx(np.abs(fresh.a[0][los_f][0]) ** 2, rel=1e-5)
    assert carried.tau[0][ref_c][0] == pytest.approx(fresh.tau[0][ref_f][0], abs=2 * 0.05**2 / 3.0 / 299_792_458.0)
    held = abs(_gamma_tm(eps, 0.8, np.hypot(*(rx0 - tx0)[0, :2]))) ** 2
    now = abs(_gamma_tm(eps, tx1[0, 2] + rx1[0, 2], np.hypot(*(rx1 - tx1)[0, :2]))) ** 2
    ratio = np.abs(carried.a[0][ref_c][0]) ** 2 / np.abs(fresh.a[0][ref_f][0]) ** 2
    assert ratio == pytest.approx(held / now, rel=5e-3)
    assert abs(held / now - 1) > 0.05  # the held coefficient is the error, and it is not small here
