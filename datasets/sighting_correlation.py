"""Landmark sightings whose errors are correlated in time: the model a loader states, the
inflation every estimator applies, and the fit against a reference.

A camera that reads a barcode's range from its apparent size, or a laser that sees the same
tree trunk from nearly the same place, makes nearly the same error in consecutive sightings
of one landmark. Filters and smoothers treat sightings as independent, so ten sightings in
one second count as ten measurements where they carry about one measurement's information,
and the covariance collapses below the error. On UTIAS dataset 1 the range error of two
sightings of one landmark less than 0.5 s apart is correlated at 0.95-0.98, the bearing
error at 0.4-0.8 (robots 1, 4, 5, against Vicon and the surveyed map); at 3-10 s apart still
0.3-0.7. There, with the real odometry and sightings simulated from Vicon at the stated
noise, ekf-slam reads a pose NEES of 3.9 (robot 4) and 6.2 (robot 5) per 3 dof; with the real
sightings 16.6 and 25.4.

The model: each sighting's error splits into a radial part (along the line of sight) and a
tangential part (across it), each a first-order autoregressive process over the sightings of
one landmark, with correlation ``rho(dt) = c exp(-dt / tau)`` between a sighting and the
previous one of the same landmark ``dt`` seconds earlier.

The inflation (``SightingCorrelation.inflate``): an estimator that treats the sightings as
independent counts each with its covariance component multiplied by

    f = (1 + rho) / (1 - rho)

For an AR(1) error over the sightings of one fixed quantity, the chain's information is
exactly ``(1 + sum_k (1 - rho_k) / (1 + rho_k)) / sigma^2`` (the generalised-least-squares
information of a Markov chain: the first sighting in full, each later one as the part of it
its predecessor does not explain), and that is what the inflated sightings add up to; a
sighting long after the previous one (``rho`` about 0) counts in full. The filter's weighted
mean is not the GLS estimate, so its error is slightly larger than the covariance it states:
a static landmark seen in bursts reads a NEES of 1.08 per dof with the inflation and 8.6 with
independent sightings (``tests/test_sighting_correlation.py``). For a moving sensor the
inflation gives up the motion information that differences of correlated sightings still
carry, which errs the other way. The exact alternative, whitening by differencing
consecutive sightings (Bryson and Henrikson 1968), couples two states per measurement; no
estimator here does that.

The fit (``fit_sighting_correlation``): maximum likelihood of ``c`` and ``tau`` from pairs of
consecutive residuals of one landmark (sighting minus reference prediction, each divided by
its stated std): ``e_k | e_(k-1) ~ N(rho e_(k-1), (1 - rho^2) s^2)`` with ``s^2`` the residuals'
mean square. Units: ``tau`` [s].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.errors import InputError

MAX_CORRELATION = 0.99
"""Upper bound of ``c``: an inflation of at most 199 for sightings at the same instant."""


@dataclass(frozen=True)
class Autocorrelation:
    """``rho(dt) = scale * exp(-dt / time_constant_s)`` between consecutive sightings.

    Attributes:
        scale: c in [0, ``MAX_CORRELATION``]: the correlation of sightings at the same time.
        time_constant_s: tau [s], > 0.
    """

    scale: float
    time_constant_s: float

    def __post_init__(self) -> None:
        if not (0.0 <= self.scale <= MAX_CORRELATION) or not self.time_constant_s > 0.0:
            raise InputError(
                f"sighting autocorrelation needs 0 <= scale <= {MAX_CORRELATION} and a "
                f"positive time constant, got {self.scale}, {self.time_constant_s} s"
            )

    def at(self, dt: np.ndarray | float) -> np.ndarray:
        """``rho`` of sightings ``dt`` [s] apart (0 where ``dt`` is infinite)."""
        dt = np.maximum(np.asarray(dt, dtype=float), 0.0)
        return self.scale * np.exp(-dt / self.time_constant_s)

    def inflation(self, dt: np.ndarray | float) -> np.ndarray:
        """``(1 + rho) / (1 - rho)`` (module docstring)."""
        rho = self.at(dt)
        return (1.0 + rho) / (1.0 - rho)


@dataclass(frozen=True)
class SightingCorrelation:
    """The correlation model of one landmark sensor (module docstring).

    Attributes:
        radial: along the line of sight (range).
        tangential: across it (bearing).
        source: how it was obtained (written to the run's metadata).
    """

    radial: Autocorrelation
    tangential: Autocorrelation
    source: str = ""

    def inflate(self, covariance: np.ndarray, point: np.ndarray, dt: float) -> np.ndarray:
        """The covariance (d, d) of a sighting at body-frame ``point`` (d,) [m] taken ``dt``
        [s] after the previous sighting of the same landmark, inflated for use as an
        independent measurement: ``C + (f_r - 1) P_r C P_r + (f_t - 1) P_t C P_t`` with
        ``P_r = u u^T`` (u the unit line of sight) and ``P_t = I - P_r``; symmetric positive
        definite whenever ``C`` is. ``dt = inf``: unchanged."""
        covariance = np.asarray(covariance, dtype=float)
        if not np.isfinite(dt):
            return covariance
        point = np.asarray(point, dtype=float)
        norm = float(np.linalg.norm(point))
        if norm <= 0.0:
            return covariance
        unit = point / norm
        radial = np.outer(unit, unit)
        tangential = np.eye(len(unit)) - radial
        grow_radial = float(self.radial.inflation(dt)) - 1.0
        grow_tangential = float(self.tangential.inflation(dt)) - 1.0
        inflated = (
            covariance
            + grow_radial * radial @ covariance @ radial
            + grow_tangential * tangential @ covariance @ tangential
        )
        return 0.5 * (inflated + inflated.T)

    def as_dict(self) -> dict[str, object]:
        return {
            "radial": {"scale": self.radial.scale, "time_constant_s": self.radial.time_constant_s},
            "tangential": {
                "scale": self.tangential.scale,
                "time_constant_s": self.tangential.time_constant_s,
            },
            "source": self.source,
        }


def fit_autocorrelation(
    dt: np.ndarray, previous: np.ndarray, current: np.ndarray, outlier_sigmas: float = 5.0
) -> Autocorrelation:
    """Maximum-likelihood ``rho(dt) = c exp(-dt / tau)`` from pairs of consecutive normalised
    residuals of one landmark (module docstring): ``dt`` (n,) [s] apart, ``previous`` and
    ``current`` (n,) each residual over its stated std. Pairs with a residual beyond
    ``outlier_sigmas`` RMS are left out (a glitch in the reference, a misread barcode)."""
    dt, previous, current = (np.asarray(a, dtype=float).ravel() for a in (dt, previous, current))
    if not (len(dt) == len(previous) == len(current)):
        raise InputError("sighting correlation fit: dt, previous and current differ in length")
    finite = np.isfinite(dt) & np.isfinite(previous) & np.isfinite(current) & (dt >= 0.0)
    dt, previous, current = dt[finite], previous[finite], current[finite]
    if len(dt) < 20:
        raise InputError(
            f"sighting correlation fit: {len(dt)} pairs of consecutive sightings (need 20)"
        )
    rms = np.sqrt(np.mean(np.concatenate([previous, current]) ** 2))
    keep = (np.abs(previous) <= outlier_sigmas * rms) & (np.abs(current) <= outlier_sigmas * rms)
    dt, previous, current = dt[keep], previous[keep], current[keep]
    variance = float(np.mean(np.concatenate([previous, current]) ** 2))

    def negative_log_likelihood(parameters: np.ndarray) -> float:
        logit, log_tau = np.clip(parameters, [-30.0, -10.0], [30.0, 15.0])
        scale = MAX_CORRELATION / (1.0 + np.exp(-logit))
        rho = scale * np.exp(-dt / np.exp(log_tau))
        conditional = (1.0 - rho**2) * variance
        return float(np.sum(np.log(conditional) + (current - rho * previous) ** 2 / conditional))

    # imported here: scipy.optimize is half of the CLI's start-up time (0.56 of 1.0 s), and
    # only a fit needs it
    from scipy.optimize import minimize

    typical = float(np.median(dt[dt > 0])) if np.any(dt > 0) else 1.0
    best = None
    for start_scale in (-2.0, 0.0, 2.0):  # logits of c: 0.11, 0.5, 0.87 of the bound
        for start_tau in (0.3 * typical, 3.0 * typical, 30.0 * typical):
            result = minimize(
                negative_log_likelihood,
                np.array([start_scale, np.log(max(start_tau, 1e-3))]),
                method="Nelder-Mead",
                options={"xatol": 1e-6, "fatol": 1e-9, "maxiter": 4000},
            )
            if best is None or result.fun < best.fun:
                best = result
    assert best is not None
    logit, log_tau = np.clip(best.x, [-30.0, -10.0], [30.0, 15.0])
    return Autocorrelation(float(MAX_CORRELATION / (1.0 + np.exp(-logit))), float(np.exp(log_tau)))


def consecutive_pairs(
    t: np.ndarray, landmark: np.ndarray, residuals: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs of consecutive sightings of the same landmark: (dt (n,) [s], previous (n, c),
    current (n, c)) from sighting times ``t`` (k,) in stream order, their landmark ids (k,)
    and residuals (k, c)."""
    t = np.asarray(t, dtype=float)
    landmark = np.asarray(landmark)
    residuals = np.asarray(residuals, dtype=float).reshape(len(t), -1)
    order = np.lexsort((t, landmark))  # by landmark, then time (stable for equal times)
    same = landmark[order][1:] == landmark[order][:-1]
    before, after = order[:-1][same], order[1:][same]
    return t[after] - t[before], residuals[before], residuals[after]


def planar_residuals(points: np.ndarray, predicted: np.ndarray) -> np.ndarray:
    """(k, 2) residuals of planar sightings ``points`` (k, 2) [m] against the reference's
    ``predicted`` body-frame points (k, 2): radial as a fraction of the predicted range,
    tangential as a bearing [rad]."""
    points = np.asarray(points, dtype=float)
    predicted = np.asarray(predicted, dtype=float)
    ranges = np.linalg.norm(predicted, axis=1)
    radial = np.linalg.norm(points, axis=1) / np.maximum(ranges, 1e-9) - 1.0
    bearing = np.arctan2(points[:, 1], points[:, 0]) - np.arctan2(predicted[:, 1], predicted[:, 0])
    return np.column_stack([radial, np.angle(np.exp(1j * bearing))])


def fit_sighting_correlation(
    times: np.ndarray, landmarks: np.ndarray, residuals: np.ndarray, source: str
) -> SightingCorrelation:
    """Both components' ``fit_autocorrelation`` from sightings at ``times`` (k,) [s] of
    ``landmarks`` (k,) with (radial, tangential) ``residuals`` (k, 2) against a reference
    (``planar_residuals``)."""
    dt, previous, current = consecutive_pairs(times, landmarks, residuals)
    return SightingCorrelation(
        fit_autocorrelation(dt, previous[:, 0], current[:, 0]),
        fit_autocorrelation(dt, previous[:, 1], current[:, 1]),
        source,
    )
