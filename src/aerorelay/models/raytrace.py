"""Ray-traced links (Sionna RT), weighed by aerorelay's own antennas at each node's attitude.

A link is traced **once with isotropic antennas** at both ends (Sionna RT's ``PathSolver``: line of
sight, specular reflection, refraction, diffuse reflection (scattering) and diffraction as chosen,
up to ``max_depth`` interactions). Each traced path ``p`` carries a complex coefficient ``a_p`` at
the carrier (``|a_p|^2`` its path gain: ``(lambda / 4 pi d)^2`` in free space, times each
interaction's coefficient; its phase the interactions' times the propagation's ``exp(-j 2 pi f_c
tau_p)``, which Sionna's baseband coefficients leave to its ``cfr``), a delay ``tau_p`` (s), the direction it leaves the transmitter ``u_t,p`` and the
direction it arrives from at the receiver ``u_r,p`` (unit, pointing from the receiver toward the
path's last point). aerorelay then weighs each path by each end's **own pattern toward that
direction in its body frame**: with antenna axes ``b_tx`` and ``b_rx`` (unit, world) the path's power
gain is ``G_tx(u_t,p . b_tx) G_rx(u_r,p . b_rx)`` (``AntennaPattern.gain_from_cos``; for the line of
sight exactly the analytic channel's ``link_gain``, eq. 6). The link's power gain is then

- ``coherent`` (narrowband): ``|sum_p a_p sqrt(G_tx,p G_rx,p)|^2``: the paths add with their phases
  (the field changes over half a wavelength, 6 cm at 2.4 GHz);
- ``power`` (wideband, paths resolved): ``sum_p |a_p|^2 G_tx,p G_rx,p``.

**Polarization** is what the isotropic trace carried: both ends vertically polarized (Sionna's
``"V"``), so each interaction's coefficient is that polarization's; the weighting changes the power
toward each direction, not the polarization a tilted dipole would have (a relay's tilt changes its
field's polarization too: not modelled, said beside the results). The RMS delay spread of a link is
``sqrt(sum w_p tau_p^2 / sum w_p - (sum w_p tau_p / sum w_p)^2)`` with ``w_p`` the weighed path powers.

The scenario's frame sits in the scene at ``origin_m`` (m, the scene's coordinates of the scenario's
origin) turned by ``yaw_deg`` (deg, about z, counter-clockwise): ``x_scene = Rz(yaw) x + origin``.
On CPU Sionna RT runs Mitsuba's LLVM variant, which needs the system's LLVM (Debian: ``libllvm19``);
its GPU variant is used when present.
"""

from __future__ import annotations

import functools
import glob
import hashlib
import os
import re
import tempfile
import threading
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..filecheck import not_a_file
from ..store.cache import cache_dir, cache_lock, entry_is_intact, file_digest, publish_checked
from .propagation import SPEED_OF_LIGHT_M_S

RT_EXTRA = ("the ray-traced channel needs the optional extra: pip install 'aerorelay[rt]' (Sionna RT) and, on a machine "
            "without a GPU, the system's LLVM library for its CPU variant (Debian/Ubuntu: apt-get install libllvm19)")
TRACE_VERSION = "3"  # bump when a trace's computation changes: cached traces are traced again
MEMORY_TRACES = 4096  # traces kept in memory (the oldest dropped first) ...
MEMORY_BYTES = 512 * 2**20  # ... and at most this many bytes of them (a radio map's trace holds thousands of links)
SCENE_NAMES_HINT = "a scene shipped with Sionna RT (simple_street_canyon, munich, etoile, floor_wall, box, ...) or a Mitsuba XML file"


class RayTracingUnavailable(RuntimeError):
    """Sionna RT (the ``rt`` extra) or the LLVM library its CPU variant needs is missing."""


