"""Numbers as the tables show them (``Rounded``): rounded to their uncertainty or to
significant digits.

Rounding (one convention, stated in every caption): a mean over runs is shown with its
sample std rounded to two significant digits, the mean to the same decimal place, the std in
parentheses in units of the mean's last digit, as siunitx's compact uncertainty does:
0.006716 ± 3.1e-04 -> ``0.00672(31)``; 67.43 ± 12.2 -> ``67(12)``; 1234 ± 156 ->
``1230(160)``. A std of 0 (every run alike) shows the value with up to four significant
digits and ``(0)``: ``27(0)``; one run (no std) shows three significant digits, as do
consistency cells and ratios. Means below 1e-3 or from 1e5 up are written with a power of
ten: ``1.50(30)\\times10^{-5}``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Rounded:
    """A number as shown: ``digits`` (the mean, or the mantissa with ``exponent``), the
    uncertainty's digits in units of its last digit (None without one)."""

    digits: str
    uncertainty: str | None = None
    exponent: int | None = None

    def plain(self) -> str:
        """``0.00672(31)``, ``1.50(30)e-05``: for Markdown, terminals and tests."""
        text = self.digits + (f"({self.uncertainty})" if self.uncertainty is not None else "")
        return text if self.exponent is None else f"{text}e{self.exponent:+03d}"

    def shown(self) -> str:
        """What the reader sees (for widths): ``1.50(30)×10-5``."""
        text = self.digits + (f"({self.uncertainty})" if self.uncertainty is not None else "")
        return text if self.exponent is None else f"{text}×10{self.exponent}"

    def latex(self, bold: bool = False) -> str:
        text = self.digits + (f"({self.uncertainty})" if self.uncertainty is not None else "")
        if self.exponent is None:
            return f"\\textbf{{{text}}}" if bold else text
        math = f"{text}\\times10^{{{self.exponent}}}"
        return f"{{\\boldmath${math}$}}" if bold else f"${math}$"


def _needs_exponent(value: float) -> bool:
    return value != 0 and not 1e-3 <= abs(value) < 1e5


def _fixed(value: float, decimals: int) -> str:
    """``value`` rounded to ``decimals`` decimal places (negative: to tens, hundreds)."""
    if decimals > 0:
        return f"{value:.{decimals}f}"
    text = f"{round(value, decimals):.0f}"
    return "0" if text == "-0" else text


def significant(value: float, digits: int = 3) -> Rounded:
    """``value`` to ``digits`` significant digits, trailing zeros kept (``1.00``)."""
    if not math.isfinite(value):
        return Rounded("")
    exponent = None
    if _needs_exponent(value):
        exponent = math.floor(math.log10(abs(value)))
        value = value / 10**exponent
    if value == 0:
        return Rounded("0", None, exponent)
    decimals = digits - 1 - math.floor(math.log10(abs(value)))
    rounded = round(value, decimals)
    if rounded != 0 and math.floor(math.log10(abs(rounded))) > math.floor(math.log10(abs(value))):
        decimals -= 1  # 9.996 -> 10.0, not 10.00
    return Rounded(_fixed(value, max(decimals, 0)), None, exponent)


def round_to_uncertainty(mean: float, std: float | None, digits: int = 2) -> Rounded:
    """The mean rounded to its std (module docstring: the std's ``digits`` significant
    digits, the mean to the same decimal place); ``significant(mean)`` without a std."""
    if std is None or not math.isfinite(std):
        return significant(mean)
    if std == 0:  # every run gave the same value (a landmark count): shown as it is
        exponent = math.floor(math.log10(abs(mean))) if _needs_exponent(mean) else None
        scaled = mean if exponent is None else mean / 10**exponent
        return Rounded(f"{scaled:.4g}", "0", exponent)
    exponent = None
    if _needs_exponent(mean):
        exponent = math.floor(math.log10(abs(mean)))
        mean, std = mean / 10**exponent, std / 10**exponent
    decimals = digits - 1 - math.floor(math.log10(std))
    if round(std, decimals) >= 10 ** (digits - decimals):
        decimals -= 1  # 0.0996 -> 0.10: two digits of the rounded std, not three
    uncertainty = round(std * 10**decimals) if decimals > 0 else round(std, decimals)
    return Rounded(_fixed(mean, decimals), str(int(uncertainty)), exponent)
