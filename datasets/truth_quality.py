"""Truth quality as data: where a truth stream (Vicon, GPS, a bag's truth topic) cannot be
trusted, as typed time intervals that scoring leaves out.

``assess_truth(t, positions, rotations, motion, settings)`` looks at any truth stream,
planar or 3-D poses or positions only, and returns a ``TruthQuality`` whose intervals each
say what was found (``TruthKind``), when, and the numbers that found it:

* ``dropout``: a time gap longer than ``dropout_min_steps`` median steps. The interval
  spans the *missing* samples (one median step after the last sample before the gap to
  one before the first sample after it), so no real sample is dropped.
* ``rate_change``: at least ``rate_change_min_steps`` consecutive steps all longer than
  ``rate_change_factor`` median steps, or all shorter than 1 / ``rate_change_factor``.
* ``freeze``: the same value (every coordinate bit for bit) held for at least
  ``freeze_min_steps`` steps while time advances, and the stream moved across it (the step
  out of the held value is itself a jump). The first held sample is the real value at its
  time; the interval spans the stale ones. A vehicle standing still is not a freeze.
* ``jump``: a step (or a run of steps) in position or rotation that the stream's own
  motion cannot explain (see below) and that no later opposite jump undoes: the interval
  spans the samples around it (which side is wrong cannot be told).
* ``wrong_track``: the samples between a jump away and a later opposite jump back, however
  smooth the track is in between (a Vicon marker set fitted to the wrong markers moves
  smoothly with the robot). Opposite: in some part significant in both, the return points
  within ``acos(pair_min_cosine)`` of the reverse of the departure, whatever its size (a
  drifting offset leaves at 0.3 m and returns from 2.7 m). Pairs nest and never cross;
  exact ones (``pair_exact_remainder``) are taken first, then the shortest. A spike, a
  run of unexplained steps that cancel (``spike_max_net_fraction``; headings modulo a
  full turn, so a heading interpolated the long way round across +-pi is one), is a
  wrong track of the samples inside it. Limits: without odometry, a wrong track whose
  offset turns by more than 60 degrees between its edges, or whose edges are ramps rather
  than steps, is not bound (its edges stay jumps, or go unseen).
* ``heading`` (planar truth by default): for a sustained time while moving, the heading
  disagrees with the direction of travel of the truth's own positions by more than
  ``heading_max_angle_rad`` (a large body-frame lateral or backward velocity). Assumption:
  the vehicle drives forward (a car, a differential-drive robot); switch the check off
  (``heading_check=False``) for a vehicle that reverses or strafes.
* ``motion`` (only with ``motion``, the vehicle's odometry increments, independent of the
  truth): over short windows, the truth's relative motion differs from the odometry's by
  more than ``motion_min_spreads`` robust spreads (1.4826 x median absolute deviation) of
  that difference over the whole recording. A few percent of odometry calibration error
  moves the median and widens the spread; it does not trigger the check. Overlapping
  flagged windows make one disagreement whose net change (the truth's motion beyond the
  odometry's) pairs like a jump: a smooth departure and its return bound a wrong track.
  Edges are known to a window (``motion_window_steps``), not to a sample.

How a step is judged (the same for positions and rotations): the local velocity is the
median of the velocities over ``2 jump_window_steps + 1`` steps around it; the step's
residual is its difference from that velocity times its duration. A jump is a residual
larger than every one of: ``jump_min_sigmas`` robust sigmas of the residuals over the
whole stream (its noise), ``jump_min_fast_steps`` times the stream's fast step (the
``fast_step_percentile`` percentile of the step lengths: a change of velocity of several
times the vehicle's fast speed within one sample is not driving), and a resolution floor.
Every threshold is therefore a multiple of the stream's own statistics; the defaults hold
for any rate and any vehicle speed. The thresholds actually used are in
``TruthQuality.thresholds``.

Intervals are closed, ``[start_s, end_s]`` on the truth's clock; ``keep_mask`` says which
times lie outside all of them. ``datasets.state.GroundTruth.excluded`` carries them to the
metrics, which score nothing inside them.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from datasets.errors import InputError
from datasets.rotations import matrix_from_quat_wxyz, so3_log, wrap_angle

if TYPE_CHECKING:
    from datasets.odometry_calibration import Increments


class TruthKind(enum.StrEnum):
    """What made a truth interval untrustworthy (module docstring: one paragraph each)."""

    DROPOUT = "dropout"
    RATE_CHANGE = "rate_change"
    FREEZE = "freeze"
    JUMP = "jump"
    WRONG_TRACK = "wrong_track"
    HEADING = "heading"
    MOTION = "motion"


@dataclass(frozen=True)
class TruthInterval:
    """A closed time interval of a truth stream that scoring must leave out.

    Attributes:
        start_s: first excluded time [s] (on the truth's clock).
        end_s: last excluded time [s], >= ``start_s`` (equal for a single sample).
        kind: what was found.
        evidence: the numbers that found it, one line of text.
    """

    start_s: float
    end_s: float
    kind: TruthKind
    evidence: str

    def __post_init__(self) -> None:
        if not (math.isfinite(self.start_s) and math.isfinite(self.end_s)):
            raise ValueError(f"TruthInterval needs finite times, got {self.start_s}, {self.end_s}")
        if self.end_s < self.start_s:
            raise ValueError(f"TruthInterval ends before it starts: {self.start_s} > {self.end_s}")

    @property
    def duration_s(self) -> float:
        """Length [s] (0 for a single sample)."""
        return self.end_s - self.start_s

    def line(self) -> str:
        """``kind  start-end s  evidence``, one line for printing."""
        return f"{self.kind.value:<11} {self.start_s:10.3f}-{self.end_s:10.3f} s  {self.evidence}"


def merged_spans(intervals: tuple[TruthInterval, ...] | list[TruthInterval]) -> np.ndarray:
    """The union of the intervals as sorted disjoint closed spans, shape (K, 2) [s]."""
    if not intervals:
        return np.zeros((0, 2))
    spans = np.array(sorted((i.start_s, i.end_s) for i in intervals), dtype=float)
    merged = [list(spans[0])]
    for start, end in spans[1:]:
        if start <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], end)
        else:
            merged.append([start, end])
    return np.array(merged, dtype=float)


def excluded_mask(times: np.ndarray, intervals: tuple[TruthInterval, ...]) -> np.ndarray:
    """(N,) bool: True where a time [s] lies inside (edges included) any of the intervals."""
    times = np.asarray(times, dtype=float)
    spans = merged_spans(intervals)
    if len(spans) == 0:
        return np.zeros(times.shape, dtype=bool)
    index = np.searchsorted(spans[:, 0], times, side="right") - 1
    inside = index >= 0
    inside[inside] = times[inside] <= spans[index[inside], 1]
    return inside


class TruthQualitySettings(BaseModel):
    """Thresholds of ``assess_truth``. Each is a multiple of a statistic of the stream
    itself (its median step, its robust noise, its fast step), so the defaults hold for any
    rate, vehicle and truth system; none is fitted to one recording."""

    model_config = ConfigDict(frozen=True, extra="forbid", use_attribute_docstrings=True)

    dropout_min_steps: float = Field(4.0, gt=1.0)
    """A gap longer than this many median steps is a dropout: at least three samples in a
    row are missing, which clock jitter never gives. The metrics refuse to interpolate the
    truth across the same gap (``workbench.metrics.timestamps``)."""

    rate_change_factor: float = Field(1.5, gt=1.0)
    """Steps longer than this many median steps (or shorter than its inverse) are at
    another rate: a stream that changes rate does so by a factor of 2 or more (100 -> 50 Hz),
    while jitter moves single steps, not runs of them."""

    rate_change_min_steps: int = Field(5, ge=2)
    """Consecutive off-rate steps (all longer, or all shorter) that make a rate change;
    fewer are jitter or a dropout."""

    jump_window_steps: int = Field(5, ge=1)
    """Half-width [steps] of the running median that gives the local velocity: 11 steps
    outvote a spike or a step of a few samples, and are short against any manoeuvre."""

    jump_min_sigmas: float = Field(20.0, gt=0.0)
    """A jump's residual exceeds this many robust sigmas (1.4826 MAD) of all residuals: the
    stream's own noise, heavy tails included (Vicon's reach about 14 sigma), never does."""

    jump_min_fast_steps: float = Field(3.0, gt=0.0)
    """... and this many fast steps (``fast_step_percentile`` of the step lengths): a
    change of velocity of three times the vehicle's fast speed within one sample is not a
    manoeuvre. Keeps noise-free (simulated) truth from flagging its turns."""

    fast_step_percentile: float = Field(99.0, gt=50.0, le=100.0)
    """Percentile of the step lengths that is the stream's fast step (robust to a few
    percent of bad steps)."""

    jump_floor_m: float = Field(1e-6, ge=0.0)
    """Position resolution floor [m]: below a micrometre no truth system resolves anything;
    only keeps noise-free truth from flagging its rounding."""

    jump_floor_rad: float = Field(1e-6, ge=0.0)
    """Rotation resolution floor [rad], as ``jump_floor_m``."""

    spike_max_net_fraction: float = Field(0.25, gt=0.0, lt=1.0)
    """A burst of consecutive unexplained steps whose net change stays below this fraction
    of its largest step (or below the jump threshold) returns to the track: a spike. The
    local velocity is uncertain inside a cluster of glitches, so the net of a long burst
    is not exactly zero; a step away keeps most of its largest step."""

    pair_min_cosine: float = Field(0.5, ge=-1.0, le=1.0)
    """A jump back pairs with a jump away when it points within 60 degrees of the reverse
    (cosine >= 0.5) in a part (position, rotation) significant in both: the size may
    differ, since a wrong track's offset drifts (0.3 m away, 2.7 m back), but its direction
    must not turn by more than 60 degrees meanwhile (beyond that only the motion check,
    with odometry, sees the track)."""

    pair_exact_remainder: float = Field(0.25, gt=0.0, lt=1.0)
    """A return that undoes its departure to within this fraction
    (``|away + back| / (|away| + |back|)``) is an exact pair, taken before any inexact one:
    a heading failure's constant offset undoes itself exactly, a jump that happens to point
    back rarely does."""

    wrong_track_max_fraction: float = Field(0.5, gt=0.0, le=1.0)
    """A pair spanning more than this fraction of the recording is not paired (both stay
    jumps): truth that is off for most of a recording cannot be told from truth that is
    right."""

    freeze_min_steps: int = Field(3, ge=1)
    """Identical consecutive values over at least this many steps (4 samples) can be a
    freeze; it is one only when the stream moved across it (see the module docstring)."""

    heading_check: bool | None = None
    """Check the heading against the direction of travel (assumes a vehicle that drives
    forward); None: on for planar truth, off for 3-D truth (drones, hand-held rigs)."""

    heading_window_steps: int = Field(25, ge=1)
    """Half-width [steps] of the chord that gives the direction of travel: long enough to
    rise well above the position noise at walking speed, short against a turn."""

    heading_max_angle_rad: float = Field(math.pi / 3, gt=0.0, lt=math.pi)
    """The heading disagrees with the direction of travel when they are more than 60 degrees
    apart: a forward-driving vehicle slips sideways by a few degrees, not tens."""

    heading_min_travel_fraction: float = Field(0.1, gt=0.0)
    """The vehicle moves when its chord is at least this fraction of the chord at the fast
    step (and above ``jump_min_sigmas`` noise sigmas): slower, a sensor offset from the
    turning axis or the noise sets the direction of travel."""

    heading_min_steps: int = Field(50, ge=1)
    """Disagreeing samples (not interrupted by an agreeing one) that make a sustained heading
    failure: two chord windows; a single-sample glitch is a jump, not a heading failure."""

    motion_window_steps: int = Field(100, ge=2)
    """Length [truth steps] of the windows over which truth and odometry motion are compared
    (stride: half of it): long against the odometry's delay and noise (commanded velocities
    lead the motion by a fraction of a second), short against a wrong track."""

    motion_min_spreads: float = Field(40.0, gt=0.0)
    """A window's truth-minus-odometry motion lies this many robust spreads from the
    recording's median in some component: commanded-velocity odometry that stalls in turns
    (UTIAS, with or without its delay) stays within about 22; a heading off by 2 rad or a
    wrong track drifting by 0.2 m/s gives 50-100."""


@dataclass(frozen=True)
class TruthQuality:
    """What ``assess_truth`` found in one truth stream.

    Attributes:
        intervals: the untrusted intervals, sorted by start (kinds may overlap).
        samples: number of truth samples assessed.
        start_s, end_s: the stream's time span [s].
        median_step_s: the stream's median sample step [s].
        thresholds: the thresholds and statistics actually used (names carry units).
        settings: the settings used.
    """

    intervals: tuple[TruthInterval, ...]
    samples: int
    start_s: float
    end_s: float
    median_step_s: float
    thresholds: dict[str, float] = field(default_factory=dict)
    settings: TruthQualitySettings = field(default_factory=TruthQualitySettings)

    def keep_mask(self, t: np.ndarray) -> np.ndarray:
        """(N,) bool: True for times [s] outside every interval (the samples to keep)."""
        return ~excluded_mask(t, self.intervals)

    def lines(self) -> list[str]:
        """One printable line per interval: kind, start-end [s], evidence."""
        return [interval.line() for interval in self.intervals]

    @property
    def excluded_s(self) -> float:
        """Total time [s] covered by the union of the intervals."""
        spans = merged_spans(self.intervals)
        return float(np.sum(spans[:, 1] - spans[:, 0])) if len(spans) else 0.0

    def counts(self) -> dict[str, int]:
        """Number of intervals per kind (kinds found only)."""
        found: dict[str, int] = {}
        for interval in self.intervals:
            found[interval.kind.value] = found.get(interval.kind.value, 0) + 1
        return found

    def summary(self) -> str:
        """One line: how many intervals of which kinds, and the time they cover."""
        if not self.intervals:
            return f"truth quality: nothing excluded ({self.samples} samples)"
        kinds = ", ".join(f"{count} {kind}" for kind, count in self.counts().items())
        span = self.end_s - self.start_s
        share = self.excluded_s / span if span > 0 else 0.0
        return (
            f"truth quality: {len(self.intervals)} intervals excluded ({kinds}), "
            f"{self.excluded_s:.2f} s of {span:.2f} s ({100 * share:.2f} %)"
        )


# ----------------------------------------------------------------------------- internals


@dataclass
class _Jump:
    """Consecutive flagged steps ``first..last`` (step k joins samples k and k+1), their
    net change beyond the local motion and which parts of it are significant. A jump found
    by the motion check (a smooth departure that odometry contradicts) carries its evidence
    and, left unpaired, stays a ``motion`` interval."""

    first: int
    last: int
    position: np.ndarray
    rotation: np.ndarray
    position_significant: bool
    rotation_significant: bool
    motion_evidence: str | None = None


@dataclass(frozen=True)
class _Increments:
    """Per-step increments of one part (positions or rotations) and their judgement.

    Attributes:
        steps: increments (N-1, k) (rotations: body-frame rotation vectors, or headings).
        residuals: steps minus the local median velocity times the step duration (N-1, k).
        flagged: (N-1,) bool, residual norm above ``threshold``.
        threshold: the jump threshold used.
        sigma: robust sigma of the residuals (largest over the axes).
        fast_step: the fast step length.
    """

    steps: np.ndarray
    residuals: np.ndarray
    flagged: np.ndarray
    threshold: float
    sigma: float
    fast_step: float


def _robust_sigma(values: np.ndarray) -> np.ndarray:
    """1.4826 x median absolute deviation per column of (M, k) values (0 without rows)."""
    if len(values) == 0:
        return np.zeros(values.shape[1])
    centre = np.median(values, axis=0)
    return 1.4826 * np.median(np.abs(values - centre), axis=0)


def _judge(
    steps: np.ndarray,
    dt: np.ndarray,
    assessed: np.ndarray,
    settings: TruthQualitySettings,
    floor: float,
    angular: bool,
) -> _Increments:
    """Residuals of ``steps`` (N-1, k) against the running-median velocity, and the flags."""
    from scipy.ndimage import median_filter

    rates = steps / dt[:, None]
    size = 2 * settings.jump_window_steps + 1
    local = median_filter(rates, size=(size, 1), mode="nearest")
    residuals = steps - local * dt[:, None]
    if angular and steps.shape[1] == 1:
        residuals = np.asarray(wrap_angle(residuals), dtype=float)
    residuals = np.where(assessed[:, None], residuals, 0.0)
    sigma = float(np.max(_robust_sigma(residuals[assessed]))) if np.any(assessed) else 0.0
    lengths = np.linalg.norm(steps[assessed], axis=1)
    fast = float(np.percentile(lengths, settings.fast_step_percentile)) if len(lengths) else 0.0
    threshold = max(settings.jump_min_sigmas * sigma, settings.jump_min_fast_steps * fast, floor)
    flagged = assessed & (np.linalg.norm(residuals, axis=1) > threshold)
    return _Increments(steps, residuals, flagged, threshold, sigma, fast)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of every run of True in a 1-D bool array."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2])]


def _timing(
    t: np.ndarray, dt: np.ndarray, step: float, settings: TruthQualitySettings
) -> tuple[list[TruthInterval], np.ndarray]:
    """Dropouts and rate changes; returns them and the (N-1,) mask of dropout steps."""
    found: list[TruthInterval] = []
    long = dt > settings.rate_change_factor * step
    short = dt < step / settings.rate_change_factor
    in_rate_change = np.zeros(len(dt), dtype=bool)
    factor = settings.rate_change_factor
    for mask, word in (
        (long, f"longer than {factor:g}x"),
        (short, f"shorter than 1/{factor:g} of"),
    ):
        for first, last in _runs(mask):
            count = last - first + 1
            if count < settings.rate_change_min_steps:
                continue
            in_rate_change[first : last + 1] = True
            local = float(np.median(dt[first : last + 1]))
            found.append(
                TruthInterval(
                    float(t[first]),
                    float(t[last + 1]),
                    TruthKind.RATE_CHANGE,
                    f"{count} consecutive steps {word} the median step {step:.4g} s "
                    f"(median {local:.4g} s there)",
                )
            )
    dropout = (dt > settings.dropout_min_steps * step) & ~in_rate_change
    for index in np.flatnonzero(dropout):
        gap = float(dt[index])
        found.append(
            TruthInterval(
                float(t[index]) + step,
                float(t[index + 1]) - step,
                TruthKind.DROPOUT,
                f"no sample for {gap:.4g} s ({gap / step:.1f}x the median step {step:.4g} s) "
                f"after {t[index]:.3f} s",
            )
        )
    return found, dt > settings.dropout_min_steps * step


def _rotation_increments(rotations: np.ndarray, planar: bool) -> np.ndarray:
    """Per-step rotation increments: wrapped heading changes (N-1, 1) for planar truth,
    body-frame rotation vectors Log(R_k^T R_k+1) (N-1, 3) in 3-D."""
    if planar:
        return np.asarray(wrap_angle(np.diff(rotations)), dtype=float)[:, None]
    matrices = matrix_from_quat_wxyz(rotations)
    relative = np.einsum("nji,njk->nik", matrices[:-1], matrices[1:])
    return np.asarray(so3_log(relative), dtype=float).reshape(-1, 3)


def _reverse(away: np.ndarray, back: np.ndarray, angular: bool) -> tuple[float, float]:
    """How well ``back`` reverses ``away``: (cosine between ``-away`` and ``back``, the
    remainder ``|away + back| / (|away| + |back|)``, 0 when it undoes it exactly). For
    rotations ``back`` is taken as the equivalent rotation vector (or heading) nearest to
    ``-away``, so a flip by pi is its own reverse."""
    away = np.asarray(away, dtype=float)
    candidates = [np.asarray(back, dtype=float)]
    if angular:
        size = float(np.linalg.norm(back))
        if size > 0:
            candidates.append(candidates[0] * (1.0 - 2.0 * math.pi / size))
    best = (-1.0, 1.0)
    for candidate in candidates:
        norms = float(np.linalg.norm(away) * np.linalg.norm(candidate))
        if norms <= 0:
            continue
        cosine = float(np.dot(-away, candidate)) / norms
        total = float(np.linalg.norm(away) + np.linalg.norm(candidate))
        remainder = float(np.linalg.norm(away + candidate)) / total
        if cosine > best[0]:
            best = (cosine, remainder)
    return best


def _reversal(away: _Jump, back: _Jump, min_cosine: float) -> float | None:
    """The remainder (0: exact) with which ``back`` undoes ``away``, or None when it does
    not: some part significant in both (position, rotation) must point back within
    ``acos(min_cosine)`` of the reverse. One part is enough: a heading failure's small
    position steps at its edges turn with the robot, its heading offset does not."""
    remainders = []
    if away.position_significant and back.position_significant:
        cosine, remainder = _reverse(away.position, back.position, angular=False)
        if cosine >= min_cosine:
            remainders.append(remainder)
    if away.rotation_significant and back.rotation_significant:
        cosine, remainder = _reverse(away.rotation, back.rotation, angular=True)
        if cosine >= min_cosine:
            remainders.append(remainder)
    return min(remainders) if remainders else None


def _jump_words(jump: _Jump, planar: bool) -> str:
    parts = []
    if jump.position_significant:
        parts.append(f"{np.linalg.norm(jump.position):.3f} m")
    if jump.rotation_significant:
        angle = float(jump.rotation[0]) if planar else float(np.linalg.norm(jump.rotation))
        parts.append(f"{angle:+.2f} rad" if planar else f"{angle:.2f} rad")
    return " and ".join(parts)


def _wrapped_rotation(vector: np.ndarray) -> np.ndarray:
    """The rotation vector (or heading) of the same rotation with the smallest angle."""
    vector = np.asarray(vector, dtype=float)
    size = float(np.linalg.norm(vector))
    if size <= math.pi:
        return vector
    if len(vector) == 1:
        return np.atleast_1d(np.asarray(wrap_angle(vector), dtype=float))
    return vector * (1.0 - 2.0 * math.pi * math.ceil((size - math.pi) / (2.0 * math.pi)) / size)


def _net_significant(
    net: np.ndarray, steps: np.ndarray, threshold: float, settings: TruthQualitySettings
) -> bool:
    """A burst's net change is a step of its own: above the jump threshold and above
    ``spike_max_net_fraction`` of the burst's largest step."""
    size = float(np.linalg.norm(net))
    largest = float(np.max(np.linalg.norm(steps, axis=1)))
    return size > threshold and size > settings.spike_max_net_fraction * largest


