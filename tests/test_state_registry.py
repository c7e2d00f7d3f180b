"""The state registry (``filters.state_registry``) against a hand-built layout."""

from __future__ import annotations

import numpy as np

from filters import kalman
from filters.state_registry import StateRegistry


def _registry() -> StateRegistry:
    """Vehicle [position 2 | heading 1], landmark 10 (position), landmark 11 (position and
    two directions), landmark 12 (position): 3 + 2 + 6 + 2 = 13 entries."""
    registry = StateRegistry([("position", 2), ("heading", 1)])
    assert registry.augment(10, [("position", 2)]) == slice(3, 5)
    assert registry.augment(11, [("position", 2), ("direction", 2), ("direction", 2)]) == slice(
        5, 11
    )
    assert registry.augment(12, [("position", 2)]) == slice(11, 13)
    return registry


def test_lookups_agree_with_the_hand_built_layout() -> None:
    registry = _registry()
    assert registry.vehicle_size == 3 and registry.size == 13 and len(registry) == 3
    assert registry.vehicle("heading") == slice(2, 3)
    np.testing.assert_array_equal(registry.ids, [10, 11, 12])
    assert registry.slice_of(11) == slice(5, 11)
    assert registry.slice_of(11, "direction") == slice(7, 9)
    np.testing.assert_array_equal(registry.indices([12, 10]), [11, 12, 3, 4])
    np.testing.assert_array_equal(registry.indices([11, 12], "position"), [5, 6, 11, 12])
    np.testing.assert_array_equal(registry.columns(["heading"], [10]), [2, 3, 4])
    np.testing.assert_array_equal(registry.columns(None, [12]), [0, 1, 2, 11, 12])
    np.testing.assert_array_equal(registry.block_owners, [10, 11, 11, 11, 12])
    np.testing.assert_array_equal(
        registry.block_names, ["position", "position", "direction", "direction", "position"]
    )
    np.testing.assert_array_equal(registry.block_indices([3, 0]), [9, 10, 3, 4])
    assert 11 in registry and 13 not in registry


def test_marginalizing_through_it_equals_deleting_rows_and_columns() -> None:
    registry = _registry()
    rng = np.random.default_rng(0)
    root = rng.normal(size=(13, 13))
    covariance = root @ root.T
    x = rng.normal(size=13)
    keep = registry.marginalize([11, 99])  # 99 is not in the state: ignored
    deleted = np.delete(np.delete(covariance, np.s_[5:11], axis=0), np.s_[5:11], axis=1)
    np.testing.assert_array_equal(kalman.marginalize(covariance, keep), deleted)
    np.testing.assert_array_equal(x[keep], np.delete(x, np.s_[5:11]))
    # the registry now describes the shrunk state
    np.testing.assert_array_equal(registry.ids, [10, 12])
    assert registry.size == 7 and registry.slice_of(12) == slice(5, 7)
    np.testing.assert_array_equal(registry.indices([12]), [5, 6])
    assert registry.augment(13, [("position", 2)]) == slice(7, 9)


def test_a_copy_is_independent() -> None:
    registry = _registry()
    copied = registry.copy()
    copied.marginalize([10])
    copied.augment(14, [("position", 2)])
    np.testing.assert_array_equal(registry.ids, [10, 11, 12])
    np.testing.assert_array_equal(copied.ids, [11, 12, 14])
    assert registry.slice_of(12) == slice(11, 13)
