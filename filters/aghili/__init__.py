"""Aghili, "Lidar SLAM for Autonomous Driving Vehicles": adaptive error-state EKF SLAM with a
strap-down IMU and 3-D landmark positions, plus its observability analysis (section 3).

Modules (each owns one idea):
- ``quaternion_jpl``: the paper's quaternion algebra (section 2.1, eqs. (3), (12), (39)).
- ``transition``: closed-form state transition matrix (eq. (35), corrected).
- ``process_noise``: discrete process noise (eqs. (36)-(37)): Van Loan and a verified
  closed form.
- ``measurement``: observation model and sensitivity matrix (eqs. (7b), (10)-(11)).
- ``adaptive_noise``: sliding-window measurement-noise estimate (section 4.4, eq. (42)).
- ``observability``: eqs. (22), (25)-(27), (30)-(32).
- ``filter``: the estimator (``AghiliFilter``), registered as ``aghili``.

Kept free of imports so that importing one module does not load the others.
"""