def _bursts(
    position: _Increments,
    rotation: _Increments | None,
    explained: np.ndarray,
    settings: TruthQualitySettings,
) -> tuple[list[_Jump], list[tuple[int, int, str]]]:
    """Runs of consecutive flagged steps not explained by a freeze ("bursts").

    A burst whose steps cancel (``_net_significant`` false in every part; headings and
    rotations modulo a full turn, so a heading interpolated the long way round across
    +-pi cancels) is a spike: the samples inside it are off and the track returns. Any
    other burst is a jump whose net change is what a later jump must undo.

    Returns:
        (jumps, spikes as (first step, last step, evidence)).
    """
    flagged = position.flagged | (rotation.flagged if rotation is not None else False)
    flagged = flagged & ~explained
    jumps: list[_Jump] = []
    spikes: list[tuple[int, int, str]] = []
    for first, last in _runs(flagged):
        p_steps = position.residuals[first : last + 1]
        p_net = p_steps.sum(axis=0)
        p_sig = _net_significant(p_net, p_steps, position.threshold, settings)
        if rotation is not None:
            r_steps = rotation.residuals[first : last + 1]
            r_net = _wrapped_rotation(r_steps.sum(axis=0))
            r_sig = _net_significant(r_net, r_steps, rotation.threshold, settings)
        else:
            r_net, r_sig = np.zeros(1), False
        if p_sig or r_sig:
            jumps.append(_Jump(first, last, p_net, r_net, p_sig, r_sig))
            continue
        largest = f"{np.max(np.linalg.norm(position.residuals[first : last + 1], axis=1)):.3f} m"
        if rotation is not None:
            size = np.max(np.linalg.norm(rotation.residuals[first : last + 1], axis=1))
            largest += f" / {size:.2f} rad"
        spikes.append(
            (
                first,
                last,
                f"{last - first} samples off and back: {last - first + 1} unexplained steps of "
                f"up to {largest} that cancel (net {np.linalg.norm(p_net):.3f} m"
                + (f", {np.linalg.norm(r_net):.3f} rad)" if rotation is not None else ")"),
            )
        )
    return jumps, spikes


