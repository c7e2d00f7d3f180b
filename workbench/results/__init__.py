"""Results that travel: run folders read back into records and one tidy table, rows per
(dataset, estimator) pair with their accuracy and consistency, and the one table writer.

Modules: ``runs`` (run folders -> ``RunRecord``, the tidy DataFrame), ``consistency`` (the
per-run NEES/NIS series and the consistency cells), ``summary`` (one row per pair,
``table.csv``'s columns), ``tables`` (Markdown, LaTeX, CSV, terminal), ``latex`` and its
``latex_*`` siblings (the paper tables: rounding, cells, widths, layout, captions).
"""
