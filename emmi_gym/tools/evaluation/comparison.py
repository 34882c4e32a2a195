"""Policies compared on many worlds, paired by world and seed, under the ground-truth scores.

A policy is a scripted one, by name (:func:`emmi_gym.tools.policies.make_policy`), or any object with a
``name`` and a ``make_actor()`` that returns what acts in
:func:`~emmi_gym.tools.evaluation.episodes.play_episode` (a trained agent:
:class:`emmi_gym.tools.training.evaluate.TrainedAgent`). Each (world, seed) gives one
episode per policy from the same start and the same random draws up to the first decision; the
table reports each policy's mean and the paired difference with its 95% interval (Student's t,
clipped to the measure's range; Wilson for proportions), the scores being the final ``info`` of
the episode: accuracy against the oracle map (1.0: SLAM added no error), wall consistency, ATE,
map accuracy against the floor plan, coverage, whether and when the coverage target was
reached, and the share of decisions that went back to close a loop.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import partial

import gymnasium as gym
import numpy as np

from ...concurrency.parallel import run_in_processes
from ...formats.atomic_files import write_atomically
from ...world.map_sets import map_set_files, world_name
from ..policies import make_policy
from .directions import better_side, count_better, format_number
from .episodes import PolicyActor, info_options, play_episode, summarise
from .intervals import difference_interval, measure_interval
from .loop_order import LOOP_ORDER_KEY, LoopOrderInfo
from .robot_time import TRACE

#: The scores compared, with their labels.
SCORES = {"oracle_accuracy": "accuracy against the oracle map", "wall_consistency": "wall consistency",
          "ate": "ATE (m)", "map_accuracy": "map accuracy (floor plan)", "coverage": "coverage",
          "reached_target": "coverage target reached", "sim_steps_to_target": "simulator steps to the target",
          "revisit_share": "revisit share", LOOP_ORDER_KEY: "closed the loop first",
          "decisions": "decisions", "sim_steps": "simulator steps"}


@dataclass(frozen=True)
class ComparisonSettings:
    """The environment every episode runs in (``world`` is set per episode)."""

    env_id: str = "emmi_gym/ExplorePlans-v1"
    env_options: dict = field(default_factory=dict)

    def env_on(self, world, keep_steps: bool = False, keep_trace: bool = False) -> gym.Env:
        """The comparison's env with ``world``, reporting each episode's loop order (and with ``keep_steps`` and
        ``keep_trace`` what :func:`~emmi_gym.tools.evaluation.episodes.play_episode` keeps of each step)."""
        options = dict(self.env_options, world=world, **info_options(keep_steps, keep_trace))
        return LoopOrderInfo(gym.make(self.env_id, **options))


def policy_name(policy) -> str:
    """The name a policy's rows carry: a scripted policy's own, another policy's ``name``."""
    return policy if isinstance(policy, str) else policy.name


def make_actor(policy):
    """What acts in :func:`~emmi_gym.tools.evaluation.episodes.play_episode`: a fresh scripted policy, or what
    ``policy.make_actor()`` gives."""
    return PolicyActor(make_policy(policy)) if isinstance(policy, str) else policy.make_actor()


def play_on_world(world, seed: int, policy, settings: ComparisonSettings = ComparisonSettings(),
                  keep_maps: bool = False, keep_steps: bool = False, keep_trace: bool = False) -> dict:
    """One episode of ``policy`` (a scripted policy's name or an object with ``make_actor()``) on ``world`` with
    ``seed``: its final scores (with ``keep_maps``, the expected map, the oracle map and the grid's
    extent; with ``keep_steps``, every step's reward components; with ``keep_trace``, the scores after
    every decision: see :func:`emmi_gym.tools.evaluation.episodes.play_episode`)."""
    env = settings.env_on(world, keep_steps, keep_trace)
    core = env.unwrapped
    scores = play_episode(env, make_actor(policy), seed, keep_steps=keep_steps, keep_trace=keep_trace)
    row = {"world": world_name(world), "plan": core.world.name, "seed": seed, "policy": policy_name(policy),
           "decisions": core.decisions, "return": scores["return"], **{k: scores[k] for k in SCORES if k in scores}}
    for kept in ("steps", TRACE):
        if kept in scores:
            row[kept] = scores[kept]
    if keep_maps:
        row.update(expected_map=core.expected_map, oracle_map=core.oracle_map,
                   extent=core.geometry.extent, true_path=core.true_path)
    env.close()
    return row


def _run(job) -> dict:
    world, seed, policy, settings, keep_steps, keep_trace = job
    return play_on_world(world, seed, policy, settings, keep_steps=keep_steps, keep_trace=keep_trace)


