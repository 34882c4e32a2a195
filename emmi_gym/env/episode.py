"""The robot of one episode: the simulator stepped, the filter fed from it, the ground truth kept beside.

:class:`RobotEpisode` is what the action types drive (as HighwayEnv's action types drive the
env's vehicle) and the :class:`~emmi_gym.navigation.executor.Robot` a macro-action follows its
path with. The environment owns the loop round it: after each action it asks
:meth:`RobotEpisode.take_filter_updated` whether what it derives from the expected map is out of
date, and reads the ground truth (the true path, the true poses at the filter's updates, the
oracle map) for its scores.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..scoring.oracle import OracleMap
from ..slam import RBPF
from ..world import Simulator

#: Called after every filter update with the filter and the true pose at that update.
UpdateWatcher = Callable[[RBPF, np.ndarray], None]


class RobotEpisode:
    """One episode of the robot: :meth:`step` moves it one control step in the simulator and gives the
    filter a scan whenever an update is due (the laser is not simulated in between), inserting the
    same scan into the oracle map at the true pose; :meth:`scan` casts the scan at the current
    simulator time once, for the safety layer and the filter alike.

    ``max_sim_steps`` is the episode's budget of simulator steps (:meth:`out_of_time`); with
    ``measure_updates`` the metrics of every filter update are kept until
    :meth:`take_update_records`; each of ``watchers`` is called as ``watcher(slam, true_pose)``
    after every filter update (what a measurement of the filter against the truth reads). The
    first scan is fed at once, so the filter has a map from the start.
    """

    def __init__(self, sim: Simulator, slam: RBPF, angles: np.ndarray, max_sim_steps: int, measure_updates: bool,
                 watchers: tuple[UpdateWatcher, ...] = ()):
        self.sim, self.slam = sim, slam
        self.watchers = watchers
        self.oracle = OracleMap(slam)
        self.angles = angles
        self.max_sim_steps = max_sim_steps
        self.measure_updates = measure_updates
        self.sim_steps = 0
        self.collisions = 0
        self._true_path = [sim.true_pose]
        self._true_at_updates = np.empty((64, 3))  # the true pose at each filter update, the first _n_true rows
        self._n_true = 0
        self._scan_cache: tuple[float, np.ndarray] | None = None
        self._filter_updated = False  # since the last take_filter_updated()
        self._update_records: list[dict] = []
        self._update_filter(sim.odometry_pose, sim.true_pose)

    # ------------------------------------------------------------------ the Robot a macro-action drives

    @property
    def filter_step(self) -> int:
        """The filter's update count: it changes whenever the filter updated (the map may have changed)."""
        return self.slam.step

    def pose_estimate(self) -> np.ndarray:
        """The robot's pose as the filter believes it now (best particle plus odometry since its update)."""
        return self.slam.pose_estimate(self.sim.odometry_pose)

    def scan(self) -> np.ndarray:
        """The laser scan at the current simulator time, cast once and shared by the safety layer and the filter."""
        if self._scan_cache is None or self._scan_cache[0] != self.sim.time:
            self._scan_cache = (self.sim.time, self.sim.scan())
        return self._scan_cache[1]

    def expected_map(self) -> np.ndarray:
        """The filter's expected map now (eq. 6), a read-only view the next update changes."""
        return self.slam.expected_map()

    def step(self, v: float, omega: float) -> bool:
        """One control step at (v, omega), feeding the filter if an update is due; True if the robot collided."""
        result = self.sim.step(v, omega)
        self.sim_steps += 1
        self.collisions += int(result.collided)
        self._true_path.append(result.true_pose)
        self._update_filter(result.odometry_pose, result.true_pose)
        return result.collided

    def out_of_time(self) -> bool:
        """Whether the episode's simulator steps are spent."""
        return self.sim_steps >= self.max_sim_steps

    # ------------------------------------------------------------------ what the environment reads

    def restart_counts(self) -> None:
        """Count simulator steps and collisions from now on (the drive to the decision point is not the agent's)."""
        self.sim_steps = self.collisions = 0

    def take_filter_updated(self) -> bool:
        """Whether the filter updated since the last call (or since the episode began)."""
        updated, self._filter_updated = self._filter_updated, False
        return updated

    def take_update_records(self) -> list[dict]:
        """The metrics of every filter update since the last call, once (kept only with ``measure_updates``)."""
        records, self._update_records = self._update_records, []
        return records

    @property
    def true_path(self) -> list[np.ndarray]:
        """The true pose at every simulator step of the episode (ground truth, for evaluation only)."""
        return self._true_path

    @property
    def true_poses_at_updates(self) -> np.ndarray:
        """(updates, 3) the true pose at each filter update (ground truth, for the ATE)."""
        return self._true_at_updates[:self._n_true]

    def _update_filter(self, odometry_pose, true_pose) -> None:
        """Give the filter a scan when it will use one, and the oracle map the same scan at the true pose."""
        if not self.slam.update_due(odometry_pose):
            return
        scan = self.scan()
        metrics = self.slam.process(odometry_pose, scan, self.angles, self.sim.time, measure=self.measure_updates)
        self.oracle.insert(true_pose, scan, self.angles)
        if self._n_true == len(self._true_at_updates):  # doubled as needed: appending costs the same all episode
            self._true_at_updates = np.concatenate([self._true_at_updates, np.empty_like(self._true_at_updates)])
        self._true_at_updates[self._n_true] = true_pose
        self._n_true += 1
        if metrics is not None:
            self._update_records.append(metrics.measures())
        for watcher in self.watchers:
            watcher(self.slam, true_pose)
        self._filter_updated = True