def llvm_available() -> bool:
    """Whether a system LLVM library of version 16 or later (Dr.Jit's CPU back end) is installed."""
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return Path(os.environ["DRJIT_LIBLLVM_PATH"]).is_file()
    found = [p for pattern in ("/usr/lib/libLLVM*.so*", "/usr/lib/*/libLLVM*.so*", "/usr/lib64/libLLVM*.so*",
                               "/usr/local/lib/libLLVM*.so*", "/usr/lib/llvm-*/lib/libLLVM*.so*") for p in glob.glob(pattern)]
    for path in found:
        m = re.search(r"libLLVM[-.](?:so\.)?(\d+)", Path(path).name)
        if m and int(m.group(1)) >= 16:
            return True
    return False


def sionna_rt():
    """The ``sionna.rt`` module, or ``RayTracingUnavailable`` naming the extra and the LLVM library."""
    try:
        import mitsuba as mi
        import sionna.rt as rt  # the optional extra: imported only when a ray-traced channel is asked for (sets the variant)
    except ImportError as exc:
        raise RayTracingUnavailable(f"{RT_EXTRA} ({exc})") from None
    if str(mi.variant()).startswith("llvm") and not llvm_available():  # Dr.Jit would abort the process at the first trace
        raise RayTracingUnavailable(f"{RT_EXTRA}: no GPU and no LLVM 16 or later found (Mitsuba variant {mi.variant()})")
    return rt


def unit_from_angles(theta, phi) -> np.ndarray:
    """Unit vectors ``(..., 3)`` from zenith ``theta`` and azimuth ``phi`` (rad; Sionna's angles)."""
    theta, phi = np.asarray(theta, float), np.asarray(phi, float)
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=-1)


