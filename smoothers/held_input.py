"""Zero-order hold of the latest input sample between keyframes (shared by the IMU and
rate-gyro integrators)."""

from __future__ import annotations

from datasets.errors import InputError


def held_interval(
    cursor: float,
    held_t: float | None,
    t: float,
    max_gap_s: float,
    sensor: str,
    option: str = "max_gap_s",
) -> float:
    """Seconds to integrate the held sample from ``cursor`` up to ``t`` (0 when nothing is
    held or ``t`` is not later); ``InputError`` when the sample would be held longer than
    ``max_gap_s`` (an outage of ``sensor``: the model would be meaningless), naming the
    smoother ``option`` that sets it."""
    if held_t is None or t <= cursor:
        return 0.0
    if t - held_t > max_gap_s:
        raise InputError(
            f"{sensor} gap: no sample between t={held_t:.6f} s and t={t:.6f} s "
            f"({t - held_t:.3f} s > {option}={max_gap_s})"
        )
    return t - cursor
