"""Maximum-likelihood fit of ``datasets.odometry_noise.OdometryNoiseModel`` to a reference.

The odometry increments are composed over windows of about ``window_s`` seconds and
compared with the reference's relative pose over the same window (the truth, or a
smoother's estimate when there is no truth). Under the model, the residual of window ``w``
is zero-mean Gaussian with covariance

    Sigma_w(theta) = sum_p theta_p M_wp + Sigma_ref,w ,   M_wp = sum_j f_p(j) J_j e_a e_a^T J_j^T

where ``theta_p`` is one rate (term ``p``: time / distance / turn of axis ``a``), ``f_p(j)``
the feature of step ``j`` (``dt``, ``|ds|`` or ``|dphi|``) and ``J_j`` the first-order
Jacobian of the composed window pose with respect to the increment of step ``j``
(planar compounding, Smith, Self and Cheeseman 1990). The rates maximise

    sum_w  -log det Sigma_w - r_w^T Sigma_w^-1 r_w

subject to ``theta >= 0``, the time rates above a small floor (``fit_rates``) (L-BFGS-B with the analytic gradient). Non-overlapping windows
make the residuals independent under the model. Windows whose residual lies beyond the
``outlier_probability`` chi-square quantile of the fitted model (a reference glitch, a
wheel lifted off the floor) are excluded and the fit repeated; their number is returned,
never hidden.

Systematic scale errors (commanded velocities that overstate the motion) are fitted first
and separately, on the same windows (``fit_scales``): the noise model is then fitted to the
scaled odometry.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize
from scipy.stats import chi2

from datasets.errors import InputError
from datasets.odometry_noise import OdometryNoiseModel
from datasets.rotations import PLANAR_GENERATOR, rot2_batch, wrap_angle


@dataclass(frozen=True)
class Increments:
    """A recording's planar odometry as increments.

    Attributes:
        t_end: end time of each increment [s], (n,), increasing.
        dt: duration [s], (n,).
        values: (dx, dy, dtheta) in the previous body frame, (n, 3).
    """

    t_end: np.ndarray
    dt: np.ndarray
    values: np.ndarray


@dataclass(frozen=True)
class Windows:
    """Residuals and per-rate covariance bases of the fitting windows.

    Attributes:
        t_start, t_end: window limits [s], (W,).
        residuals: reference minus composed odometry, window-start frame, (W, 3).
        bases: ``M_wp``, (W, 9, 3, 3), rates ordered (term, axis) row-major as
            ``OdometryNoiseModel.rates``.
        reference_covariance: ``Sigma_ref,w`` (W, 3, 3) (zeros for truth).
    """

    t_start: np.ndarray
    t_end: np.ndarray
    residuals: np.ndarray
    bases: np.ndarray
    reference_covariance: np.ndarray


@dataclass(frozen=True)
class FitResult:
    """The fitted model and how well it explains the windows.

    Attributes:
        model: the rates.
        windows: windows used.
        excluded: windows excluded as outliers (their start times [s]).
        nees_per_dof: mean of ``r^T Sigma^-1 r / 3`` over the used windows (1 when the model
            fits).
    """

    model: OdometryNoiseModel
    windows: int
    excluded: np.ndarray
    nees_per_dof: float


def compose(values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Compose planar increments (n, 3) from the identity.

    Returns:
        positions (n + 1, 2) and headings (n + 1,) after 0..n steps, and the Jacobians
        (n, 3, 3) of the final pose (position and heading in the start frame) with
        respect to each increment (its own frame).
    """
    n = len(values)
    headings = np.concatenate([[0.0], np.cumsum(values[:, 2])])
    rotations = rot2_batch(headings[:-1])  # (n, 2, 2): frame before each step
    steps = np.einsum("nij,nj->ni", rotations, values[:, :2])
    positions = np.vstack([np.zeros(2), np.cumsum(steps, axis=0)])
    jacobians = np.zeros((n, 3, 3))
    jacobians[:, :2, :2] = rotations
    # turning step j's end frame by d rotates everything after it about its end point
    jacobians[:, :2, 2] = (PLANAR_GENERATOR @ (positions[-1] - positions[1:]).T).T
    jacobians[:, 2, 2] = 1.0
    return positions, headings, jacobians


