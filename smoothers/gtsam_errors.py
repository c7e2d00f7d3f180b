"""GTSAM's exceptions as ``InputError``: the time, the step, and GTSAM's *whole* message.

GTSAM raises ``RuntimeError`` whose first line is sometimes empty or only a heading (the
indeterminate-system message names the variable on a later line), so the message is kept
whole, collapsed to one line, never cut to its first line.
"""

from __future__ import annotations

import math

from datasets.errors import InputError


class IndeterminateSystem(InputError):
    """GTSAM found the linear system indeterminate (``explain``): at the first solve, a state
    nothing constrains (an input problem); mid-run, after the same graph solved before, a
    numerical failure of the solver (``KeyframeSmoother`` stops the run there).

    Attributes:
        gtsam: GTSAM's own message on one line.
    """

    gtsam: str = ""


def gtsam_message(error: BaseException) -> str:
    """GTSAM's whole message on one line (the exception's type when it has none)."""
    text = " ".join(line.strip() for line in str(error).strip().splitlines() if line.strip())
    return text or type(error).__name__


def is_indeterminate(error: BaseException) -> bool:
    """Whether GTSAM found the linear system indeterminate (``IndeterminantLinearSystem``:
    an unconstrained variable, or Cholesky failing on a badly conditioned system)."""
    text = str(error)
    return "ndeterminant" in text or "ndeterminate" in text


def explain(error: BaseException, t: float, context: str) -> InputError:
    """The ``InputError`` for ``error`` raised by GTSAM during ``context`` at time ``t`` [s]
    (NaN: no time)."""
    message = gtsam_message(error)
    where = f"{context} at t={t:.6f} s" if math.isfinite(t) else context
    if is_indeterminate(error):
        failure = IndeterminateSystem(
            f"{where}: the system is indeterminate (some state is not constrained: no prior, "
            f"anchors, GPS or enough landmarks reach it) -- GTSAM: {message}"
        )
        failure.gtsam = message
        return failure
    return InputError(f"{where} failed inside GTSAM: {message}")
