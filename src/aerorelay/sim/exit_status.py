"""How a run ended, as a value and a sentence (RotorPy's ``ExitStatus`` style), not free text:
``metrics.json`` carries ``exit_status`` (the first that applies, in this order) and
``exit_statuses`` (every one that does), beside the human ``unsafe_reason``."""

from __future__ import annotations

from enum import StrEnum


class ExitStatus(StrEnum):
    """A run's end. Every status but ``COMPLETE`` and ``FELL_BACK`` makes the run unsafe; ``FELL_BACK`` (a relay
    flew more than ``verdict.fallback_fraction_max`` of its steps on the brake law or with failed QPs) is safe but
    not complete: its controller did not fly it."""

    COMPLETE = "complete"
    NON_FINITE = "non_finite"
    LEFT_WORKSPACE = "left_workspace"
    BELOW_GROUND = "below_ground"
    FLIPPED = "flipped"
    IN_OBSTACLE = "in_obstacle"
    TOO_CLOSE = "too_close"
    BATTERY_EMPTY = "battery_empty"
    ENDED_EARLY = "ended_early"
    METRICS_FAILED = "metrics_failed"
    FELL_BACK = "fell_back"

    @property
    def unsafe(self) -> bool:
        return self not in (ExitStatus.COMPLETE, ExitStatus.FELL_BACK)

    @property
    def sentence(self) -> str:
        return SENTENCES[self]


SENTENCES = {
    ExitStatus.COMPLETE: "flown to the end inside its world",
    ExitStatus.NON_FINITE: "a state stopped being finite (the plant's, or a logged pose)",
    ExitStatus.LEFT_WORKSPACE: "a relay left its workspace beyond the tolerance",
    ExitStatus.BELOW_GROUND: "a relay went below the ground",
    ExitStatus.FLIPPED: "a relay flipped (tilt beyond 90 deg)",
    ExitStatus.IN_OBSTACLE: "a relay entered an obstacle",
    ExitStatus.BATTERY_EMPTY: "a relay flew on an empty battery (its usable energy spent)",
    ExitStatus.TOO_CLOSE: "two vehicles came closer than the separation",
    ExitStatus.ENDED_EARLY: "the flight ended before its end (interrupted, or ended by the autopilot bridge)",
    ExitStatus.METRICS_FAILED: "its metrics could not be computed (the time series is kept)",
    ExitStatus.FELL_BACK: "a relay's controller did not fly it (the brake law or failed QPs beyond "
                          "verdict.fallback_fraction_max of its steps)",
}


def exit_fields(statuses: list[ExitStatus]) -> dict:
    """``exit_status`` (the first, or ``complete``), its ``exit_sentence`` and every status that applies."""
    first = statuses[0] if statuses else ExitStatus.COMPLETE
    return {"exit_status": first.value, "exit_sentence": first.sentence,
            "exit_statuses": [s.value for s in dict.fromkeys(statuses)]}
