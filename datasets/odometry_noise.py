"""Planar odometry noise that grows with time, distance travelled and angle turned.

Real odometry is not white noise at a fixed rate: wheel slip, a wrong wheel radius or a
commanded velocity that leads the motion make the error of an increment grow with how far
and how much the vehicle moved, not only with how long. ``OdometryNoiseModel`` gives each
axis of an increment ``(dx, dy, dtheta)`` (previous body frame) the variance

    var_a = time_rate_a * dt + distance_rate_a * |ds| + turn_rate_a * |dphi|

with ``ds`` the distance and ``dphi`` the heading change of the increment. Variances that
are *linear* in ``dt``, ``|ds|`` and ``|dphi|`` add over sub-intervals: the model states the
same noise whether an estimator integrates 50 Hz samples or one keyframe interval (a model
quadratic in ``ds``, ``sigma = k ds``, would shrink by the number of sub-steps). The
parameters are fitted from a recording's own truth by ``workbench calibrate-noise``
(``workbench.calibration``); each loader states the model it used in its ``NoiseSpec``.

Units: ``time_rate`` (m^2/s, m^2/s, rad^2/s); ``distance_rate`` (m^2/m, m^2/m, rad^2/m);
``turn_rate`` (m^2/rad, m^2/rad, rad^2/rad).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from datasets.errors import InputError

AXES = ("x", "y", "theta")
TERMS = ("time", "distance", "turn")


@dataclass(frozen=True)
class OdometryNoiseModel:
    """Per-axis variance rates of a planar odometry increment (module docstring).

    Attributes:
        rates: (3 terms: time, distance, turn) x (3 axes: x, y, theta), non-negative.
        source: how the rates were obtained (printed and written to the run's metadata).
    """

    rates: np.ndarray
    source: str = ""

    def __post_init__(self) -> None:
        rates = np.array(self.rates, dtype=float).reshape(3, 3)
        if not np.all(np.isfinite(rates)) or np.any(rates < 0.0):
            raise InputError(f"odometry noise rates must be finite and >= 0, got {rates.tolist()}")
        object.__setattr__(self, "rates", rates)

    def variances(self, dt: np.ndarray, distance: np.ndarray, turn: np.ndarray) -> np.ndarray:
        """Variances of (x, y, theta) of increments lasting ``dt`` [s] over ``distance`` [m]
        turning ``turn`` [rad]: inputs broadcast to (n,), output (n, 3)."""
        features = np.column_stack(
            np.broadcast_arrays(
                np.abs(np.asarray(dt, float)).ravel(),
                np.abs(np.asarray(distance, float)).ravel(),
                np.abs(np.asarray(turn, float)).ravel(),
            )
        )
        return features @ self.rates

    def increment_covariance(self, increment: np.ndarray, dt: float) -> np.ndarray:
        """Covariance (3, 3) of one relative-pose increment ``(dx, dy, dtheta)`` over ``dt``."""
        increment = np.asarray(increment, dtype=float)
        distance = float(np.hypot(increment[0], increment[1]))
        return np.diag(self.variances(np.array([dt]), distance, increment[2])[0])

    def velocity_covariance(self, speed: float, rate: float, dt: float) -> np.ndarray:
        """Per-sample covariance (2, 2) of a velocity sample ``(v, omega)`` held over ``dt``:
        the integrated increment ``(v dt, omega dt)`` then has the model's x and theta
        variances (``dt^2 * covariance``, the ``Odometry`` convention). A unicycle has no
        lateral axis: the y rates are not used."""
        variances = self.variances(np.array([dt]), abs(speed) * dt, abs(rate) * dt)[0]
        return np.diag([variances[0], variances[2]]) / dt**2

    def as_dict(self) -> dict[str, object]:
        """JSON/YAML form: ``{term: {axis: rate}}`` plus the source."""
        return {
            "rates": {
                term: {axis: float(self.rates[i, j]) for j, axis in enumerate(AXES)}
                for i, term in enumerate(TERMS)
            },
            "source": self.source,
        }

    @staticmethod
    def from_dict(data: dict, origin: str = "odometry noise model") -> OdometryNoiseModel:
        """Inverse of ``as_dict``; ``InputError`` naming ``origin`` and the missing key."""
        try:
            rates = data["rates"]
            values = [[float(rates[term][axis]) for axis in AXES] for term in TERMS]
        except (KeyError, TypeError, ValueError) as error:
            raise InputError(
                f"{origin}: expected rates.{{{','.join(TERMS)}}}.{{{','.join(AXES)}}} numbers ({error})"
            ) from None
        return OdometryNoiseModel(np.array(values), str(data.get("source", origin)))

    def describe(self) -> list[str]:
        """Human-readable lines: the standard deviation each term gives per unit."""
        units = {
            "time": ("s", "m", "rad"),
            "distance": ("m", "m", "rad"),
            "turn": ("rad", "m", "rad"),
        }
        lines = []
        for i, term in enumerate(TERMS):
            per, linear, angular = units[term]
            parts = [
                f"{axis} {np.sqrt(self.rates[i, j]):.3g} {angular if axis == 'theta' else linear}"
                for j, axis in enumerate(AXES)
            ]
            lines.append(f"{term:>8}: std per sqrt({per}): " + ", ".join(parts))
        return lines


def read_model_file(path: Path) -> OdometryNoiseModel:
    """An ``OdometryNoiseModel`` from a YAML file written by ``workbench calibrate-noise``."""
    from datasets.yaml_files import read_yaml_file

    path = Path(path).expanduser()
    if not path.is_file():
        raise InputError(f"{path}: odometry noise model file not found")
    data = read_yaml_file(path)
    if not isinstance(data, dict):
        raise InputError(f"{path}: expected a mapping with 'rates'")
    block = data.get("odometry_noise", data)
    return OdometryNoiseModel.from_dict(block, str(path))


def mean_heading_density(
    model: OdometryNoiseModel, increments: np.ndarray, dt: np.ndarray
) -> float:
    """The white heading-rate density [rad/s/sqrt(Hz)] with the model's mean heading variance
    per second over ``increments`` (n, 3) of durations ``dt`` (n,): what a rate-gyro
    estimator fed with the odometry's turn rate can be told."""
    variances = model.variances(dt, np.hypot(increments[:, 0], increments[:, 1]), increments[:, 2])
    return float(np.sqrt(variances[:, 2].sum() / max(float(np.sum(dt)), 1e-12)))
