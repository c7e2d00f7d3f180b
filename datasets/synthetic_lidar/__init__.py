"""Synthetic lidar world (walls, boxes, pillars, a corridor loop), a spinning lidar
ray-caster, and a bag writer (``write_lidar_bag``) for ``workbench simulate lidar-corridor``."""

from datasets.synthetic_lidar.writer import LidarBagOptions, describe, sidecar_path, write_lidar_bag

__all__ = ["LidarBagOptions", "describe", "sidecar_path", "write_lidar_bag"]
