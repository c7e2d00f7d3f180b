"""The lidar front end: KISS-ICP odometry (``kiss_icp_odometry``), corner landmarks
(``corners``), both per cloud with a cache (``frontend``), and scoring against the exact
corners of a synthetic world (``corner_truth``)."""
