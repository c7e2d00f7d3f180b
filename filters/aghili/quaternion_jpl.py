"""The quaternion algebra of Aghili's paper (section 2.1), and its boundary to the interface.

Paper convention ("JPL-like"): ``q = [q_v, q_o]`` (vector part first, scalar last) with

- eq. (3): ``A(q) = (2 q_o^2 - 1) 1 + 2 q_o [q_v x] + 2 q_v q_v^T``, the rotation of the body
  frame {B} relative to the inertial frame {A} (body-to-world, ``p = A^T (rho - r)``);
- the product ``A(q3) = A(q1) A(q2)  <=>  q3 = q2 (x) q1`` with
  ``[q (x)] = [[q_o 1 - [q_v x], q_v], [-q_v^T, q_o]]``.

Comparing with the Hamilton algebra: ``A(q)`` above is exactly the Hamilton rotation matrix
of the quaternion ``(w, x, y, z) = (q_o, q_v)``, and the paper's product is the Hamilton
product with its factors swapped (``a (x)_paper b = b (x)_Hamilton a``). So the interface
quaternion (Hamilton, wxyz, body-to-world) and the paper's quaternion hold the *same four
numbers*, only reordered: the boundary conversion is a permutation (``to_interface_wxyz``,
``from_interface_wxyz``), tested in ``tests/test_aghili_quaternion.py``.

The error quaternion ``dq = q (x) qbar^*`` (eqs. (8), (16b)) then gives
``A(q) = A(qbar) A(dq) ~ Abar (1 + 2 [dq_v x])``: a *body-frame right* perturbation whose
rotation vector is ``2 dq_v`` (half-angle: the rotation-vector covariance is 4x that of dq_v).
"""

from __future__ import annotations

import numpy as np

from datasets.rotations import skew

IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])
"""The identity quaternion ``[0, 0, 0, 1]`` (paper order, scalar last)."""


def rotation_matrix(q: np.ndarray) -> np.ndarray:
    """Aghili eq. (3): ``A(q)``, shape (3, 3), of a unit quaternion ``q = [q_v, q_o]`` (4,)."""
    qv, qo = q[:3], q[3]
    return (2.0 * qo * qo - 1.0) * np.eye(3) + 2.0 * qo * skew(qv) + 2.0 * np.outer(qv, qv)


def product_matrix(q: np.ndarray) -> np.ndarray:
    """Aghili section 2.1: ``[q (x)]`` (4, 4), so that ``q (x) p = product_matrix(q) @ p``."""
    qv, qo = q[:3], q[3]
    matrix = np.empty((4, 4))
    matrix[:3, :3] = qo * np.eye(3) - skew(qv)
    matrix[:3, 3] = qv
    matrix[3, :3] = -qv
    matrix[3, 3] = qo
    return matrix


