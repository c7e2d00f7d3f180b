"""Guerreiro et al. (2013) globally asymptotically stable sensor-based SLAM filter.

Modules: ``filter`` (the estimator, ``sensor-based``: inputs, propagation, the order of a
scan's steps), ``config`` (options), ``prior`` (the start), ``dynamics`` (eqs. (1)-(4), (10),
IV-A), ``state`` (state vector bookkeeping), ``directions`` (line-direction features, eq. (1)),
``scan_association`` (a scan's sightings and their association, IV-B, V), ``update`` (IV-B,
eq. (11)), ``landmark_management`` (section V), ``loop_closing`` (IV-C), ``odometry``
(odometry as an input, our extension), ``earth_motion`` and ``earth_frame`` (the Earth-frame
trajectory and map), ``earth_pose_covariance`` (its first-order covariance, our extension),
``recording`` (what goes into the estimate).
"""
