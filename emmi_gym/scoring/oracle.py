"""The oracle map: what the robot's own scans give when inserted at its *true* poses.

It uses the filter's sensor model, grid and scans (the same scans the filter inserted,
at the same updates), so it holds everything a perfectly localised robot would have
mapped and nothing else: the ground truth against which SLAM's own error shows. The
map accuracy against the floor plan (:func:`~emmi_gym.scoring.scores.map_accuracy`)
measures rasterisation, blur and unseen corners as much as SLAM; against the oracle
(:func:`~emmi_gym.scoring.scores.oracle_accuracy`) a perfect run scores exactly 1.0, and
:func:`~emmi_gym.scoring.scores.wall_consistency` catches doubled walls at revisited places.
The environments also read their coverage on it (what the scans swept), so that coverage
measures exploration whatever the SLAM error.
"""

from __future__ import annotations

import numpy as np

from ..slam.occupancy import ParticleMaps
from ..slam.rbpf import RBPF
from .scores import map_labels


class OracleMap:
    """One occupancy grid on the filter's geometry, fed the filter's scans at the true poses."""

    def __init__(self, rbpf: RBPF):
        self._rbpf = rbpf
        self.maps = ParticleMaps(rbpf.geometry, 1, rbpf.cell_codes, rbpf.config.coarse_block())
        # map_labels of each of the 256 codes, indexed by the code's byte read as unsigned
        self._label_of_byte = np.roll(map_labels(rbpf.cell_codes.probability), -128)

    def insert(self, true_pose, ranges: np.ndarray, angles: np.ndarray) -> None:
        """Insert a scan at the true pose, as the filter inserts it at each particle's pose."""
        cfg = self._rbpf.config
        self.maps.insert(np.asarray(true_pose, dtype=np.float64)[None, :], np.ascontiguousarray(ranges, np.float64),
                         np.ascontiguousarray(angles, np.float64), self._rbpf.max_range, cfg.max_range_free,
                         cfg.insertion_range)

    def probabilities(self) -> np.ndarray:
        """The oracle map's occupancy probabilities (H, W)."""
        return self.maps.probabilities(0)

    def labels(self) -> np.ndarray:
        """:func:`~emmi_gym.scoring.scores.map_labels` of :meth:`probabilities` (-1 unobserved, 0 free, 1 occupied),
        read off a table of the codes (the environment's coverage and scores need these, every filter update)."""
        return self._label_of_byte[self.maps.codes[0].view(np.uint8)]
