"""The lidar front end: KISS-ICP odometry (``kiss_icp_odometry``), corner landmarks
(``corners``), both per cloud with a cache (``frontend``; its settings ``frontend_settings``,
its reports ``frontend_diagnostics``, in a stream ``frontend_stream``), and scoring against
the exact corners of a synthetic world (``corner_truth``)."""
