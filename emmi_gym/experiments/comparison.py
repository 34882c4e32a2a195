"""Scripted policies compared on many worlds, paired by world and seed, under the ground-truth scores.

Each (world, seed) gives one episode per policy from the same start and the same random
draws up to the first decision; the table reports each policy's mean and the paired
difference with its 95% interval (Student's t, clipped to the measure's range), the scores
being the final ``info`` of the episode: accuracy against the oracle map (1.0: SLAM added no
error), wall consistency, ATE, map accuracy against the floor plan, coverage.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np

from ..concurrency.parallel import run_in_processes
from ..policies import make_policy
from .intervals import difference_interval, measure_interval

#: The scores compared, with their labels; for "ate" lower is better.
SCORES = {"oracle_accuracy": "accuracy against the oracle map", "wall_consistency": "wall consistency",
          "ate": "ATE (m)", "map_accuracy": "map accuracy (floor plan)", "coverage": "coverage",
          "decisions": "decisions", "sim_steps": "simulator steps"}


@dataclass(frozen=True)
class ComparisonSettings:
    """The environment every episode runs in (``world`` is set per episode)."""

    env_id: str = "emmi_gym/ExplorePlans-v0"
    env_options: dict = field(default_factory=dict)

    def make_env(self, world: str) -> gym.Env:
        return gym.make(self.env_id, **dict(self.env_options, world=world))


def run_episode(world: str, seed: int, policy_name: str, settings: ComparisonSettings = ComparisonSettings(),
                keep_maps: bool = False) -> dict:
    """One episode of ``policy_name`` on ``world`` with ``seed``: its final scores (and, with ``keep_maps``, the
    expected map, the oracle map and the grid's extent)."""
    env = settings.make_env(world)
    core = env.unwrapped
    policy = make_policy(policy_name)
    _, info = env.reset(seed=seed)
    policy.reset(seed)
    terminated = truncated = False
    while not (terminated or truncated):
        _, _, terminated, truncated, info = env.step(policy(env))
    row = {"world": str(world), "plan": core.world.name, "seed": seed, "policy": policy_name,
           "decisions": core.decisions, **{k: float(info[k]) for k in SCORES if k in info}}
    if keep_maps:
        row.update(expected_map=core.expected_map, oracle_map=core.oracle_map,
                   extent=core.geometry.extent, true_path=core.true_path)
    env.close()
    return row


def _run(job) -> dict:
    return run_episode(*job)


def compare(worlds, seeds, policies, settings: ComparisonSettings = ComparisonSettings(), *,
            workers: int | None = None, progress: bool = True) -> list[dict]:
    """Every policy on every (world, seed), in ``workers`` processes; rows sorted by world, seed, policy."""
    jobs = [(str(w), int(s), p, settings) for w in worlds for s in seeds for p in policies]
    rows = run_in_processes(_run, jobs, workers=workers, desc="episodes", progress=progress)
    order = {p: i for i, p in enumerate(policies)}
    return sorted(rows, key=lambda r: (r["world"], r["seed"], order[r["policy"]]))


def paired(rows: list[dict], column: str, policy: str, baseline: str) -> np.ndarray:
    """``policy``'s score minus ``baseline``'s on each (world, seed) where both ran."""
    by_key = {(r["world"], r["seed"], r["policy"]): r[column] for r in rows}
    return np.array([by_key[(w, s, policy)] - value for (w, s, p), value in by_key.items()
                     if p == baseline and (w, s, policy) in by_key], dtype=np.float64)


def markdown_table(rows: list[dict], policy: str, baseline: str, title: str) -> str:
    """Mean [95% interval] of each score per policy and of the paired difference ``policy - baseline``."""
    pairs = len(paired(rows, "coverage", policy, baseline))
    lines = [f"{title}: {pairs} pairs (world, seed); mean [95% interval]; differences paired.", "",
             f"| score | {baseline} | {policy} | {policy} - {baseline} | {policy} better |",
             "| --- | --- | --- | --- | --- |"]
    for column, label in SCORES.items():
        cells = []
        for name in (baseline, policy):
            m, lo, hi, n = measure_interval([r[column] for r in rows if r["policy"] == name], column)
            cells.append(f"{m:.3f} [{lo:.3f}, {hi:.3f}]")
        diff = paired(rows, column, policy, baseline)
        m, lo, hi, n = difference_interval(diff, column)
        better = int(np.sum(diff < 0)) if column == "ate" else int(np.sum(diff > 0))
        better_text = "" if column in ("decisions", "sim_steps") else f"{better}/{n}"
        lines.append(f"| {label} | {cells[0]} | {cells[1]} | {m:+.3f} [{lo:+.3f}, {hi:+.3f}] | {better_text} |")
    return "\n".join(lines)


def plot_pair(rows: list[dict], path) -> None:
    """The expected maps of one (world, seed)'s episodes side by side, with the oracle map and true paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [(f"oracle map of the {rows[0]['policy']} episode (its scans at the true poses)", rows[0]["oracle_map"],
               None)] + [
        (f"{r['policy']}: oracle acc. {r['oracle_accuracy']:.3f}, walls {r['wall_consistency']:.3f}, "
         f"ATE {r['ate']:.2f} m", r["expected_map"], r["true_path"]) for r in rows]
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 4.6))
    for ax, (title, grid, path_xy) in zip(axes, panels):
        ax.imshow(1.0 - grid, cmap="gray", origin="lower", extent=rows[0]["extent"], vmin=0, vmax=1)
        if path_xy is not None:
            ax.plot(path_xy[:, 0], path_xy[:, 1], color="tab:red", lw=0.6)
        ax.set_title(title, fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(f"{rows[0]['plan']}, seed {rows[0]['seed']}: the expected map at the end of each policy's episode",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
