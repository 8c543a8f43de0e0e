"""The plant's random channel terms per link, composed from ``models/fading.py`` and
``models/propagation.py``: small-scale fading (the paper's i.i.d. Rician draw per control step,
or Doppler fading that evolves in time) and log-normal shadowing, a field over each link's
geometry. The controller never sees them (it plans with the deterministic channel); every value is
logged, so a run's capacity can be recomputed from its log alone. The large-scale terms (the
shadowing field, and with 3GPP RMa-AV each link's LoS state) are a ``LargeScaleRealization``
fixed by the run's seed over every geometry: the bound searches the same one.

Links are the scene's distinct radio paths: every hop, then every (receiver, jammer) pair once
(``layout`` spreads them over ``RadioScene.fading_links``, where two hops into one receiver each
carry its jammer links). Log columns: ``fade_amp_<tx>_<rx>`` (amplitude |h|) and
``shadow_db_<tx>_<rx>`` (dB), ``los_<tx>_<rx>`` (1 LoS, 0 NLoS; RMa-AV); the power gain of a link
is ``fade_amp^2 10^(shadow_db / 10)`` times, with RMa-AV, its state's gain over the expected one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..models.fading import ClarkeRicianFading, RicianFading
from ..models.propagation import SPEED_OF_LIGHT_M_S, LargeScaleRealization
from ..models.radio import RadioScene
from ..models.streams import stream


@dataclass(frozen=True)
class PerturbationSettings:
    """Rician K (dB; None or inf: no fading), ``fading_model`` ``"iid"`` or ``"doppler"``,
    shadowing std (dB; 0: none) and decorrelation distance (m), carrier (Hz, for the Doppler
    frequency ``f_D = |v_tx - v_rx| f_c / c``)."""

    k_db: float | None = None
    fading_model: str = "iid"
    shadow_std_db: float = 0.0
    decorrelation_m: float = 10.0
    carrier_hz: float = 2.4e9


def distinct_links(scene: RadioScene) -> list[tuple[str, str, int | None]]:
    """``scene.link_ends()`` with each link once: two hops into one receiver share its jammers' links
    (one radio path each, one draw)."""
    return list(dict.fromkeys(scene.link_ends()))


def large_scale_realization(scene: RadioScene, settings: PerturbationSettings, seed: int) -> LargeScaleRealization:
    """The run's shadowing field and LoS states over the scene's distinct links: the plant's, and the
    bound's for the same seed."""
    return LargeScaleRealization(scene.path_gain, len(distinct_links(scene)), std_db=settings.shadow_std_db,
                                 decorrelation_m=settings.decorrelation_m, seed=seed)


class LinkPerturbations:
    """Per control step: ``gains, values = step(t, positions, velocities)``; ``gains`` (or None
    when nothing is random) multiplies the links' received powers, ``values`` fills the log."""

    def __init__(self, scene: RadioScene, settings: PerturbationSettings, *, period_s: float, seed: int):
        self.scene, self.period = scene, period_s
        self.links = distinct_links(scene)  # one draw per radio path; ``expand`` lays them out as the scene's links
        n = len(self.links)
        fading_on = settings.k_db is not None and not math.isinf(settings.k_db)
        k = float(settings.k_db) if settings.k_db is not None else math.inf
        self.doppler = fading_on and settings.fading_model == "doppler"
        self.iid = RicianFading(k, seed=stream(seed, "fading")) if fading_on and not self.doppler else None
        self.clarke = ClarkeRicianFading(k, n, seed=stream(seed, "fading")) if self.doppler else None
        self.large_scale = large_scale_realization(scene, settings, seed)
        self.carrier = settings.carrier_hz
        labels = [f"{tx}_{rx}" for tx, rx, _ in self.links]
        self.fade_columns = [f"fade_amp_{lb}" for lb in labels] if fading_on else []
        self.shadow_columns = [f"shadow_db_{lb}" for lb in labels] if self.large_scale.active else []
        self.los_columns = [f"los_{lb}" for lb in labels] if self.large_scale.has_los else []

    def layout(self, scene: RadioScene) -> np.ndarray:
        """Where each of ``scene``'s fading links (``link_ends`` order, a shared receiver's jammer links once
        per hop) sits among this object's links: ``gains[layout(scene)]`` is what ``scene.evaluate`` takes."""
        return np.array([self.links.index(link) for link in scene.link_ends()], dtype=int)

    @property
    def columns(self) -> list[str]:
        return self.fade_columns + self.shadow_columns + self.los_columns

    @property
    def active(self) -> bool:
        return bool(self.columns)

    def _ends(self, t: float, positions: dict, velocities: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per link the transmitter's and receiver's positions (m, world) and the relative velocity (m/s)."""
        tx_p, rx_p, dv = [], [], []
        for tx, rx, j in self.links:
            if j is None:
                p_tx, v_tx = positions[tx], velocities[tx]
            else:
                jam = self.scene.jammers[j]
                p_tx = jam.position_at(t)
                v_tx = (p_tx - jam.position_at(max(t - self.period, 0.0))) / self.period
            tx_p.append(np.asarray(p_tx, float))
            rx_p.append(np.asarray(positions[rx], float))
            dv.append(np.asarray(velocities[rx], float) - v_tx)
        return np.array(tx_p), np.array(rx_p), np.array(dv)

    def step(self, t: float, positions: dict, velocities: dict) -> tuple[np.ndarray | None, dict[str, float]]:
        if not self.active:
            return None, {}
        n = len(self.links)
        gains = np.ones(n)
        values: dict[str, float] = {}
        if self.clarke is not None or self.large_scale.active:  # i.i.d. fading needs no geometry
            p_tx, p_rx, rel_v = self._ends(t, positions, velocities)
        if self.iid is not None:
            amp = np.asarray(self.iid.amplitude(n), float)
            gains = gains * amp**2
            values.update(zip(self.fade_columns, amp, strict=True))
        elif self.clarke is not None:
            f_d = np.linalg.norm(rel_v, axis=1) * self.carrier / SPEED_OF_LIGHT_M_S
            amp = self.clarke.amplitude(f_d, self.period)
            gains = gains * amp**2
            values.update(zip(self.fade_columns, amp, strict=True))
        if self.large_scale.active:
            links = [self.large_scale.link(k, p_tx[k], p_rx[k]) for k in range(n)]
            gains = gains * np.array([float(lk.gain) for lk in links])
            values.update(zip(self.shadow_columns, [float(np.asarray(lk.shadow_db)) for lk in links], strict=True))
            if self.los_columns:
                values.update(zip(self.los_columns, [float(np.asarray(lk.los)) for lk in links], strict=True))
        return gains, values

