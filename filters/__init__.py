"""Recursive estimators. Kept free of imports so ``smoothers`` can load ``filters.association``
and ``filters.kalman`` alone."""