def _pair(
    jumps: list[_Jump], t: np.ndarray, settings: TruthQualitySettings
) -> tuple[list[tuple[_Jump, _Jump]], list[_Jump]]:
    """Pairs (away, back) of neighbouring jumps where the second undoes the first, and the
    jumps left alone. A pair leaves the list, so its neighbours become neighbours: pairs
    nest and never cross. Exact pairs (remainder within ``pair_exact_remainder``) go first,
    shortest first, then inexact ones, shortest first: a heading failure undoes its entry
    exactly while a jump next to it may point back by chance, and a drifting position
    offset undoes its entry only roughly, so among rough pairs the innermost is likeliest."""
    remaining = list(range(len(jumps)))
    pairs: list[tuple[_Jump, _Jump]] = []
    longest = settings.wrong_track_max_fraction * float(t[-1] - t[0])
    keys: dict[tuple[int, int], tuple[bool, float] | None] = {}

    def key(a: int, b: int) -> tuple[bool, float] | None:
        # cached: only the pair that a removal makes neighbours is new each round
        if (a, b) not in keys:
            away, back = jumps[a], jumps[b]
            span = float(t[back.last] - t[away.first + 1])
            remainder = _reversal(away, back, settings.pair_min_cosine)
            keys[(a, b)] = (
                None
                if span > longest or remainder is None
                else (remainder > settings.pair_exact_remainder, span)
            )
        return keys[(a, b)]

    while True:
        best, best_key = None, (True, math.inf)
        for k in range(len(remaining) - 1):
            found = key(remaining[k], remaining[k + 1])
            if found is not None and found < best_key:
                best, best_key = k, found
        if best is None:
            return pairs, [jumps[index] for index in remaining]
        pairs.append((jumps[remaining[best]], jumps[remaining[best + 1]]))
        del remaining[best : best + 2]


