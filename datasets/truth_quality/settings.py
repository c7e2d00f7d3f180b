"""The thresholds of ``assess_truth`` (``TruthQualitySettings``), each a multiple of a
statistic of the stream itself."""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, Field


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
    freeze; it is one only when the stream moved across it (see the
    ``datasets.truth_quality`` docstring)."""

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
