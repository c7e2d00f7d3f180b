"""Estimated typeset widths for the LaTeX tables: Computer Modern's 8 pt glyph widths (a
10 pt article's ``\\footnotesize``), the column separation, and the text width a table
must fit (``results.latex_layout``: how a table too wide is split)."""

from __future__ import annotations

TEXT_WIDTH_PT = 452.97
"""\\textwidth of a one-column article on A4 with 1-inch margins (597.51 pt - 2 x 72.27 pt),
the narrower of A4 and letter."""
WIDTH_MARGIN = 0.97
"""Share of the text width a table may fill: the glyph model is Computer Modern's, other
fonts differ by a few per cent."""
COLUMN_SEPARATION_PT = 12.0
"""2 \\tabcolsep (6 pt each side) between two columns; the outer edges are ``@{}``."""
FONT_SIZE_PT = 8.0
"""\\footnotesize of a 10 pt article."""
BOLD_FACTOR = 1.16
"""Computer Modern bold extended over roman at 8 pt (digits 4.90 pt against 4.25 pt)."""

# cmr8 glyph widths in em (its TFM), ASCII; anything else counts as 0.8 em
_GLYPHS_EM = {
    **dict.fromkeys("!',.:;[]`il", 0.295),
    **dict.fromkeys("fj", 0.325),
    "-": 0.354,
    " ": 0.354,
    "I": 0.383,
    **dict.fromkeys("()trs", 0.415),
    **dict.fromkeys("cez", 0.472),
    "?": 0.502,
    **dict.fromkeys('"$*/0123456789\\^ago{}~_', 0.531),
    "J": 0.545,
    **dict.fromkeys("kqvxy", 0.561),
    **dict.fromkeys("Sbdhnpu", 0.59),
    "Z": 0.649,
    "L": 0.664,
    "F": 0.693,
    **dict.fromkeys("EP", 0.723),
    "B": 0.752,
    **dict.fromkeys("CTw", 0.767),
    "R": 0.782,
    **dict.fromkeys("AHNUVXY", 0.796),
    "D": 0.811,
    "K": 0.825,
    **dict.fromkeys("&+=@OQ", 0.826),
    "G": 0.834,
    **dict.fromkeys("#%m", 0.885),
    "M": 0.973,
    "W": 1.091,
}
# what a mark or a sign is typeset as, and its width [em]
_SYMBOLS_EM = {
    "✓": 0.833,  # \checkmark (msam)
    "▲": 0.778,  # \blacktriangle
    "▼": 0.778,
    "·": 0.278,  # \cdot
    "ˢ": 0.35,  # \textsuperscript{s} at 70 %
    "×": 0.778,
    "÷": 0.778,
    "±": 0.778,
    " ": 0.354,
}


def text_width_pt(text: str, bold: bool = False, size_pt: float = FONT_SIZE_PT) -> float:
    """Estimated typeset width [pt] of ``text`` (as shown, not as LaTeX source)."""
    em = sum(_GLYPHS_EM.get(char, _SYMBOLS_EM.get(char, 0.8)) for char in text)
    return em * size_pt * (BOLD_FACTOR if bold else 1.0)
