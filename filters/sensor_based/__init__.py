"""Guerreiro et al. (2013) globally asymptotically stable sensor-based SLAM filter.

Modules: ``dynamics`` (eqs. (1)-(4), (10), IV-A), ``state`` (state vector bookkeeping),
``update`` (IV-B, eq. (11)), ``landmark_management`` (section V), ``filter`` (the estimator).
"""
