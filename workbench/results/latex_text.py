"""Text as LaTeX source: the escaping of LaTeX specials and of the signs the tables use,
the verdict marks of consistency cells and the smoothed-estimate superscript (each as
source and as the reader sees it, for widths)."""

from __future__ import annotations

from workbench.metrics.verdicts import Verdict

VERDICT_LATEX = {
    Verdict.CONSISTENT: r"$\checkmark$",
    Verdict.OPTIMISTIC: r"$\blacktriangle$",
    Verdict.CONSERVATIVE: r"$\blacktriangledown$",
    Verdict.TOO_FEW_RUNS: r"$\cdot$",
}
VERDICT_SHOWN = {
    Verdict.CONSISTENT: "✓",
    Verdict.OPTIMISTIC: "▲",
    Verdict.CONSERVATIVE: "▼",
    Verdict.TOO_FEW_RUNS: "·",
}
SMOOTHED_LATEX = r"\textsuperscript{s}"

_LATEX_SPECIAL = {
    "\\": r"\textbackslash{}",
    "&": r"\&",
    "%": r"\%",
    "$": r"\$",
    "#": r"\#",
    "_": r"\_",
    "{": r"\{",
    "}": r"\}",
    "~": r"\textasciitilde{}",
    "^": r"\^{}",
    "÷": r"$\div$",
    "±": r"$\pm$",
    "×": r"$\times$",
    "≥": r"$\geq$",
    "≤": r"$\leq$",
    "ˢ": SMOOTHED_LATEX,
}


def latex_escape(text: str) -> str:
    """``text`` as LaTeX source that prints it (specials and the signs the tables use)."""
    return "".join(_LATEX_SPECIAL.get(character, character) for character in text)