def _freezes(
    t: np.ndarray,
    positions: np.ndarray,
    rotations: np.ndarray | None,
    position: _Increments,
    rotation: _Increments | None,
    settings: TruthQualitySettings,
) -> tuple[list[TruthInterval], np.ndarray]:
    """Held values while the stream moves; returns them and the (N-1,) mask of the steps
    they explain (the held steps and the step out of the held value)."""
    same = np.all(np.diff(positions, axis=0) == 0.0, axis=1)
    if rotations is not None:
        rows = rotations.reshape(len(rotations), -1)
        same &= np.all(np.diff(rows, axis=0) == 0.0, axis=1)
    explained = np.zeros(len(same), dtype=bool)
    found: list[TruthInterval] = []
    for first, last in _runs(same):
        count = last - first + 1
        if count < settings.freeze_min_steps:
            continue
        exit_step = last + 1
        if exit_step < len(same):
            moved = bool(position.flagged[exit_step]) or (
                rotation is not None and bool(rotation.flagged[exit_step])
            )
            how = f"then moves by {np.linalg.norm(position.steps[exit_step]):.3f} m"
            if rotation is not None:
                how += f" / {np.linalg.norm(rotation.steps[exit_step]):.3f} rad"
            how += " in one step"
        else:
            # held to the end: moved if the velocity before it would have carried it
            # beyond the jump threshold in the time it was held
            before = max(first - 1, 0)
            velocity = position.steps[before] / max(float(t[before + 1] - t[before]), 1e-12)
            reach = float(np.linalg.norm(velocity)) * float(t[last + 1] - t[first])
            moved = reach > position.threshold
            how = f"to the end while moving at {np.linalg.norm(velocity):.3f} m/s before"
        if not moved:
            continue
        explained[first : min(exit_step, len(same) - 1) + 1] = True
        found.append(
            TruthInterval(
                float(t[first + 1]),
                float(t[last + 1]),
                TruthKind.FREEZE,
                f"{count + 1} samples hold the same value for {t[last + 1] - t[first]:.3f} s, "
                + how,
            )
        )
    return found, explained


