"""Shared test helpers."""

import numpy as np


def radial_profile_error(grid, pressure, reference_fn):
    """Max |p - p_ref| over the grid, relative to max(p_ref)."""
    x, y = (np.asarray(c) for c in grid.coordinates())
    ref = np.asarray(reference_fn(np.hypot(x, y)))
    return np.max(np.abs(np.asarray(pressure) - ref)) / np.max(ref)
