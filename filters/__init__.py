"""Recursive estimators. Kept free of imports so ``smoothers`` can load ``filters.association`` alone."""