def _broken_windows(broken: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """True where the steps ``lower..upper-1`` contain a broken step."""
    cumulative = np.concatenate([[0], np.cumsum(broken)])
    return (cumulative[upper] - cumulative[lower]) > 0


def _heading(
    t: np.ndarray,
    positions: np.ndarray,
    forward: np.ndarray,
    position: _Increments,
    broken: np.ndarray,
    settings: TruthQualitySettings,
) -> tuple[list[TruthInterval], dict[str, float]]:
    """Sustained disagreement of the heading (body x axis ``forward``, (N, d)) with the
    direction of travel (the chord over +-``heading_window_steps``)."""
    count = len(t)
    index = np.arange(count)
    lower = np.clip(index - settings.heading_window_steps, 0, count - 1)
    upper = np.clip(index + settings.heading_window_steps, 0, count - 1)
    chord = positions[upper] - positions[lower]
    length = np.linalg.norm(chord, axis=1)
    travel = max(
        settings.jump_min_sigmas * position.sigma,
        settings.heading_min_travel_fraction
        * 2
        * settings.heading_window_steps
        * position.fast_step,
        settings.jump_floor_m,
    )
    moving = (length > travel) & ~_broken_windows(broken, lower, upper)
    cosine = np.einsum("nd,nd->n", chord, forward) / np.maximum(
        length * np.linalg.norm(forward, axis=1), 1e-300
    )
    angle = np.arccos(np.clip(cosine, -1.0, 1.0))
    disagree = moving & (angle > settings.heading_max_angle_rad)
    agree = moving & ~disagree
    found: list[TruthInterval] = []
    samples = np.flatnonzero(disagree)
    if len(samples):
        groups = np.cumsum(agree)[samples]
        for part in np.split(samples, np.flatnonzero(np.diff(groups)) + 1):
            if len(part) < settings.heading_min_steps:
                continue
            found.append(
                TruthInterval(
                    float(t[part[0]]),
                    float(t[part[-1]]),
                    TruthKind.HEADING,
                    f"heading {np.median(angle[part]):.2f} rad (median; max "
                    f"{np.max(angle[part]):.2f}) off the direction of travel on {len(part)} "
                    f"moving samples (threshold {settings.heading_max_angle_rad:.2f} rad; "
                    "assumes forward driving)",
                )
            )
    return found, {"heading_min_travel_m": travel, "heading_moving_fraction": float(moving.mean())}


def _dead_reckoning(motion: Increments) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Composed odometry: (times (M+1,), planar poses (M+1, 3) as x, y, unwrapped theta,
    (M,) bool: increment k starts later than increment k-1 ends (a gap))."""
    t_end = np.asarray(motion.t_end, dtype=float)
    dt = np.asarray(motion.dt, dtype=float)
    values = np.asarray(motion.values, dtype=float)
    if values.ndim != 2 or values.shape != (len(t_end), 3) or dt.shape != t_end.shape:
        raise InputError(
            f"motion increments must be t_end (M,), dt (M,), values (M, 3); got "
            f"{t_end.shape}, {dt.shape}, {values.shape}"
        )
    heading = np.concatenate([[0.0], np.cumsum(values[:, 2])])
    cos, sin = np.cos(heading[:-1]), np.sin(heading[:-1])
    world = np.column_stack(
        [cos * values[:, 0] - sin * values[:, 1], sin * values[:, 0] + cos * values[:, 1]]
    )
    xy = np.vstack([np.zeros((1, 2)), np.cumsum(world, axis=0)])
    times = np.concatenate([[t_end[0] - dt[0]], t_end])
    starts = t_end - dt
    gap = np.zeros(len(t_end), dtype=bool)
    gap[1:] = starts[1:] > t_end[:-1] + 0.5 * np.median(dt)
    return times, np.column_stack([xy, heading]), gap


def _relative_planar(xy: np.ndarray, heading: np.ndarray, a: np.ndarray, b: np.ndarray):
    """(dx, dy, dtheta) from pose a to pose b in frame a, shape (W, 3)."""
    delta = xy[b] - xy[a]
    cos, sin = np.cos(heading[a]), np.sin(heading[a])
    return np.column_stack(
        [
            cos * delta[:, 0] + sin * delta[:, 1],
            -sin * delta[:, 0] + cos * delta[:, 1],
            np.asarray(wrap_angle(heading[b] - heading[a]), dtype=float),
        ]
    )


def _motion(
    t: np.ndarray,
    positions: np.ndarray,
    rotations: np.ndarray | None,
    planar: bool,
    motion: Increments,
    broken: np.ndarray,
    thresholds: tuple[float, float],
    settings: TruthQualitySettings,
) -> tuple[list[_Jump], dict[str, float]]:
    """Windows where the truth's relative motion disagrees with the odometry's, merged where
    they overlap, each as a jump whose net change is the truth's motion beyond the
    odometry's (world frame, the truth's heading at its start), so that a smooth departure
    pairs with its return like a step does. ``thresholds``: (position [m], rotation [rad])
    above which a net change is significant."""
    odo_t, odo_pose, odo_gap = _dead_reckoning(motion)
    count = len(t)
    length = settings.motion_window_steps
    stride = max(length // 2, 1)
    lower = np.arange(0, max(count - length, 0), stride)
    upper = lower + length
    usable = ~_broken_windows(broken, lower, upper)
    usable &= (t[lower] >= odo_t[0]) & (t[upper] <= odo_t[-1])
    if np.any(odo_gap):
        # a window that spans a gap in the odometry has no odometry motion to compare
        gap_starts = (np.asarray(motion.t_end) - np.asarray(motion.dt))[odo_gap]
        gap_ends = np.asarray(motion.t_end)[np.flatnonzero(odo_gap) - 1]
        for start, end in zip(gap_ends, gap_starts):
            usable &= ~((t[lower] < start) & (t[upper] > end))
    lower, upper = lower[usable], upper[usable]
    stats = {"motion_windows": float(len(lower))}
    if len(lower) < 10:
        return [], stats  # too few windows for a robust spread
    odo = np.column_stack([np.interp(t, odo_t, odo_pose[:, k]) for k in range(3)])
    truth_rel, odo_rel, names = _relative_motions(positions, rotations, planar, odo, lower, upper)
    difference = truth_rel - odo_rel
    if difference.shape[1] == 3:
        difference[:, 2] = np.asarray(wrap_angle(difference[:, 2]), dtype=float)
    centre = np.median(difference, axis=0)
    floors = np.array([settings.jump_floor_m] * 2 + [settings.jump_floor_rad])[: len(names)]
    spread = np.maximum(_robust_sigma(difference), floors)
    score = np.abs(difference - centre) / spread
    worst = np.max(score, axis=1)
    for name, value in zip(names, spread):
        stats[f"motion_spread_{name}"] = float(value)
    stats["motion_largest_spreads"] = float(np.max(worst))
    flagged = np.flatnonzero(worst > settings.motion_min_spreads)
    groups: list[list[int]] = []
    for k in flagged:
        if groups and lower[k] <= upper[groups[-1][-1]]:
            groups[-1].append(int(k))
        else:
            groups.append([int(k)])
    found: list[_Jump] = []
    for group in groups:
        a, b = int(lower[group[0]]), int(upper[group[-1]])
        k = group[int(np.argmax(worst[group]))]
        axis = int(np.argmax(score[k]))
        evidence = (
            f"truth moved {np.round(truth_rel[k], 3).tolist()} ({', '.join(names)}) in "
            f"{t[upper[k]] - t[lower[k]]:.2f} s where the odometry says "
            f"{np.round(odo_rel[k], 3).tolist()}: {names[axis]} {score[k, axis]:.0f} robust "
            f"spreads ({spread[axis]:.3g}) off the median"
            + (f" ({len(group)} overlapping windows)" if len(group) > 1 else "")
        )
        pos_net, rot_net = _motion_net(positions, rotations, planar, odo, a, b)
        found.append(
            _Jump(
                a,
                b - 1,
                pos_net,
                rot_net,
                bool(np.linalg.norm(pos_net) > thresholds[0]),
                bool(np.linalg.norm(rot_net) > thresholds[1]),
                evidence,
            )
        )
    return found, stats


def _relative_motions(
    positions: np.ndarray,
    rotations: np.ndarray | None,
    planar: bool,
    odo: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Truth and odometry motion from ``lower`` to ``upper`` in the frame at ``lower``:
    (dx, dy, dtheta) each (W, 3); positions only: the travelled distance (W, 1)."""
    odo_rel = _relative_planar(odo[:, :2], odo[:, 2], lower, upper)
    if rotations is None:
        # positions only: the travelled distance is all that has no frame
        truth_rel = np.linalg.norm(positions[upper] - positions[lower], axis=1)[:, None]
        return truth_rel, np.linalg.norm(odo_rel[:, :2], axis=1)[:, None], ("distance",)
    if planar:
        truth_rel = _relative_planar(positions[:, :2], rotations, lower, upper)
    else:
        matrices = matrix_from_quat_wxyz(rotations)
        body = np.einsum("nji,nj->ni", matrices[lower], positions[upper] - positions[lower])
        turn = so3_log(np.einsum("nji,njk->nik", matrices[lower], matrices[upper]))
        truth_rel = np.column_stack([body[:, :2], np.asarray(turn).reshape(-1, 3)[:, 2]])
    return truth_rel, odo_rel, ("dx", "dy", "dtheta")


