"""Policies played on the same episodes and compared under the ground-truth scores: the one place that plays them.

``emmi-gym evaluate``, ``benchmark``, ``compare-policies`` and ``score-checkpoints`` play their episodes here. A
policy is a scripted one, by name (:func:`emmi_gym.tools.policies.make_policy`), or any object with a ``name`` and a
``make_actor()`` that returns what acts in :func:`~emmi_gym.tools.evaluation.episodes.play_episode` (a trained
agent: :class:`emmi_gym.tools.training.evaluate.TrainedAgent`, which knows how to load its model). The episodes are
(world, seed) pairs (:func:`episodes_on`; on a map set each plan can be played with several seeds); each gives one
episode per policy from the same start and the same random draws up to the first decision. A row holds the
episode's world, plan, seed and policy, its decisions and what
:func:`~emmi_gym.tools.evaluation.episodes.play_episode` measured: accuracy against the oracle map (1.0: SLAM
added no error), wall consistency, ATE, map accuracy against the floor plan, building accuracy (unmapped cells
counting as wrong), coverage, whether and when the coverage target was reached, the share of decisions that went
back to close a loop.

The tables count the plans as the units: a policy's mean over plans (each plan's mean over its seeds; Student's
t, clipped to the measure's range; Wilson for proportions), the paired difference with the interval of a paired
bootstrap that resamples plans with all their seeds
(:func:`~emmi_gym.tools.evaluation.intervals.plan_bootstrap`) and the smallest difference that protocol detects;
on one world, the episodes. The scores are those of the final ``info`` or, read at equal robot time
(:func:`~emmi_gym.tools.evaluation.robot_time.at_equal_robot_time`), of the trace, with the coverage and the
building accuracy beside them.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import gymnasium as gym
import numpy as np

from ...concurrency.parallel import run_in_processes
from ...formats.atomic_files import write_atomically, write_csv, write_text_atomically
from ...world.map_sets import map_set_files, world_name
from ..policies import make_policy
from .directions import better_side, count_better, format_number
from .episodes import PolicyActor, info_options, nanmean, play_episode, summarise
from .intervals import difference_interval, measure_interval, plan_bootstrap
from .loop_order import LOOP_ORDER_KEY, LoopOrderInfo
from .robot_time import TRACE, at_equal_robot_time, trace_rows, without_traces

#: What a row keeps of :func:`~emmi_gym.tools.evaluation.episodes.play_episode`'s besides its scores: the steps and
#: the trace, when asked; the episode's seed is the row's ``seed``.
_KEPT_APART = ("steps", TRACE, "episode_seed")
#: The scores compared, with their labels.
SCORES = {"oracle_accuracy": "accuracy against the oracle map", "wall_consistency": "wall consistency",
          "ate": "ATE (m)", "map_accuracy": "map accuracy (floor plan)", "coverage": "coverage",
          "building_accuracy": "building accuracy (unmapped counts as wrong)",
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
    ``seed``: its row (with ``keep_maps``, the expected map, the oracle map, the grid's extent and the true path;
    with ``keep_steps``, every step's reward components; with ``keep_trace``, the scores after every decision: see
    :func:`emmi_gym.tools.evaluation.episodes.play_episode`)."""
    env = settings.env_on(world, keep_steps, keep_trace)
    core = env.unwrapped
    scores = play_episode(env, make_actor(policy), seed, keep_steps=keep_steps, keep_trace=keep_trace)
    row = {"world": world_name(world), "plan": core.world.name, "seed": seed, "policy": policy_name(policy),
           "decisions": core.decisions, **{k: v for k, v in scores.items() if k not in _KEPT_APART}}
    row.update({kept: scores[kept] for kept in ("steps", TRACE) if kept in scores})
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


def episodes_on(world, episodes: int, first_seed: int, seeds_per_plan: int = 1) -> EpisodesOn:
    """The (world, seed) pairs of an evaluation on ``world``: on a map set (a shipped set, a folder, a glob),
    its first ``episodes`` maps, each with ``seeds_per_plan`` seeds from ``first_seed`` on (going round the set
    with the next seeds if it has fewer maps); on one world (a name, a file, ``None`` for a generated one, a
    family) ``episodes`` seeds from ``first_seed`` on, one episode each (``seeds_per_plan`` > 1 is a
    ``ValueError``: a world that is not a map set has no plans to repeat). A sequence that makes each pair when
    it is asked for (the list of a million would not be built)."""
    if isinstance(seeds_per_plan, bool) or not isinstance(seeds_per_plan, int) or seeds_per_plan < 1:
        raise ValueError(f"seeds per plan: expected an integer of at least 1, got {seeds_per_plan!r}")
    files = map_set_files(world) if isinstance(world, str) else None
    if files is None and seeds_per_plan > 1:
        raise ValueError(f"{seeds_per_plan} seeds per plan need a map set to draw the plans from, but the world "
                         f"{world!r} is not one (its episodes each have a world of their own, or all the same one): "
                         "give a map set, or one seed per plan")
    if files is None:
        return EpisodesOn(world, False, episodes, first_seed)
    return EpisodesOn(tuple(str(f) for f in files), True, episodes * seeds_per_plan, first_seed, seeds_per_plan)


