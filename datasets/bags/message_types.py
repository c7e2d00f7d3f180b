"""The ROS message types a bag is read for, by the names rosbags gives them
(``package/msg/Type``), and the groups of them the readers choose by."""

from __future__ import annotations

POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"
LASERSCAN = "sensor_msgs/msg/LaserScan"
IMU = "sensor_msgs/msg/Imu"
NAVSATFIX = "sensor_msgs/msg/NavSatFix"
ODOMETRY = "nav_msgs/msg/Odometry"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
POSE_WITH_COVARIANCE_STAMPED = "geometry_msgs/msg/PoseWithCovarianceStamped"
GROUND_TRUTH_TYPES = (ODOMETRY, POSE_STAMPED, POSE_WITH_COVARIANCE_STAMPED)
POSE_TYPES = (ODOMETRY, POSE_STAMPED, POSE_WITH_COVARIANCE_STAMPED)
"""Message types with a pose: a wheel-odometry input (``odometry_topic``, differenced:
``datasets.bags.wheel_odometry``) or, when named, the ground truth."""