def _motion_net(
    positions: np.ndarray,
    rotations: np.ndarray | None,
    planar: bool,
    odo: np.ndarray,
    a: int,
    b: int,
) -> tuple[np.ndarray, np.ndarray]:
    """The truth's change from sample a to b beyond the odometry's: world-frame position
    (odometry turned by the truth's heading at a), and heading (planar only; 3-D and
    positions-only truth give no rotation part)."""
    delta = positions[b] - positions[a]
    odo_rel = _relative_planar(odo[:, :2], odo[:, 2], np.array([a]), np.array([b]))[0]
    if rotations is None:
        return np.zeros_like(delta), np.zeros(1)  # no frame: no direction to pair by
    if planar:
        cos, sin = math.cos(rotations[a]), math.sin(rotations[a])
        odo_world = np.array(
            [cos * odo_rel[0] - sin * odo_rel[1], sin * odo_rel[0] + cos * odo_rel[1]]
        )
        position = delta[:2] - odo_world
        turn = float(wrap_angle(rotations[b] - rotations[a] - odo_rel[2]))
        return position, np.array([turn])
    matrix = matrix_from_quat_wxyz(rotations[a])
    return delta - matrix @ np.array([odo_rel[0], odo_rel[1], 0.0]), np.zeros(3)


def _merged_same_kind(intervals: list[TruthInterval]) -> list[TruthInterval]:
    """Overlapping intervals of one kind joined (evidence of the first, with a count)."""
    result: list[TruthInterval] = []
    for kind in TruthKind:
        group = sorted((i for i in intervals if i.kind == kind), key=lambda i: i.start_s)
        current: list[TruthInterval] = []
        for interval in group:
            if current and interval.start_s <= max(i.end_s for i in current):
                current.append(interval)
                continue
            if current:
                result.append(_join(current))
            current = [interval]
        if current:
            result.append(_join(current))
    return sorted(result, key=lambda i: (i.start_s, i.end_s, i.kind.value))


