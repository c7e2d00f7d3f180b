"""ROS 1 / ROS 2 bags through rosbags' AnyReader: reading (``reader``), PointCloud2 decoding
(``pointcloud2``), NavSatFix to local ENU (``gps``), and the ``bag:PATH`` dataset
(``source``; its options ``bag_options``; a bag without a lidar ``sensor_source``).
Submodules are imported on use (rosbags and KISS-ICP load only when needed)."""
