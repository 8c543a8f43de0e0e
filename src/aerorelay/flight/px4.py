"""The PX4 subset of MAVLink that the offboard bridge and the in-repo vehicle speak: PX4's custom
modes (main mode << 16 | sub mode << 24), the offboard rules (a setpoint stream of at least 2 Hz for
1 s before OFFBOARD is accepted; OFFBOARD left for a hold after ``OFFBOARD_LOSS_S`` without one,
PX4's ``COM_OF_LOSS_T``), the setpoint type masks."""

from __future__ import annotations

PX4_MAIN_MODE = {"MANUAL": 1, "ALTCTL": 2, "POSCTL": 3, "AUTO": 4, "ACRO": 5, "OFFBOARD": 6, "STABILIZED": 7}
PX4_AUTO_SUB_MODE = {"READY": 1, "TAKEOFF": 2, "LOITER": 3, "MISSION": 4, "RTL": 5, "LAND": 6}

OFFBOARD_PROOF_S = 1.0  # PX4 accepts OFFBOARD only after setpoints streamed this long
OFFBOARD_MIN_RATE_HZ = 2.0  # ... at least this fast
OFFBOARD_LOSS_S = 1.0  # COM_OF_LOSS_T: without a setpoint this long, PX4 leaves OFFBOARD (here: for a hold)

# SET_POSITION_TARGET_LOCAL_NED.type_mask: position, velocity, acceleration and yaw used, yaw rate ignored
POSITION_TARGET_MASK = 2048
# SET_ATTITUDE_TARGET.type_mask: body rates, thrust and attitude all used
ATTITUDE_TARGET_MASK = 0


def custom_mode(main: str, sub: str | None = None) -> int:
    """PX4's ``custom_mode`` word for a main mode (and an AUTO sub mode)."""
    return (PX4_MAIN_MODE[main] << 16) | ((PX4_AUTO_SUB_MODE[sub] if sub else 0) << 24)


def mode_name(custom: int) -> str:
    """``"OFFBOARD"``, ``"AUTO.LOITER"``, ... from a ``custom_mode`` word."""
    mains = {v: k for k, v in PX4_MAIN_MODE.items()}
    subs = {v: k for k, v in PX4_AUTO_SUB_MODE.items()}
    main, sub = mains.get((custom >> 16) & 0xFF, "UNKNOWN"), (custom >> 24) & 0xFF
    return f"AUTO.{subs.get(sub, str(sub))}" if main == "AUTO" and sub else main
