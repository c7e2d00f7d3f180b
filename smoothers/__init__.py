"""GTSAM factor-graph smoothers (registered as smoother-batch, smoother-isam2, smoother-fixed-lag).

Modules, one idea each:
- ``imu_graph``: CombinedImuFactor preintegration between 3-D keyframes (X, V, B keys).
- ``planar_graph``: the Pose2/Point2 variant: odometry between-factors, or the documented
  gyro-only constant-velocity model.
- ``landmark_factors``: body-frame landmark factors (``p = R^T (rho - r)``), anchor priors.
- ``odometry_factors``: optional 3-D relative-pose (lidar odometry) factors.
- ``covariances``: GTSAM marginals -> interface covariance conventions.
- ``initialization``: prior sigmas; Levenberg-Marquardt started from the incremental solution.
- ``backends``: iSAM2 and IncrementalFixedLagSmoother behind one small interface.
- ``keyframe_smoother``: the shared keyframe machinery (stream, association, recording).
- ``modes``: the three registered estimators.

Imports ``datasets`` and, from ``filters``, only ``filters.association``.
"""