@dataclass(frozen=True)
class EpisodesOn(Sequence):
    """The (world, seed) pairs of :func:`episodes_on`, made when asked for: on one world (``worlds`` is it,
    ``is_set`` false) the seeds from ``first_seed`` on; on a map set (``worlds`` its files) its maps in turn, each
    with the ``seeds_per_plan`` seeds from ``first_seed`` on, the seeds going up by ``seeds_per_plan`` each round
    of the set."""

    worlds: object
    is_set: bool
    length: int
    first_seed: int
    seeds_per_plan: int = 1

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
        plan, repeat = divmod(k, self.seeds_per_plan)
        rounds, map_index = divmod(plan, len(self.worlds))
        return self.worlds[map_index], self.first_seed + rounds * self.seeds_per_plan + repeat



def plan_of(row: dict) -> str:
    """The plan a row's episode played (its world where the row does not say)."""
    return str(row.get("plan", row.get("world")))


def paired(rows: list[dict], column: str, policy: str, baseline: str) -> np.ndarray:
    """``policy``'s score minus ``baseline``'s on each (world, seed) where both ran."""
    return paired_by_plan(rows, column, policy, baseline)[0]


def paired_by_plan(rows: list[dict], column: str, policy: str, baseline: str) -> tuple[np.ndarray, list[str]]:
    """``policy``'s score minus ``baseline``'s on each (world, seed) where both ran, and the plan of each pair."""
    by_key = {(r["world"], r["seed"], r["policy"]): r for r in rows}
    pairs = [(mine, theirs) for (w, s, p), theirs in by_key.items()
             if p == baseline and (mine := by_key.get((w, s, policy))) is not None]
    return (np.array([mine.get(column, np.nan) - theirs.get(column, np.nan) for mine, theirs in pairs],
                     dtype=np.float64), [plan_of(mine) for mine, _ in pairs])


def plan_means(rows: list[dict], column: str) -> list[float]:
    """The mean of ``column`` over each plan's episodes among ``rows`` (on one world: each episode's value)."""
    plans = [plan_of(r) for r in rows]
    if len(set(plans)) < 2:
        return [r.get(column, np.nan) for r in rows]
    return [nanmean([r.get(column, np.nan) for r, p in zip(rows, plans, strict=True) if p == plan])
            for plan in dict.fromkeys(plans)]