def compare(worlds, seeds, policies, settings: ComparisonSettings = ComparisonSettings(), *,
            workers: int | None = None, progress: bool = True) -> list[dict]:
    """Every policy on every (world, seed), in ``workers`` processes; rows sorted by world, seed, policy."""
    return compare_on([(w, s) for w in worlds for s in seeds], policies, settings, workers=workers,
                      progress=progress)


def compare_on(episodes, policies, settings: ComparisonSettings = ComparisonSettings(), *,
               workers: int | None = None, progress: bool = True, keep_steps: bool = False,
               keep_trace: bool = False, start_method: str | None = None) -> list[dict]:
    """Every policy on each ``(world, seed)`` of ``episodes``, in ``workers`` processes (started by
    ``start_method``: "spawn" where a policy uses torch); rows sorted by world, seed, policy (with
    ``keep_steps`` and ``keep_trace``, each row's ``steps`` and ``trace``: see :func:`play_on_world`)."""
    jobs = ((w if w is None else str(w), int(s), p, settings, keep_steps, keep_trace)
            for w, s in episodes for p in policies)
    rows = run_in_processes(_run, jobs, total=len(episodes) * len(policies), workers=workers, desc="episodes",
                            progress=progress, start_method=start_method)
    order = {policy_name(p): i for i, p in enumerate(policies)}
    return sorted(rows, key=lambda r: (r["world"], r["seed"], order[r["policy"]]))


def worlds_of(names, plans: int) -> list[str]:
    """The worlds ``names`` stand for: the first ``plans`` maps of each map set (a shipped set, a folder,
    a glob), a world (a name, a file) as it is."""
    worlds = []
    for name in names:
        files = map_set_files(name)
        worlds += [str(f) for f in files[:plans]] if files is not None else [name]
    return worlds


def policy_means(rows: list[dict]) -> list[dict]:
    """Each policy's mean of every numeric score over its episodes, in the rows' order of policies."""
    policies = list(dict.fromkeys(r["policy"] for r in rows))
    return [{"policy": p, **summarise([{k: v for k, v in r.items() if isinstance(v, float)}
                                       for r in rows if r["policy"] == p])} for p in policies]


def episodes_on(world, episodes: int, first_seed: int) -> EpisodesOn:
    """``episodes`` (world, seed) pairs on ``world``: the first maps of a map set (a shipped set, a folder,
    a glob), each with ``first_seed``, going round the set with the next seeds if it has fewer maps;
    one world (a name, a file, ``None`` for a generated one) with the seeds from ``first_seed`` on.
    A sequence that makes each pair when it is asked for (the list of a million would not be built)."""
    files = map_set_files(world) if isinstance(world, str) else None
    return EpisodesOn(world if files is None else tuple(str(f) for f in files), files is not None, episodes, first_seed)


@dataclass(frozen=True)
class EpisodesOn(Sequence):
    """The (world, seed) pairs of :func:`episodes_on`, made when asked for: on one world (``worlds`` is it,
    ``is_set`` false) the seeds from ``first_seed`` on; on a map set (``worlds`` its files) its maps in turn,
    the seed going up by one each round."""

    worlds: object
    is_set: bool
    length: int
    first_seed: int

    def __len__(self) -> int:
        return self.length

    def __getitem__(self, k):
        if isinstance(k, slice):
            return [self[i] for i in range(*k.indices(self.length))]
        if not -self.length <= k < self.length:
            raise IndexError(k)
        k %= self.length
        if not self.is_set:
            return self.worlds, self.first_seed + k
        return self.worlds[k % len(self.worlds)], self.first_seed + k // len(self.worlds)


def paired(rows: list[dict], column: str, policy: str, baseline: str) -> np.ndarray:
    """``policy``'s score minus ``baseline``'s on each (world, seed) where both ran."""
    by_key = {(r["world"], r["seed"], r["policy"]): r.get(column, np.nan) for r in rows}
    return np.array([by_key[(w, s, policy)] - value for (w, s, p), value in by_key.items()
                     if p == baseline and (w, s, policy) in by_key], dtype=np.float64)


def markdown_table(rows: list[dict], policy: str, baseline: str, title: str) -> str:
    """Mean [95% interval] of each score per policy and of the paired difference ``policy - baseline``, which
    side of the score is better, and on how many pairs ``policy`` did better (the scores that no row has are
    left out)."""
    pairs = len(paired(rows, "coverage", policy, baseline))
    lines = [f"{title}: {pairs} pairs (world, seed); mean [95% interval]; differences paired; '{policy} better': "
             f"on how many pairs {policy}'s score was on the better side of {baseline}'s, ties (equal scores) counted "
             "apart ('-': no better side).", "",
             f"| score | better | {baseline} | {policy} | {policy} - {baseline} | {policy} better |",
             "| --- | --- | --- | --- | --- | --- |"]
    for column, label in SCORES.items():
        if not any(np.isfinite(r.get(column, np.nan)) for r in rows):
            continue
        cells = []
        for name in (baseline, policy):
            m, lo, hi, n = measure_interval([r.get(column, np.nan) for r in rows if r["policy"] == name], column)
            cells.append(f"{format_number(m, column)} [{format_number(lo, column)}, {format_number(hi, column)}]")
        diff = paired(rows, column, policy, baseline)
        better = count_better(diff, column)
        count = "-" if better is None else str(better)
        lines.append(f"| {label} | {better_side(column)} | {cells[0]} | {cells[1]} | "
                     f"{difference_cell(diff, column)} | {count} |")
    return "\n".join(lines)


