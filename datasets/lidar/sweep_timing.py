"""Are a recording's sweeps motion-compensated? Decided from its first clouds, by two seam
tests that need neither per-point times nor truth, and say how each point is timed.

A spinning lidar measures each point from where the sensor was at that point's firing time.
A sweep is cut at one encoder angle; each laser's cut lies at that angle plus its own
azimuth offset, so its first and last points are neighbours in azimuth but one sweep apart
in time. What the cut looks like depends on whether the sweep was compensated:

- **Raw** (not compensated): a ring's range jumps at its cut by the change one sweep makes
  at that azimuth, which the next cloud measures directly; the test gives the spin
  direction and the cut's azimuth (``datasets.lidar.sweep_raw_cut``).
- **Compensated**: surfaces are continuous across the cut, but the ground's rings are not:
  they line up only after shifting one side by the travel of one sweep projected on the ray
  (``datasets.lidar.sweep_compensated_cut``).

Decision (``decide_sweep_timing``), from the first ``SweepOptions.frames`` clouds (10 by
default, one second at 10 Hz: enough for a cut to repeat in ``MIN_SEAM_FRAMES`` of them):

- clouds with per-point times keep them (nothing to decide);
- raw: at least ``MIN_SEAM_ROWS`` rings cut in one ``SEAM_BAND_DEG`` band in one direction,
  ``SEAM_DIRECTION_RATIO`` times as many as in the other, and no compensated cut on the
  ground: timed by azimuth from the cut found (direction and start stated in options win);
- compensated: a compensated cut on the ground (in ``CUT_FRACTION`` of the clouds), and
  fewer than ``MIN_SEAM_ROWS`` raw cuts in either direction;
- undecided otherwise: the sensor barely moved (no range change one sweep makes stands out
  of the noise), or nothing faced it where a cut could lie, or the tests disagree. The
  clouds are then read as the stated default (no times: as compensated), with a warning.

The thresholds named are the raw test's (``sweep_raw_cut``) and the compensated test's
(``sweep_compensated_cut``): ratios to noise the clouds themselves show, or properties of any
spinning lidar (one cut per laser at a fixed azimuth, laser azimuth offsets within
``SEAM_BAND_DEG``), never fitted to one recording. On the shared KITTI clips, the synthetic
corridor (raw and compensated) and a sensor standing still: ``tests/test_sweep_timing.py``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from datasets.lidar.sweep_compensated_cut import (
    CUT_NOISE,
    CompensatedCutEvidence,
    compensated_cut_evidence,
    sweep_motion,
)
from datasets.lidar.sweep_raw_cut import (
    INFORMATIVE_NOISE,
    MIN_SEAM_ROWS,
    RawSeamEvidence,
    _raw_direction,
    raw_seam_evidence,
)
from datasets.lidar.sweep_times import CLOCKWISE, COUNTERCLOCKWISE, AzimuthSweep, SweepOptions
from datasets.measurements import PointCloud


@dataclass(frozen=True)
class SweepTimingDecision:
    """What the clouds are read with, and why.

    Attributes:
        outcome: ``stated`` (``point_times=field``: nothing decided), ``times`` (the clouds
            carry per-point times), ``raw``, ``compensated`` or ``undecided``.
        point_times: what the loader applies: ``field`` (a cloud's own times, or none) or
            ``azimuth``.
        azimuth: the sweep timing when ``point_times == "azimuth"``, else None.
        source: ``data``, or ``options`` where the user stated point_times (or the sweep's
            direction and start).
        frames: clouds the decision read.
        evidence: the numbers behind it (JSON-serialisable).
        text: one line saying the decision and its evidence.
    """

    outcome: Literal["stated", "times", "raw", "compensated", "undecided"]
    point_times: Literal["field", "azimuth"]
    azimuth: AzimuthSweep | None
    source: Literal["data", "options"]
    frames: int
    evidence: dict[str, object] = field(default_factory=dict)
    text: str = ""
    warnings: tuple[str, ...] = ()

    @property
    def clear(self) -> bool:
        """Whether the decision is one to note rather than warn about."""
        return self.outcome != "undecided"

    def as_dict(self) -> dict[str, object]:
        """JSON-serialisable record (``Sequence.metadata["sweep_timing"]``)."""
        return {
            "outcome": self.outcome,
            "point_times": self.point_times,
            "source": self.source,
            "frames": self.frames,
            "direction": None
            if self.azimuth is None
            else ("clockwise" if self.azimuth.direction == CLOCKWISE else "counterclockwise"),
            "start_deg": None if self.azimuth is None else self.azimuth.start_deg,
            "sweep_s": None if self.azimuth is None else float(self.azimuth),
            "stamp": None if self.azimuth is None else self.azimuth.stamp,
            "evidence": self.evidence,
            "text": self.text,
        }


def decide_sweep_timing(
    clouds: list[PointCloud],
    sweep_s: float,
    point_times: str = "auto",
    options: SweepOptions | None = None,
) -> SweepTimingDecision:
    """How a recording's clouds are timed (module docstring), from its first ``clouds``
    (lidar frame, consecutive, one sweep of ``sweep_s`` [s] apart) and the options: with
    ``point_times`` ``field`` nothing is decided; with ``azimuth`` the sweeps are raw by the
    user's word and only the spin and start are sought; with ``auto`` everything is."""
    options = options or SweepOptions()
    frames = len(clouds)
    if point_times == "field":
        return SweepTimingDecision(
            "stated",
            "field",
            None,
            "options",
            frames,
            text="sweep timing: per-point times from the clouds' time field where they have "
            "one, none otherwise (taken as motion-compensated) (point_times=field, stated)",
        )
    timed = sum(cloud.point_times is not None for cloud in clouds)
    if point_times == "auto" and frames and 2 * timed >= frames:
        return SweepTimingDecision(
            "times",
            "field",
            None,
            "data",
            frames,
            {"clouds_with_times": timed},
            f"sweep timing: {timed} of the first {frames} clouds carry per-point times: "
            "read with them (the sensor's own timing)",
        )
    points = [np.asarray(cloud.points, dtype=float) for cloud in clouds]
    stated = options.direction != "auto" and options.start_deg is not None
    seams = raw_seam_evidence(points) if len(points) >= 2 else None
    motion = sweep_motion(points, sweep_s) if len(points) >= 2 else np.eye(4)
    cut = compensated_cut_evidence(points, motion) if len(points) >= 2 else None
    travel = float(np.linalg.norm(motion[:2, 3]))
    evidence: dict[str, object] = {
        "frames": frames,
        "sweep_s": float(sweep_s),
        "travel_m_per_sweep": round(travel, 4),
        "yaw_deg_per_sweep": round(float(np.degrees(np.arctan2(motion[1, 0], motion[0, 0]))), 3),
    }
    if seams is not None:
        evidence.update(
            {
                "raw_cut_rings_clockwise": seams.rows[CLOCKWISE],
                "raw_cut_rings_counterclockwise": seams.rows[COUNTERCLOCKWISE],
                "raw_cut_rings_stray_clockwise": seams.stray[CLOCKWISE],
                "raw_cut_rings_stray_counterclockwise": seams.stray[COUNTERCLOCKWISE],
                "informative_ring_pairs": seams.informative,
                "step_noise_m": round(seams.step_noise_m, 4),
            }
        )
    if cut is not None:
        evidence.update(
            {
                "compensated_cut_ratio": None if np.isnan(cut.ratio) else round(cut.ratio, 2),
                "compensated_cut_at_deg": cut.at_deg,
                "compensated_cut_shift_m": round(cut.shift_m, 4),
                "ground_covered_deg": cut.covered_deg,
                "ground_noise_m": None if np.isnan(cut.noise_m) else round(cut.noise_m, 4),
                "compensated_cut_clouds_fraction": round(cut.fraction, 2),
            }
        )
    raw_direction = _raw_direction(seams)
    compensated = cut is not None and cut.found
    raw_rings = 0 if seams is None else max(seams.rows.values())
    found = _found_text(seams, raw_direction, cut, travel)
    if raw_direction is not None:
        evidence["start_deg_found"] = round(float(seams.start_deg[raw_direction]), 2)
        evidence["cut_spread_deg"] = [round(v, 2) for v in seams.spread_deg[raw_direction]]
    if point_times == "azimuth":
        azimuth, how = _azimuth_timing(sweep_s, options, seams, raw_direction)
        warnings = ()
        if compensated and raw_direction is None:
            warnings = (
                f"sweep timing: point_times=azimuth is stated, but the first {frames} clouds "
                f"look motion-compensated ({found}); timed by azimuth as asked",
            )
        if how == "KITTI raw's convention":
            warnings += (
                f"sweep timing: point_times=azimuth: no sweep cut found in the first {frames} "
                f"clouds ({found}); KITTI raw's convention used (clockwise from 180 deg); "
                "state --data sweep.direction=... sweep.start_deg=... if the lidar is another",
            )
        return SweepTimingDecision(
            "raw",
            "azimuth",
            azimuth,
            "options",
            frames,
            evidence,
            f"sweep timing: per-point times from azimuth, {azimuth.describe()} "
            f"(point_times=azimuth stated; direction and start {how}): {found}",
            warnings,
        )
    if raw_direction is not None and not compensated:
        azimuth, how = _azimuth_timing(sweep_s, options, seams, raw_direction)
        return SweepTimingDecision(
            "raw",
            "azimuth",
            azimuth,
            "options" if stated else "data",
            frames,
            evidence,
            f"sweep timing: raw sweeps (not motion-compensated) in the first {frames} clouds: "
            f"{found}; per-point times from azimuth, {azimuth.describe()} (direction and "
            f"start {how}; override: --data point_times=field|azimuth, sweep.direction, "
            "sweep.start_deg, sweep.stamp)",
        )
    if compensated and raw_rings < MIN_SEAM_ROWS:
        return SweepTimingDecision(
            "compensated",
            "field",
            None,
            "data",
            frames,
            evidence,
            f"sweep timing: motion-compensated sweeps in the first {frames} clouds: {found}; "
            "read without per-point times (override: --data point_times=azimuth)",
        )
    why = _undecided_reason(seams, cut, compensated, raw_direction, travel)
    text = (
        f"sweep timing undecided from the first {frames} clouds: {why} ({found}); read "
        "without per-point times, as motion-compensated; if the sweeps are raw, state "
        "--data point_times=azimuth (and sweep.direction, sweep.start_deg)"
    )
    return SweepTimingDecision("undecided", "field", None, "data", frames, evidence, text, (text,))


def _azimuth_timing(
    sweep_s: float, options: SweepOptions, seams: RawSeamEvidence | None, found: int | None
) -> tuple[AzimuthSweep, str]:
    """The azimuth timing: stated direction and start win, then the cut found, then KITTI
    raw's convention; and which it was."""
    direction = {"clockwise": CLOCKWISE, "counterclockwise": COUNTERCLOCKWISE}.get(
        options.direction, found
    )
    start = options.start_deg
    if start is None and found is not None and direction == found:
        start = seams.start_deg[found]
    sources = []
    if options.direction != "auto":
        sources.append("direction stated")
    if options.start_deg is not None:
        sources.append("start stated")
    if direction is None or start is None:
        if direction is None and start is None:
            return AzimuthSweep(sweep_s, CLOCKWISE, 180.0, options.stamp), "KITTI raw's convention"
        how = ", ".join(sources) + ", the rest KITTI raw's convention"
        return (
            AzimuthSweep(
                sweep_s,
                CLOCKWISE if direction is None else direction,
                180.0 if start is None else start,
                options.stamp,
            ),
            how,
        )
    how = ", ".join(sources) if sources else "found in the data"
    if sources and len(sources) < 2:
        how += ", the rest found in the data"
    return AzimuthSweep(sweep_s, direction, start, options.stamp), how


def _found_text(
    seams: RawSeamEvidence | None,
    direction: int | None,
    cut: CompensatedCutEvidence | None,
    travel: float,
) -> str:
    """The evidence in words."""
    parts = []
    if seams is not None:
        cw, ccw = seams.rows[CLOCKWISE], seams.rows[COUNTERCLOCKWISE]
        if direction is not None:
            low, high = seams.spread_deg[direction]
            spin = "clockwise" if direction == CLOCKWISE else "counterclockwise"
            parts.append(
                f"{seams.rows[direction]} rings ({ccw if direction == CLOCKWISE else cw} the "
                f"other way) step at their cut, {low:.0f}-{high:.0f} deg, by the range change "
                f"one sweep makes there: {spin}"
            )
        else:
            parts.append(
                f"raw cuts in {cw} rings clockwise, {ccw} counterclockwise (of "
                f"{seams.informative} ring pairs changing by over "
                f"{INFORMATIVE_NOISE * seams.step_noise_m:.3f} m in a sweep)"
            )
    if cut is not None:
        if cut.covered_deg == 0:
            parts.append("no ground where the motion would show a compensated cut")
        elif cut.found:
            parts.append(
                f"a compensated cut on the ground at {cut.at_deg:.0f} deg in "
                f"{100 * cut.fraction:.0f} % of the clouds (rings line up {cut.ratio:.0f}x "
                f"better shifted by the {cut.shift_m:.3f} m travel there)"
            )
        else:
            parts.append(
                f"no compensated cut on the ground (at most in {100 * cut.fraction:.0f} % of "
                f"the clouds; {cut.covered_deg:.0f} deg of azimuth could show one)"
            )
    parts.append(f"travel {travel:.3f} m per sweep")
    return "; ".join(parts)


def _undecided_reason(
    seams: RawSeamEvidence | None,
    cut: CompensatedCutEvidence | None,
    compensated: bool,
    direction: int | None,
    travel: float,
) -> str:
    """Why neither outcome holds."""
    if seams is None or cut is None:
        return "fewer than two clouds"
    if direction is not None and compensated:
        return "both a raw cut and a compensated one show: the tests disagree"
    if compensated:
        return f"a compensated cut shows, but so do raw cuts in {max(seams.rows.values())} rings"
    if np.isfinite(cut.noise_m) and travel < CUT_NOISE * cut.noise_m:
        return (
            f"the sensor barely moves (under {CUT_NOISE:g}x the ground rings' alignment noise, "
            f"{cut.noise_m:.4f} m, per sweep): no cut can stand out"
        )
    if max(seams.rows.values()) >= MIN_SEAM_ROWS:
        return "raw cuts show in both spin directions"
    return (
        "no cut shows where the motion would show one (nothing faces the sensor there, or no "
        "flat ground)"
    )
