"""Large-scale propagation: path gain as a function of distance, and log-normal shadowing.

The paper's channel is ``G / d^2`` (eq. 6): free space with the wavelength factor folded into
its normalized units. A ``PathGain`` generalizes that to ``K d^-n`` (``K`` = ``10^(-PL(d0)/10)
d0^n``): free space in physical units (Friis, ``K = (lambda / 4 pi)^2``, ``n = 2``) and the
log-distance model (``PL(d) = PL(d0) + 10 n log10(d / d0)``). The ``rma_av_*`` functions are the
RMa-AV model of 3GPP TR 36.777 Annex B (aerial UEs 10-300 m): LoS probability, LoS / NLoS path
loss and shadow-fading standard deviation; ``RmaAvPathGain`` makes it a scene's propagation (the
expected gain over the LoS state, which controllers plan with; the plant draws the state).
``ShadowingField`` is log-normal shadowing as a random field per link over the link's geometry,
correlated ``exp(-Delta d / d_corr)`` (Gudmundson 1991); ``LargeScaleRealization`` is a run's
realized large-scale channel (that field, and RMa-AV's LoS states), shared by plant and bound.

Distances in m, frequencies in Hz (the 3GPP formulas take GHz inside), losses in dB.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .backend import is_symbolic, ops
from .streams import generator, stream

SPEED_OF_LIGHT_M_S = 299_792_458.0


def wavelength_m(carrier_hz: float) -> float:
    """``lambda = c / f`` (m)."""
    return SPEED_OF_LIGHT_M_S / carrier_hz


def free_space_loss_db(distance_m, carrier_hz: float):
    """Friis free-space loss ``20 log10(4 pi d / lambda)`` (dB): 100.05 dB at 1 km, 2.4 GHz."""
    return 20.0 * np.log10(4.0 * np.pi * np.asarray(distance_m, float) / wavelength_m(carrier_hz))


@dataclass(frozen=True)
class PathGain:
    """``g(d) = K d^-n`` (linear power gain between isotropic antennas). ``K = 1, n = 2`` is the
    paper's normalized free space (eq. 6); ``gain_from_d2`` works on numpy arrays and CasADi."""

    scale: float = 1.0
    exponent: float = 2.0

    @classmethod
    def free_space(cls, carrier_hz: float) -> PathGain:
        """Friis: ``K = (lambda / 4 pi)^2``, ``n = 2``."""
        return cls((wavelength_m(carrier_hz) / (4.0 * math.pi)) ** 2, 2.0)

    @classmethod
    def log_distance(cls, exponent: float, reference_distance_m: float, reference_loss_db: float) -> PathGain:
        """``PL(d) = PL(d0) + 10 n log10(d / d0)``: ``K = 10^(-PL(d0)/10) d0^n``."""
        return cls(10.0 ** (-reference_loss_db / 10.0) * reference_distance_m**exponent, exponent)

    @property
    def is_paper(self) -> bool:
        """The paper's normalized ``1 / d^2`` (kept operation for operation)."""
        return self.scale == 1.0 and self.exponent == 2.0

    def gain_from_d2(self, d2):
        """``K (d^2)^(-n/2)`` from the squared distance (numpy or CasADi)."""
        if self.exponent == 2.0:
            return self.scale / d2
        return self.scale * d2 ** (-0.5 * self.exponent)

    def gain_between(self, p_tx, p_rx, d2):
        """The gain of the link ``p_tx -> p_rx`` whose squared length is ``d2``: ``gain_from_d2(d2)``
        here; models that need the ends' heights override it (numpy or CasADi)."""
        return self.gain_from_d2(d2)

    @property
    def distance_only(self) -> bool:
        """Whether the gain depends on the link's length alone (not on where its ends are): then a
        link's gain is the same for every translation of it."""
        return type(self).gain_between is PathGain.gain_between

    def describe(self) -> str:
        return f"path gain {self.scale:.4g} d^-{self.exponent:g}"

    def loss_db(self, distance_m):
        """``-10 log10 g(d)`` (dB)."""
        d = np.asarray(distance_m, float)
        return -10.0 * np.log10(self.scale) + 10.0 * self.exponent * np.log10(d)


