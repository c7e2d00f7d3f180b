"""GTSAM factor-graph smoothers."""