def markdown_table(rows: list[dict], policy: str, baseline: str, title: str) -> str:
    """Mean [95% interval] of each score per policy (over plans) and of the paired difference ``policy -
    baseline`` (a paired bootstrap over plans), the smallest difference the protocol detects, which side of the
    score is better, and on how many pairs ``policy`` did better (the scores that no row has are left out)."""
    differences, plans = paired_by_plan(rows, "coverage", policy, baseline)
    units = len(set(plans)) if len(set(plans)) > 1 else len(plans)
    lines = [f"{title}: {len(differences)} pairs (world, seed) on {units} "
             f"{'plans' if len(set(plans)) > 1 else 'episodes'}; mean [95% interval] over plans (each plan's "
             "mean over its seeds; on one world, over episodes); "
             "differences paired, their interval a paired bootstrap that resamples plans with all their seeds; "
             "'detectable': the smallest difference this protocol finds with 80% power (2.8 bootstrap standard "
             f"errors); '{policy} better': on how many pairs {policy}'s score was on the better side of "
             f"{baseline}'s, ties (equal scores) counted apart ('-': no better side).", "",
             f"| score | better | {baseline} | {policy} | {policy} - {baseline} | detectable | {policy} better |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for column, label in SCORES.items():
        if not any(np.isfinite(r.get(column, np.nan)) for r in rows):
            continue
        cells = []
        for name in (baseline, policy):
            m, lo, hi, n = measure_interval(plan_means([r for r in rows if r["policy"] == name], column), column)
            cells.append(f"{format_number(m, column)} [{format_number(lo, column)}, {format_number(hi, column)}]")
        diff, plans = paired_by_plan(rows, column, policy, baseline)
        estimate = plan_bootstrap(diff, plans, column)
        better = count_better(diff, column)
        count = "-" if better is None else str(better)
        lines.append(f"| {label} | {better_side(column)} | {cells[0]} | {cells[1]} | "
                     f"{signed_interval(estimate.mean, estimate.low, estimate.high, column)} | "
                     f"{format_number(estimate.detectable, column)} | {count} |")
    return "\n".join(lines)


def signed_interval(mean: float, low: float, high: float, column: str) -> str:
    """A difference and its interval, signed: ``+0.012 [-0.002, +0.026]`` (``-`` where there is none)."""
    if not np.isfinite(mean):
        return "-"
    return f"{format_number(mean, column, signed=True)} [" + ", ".join(
        format_number(v, column, signed=True) for v in (low, high)) + "]"


def difference_cell(differences, column: str) -> str:
    """The mean of paired ``differences`` of ``column`` and its 95% t-interval (the differences taken as
    independent), signed: ``+0.012 [-0.002, +0.026]``."""
    return signed_interval(*difference_interval(differences, column)[:3], column)


def format_table(rows: list[dict], columns=None) -> str:
    """A fixed-width text table of episode rows, numbers as every summary writes them (counts without
    decimals, NaN as '-'), and a line naming which side of each measure shown is better."""
    columns = columns or list(rows[0])

    def text(value, column: str) -> str:
        return format_number(value, column) if isinstance(value, float) else str(value)

    cells = [[text(row.get(c, float("nan")), c) for c in columns] for row in rows]
    widths = [max(len(c), 9, *(len(line[k]) for line in cells)) for k, c in enumerate(columns)]
    lines = [" ".join(c.rjust(w) for c, w in zip(columns, widths, strict=False))]
    lines += [" ".join(t.rjust(w) for t, w in zip(line, widths, strict=False)) for line in cells]
    sides = {side: [c for c in columns if better_side(c) == side] for side in ("higher", "lower")}
    if any(sides.values()):
        lines.append("better: " + "; ".join(f"{side} {', '.join(names)}" for side, names in sides.items() if names))
    return "\n".join(lines)


def evaluation_tables(rows: list[dict], name: str, baselines) -> list[str]:
    """The tables of an evaluation of the policy ``name`` beside the ``baselines`` (names) on the same episodes
    (rows with traces): for each baseline, the final maps (with the robot time they took), then for each, the
    maps read at equal robot time (with the coverage and the building accuracy, which count what is not mapped
    yet)."""
    tables = [markdown_table(rows, name, baseline, f"{name} - {baseline}") for baseline in baselines]
    tables += [markdown_table(at_equal_robot_time(rows, name, baseline), name, baseline,
                              f"{name} - {baseline} at equal robot time (each pair read at the robot time the "
                              f"shorter episode took, the longer one's scores linear between its decisions; the "
                              f"oracle accuracy and the ATE judge only what has been mapped, the coverage and the "
                              f"building accuracy count what has not)")
               for baseline in baselines]
    return tables


def write_evaluation(rows: list[dict], means: list[dict], tables: list[str], policy, baselines,
                     settings: ComparisonSettings, out) -> list[Path]:
    """An evaluation's files in the folder ``out``: ``episodes.csv`` (a row per episode), ``traces.csv`` (the
    scores after every decision), ``summary.md`` (the ``means`` and the ``tables``) and the figures of
    :func:`write_figures`; the paths written."""
    out = Path(out)
    files = [out / "episodes.csv", out / "traces.csv", out / "summary.md"]
    write_csv(files[0], without_traces(rows))
    write_csv(files[1], trace_rows(rows))
    write_text_atomically(files[2], "\n\n".join([format_table(means), *tables]) + "\n")
    return files + write_figures(rows, policy, baselines, settings, out)


def write_figures(rows: list[dict], policy, baselines, settings: ComparisonSettings, out) -> list[Path]:
    """``front.png`` (map quality against robot time, a point per policy) and, beside a baseline, ``maps.png``: the
    episode where ``policy``'s accuracy against the oracle map differs most from the first baseline's (among those
    where it went back, if any), played again in ``settings``, both maps with where it went back."""
    out = Path(out)
    plot_front(rows, out / "front.png")
    written = [out / "front.png"]
    if baselines:
        name = policy_name(policy)
        mine = {(r["world"], r["seed"]): r for r in rows if r["policy"] == name}
        theirs = {(r["world"], r["seed"]): r for r in rows if r["policy"] == policy_name(baselines[0])}
        gaps = {key: mine[key]["oracle_accuracy"] - theirs[key]["oracle_accuracy"] for key in mine.keys() & theirs}
        went_back = [key for key in gaps if mine[key].get("revisit_share", 0) > 0] or list(gaps)
        world, seed = max(sorted(went_back), key=lambda key: abs(gaps[key]))
        world = None if world == "None" else world  # rows name a generated world "None"
        episodes = [play_on_world(world, seed, played, settings, keep_maps=True, keep_steps=True)
                    for played in (policy, baselines[0])]
        plot_pair(episodes, out / "maps.png")
        written.append(out / "maps.png")
    return written


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