def _features(values: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """(n, 3) per-step features: dt, |ds|, |dphi|."""
    return np.column_stack([np.abs(dt), np.hypot(values[:, 0], values[:, 1]), np.abs(values[:, 2])])


def window_bounds(
    increments: Increments, reference_t: np.ndarray, window_s: float, tolerance_s: float
) -> list[tuple[int, int]]:
    """Window boundaries (module docstring): ``(first step, reference index at its start)``
    for every boundary in order; window ``a`` holds the steps from boundary ``a``'s first
    step up to boundary ``a + 1``'s, and ends at that boundary's reference index."""
    if window_s <= 0:
        raise InputError(f"odometry noise fit: window must be > 0 s, got {window_s}")
    ends = increments.t_end
    index = np.searchsorted(reference_t, ends)
    index = np.clip(index, 0, len(reference_t) - 1)
    before = np.clip(index - 1, 0, len(reference_t) - 1)
    nearest = np.where(
        np.abs(reference_t[before] - ends) < np.abs(reference_t[index] - ends), before, index
    )
    matched = np.abs(reference_t[nearest] - ends) <= tolerance_s
    starts_t = ends - increments.dt
    boundaries: list[tuple[int, int]] = []  # (first step, reference index at the start)
    # a boundary is the end of step k (reference index nearest[k]); the first boundary may
    # also be the start of step 0 when the reference has that time
    first_ref = np.searchsorted(reference_t, starts_t[0] - tolerance_s)
    if first_ref < len(reference_t) and abs(reference_t[first_ref] - starts_t[0]) <= tolerance_s:
        boundaries.append((0, int(first_ref)))
    candidates = np.flatnonzero(matched)
    for k in candidates:
        if not boundaries:
            boundaries.append((int(k) + 1, int(nearest[k])))
            continue
        start_step, _ = boundaries[-1]
        window_start_t = starts_t[start_step] if start_step < len(ends) else ends[-1]
        if ends[k] - window_start_t >= window_s - 1e-9:
            boundaries.append((int(k) + 1, int(nearest[k])))
    return boundaries


def build_windows(
    increments: Increments,
    reference_t: np.ndarray,
    reference_positions: np.ndarray,
    reference_headings: np.ndarray,
    window_s: float,
    reference_covariances: np.ndarray | None = None,
    tolerance_s: float = 1e-6,
) -> Windows:
    """Non-overlapping windows of at least ``window_s`` between increment ends that
    coincide (within ``tolerance_s``) with reference times.

    Args:
        increments: the odometry.
        reference_t (m,), reference_positions (m, 2), reference_headings (m,): world poses.
        window_s: shortest window [s].
        reference_covariances: covariance of each reference relative pose would need joint
            marginals; pass per-pose (m, 3, 3) marginals to bound it (their sum is added,
            ignoring the cross-covariance), or None for truth.
    """
    boundaries = window_bounds(increments, reference_t, window_s, tolerance_s)
    ends, starts_t = increments.t_end, increments.t_end - increments.dt
    residuals, bases, reference_cov, t_start, t_end = [], [], [], [], []
    features_all = _features(increments.values, increments.dt)
    for a in range(len(boundaries) - 1):
        (first, ref_a), (stop, ref_b) = boundaries[a], boundaries[a + 1]
        values = increments.values[first:stop]
        if len(values) == 0:
            continue
        positions, headings, jacobians = compose(values)
        rotation_a = rot2_batch(np.array([reference_headings[ref_a]]))[0]
        relative = rotation_a.T @ (reference_positions[ref_b] - reference_positions[ref_a])
        relative_heading = wrap_angle(reference_headings[ref_b] - reference_headings[ref_a])
        residual = np.array(
            [
                relative[0] - positions[-1, 0],
                relative[1] - positions[-1, 1],
                float(wrap_angle(relative_heading - headings[-1])),
            ]
        )
        features = features_all[first:stop]  # (n, 3 terms)
        # M[term, axis] = sum_j f_term(j) J_j[:, axis] J_j[:, axis]^T
        outer = np.einsum("nia,nja->naij", jacobians, jacobians)  # (n, axis, 3, 3)
        basis = np.einsum("nt,naij->taij", features, outer).reshape(9, 3, 3)
        residuals.append(residual)
        bases.append(basis)
        if reference_covariances is not None:
            # the frame of the first pose rotates the second's uncertainty into it
            rotate = np.eye(3)
            rotate[:2, :2] = rotation_a.T
            reference_cov.append(
                rotate @ (reference_covariances[ref_a] + reference_covariances[ref_b]) @ rotate.T
            )
        else:
            reference_cov.append(np.zeros((3, 3)))
        t_start.append(starts_t[first])
        t_end.append(ends[stop - 1])
    if len(residuals) < 10:
        raise InputError(
            f"only {len(residuals)} windows of {window_s:g} s where the odometry and the "
            "reference overlap (need at least 10)"
        )
    return Windows(
        np.array(t_start),
        np.array(t_end),
        np.array(residuals),
        np.array(bases),
        np.array(reference_cov),
    )


def _covariances(theta: np.ndarray, windows: Windows, floor: float) -> np.ndarray:
    return (
        np.einsum("p,wpij->wij", theta, windows.bases)
        + windows.reference_covariance
        + floor * np.eye(3)
    )


def _negative_log_likelihood(
    theta: np.ndarray, windows: Windows, floor: float
) -> tuple[float, np.ndarray]:
    covariance = _covariances(theta, windows, floor)
    sign, logdet = np.linalg.slogdet(covariance)
    if np.any(sign <= 0):
        return float("inf"), np.zeros_like(theta)
    inverse = np.linalg.inv(covariance)
    whitened = np.einsum("wij,wj->wi", inverse, windows.residuals)
    value = float(np.sum(logdet) + np.einsum("wi,wi->", windows.residuals, whitened))
    gradient = np.einsum("wij,wpji->p", inverse, windows.bases) - np.einsum(
        "wi,wpij,wj->p", whitened, windows.bases, whitened
    )
    return value, gradient


def fit_rates(windows: Windows, free: np.ndarray | None = None, floor: float = 1e-12) -> np.ndarray:
    """The maximum-likelihood rates (3, 3) (terms x axes); ``free`` (3, 3) bool marks the
    rates fitted (others stay 0)."""
    free = np.ones((3, 3), bool) if free is None else np.asarray(free, bool)
    mask = free.ravel()
    # start: every free rate explaining the mean squared residual of its axis alone
    start = np.zeros(9)
    for p in np.flatnonzero(mask):
        axis = p % 3
        weight = np.mean(windows.bases[:, p, axis, axis])
        start[p] = np.mean(windows.residuals[:, axis] ** 2) / max(weight, 1e-300) / 3.0
    scale = np.where(start > 0, start, 1.0)

    def objective(scaled: np.ndarray) -> tuple[float, np.ndarray]:
        theta = np.zeros(9)
        theta[mask] = scaled * scale[mask]
        value, gradient = _negative_log_likelihood(theta, windows, floor)
        return value, gradient[mask] * scale[mask]

    # The time rates keep a floor of 0.1 % of each axis's residual variance per second: a
    # model with no time term gives a straight, steady step zero variance in some axis,
    # and an estimator a singular covariance.
    duration = float(np.mean(windows.t_end - windows.t_start))
    floors = np.zeros(9)
    floors[:3] = 1e-3 * np.mean(windows.residuals**2, axis=0) / max(duration, 1e-9)
    lower = np.where(mask, floors / scale, 0.0)[mask]
    result = minimize(
        objective,
        np.maximum(np.ones(int(mask.sum())), lower),
        jac=True,
        method="L-BFGS-B",
        bounds=[(float(bound), None) for bound in lower],
        options={"maxiter": 2000, "ftol": 1e-12, "gtol": 1e-9},
    )
    theta = np.zeros(9)
    theta[mask] = result.x * scale[mask]
    return theta.reshape(3, 3)


def window_nees(rates: np.ndarray, windows: Windows, floor: float = 1e-12) -> np.ndarray:
    """``r^T Sigma^-1 r`` of every window under ``rates`` (W,) (3 dof)."""
    covariance = _covariances(np.asarray(rates).ravel(), windows, floor)
    solved = np.linalg.solve(covariance, windows.residuals[..., None])[..., 0]
    return np.einsum("wi,wi->w", windows.residuals, solved)


def fit_odometry_noise(
    windows: Windows,
    source: str,
    free: np.ndarray | None = None,
    outlier_probability: float = 0.9999,
    max_rounds: int = 10,
) -> FitResult:
    """Fit, exclude windows beyond the ``outlier_probability`` quantile, refit until no
    window is excluded any more (module docstring)."""
    keep = np.ones(len(windows.residuals), bool)
    limit = chi2.ppf(outlier_probability, 3)
    rates = np.zeros((3, 3))
    for _ in range(max_rounds):
        subset = _subset(windows, keep)
        rates = fit_rates(subset, free)
        nees = window_nees(rates, windows)
        new_keep = nees <= limit
        if np.array_equal(new_keep, keep):
            break
        keep = new_keep
    used = _subset(windows, keep)
    return FitResult(
        OdometryNoiseModel(rates, source),
        int(keep.sum()),
        windows.t_start[~keep],
        float(np.mean(window_nees(rates, used)) / 3.0),
    )


def _subset(windows: Windows, keep: np.ndarray) -> Windows:
    return Windows(
        windows.t_start[keep],
        windows.t_end[keep],
        windows.residuals[keep],
        windows.bases[keep],
        windows.reference_covariance[keep],
    )


@dataclass(frozen=True)
class ScaleFit:
    """Odometry calibration factors fitted to a reference (``fit_scales``).

    Attributes:
        speed: multiplies the forward (and lateral) increments.
        turn: multiplies the heading increments.
        coupling: speed lost per unit of commanded turn rate [s/rad]: the forward increments
            are further multiplied by ``max(0, 1 - coupling * |omega|)``, with ``omega`` the
            step's commanded (unscaled) turn rate.
        windows: windows used.
        heading_rms_before_rad, heading_rms_after_rad: RMS heading residual of the windows
            with the raw and the calibrated odometry [rad].
        position_rms_before_m, position_rms_after_m: the same for the position [m].
    """

    speed: float
    turn: float
    coupling: float
    windows: int
    heading_rms_before_rad: float
    heading_rms_after_rad: float
    position_rms_before_m: float
    position_rms_after_m: float


SCALE_NAMES = ("speed", "turn", "coupling")
SCALE_BOUNDS = {"speed": (0.5, 2.0), "turn": (0.5, 2.0), "coupling": (0.0, 3.0)}
_SCALE_NEUTRAL = {"speed": 1.0, "turn": 1.0, "coupling": 0.0}


def speed_factors(turn_rates: np.ndarray, speed: float, coupling: float) -> np.ndarray:
    """Per-sample factors of the forward speed, ``speed * max(0, 1 - coupling * |omega|)``
    for commanded turn rates ``omega`` [rad/s] (``ScaleFit``)."""
    return speed * np.clip(1.0 - coupling * np.abs(np.asarray(turn_rates, float)), 0.0, None)


@dataclass(frozen=True)
class Segment:
    """One recording's odometry and its reference, for a fit pooled over recordings.

    Attributes:
        increments: the odometry.
        reference_t (m,) [s], reference_positions (m, 2) [m], reference_headings (m,) [rad]:
            the reference's world poses.
        tolerance_s: how close an increment end and a reference time must be to pair [s].
    """

    increments: Increments
    reference_t: np.ndarray
    reference_positions: np.ndarray
    reference_headings: np.ndarray
    tolerance_s: float = 1e-6


def fit_scales(
    increments: Increments,
    reference_t: np.ndarray,
    reference_positions: np.ndarray,
    reference_headings: np.ndarray,
    window_s: float,
    tolerance_s: float = 1e-6,
    fixed: dict[str, float] | None = None,
) -> ScaleFit:
    """``fit_scales_pooled`` of one recording (its docstring says what is fitted)."""
    segment = Segment(increments, reference_t, reference_positions, reference_headings, tolerance_s)
    return fit_scales_pooled([segment], window_s, fixed)


@dataclass(frozen=True)
class _ScaleWindows:
    """One segment's windows as ``fit_scales_pooled`` evaluates them."""

    values: np.ndarray  # (n, 3) increments of the windows' steps
    rates: np.ndarray  # (n,) commanded turn rate of each step [rad/s]
    offsets: np.ndarray  # (W,) where each window's steps begin in ``values``
    lengths: np.ndarray  # (W,) steps per window
    relative_position: np.ndarray  # (W, 2) reference motion in the window's start frame [m]
    relative_heading: np.ndarray  # (W,) [rad]

    @staticmethod
    def of(segment: Segment, window_s: float) -> _ScaleWindows:
        increments, headings = segment.increments, segment.reference_headings
        boundaries = window_bounds(increments, segment.reference_t, window_s, segment.tolerance_s)
        firsts = np.array([first for first, _ in boundaries], dtype=int)
        references = np.array([ref for _, ref in boundaries], dtype=int)
        usable = firsts[1:] > firsts[:-1]  # windows with at least one step
        starts, stops = firsts[:-1][usable], firsts[1:][usable]
        ref_a, ref_b = references[:-1][usable], references[1:][usable]
        if len(starts) == 0:
            empty = np.zeros(0, dtype=int)
            return _ScaleWindows(
                np.zeros((0, 3)), np.zeros(0), empty, empty, np.zeros((0, 2)), np.zeros(0)
            )
        steps = slice(int(starts[0]), int(stops[-1]))
        values = increments.values[steps]
        rates = values[:, 2] / np.maximum(np.abs(increments.dt[steps]), 1e-12)
        start_rotation = rot2_batch(headings[ref_a])
        positions = segment.reference_positions
        relative_position = np.einsum(
            "wji,wj->wi", start_rotation, positions[ref_b] - positions[ref_a]
        )
        relative_heading = wrap_angle(headings[ref_b] - headings[ref_a])
        return _ScaleWindows(
            values, rates, starts - starts[0], stops - starts, relative_position, relative_heading
        )

    def residuals(self, scales: dict[str, float]) -> np.ndarray:
        """(W, 3) reference minus calibrated odometry over each window: position [m] in the
        window's start frame, heading [rad]."""
        values, offsets = self.values, self.offsets
        turns = scales["turn"] * values[:, 2]
        total = np.cumsum(turns)
        # heading before each step, from its window's start frame (exactly 0 at the first)
        before = total - turns - np.repeat((total - turns)[offsets], self.lengths)
        cos, sin = np.cos(before), np.sin(before)
        forward = speed_factors(self.rates, scales["speed"], scales["coupling"])
        moved = forward[:, None] * np.column_stack(
            [cos * values[:, 0] - sin * values[:, 1], sin * values[:, 0] + cos * values[:, 1]]
        )
        end_position = np.add.reduceat(moved, offsets, axis=0)
        end_heading = np.add.reduceat(turns, offsets)
        return np.column_stack(
            [
                self.relative_position - end_position,
                wrap_angle(self.relative_heading - end_heading),
            ]
        )


def fit_scales_pooled(
    segments: list[Segment], window_s: float, fixed: dict[str, float] | None = None
) -> ScaleFit:
    """Calibration of commanded-velocity odometry: a speed factor ``k_s``, a turn factor
    ``k_w`` and a speed-turn coupling ``c`` [s/rad], so that the increments
    ``(f dx, f dy, k_w dtheta)`` with ``f = k_s max(0, 1 - c |dtheta / dt|)`` composed over
    the windows of ``window_bounds`` best match the reference's relative poses, over the
    windows of every segment (recordings of the same kind of robot: the factors are one
    robot model's, not one recording's). ``fixed`` holds the factors given (by name,
    ``SCALE_NAMES``); the others are fitted.

    Systematic errors that the noise model (variances linear in time, distance and turn)
    cannot hold, because they keep their sign for minutes: on UTIAS dataset 1 the commanded
    turn rate overstates the turn by 4-7 % on every robot (2-8 % in each half of each
    recording), and the commanded forward speed overstates the motion the more the robot
    turns (Vicon over commanded speed, 1 s bins, all five robots: 1.02-1.03 below 0.05 rad/s,
    0.88-0.91 at 0.05-0.15, 0.76-0.80 at 0.15-0.3, 0.59-0.62 at 0.3-0.6 rad/s). A white
    model spends that error as noise. The fit minimises the window residuals (position [m]
    and heading [rad], each divided by its RMS with the raw odometry, so that neither unit
    dominates) with a soft-L1 loss, which keeps a few glitched windows from steering it
    (``scipy.optimize.least_squares``). Fit the factors first and the noise model on the
    calibrated odometry.
    """
    from scipy.optimize import least_squares

    fixed = {name: float(value) for name, value in (fixed or {}).items()}
    unknown = set(fixed) - set(SCALE_NAMES)
    if unknown:
        raise ValueError(f"fit_scales: unknown factors {sorted(unknown)}")
    free = [name for name in SCALE_NAMES if name not in fixed]
    parts = [_ScaleWindows.of(segment, window_s) for segment in segments]
    parts = [part for part in parts if len(part.offsets)]
    count = sum(len(part.offsets) for part in parts)
    if count < 10:
        raise InputError(
            f"only {count} windows of {window_s:g} s where the odometry and the "
            "reference overlap (need at least 10)"
        )

    def factors(vector: np.ndarray) -> dict[str, float]:
        return {**fixed, **dict(zip(free, map(float, vector)))}

    def residuals(scales: dict[str, float]) -> np.ndarray:
        return np.vstack([part.residuals(scales) for part in parts])

    raw = residuals(dict(_SCALE_NEUTRAL))
    spread = np.array([np.sqrt(np.mean(raw[:, :2] ** 2))] * 2 + [np.sqrt(np.mean(raw[:, 2] ** 2))])
    spread = np.maximum(spread, 1e-12)
    chosen = dict(fixed)
    if free:
        result = least_squares(
            lambda vector: (residuals(factors(vector)) / spread).ravel(),
            np.array([_SCALE_NEUTRAL[name] for name in free]),
            loss="soft_l1",
            bounds=tuple(np.array([SCALE_BOUNDS[name] for name in free]).T),
        )
        chosen = factors(result.x)
    after = residuals(chosen)
    return ScaleFit(
        chosen["speed"],
        chosen["turn"],
        chosen["coupling"],
        count,
        float(np.sqrt(np.mean(raw[:, 2] ** 2))),
        float(np.sqrt(np.mean(after[:, 2] ** 2))),
        float(np.sqrt(np.mean(np.sum(raw[:, :2] ** 2, axis=1)))),
        float(np.sqrt(np.mean(np.sum(after[:, :2] ** 2, axis=1)))),
    )


def concatenate_windows(parts: list[Windows]) -> Windows:
    """The windows of several recordings as one set (they are independent under the
    model, so a noise model pooled over recordings is fitted on their union)."""
    return Windows(
        *(
            np.concatenate([getattr(part, name) for part in parts])
            for name in ("t_start", "t_end", "residuals", "bases", "reference_covariance")
        )
    )