def multiply(q: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Paper product ``q (x) p`` (4,): ``A(q (x) p) = A(p) A(q)`` (section 2.1)."""
    return product_matrix(q) @ p


def conjugate(q: np.ndarray) -> np.ndarray:
    """``q^*``: vector part negated (footnote 1)."""
    return np.array([-q[0], -q[1], -q[2], q[3]])


def vector_part(q: np.ndarray) -> np.ndarray:
    """``vec(q)`` (3,)."""
    return np.asarray(q[:3], dtype=float)


def exponential_matrix(omega: np.ndarray, duration_s: float) -> np.ndarray:
    """Aghili eq. (39): ``exp(t/2 [omega (x)])`` (4, 4) for a constant rate ``omega`` [rad/s].

    ``Omega = [omega (x)]`` with ``omega = [omega; 0]`` satisfies ``Omega^2 = -|omega|^2 1_4``,
    hence the exact exponential ``cos(|w| t/2) 1_4 + sin(|w| t/2)/|w| Omega``.

    The paper prints ``(cos + sin) 1_4 + (2/(|w| t) sin - 1/2 cos) Omega`` (both of
    ``|w| t/2``): that matrix is not orthogonal (at ``omega = 0`` it is already
    ``(1 + 0) 1_4``; for ``|w| t = pi`` it scales norms by about 1.6), so it does not keep
    the quaternion a unit quaternion. We use the exact form above (tested against expm and
    for norm preservation).
    """
    rate = float(np.linalg.norm(omega))
    half_angle = 0.5 * rate * duration_s
    # sin(x)/|w| = (t/2) sinc: the series keeps it exact for tiny rates.
    if half_angle < 1e-4:
        sin_over_rate = 0.5 * duration_s * (1.0 - half_angle**2 / 6.0)
    else:
        sin_over_rate = np.sin(half_angle) / rate
    omega_quat = np.array([omega[0], omega[1], omega[2], 0.0])
    return np.cos(half_angle) * np.eye(4) + sin_over_rate * product_matrix(omega_quat)


def paper_printed_exponential_matrix(omega: np.ndarray, duration_s: float) -> np.ndarray:
    """Aghili eq. (39) *as printed* (not norm-preserving; kept only to test that claim)."""
    rate = float(np.linalg.norm(omega))
    half_angle = 0.5 * rate * duration_s
    omega_quat = np.array([omega[0], omega[1], omega[2], 0.0])
    scale = 2.0 / (rate * duration_s) * np.sin(half_angle) - 0.5 * np.cos(half_angle)
    return (np.cos(half_angle) + np.sin(half_angle)) * np.eye(4) + scale * product_matrix(
        omega_quat
    )


def propagate(q: np.ndarray, omega: np.ndarray, duration_s: float) -> np.ndarray:
    """Aghili eq. (39): nominal quaternion after ``duration_s`` at constant body rate ``omega``.

    Renormalised (only against round-off: the exact exponential preserves the norm).
    """
    q_next = exponential_matrix(omega, duration_s) @ q
    return q_next / np.linalg.norm(q_next)


def from_error_vector(dq_v: np.ndarray) -> np.ndarray:
    """Aghili eq. (40c): ``dq = [dq_v; sqrt(1 - |dq_v|^2)]``.

    A correction with ``|dq_v| >= 1`` has no such quaternion; it is rescaled to a unit
    quaternion (the filter counts it as an event: it means the linearisation broke down).
    """
    squared = float(dq_v @ dq_v)
    if squared >= 1.0:
        q = np.array([dq_v[0], dq_v[1], dq_v[2], 0.0])
        return q / np.sqrt(squared)
    return np.array([dq_v[0], dq_v[1], dq_v[2], np.sqrt(1.0 - squared)])


def apply_error(dq_v: np.ndarray, q_nominal: np.ndarray) -> np.ndarray:
    """Aghili eq. (40c): ``q = dq (x) qbar`` with ``dq`` from its vector part; unit norm."""
    q = multiply(from_error_vector(dq_v), q_nominal)
    return q / np.linalg.norm(q)


def error_vector(q: np.ndarray, q_nominal: np.ndarray) -> np.ndarray:
    """Aghili eqs. (16b), (38): ``dq_v = vec(q (x) qbar^*)`` (3,), sign fixed so ``dq_o >= 0``."""
    dq = multiply(q, conjugate(q_nominal))
    return dq[:3] if dq[3] >= 0 else -dq[:3]


def to_interface_wxyz(q: np.ndarray) -> np.ndarray:
    """Paper ``[q_v, q_o]`` -> interface Hamilton ``(w, x, y, z)`` body-to-world, ``w >= 0``."""
    wxyz = np.array([q[3], q[0], q[1], q[2]])
    return wxyz if wxyz[0] >= 0 else -wxyz


def from_interface_wxyz(wxyz: np.ndarray) -> np.ndarray:
    """Interface Hamilton ``(w, x, y, z)`` body-to-world -> paper ``[q_v, q_o]``, unit norm."""
    q = np.array([wxyz[1], wxyz[2], wxyz[3], wxyz[0]], dtype=float)
    return q / np.linalg.norm(q)