def _join(group: list[TruthInterval]) -> TruthInterval:
    if len(group) == 1:
        return group[0]
    worst = group[0].evidence
    return TruthInterval(
        group[0].start_s,
        max(i.end_s for i in group),
        group[0].kind,
        f"{len(group)} overlapping windows, the first: {worst}",
    )


def assess_truth(
    t: np.ndarray,
    positions: np.ndarray,
    rotations: np.ndarray | None = None,
    motion: Increments | None = None,
    settings: TruthQualitySettings = TruthQualitySettings(),  # noqa: B008 (frozen)
) -> TruthQuality:
    """Find where a truth stream cannot be trusted (module docstring: the kinds, the tests).

    Args:
        t: sample times [s], shape (N,), strictly increasing.
        positions: world positions [m], shape (N, 2) or (N, 3).
        rotations: planar headings [rad] shape (N,), body-to-world quaternions (w, x, y, z)
            shape (N, 4), or None (positions only, e.g. GPS).
        motion: the vehicle's odometry, independent of the truth, as planar increments
            (``datasets.odometry_calibration.Increments``: end times [s] (M,), durations [s]
            (M,), body-frame (dx [m], dy [m], dtheta [rad]) (M, 3)), on the truth's clock;
            None skips the motion check.
        settings: the thresholds.

    Returns:
        ``TruthQuality``: the intervals, sorted by start, and the thresholds used.

    Raises:
        InputError: shapes that disagree, non-finite values, times that do not increase.
    """
    t = np.asarray(t, dtype=float)
    positions = np.asarray(positions, dtype=float)
    count = len(t)
    if t.ndim != 1 or positions.ndim != 2 or positions.shape != (count, positions.shape[1]):
        raise InputError(
            f"truth times (N,) and positions (N, d) disagree: {t.shape}, {positions.shape}"
        )
    if positions.shape[1] not in (2, 3):
        raise InputError(f"truth positions must be (N, 2) or (N, 3), got {positions.shape}")
    if rotations is not None:
        rotations = np.asarray(rotations, dtype=float)
        if rotations.shape not in ((count,), (count, 4)):
            raise InputError(
                f"truth rotations must be headings (N,) or quaternions (N, 4), got {rotations.shape}"
            )
    planar = rotations.ndim == 1 if rotations is not None else positions.shape[1] == 2
    for name, values in (("times", t), ("positions", positions), ("rotations", rotations)):
        if values is not None and not np.all(np.isfinite(values)):
            raise InputError(f"truth {name} hold non-finite values")
    if count < 3:
        span = (float(t[0]), float(t[-1])) if count else (0.0, 0.0)
        return TruthQuality((), count, span[0], span[1], 0.0, {}, settings)
    dt = np.diff(t)
    if np.any(dt <= 0):
        index = int(np.flatnonzero(dt <= 0)[0])
        raise InputError(
            f"truth times must increase: sample {index + 1} at {t[index + 1]:.6f} s follows "
            f"{t[index]:.6f} s"
        )
    step = float(np.median(dt))

    intervals, dropout_steps = _timing(t, dt, step, settings)
    assessed = ~dropout_steps  # a step across a gap has no local velocity to judge it by
    position = _judge(
        np.diff(positions, axis=0), dt, assessed, settings, settings.jump_floor_m, False
    )
    rotation = None
    if rotations is not None:
        rotation = _judge(
            _rotation_increments(rotations, planar),
            dt,
            assessed,
            settings,
            settings.jump_floor_rad,
            True,
        )
    thresholds = {
        "median_step_s": step,
        "jump_threshold_m": position.threshold,
        "position_sigma_m": position.sigma,
        "fast_step_m": position.fast_step,
    }
    if rotation is not None:
        thresholds.update(
            jump_threshold_rad=rotation.threshold,
            rotation_sigma_rad=rotation.sigma,
            fast_step_rad=rotation.fast_step,
        )

    frozen, explained = _freezes(t, positions, rotations, position, rotation, settings)
    intervals += frozen
    jumps, spikes = _bursts(position, rotation, explained, settings)
    for first, last, evidence in spikes:
        intervals.append(
            TruthInterval(float(t[first + 1]), float(t[last]), TruthKind.WRONG_TRACK, evidence)
        )

    # steps whose neighbourhood is already explained: no chord or window is judged over them
    broken = dropout_steps | explained
    for first, last in [(j.first, j.last) for j in jumps] + [(a, b) for a, b, _ in spikes]:
        broken[first : last + 1] = True
    check_heading = settings.heading_check if settings.heading_check is not None else planar
    if check_heading and rotations is not None:
        if planar:
            forward = np.column_stack([np.cos(rotations), np.sin(rotations)])
        else:
            forward = matrix_from_quat_wxyz(rotations)[:, :, 0]
        chord_positions = positions[:, : forward.shape[1]]
        found, stats = _heading(t, chord_positions, forward, position, broken, settings)
        intervals += found
        thresholds.update(stats)
    motion_jumps: list[_Jump] = []
    if motion is not None:
        limits = (position.threshold, rotation.threshold if rotation is not None else math.inf)
        motion_jumps, stats = _motion(
            t, positions, rotations, planar, motion, broken, limits, settings
        )
        thresholds.update(stats)

    pairs, alone = _pair(jumps, t, settings)
    if motion_jumps:
        # the odometry's disagreements inside a wrong track the steps already bound are
        # that track; the others pair with what the steps left alone
        inside = [(away.first, back.last) for away, back in pairs]
        outside = [
            jump
            for jump in motion_jumps
            if not any(first <= jump.first and jump.last <= last for first, last in inside)
        ]
        more, alone = _pair(sorted(alone + outside, key=lambda jump: jump.first), t, settings)
        pairs += more
    for away, back in pairs:
        # the samples after the first step away up to the last step back are off
        inside = back.last - away.first
        intervals.append(
            TruthInterval(
                float(t[away.first + 1]),
                float(t[back.last]),
                TruthKind.WRONG_TRACK,
                f"away by {_jump_words(away, planar)} at {t[away.first + 1]:.3f} s and back by "
                f"{_jump_words(back, planar)} at {t[back.last + 1]:.3f} s ({inside} samples off"
                + (
                    ", smooth edges the odometry contradicts)"
                    if away.motion_evidence or back.motion_evidence
                    else ")"
                ),
            )
        )
    for jump in alone:
        if jump.motion_evidence is not None:
            intervals.append(
                TruthInterval(
                    float(t[jump.first]),
                    float(t[jump.last + 1]),
                    TruthKind.MOTION,
                    jump.motion_evidence,
                )
            )
            continue
        intervals.append(
            TruthInterval(
                float(t[jump.first]),
                float(t[jump.last + 1]),
                TruthKind.JUMP,
                f"a step of {_jump_words(jump, planar)} beyond the local motion, not undone "
                f"(thresholds {position.threshold:.3g} m"
                + (f", {rotation.threshold:.3g} rad)" if rotation is not None else ")"),
            )
        )
    return TruthQuality(
        tuple(_merged_same_kind(intervals)),
        count,
        float(t[0]),
        float(t[-1]),
        step,
        thresholds,
        settings,
    )