def rotation_z(yaw_rad: float) -> np.ndarray:
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class TracedLinks:
    """``n`` traced links of up to ``P`` paths each: complex coefficients ``a`` ``(n, P)`` (0 where a path is
    not valid), delays ``tau`` ``(n, P)`` (s), departure and arrival unit directions ``(n, P, 3)`` in the
    scenario's frame (departure: leaving the transmitter; arrival: from the receiver toward where the path
    comes from), ``valid`` ``(n, P)``, ``los`` ``(n, P)``: the path is the line of sight (no interaction)."""

    a: np.ndarray
    tau: np.ndarray
    departure: np.ndarray
    arrival: np.ndarray
    valid: np.ndarray
    los: np.ndarray

    FIELDS = ("a", "tau", "departure", "arrival", "valid", "los")

    def moved(self, tx0: np.ndarray, rx0: np.ndarray, tx1: np.ndarray, rx1: np.ndarray, carrier_hz: float) -> TracedLinks:
        """The links traced with their ends at ``tx0``, ``rx0`` carried to ``tx1``, ``rx1`` (``(n, 3)``, m) without
        tracing again. The line of sight exactly: its length ``|rx1 - tx1|``, its directions, its amplitude
        ``lambda / (4 pi d)`` and phase ``-2 pi d / lambda`` at the new length. Every other path to first order
        in the ends' displacements, its interactions where they were (a plane wave at each end): its length
        changes by ``-u_t . (tx1 - tx0) - u_r . (rx1 - rx0)`` (``u_t``, ``u_r`` its departure and arrival
        directions), its amplitude as ``1 / length`` and its phase with it; its directions kept. A path that
        appears or vanishes between two traces (a line of sight blocked) does so at the next trace."""
        lam = SPEED_OF_LIGHT_M_S / carrier_hz
        tx0, rx0, tx1, rx1 = (np.atleast_2d(np.asarray(v, float)) for v in (tx0, rx0, tx1, rx1))
        length = self.tau * SPEED_OF_LIGHT_M_S
        dl = -np.einsum("npi,ni->np", self.departure, tx1 - tx0) - np.einsum("npi,ni->np", self.arrival, rx1 - rx0)
        d = rx1 - tx1
        dist = np.linalg.norm(d, axis=1, keepdims=True)
        u = d / np.maximum(dist, 1e-12)
        los_len = np.broadcast_to(dist, length.shape)
        new_len = np.where(self.los, los_len, np.maximum(length + dl, 1e-9))
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = np.where(self.valid & (length > 0), length / new_len, 0.0)
        a = self.a * scale * np.exp(-2j * np.pi * (new_len - length) / lam)
        departure = np.where(self.los[..., None], u[:, None, :], self.departure)
        arrival = np.where(self.los[..., None], -u[:, None, :], self.arrival)
        return TracedLinks(np.where(self.valid, a, 0.0), np.where(self.valid, new_len / SPEED_OF_LIGHT_M_S, 0.0),
                           departure, arrival, self.valid, self.los)

    def take(self, index) -> TracedLinks:
        """The links at ``index`` (an index array or a slice)."""
        return TracedLinks(*(getattr(self, f)[index] for f in self.FIELDS))

    @property
    def paths(self) -> np.ndarray:
        """``(n,)``: how many valid paths each link has."""
        return self.valid.sum(axis=1)

    def path_powers(self, pat_tx, b_tx, pat_rx, b_rx) -> np.ndarray:
        """``(n, P)``: each path's power gain weighed by both ends' patterns toward its directions (``b_tx``,
        ``b_rx``: ``(n, 3)`` or ``(3,)`` antenna axes, unit, scenario frame)."""
        return np.abs(self.a) ** 2 * self._weights(pat_tx, b_tx, pat_rx, b_rx)

    def _weights(self, pat_tx, b_tx, pat_rx, b_rx) -> np.ndarray:
        b_tx, b_rx = np.asarray(b_tx, float), np.asarray(b_rx, float)
        c_t = np.einsum("npi,ni->np", self.departure, np.broadcast_to(b_tx, (len(self.a), 3)))
        c_r = np.einsum("npi,ni->np", self.arrival, np.broadcast_to(b_rx, (len(self.a), 3)))
        w = np.asarray(pat_tx.gain_from_cos(np.clip(c_t, -1.0, 1.0)), float) * np.asarray(pat_rx.gain_from_cos(np.clip(c_r, -1.0, 1.0)), float)
        return np.where(self.valid, w, 0.0)

    def gain(self, pat_tx, b_tx, pat_rx, b_rx, coherent: bool = True) -> np.ndarray:
        """``(n,)``: each link's power gain with the ends' patterns at their axes, the paths summed with
        their phases (``coherent``) or in power (module docstring)."""
        w = self._weights(pat_tx, b_tx, pat_rx, b_rx)
        if coherent:
            return np.abs(np.sum(self.a * np.sqrt(w), axis=1)) ** 2
        return np.sum(np.abs(self.a) ** 2 * w, axis=1)

    def delay_spread(self, pat_tx, b_tx, pat_rx, b_rx) -> np.ndarray:
        """``(n,)`` RMS delay spread (s) over the weighed path powers (0 for a link of one path or none)."""
        w = self.path_powers(pat_tx, b_tx, pat_rx, b_rx)
        total = w.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.sum(w * self.tau, axis=1) / total
            var = np.sum(w * self.tau**2, axis=1) / total - mean**2
        return np.where(total > 0, np.sqrt(np.maximum(var, 0.0)), 0.0)


@dataclass(frozen=True)
class TraceSettings:
    """What a trace is: the scene (a Sionna scene's name or a Mitsuba XML file's path), the carrier (Hz),
    where the scenario's frame sits in the scene (``origin_m`` m, ``yaw_deg`` deg), at most ``max_depth``
    interactions per path, found by ``rays_per_source`` rays shot from each transmitter (Sionna's
    ``samples_per_src``; the paths found are exact, fewer rays may miss weak ones), and which
    interactions (``reflection``: specular; ``scattering``: diffuse reflection; ``diffraction``: on
    edges; ``refraction``: through objects)."""

    scene: str
    carrier_hz: float
    origin_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    yaw_deg: float = 0.0
    max_depth: int = 3
    rays_per_source: int = 1_000_000
    reflection: bool = True
    scattering: bool = False
    diffraction: bool = False
    refraction: bool = False