# --- 3GPP TR 36.777 Annex B, RMa-AV (aerial UE 10 m < h_UT <= 300 m, d_2D <= 10 km) ----------

RMA_AV_MIN_HEIGHT_M, RMA_AV_MAX_HEIGHT_M, RMA_AV_MAX_D2D_M = 10.0, 300.0, 10_000.0
_RMA_AV_LOS_EXPONENT_MAX = 23.9 - 1.8 * math.log10(RMA_AV_MIN_HEIGHT_M)  # Table B-2's LoS dB/decade at its lowest height


def check_rma_av_range(h_ut, d2d, what: str = "link"):
    """Raise ``ValueError`` naming the range when a height or 2D distance is outside RMa-AV's."""
    h, d = np.asarray(h_ut, float), np.asarray(d2d, float)
    if np.any(h <= RMA_AV_MIN_HEIGHT_M) or np.any(h > RMA_AV_MAX_HEIGHT_M):
        raise ValueError(f"{what}: 3GPP RMa-AV (TR 36.777 Table B-2) holds for aerial heights in "
                         f"({RMA_AV_MIN_HEIGHT_M:g}, {RMA_AV_MAX_HEIGHT_M:g}] m, got {h.min():.2f}-{h.max():.2f} m")
    if np.any(d > RMA_AV_MAX_D2D_M):
        raise ValueError(f"{what}: 3GPP RMa-AV holds for 2D distances <= {RMA_AV_MAX_D2D_M:g} m, got {d.max():.0f} m")


