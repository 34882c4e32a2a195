"""Small worked examples of the certainty metrics, for the command line and the docs."""

from __future__ import annotations

import numpy as np

from . import emmi, joint_entropy, mean_information, weighted_map_entropy


def _room(shape=(40, 40), free=0.05, wall=0.95) -> np.ndarray:
    """A probability grid of a walled room: free inside, occupied border, unknown outside."""
    grid = np.full(shape, 0.5)
    grid[5:35, 5:35] = wall
    grid[6:34, 6:34] = free
    return grid


def fig5_contrast() -> list[dict]:
    """The paper's Fig. 5 on a small map: two equally weighted particles.

    ``agree``: both particles map the same room. ``disagree``: on a 10 x 10 patch one
    particle says free (p = 0.01) and the other occupied (p = 0.99). EMMI (eq. 11)
    falls because the expected map is 0.5 there; the joint entropy's map term
    (eq. 12) does not move, because each particle's own map is certain.
    """
    weights = np.array([0.5, 0.5])
    paths = np.zeros((2, 1, 3))
    rows = []
    for case in ("agree", "disagree"):
        a, b = _room(), _room()
        a[15:25, 15:25] = 0.01
        b[15:25, 15:25] = 0.01 if case == "agree" else 0.99
        grids = np.stack([a, b])
        rows.append({
            "case": case,
            "emmi_bits": emmi(grids, weights),
            "mi_particle_1_bits": mean_information(a),
            "mi_particle_2_bits": mean_information(b),
            "map_entropy_term_bits": weighted_map_entropy(grids, weights),
            "joint_entropy_nats": joint_entropy(paths, grids, weights),
        })
    return rows