class RayTracer:
    """Traces links in one Sionna RT scene (``TraceSettings``): ``trace(tx (n, 3), rx (n, 3))`` -> the ``n``
    links ``tx[i] -> rx[i]`` (m, the scenario's frame), one Sionna call per distinct transmitter not cached."""

    def __init__(self, settings: TraceSettings, cached: bool = True):
        """``cached``: every trace kept in memory and on disk (the cache folder's ``traces/``), keyed by the scene's
        files, the settings and the ends: a scene's files edited, or a setting changed, is traced again (a scene
        changed in Python after loading, its materials for instance, is not in the key: trace it uncached)."""
        rt = sionna_rt()
        self.settings, self.cached = settings, cached
        self.digest = scene_digest(rt, settings.scene)
        self._memory: dict[str, TracedLinks] = {}
        self._memory_bytes = 0
        self._lock = threading.RLock()
        self.calls = 0  # Sionna calls made (traces not found in a cache)
        self.rt = rt
        self.R = rotation_z(np.radians(settings.yaw_deg))
        self.origin = np.asarray(settings.origin_m, float)
        self._tx: list[str] = []
        self._rx: list[str] = []

    @functools.cached_property
    def scene(self):
        """The Sionna scene, loaded at the first trace that is not cached (a bound or route read from the cache never
        loads it), isotropic vertically polarized antennas at both ends, at the settings' carrier."""
        scene = load_scene(self.rt, self.settings.scene)
        scene.frequency = float(self.settings.carrier_hz)
        iso = dict(num_rows=1, num_cols=1, vertical_spacing=0.5, horizontal_spacing=0.5, pattern="iso", polarization="V")
        scene.tx_array = self.rt.PlanarArray(**iso)
        scene.rx_array = self.rt.PlanarArray(**iso)
        return scene

    @functools.cached_property
    def solver(self):
        """Sionna's path solver (made with the scene, at the first trace that is not cached)."""
        return self.rt.PathSolver()

    def to_scene(self, p: np.ndarray) -> np.ndarray:
        """Points ``(..., 3)`` of the scenario's frame in the scene's coordinates (m)."""
        return np.asarray(p, float) @ self.R.T + self.origin

    def _place(self, kind: str, names: list[str], positions: np.ndarray) -> None:
        cls = self.rt.Transmitter if kind == "tx" else self.rt.Receiver
        while len(names) < len(positions):
            name = f"aerorelay_{kind}{len(names)}"
            self.scene.add(cls(name, position=[0.0, 0.0, 0.0]))
            names.append(name)
        while len(names) > len(positions):
            self.scene.remove(names.pop())
        for name, p in zip(names, positions, strict=True):
            self.scene.get(name).position = [float(v) for v in p]

    def trace(self, tx: np.ndarray, rx: np.ndarray) -> TracedLinks:
        """The links ``tx[i] -> rx[i]``: one Sionna call per distinct transmitter that is not cached, to its
        distinct receivers only (a call traces every transmitter to every receiver it holds); cached per
        transmitter, so a fixed end's links to the same receivers (a base station's to a radio map's cells)
        are traced once."""
        tx, rx = np.atleast_2d(np.asarray(tx, float)), np.atleast_2d(np.asarray(rx, float))
        if tx.shape != rx.shape or tx.shape[1] != 3:
            raise ValueError(f"ray tracer: expected as many transmitters as receivers (n, 3), got {tx.shape} and {rx.shape}")
        with self._lock:  # one scene whose transmitters and receivers each call places: one call at a time
            return self._trace_links(tx, rx)

    def _trace_links(self, tx: np.ndarray, rx: np.ndarray) -> TracedLinks:
        utx, itx = np.unique(tx, axis=0, return_inverse=True)
        itx = itx.ravel()
        groups = []
        for u in range(len(utx)):
            links = np.flatnonzero(itx == u)
            urx, irx = np.unique(rx[links], axis=0, return_inverse=True)
            groups.append((links, irx.ravel(), self._traced_from(utx[u], urx)))
        width = max(g[2].a.shape[1] for g in groups)
        n = len(tx)
        out = {"a": np.zeros((n, width), complex), "tau": np.zeros((n, width)), "departure": np.zeros((n, width, 3)),
               "arrival": np.zeros((n, width, 3)), "valid": np.zeros((n, width), bool), "los": np.zeros((n, width), bool)}
        for links, irx, traced in groups:
            for f in TracedLinks.FIELDS:
                part = getattr(traced, f)[irx]
                out[f][links, :part.shape[1]] = part
        return TracedLinks(**out)

    def _traced_from(self, tx: np.ndarray, rx: np.ndarray) -> TracedLinks:
        """One transmitter ``(3,)`` to distinct receivers ``(m, 3)``: from memory, the disk cache, or traced."""
        if not self.cached:
            return self._trace(tx, rx)
        key = self._key(tx, rx)
        if key in self._memory:
            return self._memory[key]
        path = cache_dir() / "traces" / f"trace_{key}.npz"
        with cache_lock(path):
            links = None
            if entry_is_intact(path):
                try:
                    with np.load(path, allow_pickle=False) as z:
                        links = TracedLinks(*(z[f] for f in TracedLinks.FIELDS))
                except (OSError, ValueError, KeyError, zipfile.BadZipFile):
                    links = None  # unreadable: traced again
            if links is None:
                links = self._trace(tx, rx)
                fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".npz")
                with os.fdopen(fd, "wb") as f:
                    np.savez(f, **{name: getattr(links, name) for name in TracedLinks.FIELDS})
                publish_checked(Path(tmp), path)
        self._remember(key, links)
        return links

    def _remember(self, key: str, links: TracedLinks) -> None:
        """Kept in memory, the oldest dropped first beyond ``MEMORY_TRACES`` entries or ``MEMORY_BYTES``."""
        self._memory[key] = links
        self._memory_bytes += sum(getattr(links, f).nbytes for f in TracedLinks.FIELDS)
        while len(self._memory) > 1 and (len(self._memory) > MEMORY_TRACES or self._memory_bytes > MEMORY_BYTES):
            old = self._memory.pop(next(iter(self._memory)))
            self._memory_bytes -= sum(getattr(old, f).nbytes for f in TracedLinks.FIELDS)

    def _key(self, tx: np.ndarray, rx: np.ndarray) -> str:
        """What a trace depends on: the scene's files (``scene_digest``), the settings, the ends (to 1e-9 m)."""
        h = hashlib.sha256(f"{TRACE_VERSION}|{self.digest}|{self.settings!r}".encode())
        h.update(np.round(tx, 9).tobytes())
        h.update(np.round(rx, 9).tobytes())
        return h.hexdigest()[:24]

    def _trace(self, tx: np.ndarray, rx: np.ndarray) -> TracedLinks:
        """One transmitter ``(3,)`` to distinct receivers ``(m, 3)`` in one Sionna call: ``m`` links."""
        rx = np.atleast_2d(rx)
        self._place("tx", self._tx, self.to_scene(np.atleast_2d(tx)))
        self._place("rx", self._rx, self.to_scene(rx))
        s = self.settings
        paths = self.solver(self.scene, max_depth=s.max_depth, samples_per_src=s.rays_per_source, los=True,
                            specular_reflection=s.reflection, diffuse_reflection=s.scattering, refraction=s.refraction,
                            diffraction=s.diffraction, edge_diffraction=s.diffraction, synthetic_array=True)
        self.calls += 1
        m = len(rx)
        a = (np.asarray(paths.a[0], float) + 1j * np.asarray(paths.a[1], float)).reshape(m, -1)  # (rx, rx ant, tx, tx ant, paths)
        tau = np.asarray(paths.tau, float).reshape(m, -1)
        a = a * np.exp(-2j * np.pi * s.carrier_hz * tau)  # Sionna's coefficients are baseband: the carrier's phase
        valid = np.asarray(paths.valid, bool).reshape(m, -1)
        kinds = np.asarray(paths.interactions, int)  # (depth, rx, tx, paths): 0 = none
        los = np.all(kinds == 0, axis=0).reshape(m, -1) & valid
        dep = unit_from_angles(np.asarray(paths.theta_t), np.asarray(paths.phi_t)).reshape(m, -1, 3) @ self.R
        arr = unit_from_angles(np.asarray(paths.theta_r), np.asarray(paths.phi_r)).reshape(m, -1, 3) @ self.R
        return TracedLinks(np.where(valid, a, 0.0), np.where(valid, tau, 0.0), dep, arr, valid, los)