def assess_trajectory(
    truth_t: np.ndarray,
    positions: np.ndarray,
    rotations: np.ndarray | None,
    source: str,
    sampled_only: bool = False,
    settings: TruthQualitySettings = TruthQualitySettings(),  # noqa: B008 (frozen)
) -> tuple[tuple[TruthInterval, ...], list[str]]:
    """``assess_truth`` of a loader's truth stream, as what a ``Sequence`` carries: the
    intervals for ``GroundTruth.excluded`` and the warning lines (none when all is trusted),
    each naming ``source`` (e.g. ``topic /ground_truth``, ``held-out GPS fixes``).

    ``sampled_only``: the truth is compared only at its own samples, never interpolated
    (held-out GPS fixes): a dropout or a rate change removes nothing from the scoring, so
    only the intervals that do (freezes, jumps, wrong tracks, ...) are returned."""
    if len(truth_t) < 3:
        return (), []
    quality = assess_truth(truth_t, positions, rotations, settings=settings)
    timing = (TruthKind.DROPOUT, TruthKind.RATE_CHANGE)
    intervals = tuple(
        interval for interval in quality.intervals if not (sampled_only and interval.kind in timing)
    )
    if not intervals:
        return (), []
    spans = merged_spans(intervals)
    excluded_s = float(np.sum(spans[:, 1] - spans[:, 0]))
    shown = "; ".join(" ".join(interval.line().split()) for interval in intervals[:5])
    more = "; ..." if len(intervals) > 5 else ""
    return intervals, [
        f"{source} not trusted in {len(intervals)} interval(s), {excluded_s:.2f} s, excluded "
        f"from the scoring (datasets.truth_quality): {shown}{more}"
    ]
