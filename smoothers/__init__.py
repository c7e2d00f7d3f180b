"""GTSAM factor-graph smoothers (registered as smoother-batch, smoother-isam2, smoother-fixed-lag).

Modules, one idea each:
- ``config``: the options (the shared association/recording/noise vocabulary inherited).
- ``modes``: the three registered estimators.
- ``keyframe_smoother``: the stream turned into keyframes committed to a backend.
- ``motion_setup``: the sequence's start and sensors -> priors and motion model.
- ``imu_graph``: CombinedImuFactor preintegration between 3-D keyframes (X, V, B keys).
- ``planar_graph``: the Pose2/Point2 variant: odometry between-factors, or the documented
  gyro-only constant-velocity model.
- ``planar_odometry``: planar odometry (relative poses, held velocities) composed between
  keyframes.
- ``gyro_integration``: the rate gyro integrated between keyframes (``dtheta_m``, ``dt``).
- ``gyro_motion_factor``: the gyro-only constant-velocity model: residual, covariance, factor.
- ``odometry_factors``: optional 3-D relative-pose (lidar odometry) factors.
- ``gps_factors``: GPS fixes on keyframe poses.
- ``landmark_factors``: body-frame landmark factors (``p = R^T (rho - r)``), anchor priors.
- ``landmark_book``: map ids, their current variables, the anchors.
- ``landmark_scans``: each sighting decided, recorded (decision, reason, NIS), factored.
- ``scan_association``: the candidates a scan is associated against (``filters.association``).
- ``keyframe_prediction``: the keyframe's prediction (predicted measurements, ``H J H^T``, NIS).
- ``pending_update``: what the next backend update adds.
- ``backends``: iSAM2 and IncrementalFixedLagSmoother, Cholesky with an automatic QR fallback.
- ``joint_marginals``: marginal covariances from one batched joint query.
- ``gtsam_errors``: GTSAM exceptions -> ``InputError`` with the whole message.
- ``covariances``: GTSAM marginals -> interface covariance conventions.
- ``initialization``: prior sigmas; the batch's starting points.
- ``smoothed_output``: the smoothed history and final map at the end of a run.
- ``lag_window``: what leaves the fixed-lag window, kept.
- ``speed``: the speed figures of ``workbench bench-speed``.

Imports ``datasets`` and, from ``filters``, only ``filters.association`` and the Kalman
core's innovation statistics (``filters.kalman``; neither loads a filter).
"""