def scene_file(rt, scene: str) -> Path | None:
    """The XML file of a scene (``load_scene``'s names), None for the empty scene or one that does not exist."""
    try:
        source = scene_source(rt, scene)
    except ValueError:
        return None
    return None if source is None else Path(source)


def scene_digest(rt, scene: str) -> str:
    """SHA-256 over a scene's XML file and every file in its folder (its meshes), or of its name when it
    has no file (``"empty"``, or a name ``load_scene`` will refuse)."""
    path = scene_file(rt, scene)
    if path is None:
        return hashlib.sha256(scene.encode()).hexdigest()
    h = hashlib.sha256()
    for f in sorted(p for p in path.parent.rglob("*") if p.is_file()):
        h.update(str(f.relative_to(path.parent)).encode())
        h.update(file_digest(f).encode())
    return h.hexdigest()


def _mitsuba_xml(scene: str) -> None:
    """ValueError unless ``scene`` is well-formed XML whose root is a Mitsuba ``<scene>`` (a truncated or binary file,
    or a GPX given as a scene, validated and then crashed the run at its first trace)."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(scene).getroot()
    except ET.ParseError as exc:
        raise ValueError(f"ray tracer: scene file {scene!r}: not well-formed XML ({exc}): a Mitsuba scene is an XML "
                         "file (truncated? binary?)") from None
    if root.tag != "scene":
        raise ValueError(f"ray tracer: scene file {scene!r}: its root element is <{root.tag}>, a Mitsuba scene's is <scene>")


def scene_source(rt, scene: str) -> str | None:
    """The Mitsuba XML file a scene loads from (a shipped scene's by its name, ``rt.scene.<name>``, or the file
    given), None for ``"empty"``; ``ValueError`` naming the scene when it is none of these."""
    if Path(scene).suffix.lower() == ".xml":
        why = not_a_file(scene)
        if why is not None:  # where it looked: a file's scene is the scenario file's neighbour, a --set's the shell's
            raise ValueError(f"ray tracer: scene file {scene!r}: {why} (looked for {Path(scene).resolve()}; a scene named "
                             "in a scenario file is found beside that file, one given with --set from the working folder)")
        _mitsuba_xml(scene)
        return scene
    if scene == "empty":
        return None
    shipped = getattr(rt.scene, scene, None)
    if not isinstance(shipped, str):
        raise ValueError(f"ray tracer: no scene {scene!r}: {SCENE_NAMES_HINT}, or 'empty'")
    return shipped


def check_scene(scene: str) -> None:
    """``RayTracingUnavailable`` without the extra, ``ValueError`` naming the scene when it is not one Sionna RT
    ships, ``"empty"`` or an existing Mitsuba XML file; nothing is loaded."""
    scene_source(sionna_rt(), scene)


def load_scene(rt, scene: str):
    """A Sionna scene by its name (``rt.scene.<name>``) or from a Mitsuba XML file's path."""
    source = scene_source(rt, scene)
    return rt.load_scene() if source is None else rt.load_scene(source)
