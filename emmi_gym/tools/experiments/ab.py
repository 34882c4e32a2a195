"""The paper's main experiment (Blanco et al. 2006, Sec. V, Fig. 6): at the decision point of a
loop, A closes the loop before entering the new area, B enters the new area first.

Each seed gives one A run and one B run from the *same* state at the decision point (the
environment's reset with that seed drives the loop up to it), so A and B are compared in
pairs. A run records every RBPF update's measures (EMMI eq. 11, pose entropy, joint
entropy eq. 12, ...) and ends when its policy has reached both goals (or after
``max_decisions``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np

from ..._moved import moved_names
from ...concurrency.parallel import run_in_processes
from ...scoring.scores import absolute_trajectory_error, map_accuracy
from ...world.ground_truth import UNKNOWN
from ..evaluation import loop_order
from ..evaluation.loop_order import NEW_AREA_PLACE, new_area_now
from ..policies import make_policy

#: The two arms of the experiment and their scripted policies.
POLICIES = {"A": "close_loop_first", "B": "explore_first"}
#: The names that moved to :mod:`emmi_gym.tools.evaluation.loop_order` (deprecated here).
__getattr__ = moved_names(__name__, loop_order, ("closed_loop_first", "new_area_mask"), "0.5.0")


@dataclass(frozen=True)
class ABSettings:
    """What an A/B run is made of: the env ``env_id`` with ``env_options`` (its own world unless they name
    one), ``particles`` and ``max_decisions`` (and the metrics of every filter update,
    ``update_records``, for the per-update curves)."""

    env_id: str = "emmi_gym/LoopCorridor-v1"
    particles: int = 15
    max_decisions: int = 40
    env_options: dict = field(default_factory=dict)

    def experiment_env(self) -> gym.Env:
        """The env each arm is played in: these settings' env, particles and decisions, every RBPF update
        recorded."""
        return gym.make(self.env_id, particles=self.particles, max_decisions=self.max_decisions, coverage_target=1.0,
                        update_records=True, **self.env_options)


@dataclass
class ABRun:
    """One run of one policy from the decision point.

    ``rows`` holds the measures of every RBPF update from the start of the loop (with
    ``phase``: the number of goals the policy had reached when that update came);
    ``decision``, ``first_goal`` and ``second_goal`` are indices into ``rows`` (the last
    update before the decision, and the update at which each goal was reached; None if
    it never was). ``maps`` holds the expected map (eq. 6) at those moments,
    ``paths`` the best particle's estimated path; ``final`` the ground-truth scores at the end (with
    :func:`loop_ate`, the ATE of the loop under the final best particle's path), and
    how the loop closed: ``closure_error``, the distance between the estimated and the true pose when
    the robot got back to the loop's start (``target_a``), ``loop_hypotheses``, how many distinct poses at
    the decision point the particles still held at the end of the last step before the robot came within
    the laser's range of the start (the hypotheses resampling left for the closure), and
    ``loop_closed``, whether that error is within
    the scan matcher's capture radius (``match_radius``: the map agrees with itself where the loop
    closes). ``walls`` are the world's (generated worlds differ per seed).
    """

    seed: int
    arm: str
    policy: str
    rows: list[dict]
    decision: int
    first_goal: int | None
    second_goal: int | None
    final: dict
    maps: dict[str, np.ndarray]
    paths: dict[str, np.ndarray]
    extent: tuple[float, float, float, float]
    walls: np.ndarray

    def at(self, event: str) -> dict | None:
        """The measures of the update at ``event`` ("decision", "first_goal", "second_goal", "end")."""
        index = len(self.rows) - 1 if event == "end" else getattr(self, event)
        return None if index is None else self.rows[index]


def hypotheses_of(paths: np.ndarray, update: int) -> int:
    """How many distinct poses the particles' paths (M, T, 3) hold at ``update``: the hypotheses of the path
    up to there that resampling has left."""
    return len(np.unique(paths[:, update], axis=0))


def loop_ate(loop_rows: list[dict], best_path: np.ndarray, true_path: np.ndarray, control_period: float) -> float:
    """ATE (m, unaligned, as the env's) of the loop driven before the decision point under a particle's path:
    the same true poses for A and B, so the A - B difference is which hypothesis of the loop survived.
    ``loop_rows`` are the updates up to the decision (their ``time`` finds the true pose of each among the
    simulator steps of ``true_path``)."""
    steps = np.rint(np.array([row["time"] for row in loop_rows]) / control_period).astype(np.int64)
    return absolute_trajectory_error(best_path[:len(loop_rows)], true_path[steps], align=False)


def check_world(world) -> None:
    """Raise a ValueError naming what ``world`` lacks for the experiment: the places decision,
    target_a (back at the start: closes the loop), target_b (in the unexplored area) and a
    to_decision route."""
    missing = [f"place '{p}'" for p in ("decision", "target_a", NEW_AREA_PLACE) if p not in world.places]
    missing += [] if "to_decision" in world.routes else ["route 'to_decision'"]
    if missing:
        raise ValueError(f"world '{world.name}' ({world.source}) cannot host the A/B experiment: it lacks "
                         f"{', '.join(missing)}")


def run_arm(seed: int, arm: str, settings: ABSettings = ABSettings()) -> ABRun:
    """Run arm ``"A"`` or ``"B"`` from the decision point of ``settings.world`` with ``seed``."""
    if arm not in POLICIES:
        raise ValueError(f"arm must be one of {sorted(POLICIES)}, got {arm!r}")
    env = settings.experiment_env()
    core = env.unwrapped
    policy = make_policy(POLICIES[arm])
    _, info = env.reset(seed=seed)
    check_world(core.world)
    policy.reset(seed)
    rows = [dict(r, phase=0) for r in info["rbpf_updates"]]
    events = {"decision": len(rows) - 1}
    maps = {"decision": core.expected_map}
    paths = {"decision": core.slam.paths[core.slam.best].copy()}
    new_area = new_area_now(core)
    new_area_truth = np.where(new_area, core.truth.grid, UNKNOWN)
    new_area_on_arrival = closure_error = float("nan")
    loop_start, reach = core.world.place("target_a"), core.laser_config.max_range
    loop_hypotheses, approaching = hypotheses_of(core.slam.paths, events["decision"]), True
    truncated = False
    while not policy.done and not truncated:
        phase = policy.phase
        _, _, _, truncated, info = env.step(policy(env))
        x, y, _ = core.true_path[-1]
        approaching = approaching and math.hypot(x - loop_start.x, y - loop_start.y) > reach
        if approaching:
            loop_hypotheses = hypotheses_of(core.slam.paths, events["decision"])
        rows += [dict(r, phase=phase) for r in info["rbpf_updates"]]
        for reached in range(phase, policy.advance(env)):
            event = ("first_goal", "second_goal")[reached]
            events[event] = len(rows) - 1
            maps[event] = core.expected_map
            paths[event] = core.slam.paths[core.slam.best].copy()
            if policy.goals[reached] == NEW_AREA_PLACE:
                new_area_on_arrival = map_accuracy(maps[event], new_area_truth)
            else:
                closure_error = float(np.hypot(*(core.estimated_pose[:2] - core.true_path[-1][:2])))
    expected = core.expected_map
    scores = core.ground_truth_scores()  # the policy's end, which need not be the episode's
    final = {
        "loop_ate": loop_ate(rows[:events["decision"] + 1], core.slam.paths[core.slam.best], core.true_path,
                             core.robot_config.control_period),
        "map_accuracy": scores["map_accuracy"], "oracle_accuracy": scores["oracle_accuracy"],
        "wall_consistency": scores["wall_consistency"], "ate": scores["ate"], "coverage": info["coverage"],
        "new_area_accuracy_on_arrival": new_area_on_arrival,
        "new_area_accuracy": map_accuracy(expected, new_area_truth),
        "new_area_cells": int(new_area.sum()), "closure_error": closure_error, "loop_hypotheses": loop_hypotheses,
        "loop_closed": (float(closure_error <= core.slam_config.match_radius) if np.isfinite(closure_error)
                        else float("nan")), "sim_steps": info["sim_steps"], "decisions": core.decisions,
        "collisions": info["collisions"], "completed": policy.done,
    }
    extent, walls = core.geometry.extent, core.world.walls
    env.close()
    return ABRun(seed, arm, POLICIES[arm], rows, events["decision"], events.get("first_goal"),
                 events.get("second_goal"), final, maps, paths, extent, walls)


def _run(job: tuple[int, str, ABSettings]) -> ABRun:
    return run_arm(*job)


def run_ab(seeds, settings: ABSettings = ABSettings(), *, workers: int | None = None,
           progress: bool = True) -> list[ABRun]:
    """Run A and B for every seed, in ``workers`` processes (default: one per core; 1 = in this process).

    Returns the runs sorted by seed, then arm; the same seeds give the same runs,
    whatever the number of workers.
    """
    jobs = [(int(seed), arm, settings) for seed in seeds for arm in POLICIES]
    runs = run_in_processes(_run, jobs, workers=workers, desc="A/B runs", progress=progress)
    return sorted(runs, key=lambda run: (run.seed, run.arm))