def difference_cell(differences, column: str) -> str:
    """The mean of paired ``differences`` of ``column`` and its 95% interval, signed: ``+0.012 [-0.002, +0.026]``."""
    m, lo, hi, _ = difference_interval(differences, column)
    return f"{format_number(m, column, signed=True)} [" + ", ".join(
        format_number(v, column, signed=True) for v in (lo, hi)) + "]"


def plot_pair(rows: list[dict], path, columns: int | None = None) -> None:
    """The expected maps of one (world, seed)'s episodes side by side (``columns`` panels a row; default all
    in one), with the oracle map and true paths; where a row kept its steps, the revisit targets it chose
    are marked (where it went back)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [(f"oracle map of the {rows[0]['policy']} episode (its scans at the true poses)", rows[0]["oracle_map"],
               None, [])] + [
        (f"{r['policy']}: oracle acc. {r['oracle_accuracy']:.3f}, walls {r['wall_consistency']:.3f}, "
         f"ATE {r['ate']:.2f} m", r["expected_map"], r["true_path"],
         [s["target_xy"] for s in r.get("steps", []) if s["target_kind"] == "revisit"]) for r in rows]
    columns = min(columns or len(panels), len(panels))
    lines = -(-len(panels) // columns)
    xmin, xmax, ymin, ymax = rows[0]["extent"]
    height = 5.5 * (ymax - ymin) / (xmax - xmin) + 0.6  # the map's aspect, and the panel's title
    fig, axes = plt.subplots(lines, columns, figsize=(5.5 * columns, height * lines + 0.4), squeeze=False)
    for ax in axes.flat[len(panels):]:
        ax.set_axis_off()
    for ax, (title, grid, path_xy, revisits) in zip(axes.flat, panels, strict=False):
        ax.imshow(1.0 - grid, cmap="gray", origin="lower", extent=rows[0]["extent"], vmin=0, vmax=1)
        if path_xy is not None:
            ax.plot(path_xy[:, 0], path_xy[:, 1], color="tab:red", lw=0.6)
        if revisits:
            xy = np.array(revisits)
            ax.scatter(xy[:, 0], xy[:, 1], marker="x", s=60, color="tab:orange", lw=2,
                       label=f"went back ({len(revisits)} revisit targets)", zorder=3)
            ax.legend(loc="lower right", fontsize=7)
        ax.set_title(title, fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(f"{rows[0]['plan']}, seed {rows[0]['seed']}: the expected map at the end of each policy's episode",
                 fontsize=9)
    fig.tight_layout()
    write_atomically(path, partial(fig.savefig, dpi=110))
    plt.close(fig)


def plot_front(rows: list[dict], path, qualities=("oracle_accuracy", "ate"), time: str = "sim_steps") -> None:
    """Map quality against robot time, one point per policy (its mean, with 95% intervals on both axes):
    which policy maps better for the time it takes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    policies = list(dict.fromkeys(r["policy"] for r in rows))
    fig, axes = plt.subplots(1, len(qualities), figsize=(5.2 * len(qualities), 4.2))
    for ax, quality in zip(np.atleast_1d(axes), qualities, strict=False):
        for policy in policies:
            mine = [r for r in rows if r["policy"] == policy]
            t_mean, t_low, t_high, _ = measure_interval([r[time] for r in mine], time)
            q_mean, q_low, q_high, _ = measure_interval([r[quality] for r in mine], quality)
            ax.errorbar(t_mean, q_mean, xerr=[[t_mean - t_low], [t_high - t_mean]],
                        yerr=[[q_mean - q_low], [q_high - q_mean]], fmt="o", capsize=3, label=policy)
        ax.set_xlabel(f"robot time: {SCORES.get(time, time)}")
        ax.set_ylabel(f"{SCORES.get(quality, quality)} ({better_side(quality)} is better)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"map quality against robot time, {len(rows) // max(len(policies), 1)} episodes per policy "
                 f"(mean, 95% intervals)", fontsize=9)
    fig.tight_layout()
    write_atomically(path, partial(fig.savefig, dpi=110))
    plt.close(fig)