def rma_av_los_probability(d2d, h_ut):
    """TR 36.777 Table B-1, RMa-AV: 1 for ``d2D <= d1``, else ``d1/d2D + exp(-d2D/p1)(1 - d1/d2D)``
    with ``p1 = max(15021 log10 h - 16053, 1000)``, ``d1 = max(1350.8 log10 h - 1602, 18)`` for
    10 < h <= 40 m; 1 above 40 m."""
    d, h = _dual(d2d, h_ut)
    o = ops(d, h)
    lh = o.log10(h)
    p1 = o.fmax(15021.0 * lh - 16053.0, 1000.0)
    d1 = o.fmax(1350.8 * lh - 1602.0, 18.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        far = d1 / d + o.exp(-d / p1) * (1.0 - d1 / d)
    p = o.where(d <= d1, 1.0, far)
    return o.where(h > 40.0, 1.0, p)


def rma_av_path_loss_db(d3d, h_ut, carrier_hz: float, los):
    """TR 36.777 Table B-2, RMa-AV (dB; ``f_c`` in GHz inside):
    LoS ``max(23.9 - 1.8 log10 h, 20) log10 d3D + 20 log10(40 pi f_c / 3)``;
    NLoS ``max(PL_LoS, -12 + (35 - 5.3 log10 h) log10 d3D + 20 log10(40 pi f_c / 3))``."""
    d, h = _dual(d3d, h_ut)
    o = ops(d, h)
    fc = carrier_hz / 1e9
    tail = 20.0 * np.log10(40.0 * np.pi * fc / 3.0)
    pl_los = o.fmax(23.9 - 1.8 * o.log10(h), 20.0) * o.log10(d) + tail
    if los is True:
        return pl_los
    pl_nlos = o.fmax(pl_los, -12.0 + (35.0 - 5.3 * o.log10(h)) * o.log10(d) + tail)
    if los is False:
        return pl_nlos
    return np.where(np.asarray(los, bool), pl_los, pl_nlos)


def rma_av_shadow_std_db(h_ut, los):
    """TR 36.777 Table B-3, RMa-AV: LoS ``4.2 exp(-0.0046 h)``, NLoS 6 dB (10 < h <= 40 m)."""
    h = np.asarray(h_ut, float)
    return np.where(np.asarray(los, bool), 4.2 * np.exp(-0.0046 * h), 6.0)


def rma_av_expected_gain(d3d, d2d, h_ut, carrier_hz: float):
    """The deterministic part a controller plans with: ``P_LoS g_LoS + (1 - P_LoS) g_NLoS``
    (linear power gain, no shadowing realization). *Dual*."""
    p = rma_av_los_probability(d2d, h_ut)
    g_los = 10.0 ** (-rma_av_path_loss_db(d3d, h_ut, carrier_hz, True) / 10.0)
    g_nlos = 10.0 ** (-rma_av_path_loss_db(d3d, h_ut, carrier_hz, False) / 10.0)
    return p * g_los + (1.0 - p) * g_nlos


def _dual(*args):
    """CasADi expressions as they are, anything else as float arrays."""
    return tuple(a if is_symbolic(a) else np.asarray(a, float) for a in args)


def link_heights(p_tx, p_rx, d2):
    """``(d3D, d2D, h_UT)`` of a link: its length, horizontal length and aerial height (the higher
    end's z; TR 36.777 models ground-to-air links, an air-to-air link takes its higher end). numpy
    ``(..., 3)`` ends or CasADi 3-vectors; ``d2`` the squared length."""
    o = ops(p_tx, p_rx, d2)
    z_tx, z_rx = o.component(p_tx, 2), o.component(p_rx, 2)
    dz = z_rx - z_tx
    return o.sqrt(d2), o.sqrt(o.fmax(d2 - dz * dz, 1e-12)), o.fmax(z_tx, z_rx)


def _numeric_heights(p_tx, p_rx):
    p_tx, p_rx = np.asarray(p_tx, float), np.asarray(p_rx, float)
    d = p_rx - p_tx
    return link_heights(p_tx, p_rx, np.sum(d * d, axis=-1))


@dataclass(frozen=True)
class RmaAvPathGain(PathGain):
    """3GPP TR 36.777 RMa-AV as every link's deterministic path gain: the expected gain over the
    LoS state, ``P_LoS g_LoS + (1 - P_LoS) g_NLoS`` at the link's ``d3D``, ``d2D`` and aerial
    height (``link_heights``); valid for aerial heights in (10, 300] m (checked at validation).
    ``gain_from_d2`` (no heights) bounds it from above at every distance."""

    carrier_hz: float = 2.4e9

    @property
    def is_paper(self) -> bool:
        return False

    def gain_between(self, p_tx, p_rx, d2):
        d3, d2d, h = link_heights(p_tx, p_rx, d2)
        return rma_av_expected_gain(d3, d2d, h, self.carrier_hz)

    def realize(self, p_tx, p_rx, u) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The LoS state drawn by ``u`` (uniform; LoS while ``P_LoS > u``), that state's gain over the
        expected one, and the state's shadowing std (dB), from the links' geometry computed once."""
        d3, d2d, h = _numeric_heights(p_tx, p_rx)
        los = u < rma_av_los_probability(d2d, h)
        state = 10.0 ** (-rma_av_path_loss_db(d3, h, self.carrier_hz, los) / 10.0)
        return los, state / rma_av_expected_gain(d3, d2d, h, self.carrier_hz), rma_av_shadow_std_db(h, los)

    def gain_from_d2(self, d2):
        """Upper bound of the gain at squared length ``d2`` (m^2) for any aerial height in (10, 300]
        m: LoS (NLoS loses at least as much), ``K d^-e/10`` with ``K = 10^(-20 log10(40 pi f_c / 3) / 10)``
        (f_c in GHz) and the exponent ``e = max(23.9 - 1.8 log10 h, 20)`` of Table B-2 at its floor 20
        beyond 1 m and at its largest, 22.1 (h = 10 m), below 1 m, where a larger exponent means
        more gain. (The floor alone, ``K d^-2``, was below the gain under 1 m: 0.46e-3 against
        0.40e-3 at 0.5 m and 10.5 m height.) numpy or CasADi."""
        k = (3.0 / (40.0 * np.pi * self.carrier_hz / 1e9)) ** 2
        near = d2 ** (-0.05 * (_RMA_AV_LOS_EXPONENT_MAX - 20.0))  # d^-(e_max - 20)/10: > 1 below 1 m
        return k / d2 * ops(d2).fmax(near, 1.0)

    def describe(self) -> str:
        return f"3GPP TR 36.777 RMa-AV at {self.carrier_hz / 1e9:g} GHz (expected over the LoS state)"

    def loss_db(self, distance_m):
        raise TypeError("RMa-AV's loss depends on the link's heights: use gain_between")


class ShadowingField:
    """Log-normal shadowing as a Gaussian random field per link over the link's offset ``p_rx -
    p_tx`` (m, world): zero mean, unit std (the caller scales it), covariance ``exp(-|Delta| /
    d_corr)``: Gudmundson's exponential correlation, over the link's geometry in 3D. Being a
    field, the shadowing of any geometry is fixed before anyone flies, so the plant and the bound
    read the same realization. Random Fourier features: ``X(x) = sqrt(2/M) sum_m cos(w_m . x +
    phi_m)``, ``w_m`` multivariate Cauchy with scale ``1/d_corr`` (the spectral density of
    ``exp(-r/d)`` in 3D, a Student t with one degree of freedom), ``phi_m`` uniform. Seeded."""

    def __init__(self, n_links: int, decorrelation_m: float, seed: int | np.random.SeedSequence | None = None,
                 n_features: int = 256):
        if decorrelation_m <= 0:
            raise ValueError(f"shadowing decorrelation distance must be > 0 m, got {decorrelation_m}")
        rng = np.random.default_rng(seed)
        z = rng.standard_normal((n_links, 3, n_features))
        self.omega = z / (decorrelation_m * np.sqrt(rng.chisquare(1.0, size=(n_links, 1, n_features))))
        self.phase = rng.uniform(0.0, 2.0 * np.pi, size=(n_links, n_features))
        self.scale = math.sqrt(2.0 / n_features)

    def value(self, link: int, offsets) -> np.ndarray:
        """The unit field of ``link`` at ``offsets`` ``(..., 3)`` (m): ``(...)``."""
        x = np.asarray(offsets, float)
        return self.scale * np.cos(x @ self.omega[link] + self.phase[link]).sum(axis=-1)


@dataclass(frozen=True)
class LinkRealization:
    """One link's realized large-scale terms: power multiplier over the scene's deterministic gain,
    shadowing (dB), LoS state (None unless RMa-AV)."""

    gain: np.ndarray
    shadow_db: np.ndarray | None
    los: np.ndarray | None


class LargeScaleRealization:
    """A run's realized large-scale channel per link (``RadioScene.link_ends`` order): log-normal
    shadowing from a ``ShadowingField`` times ``std_db``, and with ``RmaAvPathGain`` the LoS state
    (LoS while ``P_LoS(d2D, h) > u``, one uniform ``u`` per link and run, so the state changes only
    as the geometry does), whose gain replaces the expected one, and the standard's shadowing std
    for that state. The plant multiplies its links by it, the bound searches the same realization.
    ``seed``: the run's seed (the field and the states draw from streams derived from it)."""

    def __init__(self, path_gain: PathGain, n_links: int, *, std_db: float, decorrelation_m: float, seed: int):
        self.rma = path_gain if isinstance(path_gain, RmaAvPathGain) else None
        self.std_db = std_db
        random = self.rma is not None or std_db > 0
        self.field = ShadowingField(n_links, decorrelation_m, seed=stream(seed, "shadowing")) if random else None
        self.u = generator(seed, "los").uniform(size=n_links) if self.rma is not None else None

    @property
    def active(self) -> bool:
        return self.field is not None

    @property
    def has_los(self) -> bool:
        return self.rma is not None

    def link(self, k: int, p_tx, p_rx) -> LinkRealization:
        """Link ``k`` between ``p_tx`` and ``p_rx`` (numpy ``(..., 3)``, broadcasting)."""
        p_tx, p_rx = np.asarray(p_tx, float), np.asarray(p_rx, float)
        off = p_rx - p_tx
        gain: np.ndarray = np.ones(off.shape[:-1])
        std: np.ndarray | float = self.std_db
        los = None
        if self.rma is not None and self.u is not None:
            los, gain, std = self.rma.realize(p_tx, p_rx, self.u[k])
        if self.field is None:
            return LinkRealization(gain, None, los)
        x_db = std * self.field.value(k, off)
        return LinkRealization(gain * 10.0 ** (x_db / 10.0), x_db, los)
