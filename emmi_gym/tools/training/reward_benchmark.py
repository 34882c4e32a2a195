"""The reward benchmark: for each reward variant, train an agent per seed, then evaluate every agent
and the baselines (scripted policies, shipped agents) on the *same* held-out episodes under the *same*
ground-truth metrics, final and at equal robot time (:mod:`emmi_gym.tools.evaluation.robot_time`), played by
:mod:`emmi_gym.tools.evaluation.comparison` (on a map set its first plans, each with one or several seeds).

Runs are independent jobs: by default they go to local worker processes; with a Ray address
(or "local" for a fresh local Ray instance) they go to a Ray cluster instead. Ray is an
optional extra, imported only on that path. A run folder that already holds the finished
model of the same configuration is evaluated, not trained again; one that holds an unfinished run
of it (a benchmark interrupted) is resumed; one that holds anything else is refused before any
job starts. Every job keeps its evaluation episodes in ``--out``'s ``played/`` as they are played
(:mod:`~emmi_gym.tools.evaluation.played_episodes`): a benchmark run again into the folder, interrupted or with more
agents beside the same baselines, plays only the episodes that are not kept there yet (on a Ray cluster of several
machines, those of the jobs that ran on this one).
"""

from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

import numpy as np

from ...concurrency.interrupts import Interrupted
from ...concurrency.parallel import run_in_processes
from ...concurrency.progress import progress_bar
from ...concurrency.ray_cluster import connect_ray
from ...formats.atomic_files import write_atomically, write_csv, write_text_atomically
from ..evaluation.comparison import plan_means, plan_of, play_on_world, policy_name
from ..evaluation.directions import better_side, format_number
from ..evaluation.episodes import nanmean
from ..evaluation.intervals import PairedDifference, measure_interval, plan_bootstrap
from ..evaluation.loop_order import LOOP_ORDER_KEY
from ..evaluation.played_episodes import PlayedEpisodes
from ..evaluation.robot_time import TRACE, read_together, trace_rows, without_traces
from .config import AgentConfig
from .evaluate import EVALUATION_SEED, TrainedAgent, run_episodes
from .run_folders import RunError, RunFolder, RunStart
from .train import set_torch_threads, train

#: The folder of a benchmark's ``--out`` where each job's evaluation episodes are kept as they are played.
PLAYED = "played"
#: Ground-truth columns of the benchmark table, with their labels.
TABLE_COLUMNS = {
    "map_accuracy": "map accuracy",
    "oracle_accuracy": "accuracy against the oracle map",
    "wall_consistency": "wall consistency",
    "ate": "ATE (m)",
    "coverage": "coverage",
    "building_accuracy": "building accuracy (unmapped counts as wrong)",
    "reached_target": "reached the coverage target",
    "sim_steps_to_target": "simulator steps to the target",
    "revisit_share": "decisions that went back to a revisit target",
    LOOP_ORDER_KEY: "closed the loop before the new area",
    "sim_steps": "robot time (simulator steps)",
}


@dataclass(frozen=True)
class Job:
    """One benchmark run: train ``config`` with reward ``variant`` (kind "agent"; from the weights of
    the model ``init_from``, if given, with ``allow_no_training`` as ``train``'s), or play the baseline
    ``policy`` named ``variant`` (kind "baseline": a scripted policy's name, or a
    :class:`~emmi_gym.tools.training.evaluate.TrainedAgent` such as a shipped agent); then evaluate on the
    held-out episodes of :func:`~emmi_gym.tools.training.evaluate.run_episodes` (``episodes`` plans of a
    map set, each with ``seeds_per_plan`` seeds from ``episode_seed``; none: trained only), keeping each
    episode's trace for the comparison at equal robot time; ``played``: the folder where its episodes are kept as
    they are played (:mod:`~emmi_gym.tools.evaluation.played_episodes`; None: kept nowhere)."""

    kind: str
    variant: str
    seed: int
    config: AgentConfig
    run_dir: Path
    episodes: int
    episode_seed: int
    init_from: Path | None = None
    allow_no_training: bool = False
    policy: object = None
    seeds_per_plan: int = 1
    played: Path | None = None


def run_job(job: Job) -> dict:
    """Do one job (in whatever process runs it); its episode rows, learning curve and wall time."""
    set_torch_threads(1)  # the jobs are the parallelism
    started = time.perf_counter()
    curve = []
    if job.kind == "agent":
        folder = RunFolder(job.run_dir)
        model_path = folder.model_path
        state = run_state(job)
        trained = state != "finished"
        if trained:
            resume = state == "unfinished"
            result = train(job.config, job.run_dir, resume=resume, progress=False,
                           init_from=None if resume else job.init_from, allow_no_training=job.allow_no_training)
            if result.interrupted:  # its checkpoint is kept for the next run of the benchmark, never evaluated
                raise KeyboardInterrupt
            model_path = result.model_path
        rows = evaluation_rows(job, TrainedAgent(str(model_path), job.variant))
        evaluations = folder.ground_truth_path
        if evaluations.exists():  # none when training stopped before the first periodic evaluation
            with open(evaluations) as f:
                curve = [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]
    else:
        trained = False
        rows = evaluation_rows(job, job.policy)
    return {"job": job, "rows": rows, "curve": curve, "trained": trained, "wall_seconds": time.perf_counter() - started,
            "kept_episodes": sum(row.pop("kept") for row in rows)}


def evaluation_rows(job: Job, policy) -> list[dict]:
    """The job's evaluation episodes of ``policy`` (a scripted policy's name or a trained agent), played one after
    the other (the jobs are the parallelism) with their traces: rows of
    :func:`~emmi_gym.tools.evaluation.comparison.play_on_world` whose ``seed`` is the job's (the agent's training
    seed; 0 for a baseline) and ``episode_seed`` the episode's, with the job's ``kind`` and ``variant``, and
    ``kept``: whether the row was kept by an earlier run in the job's ``played`` folder (then not played again; a
    policy object without ``identity()``, which says what it plays, is played every time)."""
    settings, episodes = run_episodes(job.config, episodes=job.episodes, seed=job.episode_seed,
                                      seeds_per_plan=job.seeds_per_plan)
    keepable = job.played is not None and (isinstance(policy, str) or hasattr(policy, "identity"))
    played = PlayedEpisodes.in_folder(job.played, job.run_dir.name, settings, policy) if keepable else None
    rows = []
    for world, seed in episodes:
        row = None if played is None else played.get(world, seed)
        kept = row is not None
        if not kept:
            row = play_on_world(world, seed, policy, settings, keep_trace=True)
            del row["policy"]
            if played is not None:
                played.add(row)
        rows.append({**row, "episode_seed": row["seed"], "kind": job.kind, "variant": job.variant, "seed": job.seed,
                     "kept": kept})
    return rows


def run_state(job: Job) -> str:
    """What the agent job's run folder holds: ``"new"`` (nothing), ``"finished"`` (the finished model of the
    same configuration, started from the same model: a benchmark run again into the same folder evaluates
    it instead of training again), ``"unfinished"`` (a run of them that stopped before its end, or that
    finished a smaller budget: resumed, to the budget asked; a run continued by ``train --resume`` with what a
    resumed run may change, such as rollout workers on a larger machine, is still theirs), ``"larger"`` (a run
    of them to a larger budget than asked: never cut back, nor reported under the smaller) or ``"other"``
    (anything else); the last two are refused by :func:`run_benchmark` before any job starts."""
    folder = RunFolder(job.run_dir)
    if not folder.entries():
        return "new"
    started_from = (folder.record() or {}).get("init_from")
    same = folder.config_path.is_file() and started_from == (None if job.init_from is None else str(job.init_from)) \
        and not folder.differences(job.config)
    if not same:
        return "other"
    budget = folder.config().total_timesteps
    if budget > job.config.total_timesteps:
        return "larger"
    # the budget and the model must both be this job's: a run extended to a larger budget and stopped before
    # its end holds the new budget beside the model of the old one
    finished = budget == job.config.total_timesteps and (folder.finished_decisions() or 0) >= job.config.total_timesteps
    return "finished" if finished else "unfinished"


def make_jobs(config: AgentConfig, rewards, seeds, timesteps: int, episodes: int, baselines, out_dir,
              init_from=None, allow_no_training: bool = False, eval_seed: int = EVALUATION_SEED,
              rollout_workers: bool = False, train_only: bool = False, seeds_per_plan: int = 1) -> list[Job]:
    """The agents (one per reward and seed, trained with ``dummy`` vectorisation: the jobs run in
    parallel already; with ``rollout_workers``, each agent's envs in rollout workers instead, one process
    per env, for a machine with more cores than agents; policy lag 0 either way; each from the weights of the
    model ``init_from``, if given, as ``train --init-from``) and one job per baseline (a scripted policy's
    name, or a trained agent: :class:`~emmi_gym.tools.training.evaluate.TrainedAgent`, checked to act in
    the benchmark's evaluation env); every job is evaluated on the same held-out episodes: on a map set its
    first ``episodes`` plans, each with ``seeds_per_plan`` seeds from ``eval_seed`` on (elsewhere ``episodes``
    seeds; :func:`~emmi_gym.tools.training.evaluate.run_episodes`). With ``train_only``, the agents alone,
    evaluated on none: a sitting of a budget spread over several, the last of which evaluates every agent and
    baseline once."""
    from ..policies import POLICY_NAMES

    out = Path(out_dir)
    names = [policy_name(baseline) for baseline in baselines]
    for option, given in (("--rewards", rewards), ("--seeds", seeds), ("--baselines", names)):
        twice = sorted({str(name) for name in given if list(given).count(name) > 1})
        if twice:
            raise ValueError(f"{option}: {', '.join(twice)} given more than once (each would train or play into "
                             "the same folder at once)")
    scripted = [baseline for baseline in baselines if isinstance(baseline, str)]
    unknown = sorted(set(scripted) - set(POLICY_NAMES))
    if unknown:
        raise ValueError(f"--baselines: unknown {unknown}; choose from {list(POLICY_NAMES)}")
    if scripted and _action_mode(config) != "waypoint":
        raise ValueError(f"the scripted baselines {scripted} choose waypoint targets, but {config.env_id} "
                         f"acts in {_action_mode(config)} mode: pass --baselines with no names")
    for baseline in baselines:
        if not isinstance(baseline, str):
            baseline.check_plays_in(config, "--baselines")
    try:
        run_episodes(config, episodes=episodes, seed=eval_seed, seeds_per_plan=seeds_per_plan)
    except ValueError as error:
        raise ValueError(f"--seeds-per-plan: {error} ({config.source}'s evaluation env)") from None
    jobs = []
    for reward in rewards:
        for seed in seeds:
            agent = replace(config, env_kwargs=dict(config.env_kwargs, reward=reward), seed=int(seed),
                            total_timesteps=int(timesteps), vec_env="workers" if rollout_workers else "dummy",
                            policy_lag=0)
            jobs.append(Job("agent", reward, int(seed), agent, out / "runs" / f"{reward}_seed{seed}",
                            0 if train_only else episodes, eval_seed, init_from, allow_no_training,
                            seeds_per_plan=seeds_per_plan, played=out / PLAYED))
    if train_only:
        return jobs
    for name, baseline in zip(names, baselines, strict=True):
        jobs.append(Job("baseline", name, 0, config, out / "runs" / name, episodes, eval_seed, policy=baseline,
                        seeds_per_plan=seeds_per_plan, played=out / PLAYED))
    return jobs


def _action_mode(config: AgentConfig) -> str:
    import gymnasium as gym

    import emmi_gym  # noqa: F401  (registers the ids)

    return dict(gym.spec(config.env_id).kwargs, **config.env_kwargs).get("action_mode", "waypoint")


def _ray(jobs: list[Job], address: str, progress: bool) -> list[dict]:
    ray, started_here = connect_ray(address)
    try:
        remote = ray.remote(num_cpus=1)(run_job)
        pending = [remote.remote(job) for job in jobs]
        results = []
        with progress_bar(total=len(jobs), desc="benchmark runs (Ray)", unit="run", disable=not progress) as bar:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                results.extend(ray.get(done))
                bar.update(len(done))
        return results
    finally:
        if started_here:
            ray.shutdown()


def run_benchmark(config: AgentConfig, rewards, seeds, timesteps: int, episodes: int, baselines, out_dir, *,
                  workers: int | None = None, ray_address: str | None = None, progress: bool = True,
                  init_from=None, allow_no_training: bool = False, eval_seed: int = EVALUATION_SEED,
                  rollout_workers: bool = False, train_only: bool = False, seeds_per_plan: int = 1,
                  report=None) -> list[dict]:
    """Every job of :func:`make_jobs`, locally or on Ray; results sorted by kind, variant and seed.
    ``init_from`` (a model every agent starts from, as ``train``'s) and the run folders (:func:`run_state`)
    are checked before any job starts; ``rollout_workers``: each agent's envs in rollout workers;
    ``train_only``: the agents trained, nothing evaluated; ``seeds_per_plan``: the seeds each plan is played with
    (:func:`make_jobs`); ``report``: called with a
    sentence saying where the agents start and how many decisions each will train."""
    init_from = None if init_from is None else Path(init_from)
    jobs = make_jobs(config, rewards, seeds, timesteps, episodes, baselines, out_dir, init_from, allow_no_training,
                     eval_seed, rollout_workers, train_only, seeds_per_plan)
    agents = [job for job in jobs if job.kind == "agent"]
    if init_from is not None and agents:
        start = RunFolder.check_init_from(init_from, agents[0].config, allow_no_training)
        if report is not None:
            report(f"every agent: {RunStart(start.path, start.path).summary(start.decisions, timesteps)}")
    states = {job.run_dir: run_state(job) for job in agents}
    taken = [str(folder) for folder, state in states.items() if state == "other"]
    if taken:
        raise RunError(f"{', '.join(taken[:4])}{' ...' if len(taken) > 4 else ''}: not empty, and not a run of this "
                       "benchmark's configuration (reward, seed, budget, --init-from): remove it or give another "
                       "--out")
    larger = [str(folder) for folder, state in states.items() if state == "larger"]
    if larger:
        raise RunError(f"{', '.join(larger[:4])}{' ...' if len(larger) > 4 else ''}: a run of this benchmark to "
                       f"a larger budget than --timesteps {timesteps} (its config.yaml's total_timesteps): give that "
                       "budget or more, or another --out")
    try:
        if ray_address is not None:
            results = _ray(jobs, ray_address, progress)
        else:
            results = run_in_processes(run_job, jobs, workers=workers, desc="benchmark runs", progress=progress,
                                       start_method="spawn")
    except KeyboardInterrupt:
        raise Interrupted(f"the agents stopped keep their checkpoints in {Path(out_dir) / 'runs'}; run the same "
                          "command again to go on from them (nothing was reported)") from None
    return sorted(results, key=lambda r: (r["job"].kind, r["job"].variant, r["job"].seed))


def episode_rows(results: list[dict]) -> list[dict]:
    """Every evaluation episode of the jobs' ``results``, as ``benchmark_episodes.csv`` holds them."""
    return [row for r in results for row in r["rows"]]


def _agent_means(rows: list[dict], column: str, value=lambda row, column: row.get(column, math.nan)) -> list[float]:
    """Each agent's (training seed's) mean of ``value(row, column)`` over its episode ``rows``."""
    seeds = dict.fromkeys(row["seed"] for row in rows)
    return [nanmean([value(row, column) for row in rows if row["seed"] == seed]) for seed in seeds]


def summary(rows: list[dict]) -> dict[str, dict[str, tuple]]:
    """Per variant and column of the episode ``rows`` (as ``benchmark_episodes.csv`` holds them): mean [95%
    interval]. For trained variants each agent's episode mean is one sample (the interval is over training
    seeds); for a baseline (scripted or a shipped agent), each plan's mean over its seeds is (on one world, each
    episode)."""
    table = {}
    for variant in dict.fromkeys(row["variant"] for row in rows):
        own = [row for row in rows if row["variant"] == variant]
        agent = own[0]["kind"] == "agent"
        entry = {column: measure_interval(_agent_means(own, column) if agent else plan_means(own, column), column)
                 for column in TABLE_COLUMNS}
        entry["agents"] = len({row["seed"] for row in own}) if agent else 0
        table[variant] = entry
    return table


#: Columns of the paired comparison of each trained variant with each baseline: of the final maps (with the robot
#: time they took), and at equal robot time (each pair read at the robot time the shorter episode took, with the
#: coverage and the building accuracy, which count what is not mapped yet).
PAIRED_COLUMNS = ("ate", "oracle_accuracy", "building_accuracy", "sim_steps", LOOP_ORDER_KEY)
EQUAL_TIME_COLUMNS = ("ate", "oracle_accuracy", "wall_consistency", "coverage", "building_accuracy", "sim_steps")


def paired_with(rows: list[dict], baseline: str, *, equal_robot_time: bool = False) -> dict[str, dict]:
    """Each trained variant minus ``baseline`` on the same held-out episodes, paired by (world, episode seed): the
    mean over the variant's agents and the plans, with its 95% interval by a paired bootstrap that resamples
    the plans (each with all its seeds) and, where the variant has several agents, the agents
    (:func:`~emmi_gym.tools.evaluation.intervals.plan_bootstrap`: a ``PairedDifference``, with the smallest
    difference it detects). With ``equal_robot_time`` (rows with traces), each pair of episodes is read at the
    robot time the shorter took (:func:`~emmi_gym.tools.evaluation.robot_time.read_together`); ``sim_steps`` is
    then that time, the agent's own, not a difference: mean [95% t-interval] over the agents, as :func:`summary`
    gives."""
    theirs = {(row.get("world"), row["episode_seed"]): row for row in rows
              if row["kind"] == "baseline" and row["variant"] == baseline}

    def difference(row, column):
        other = theirs.get((row.get("world"), row["episode_seed"]))
        if other is None:
            return math.nan
        if not equal_robot_time:
            return row.get(column, math.nan) - other.get(column, math.nan)
        mine, its = read_together(row, other)
        return mine[column] if column == "sim_steps" else mine[column] - its[column]

    table = {}
    for variant in dict.fromkeys(row["variant"] for row in rows if row["kind"] == "agent"):
        own = [row for row in rows if row["variant"] == variant and (TRACE in row or not equal_robot_time)]
        table[variant] = {
            column: measure_interval(_agent_means(own, column, difference), column)
            if equal_robot_time and column == "sim_steps" else
            plan_bootstrap([difference(row, column) for row in own], [plan_of(row) for row in own], column,
                           agents=[row["seed"] for row in own], episodes=[row["episode_seed"] for row in own])
            for column in (EQUAL_TIME_COLUMNS if equal_robot_time else PAIRED_COLUMNS)}
    return table


def _measured(entry) -> int:
    """How many values an interval of :func:`summary` or :func:`paired_with` stands on (agents, plans)."""
    return entry.plans if isinstance(entry, PairedDifference) else entry[3]


def measured_columns(table: dict, columns=tuple(TABLE_COLUMNS)) -> list[str]:
    """The ``columns`` that some variant of a :func:`summary` has a value for (the loop order only on
    the loop worlds, the revisit share only in waypoint mode)."""
    return [c for c in columns if any(_measured(entry[c]) > 0 for entry in table.values())]


def _cell(interval, column: str, signed: bool = False) -> str:
    """An interval of :func:`summary` (``(mean, low, high, n)``) or a ``PairedDifference`` of :func:`paired_with`
    (with its plans and the smallest difference it detects) as a table cell."""
    if isinstance(interval, PairedDifference):
        mean, low, high, n = interval.mean, interval.low, interval.high, interval.plans
        counted = f"n={n}; detects {format_number(interval.detectable, column)}"
    else:
        mean, low, high, n = interval
        counted = f"n={n}"
    if n == 0:
        return "n/a"
    if n == 1:  # one agent or plan: no interval
        return f"{format_number(mean, column, signed)} (n=1)"
    return (f"{format_number(mean, column, signed)} [{format_number(low, column, signed)}, "
            f"{format_number(high, column, signed)}] ({counted})")


def _heading(column: str) -> str:
    """A column's label, with the side that is better where it has one."""
    side = better_side(column)
    return TABLE_COLUMNS[column] + ("" if side == "-" else f" ({side} is better)")


def markdown(rows: list[dict], header: str) -> str:
    """The benchmark's summary of its episode ``rows``: each variant's means, then, per scripted baseline,
    each trained variant's paired differences with it."""
    table = summary(rows)
    columns = measured_columns(table)
    lines = [header, "", "| variant | " + " | ".join(_heading(c) for c in columns) + " |",
             "| --- |" + " --- |" * len(columns)]
    for variant, entry in table.items():
        name = f"{variant} ({entry['agents']} agents)" if entry["agents"] else f"{variant} (baseline)"
        lines.append(f"| {name} | " + " | ".join(_cell(entry[column], column) for column in columns) + " |")
    traced = any(TRACE in row for row in rows)
    for baseline in dict.fromkeys(row["variant"] for row in rows if row["kind"] == "baseline"):
        lines += _paired_table(paired_with(rows, baseline), baseline,
                               f"Paired with {baseline} on the same episodes, final maps (agent minus {baseline}, "
                               "paired by plan and seed; mean over the agents and plans [95% interval of a paired "
                               "bootstrap that resamples the plans, each with all its seeds, and the agents]; "
                               "'detects': the smallest difference this protocol finds with 80% power, 2.8 bootstrap "
                               "standard errors; the robot time each took beside them):")
        if traced:
            lines += _paired_table(
                paired_with(rows, baseline, equal_robot_time=True), baseline,
                f"At equal robot time with {baseline}: each pair of episodes read at the robot time the shorter "
                f"of the two took (the longer one's scores linear between its decisions), agent minus {baseline} "
                f"as above, with the coverage and the building accuracy, which count what is not mapped yet (the "
                f"oracle accuracy and the ATE judge only what was); robot time: that time (the mean over agents of "
                f"their mean), not a difference:",
                time_column="sim_steps")
    return "\n".join(lines) + "\n"


def _paired_table(paired: dict, baseline: str, title: str, time_column: str | None = None) -> list[str]:
    """The Markdown lines of a :func:`paired_with` table (none if no variant has a value); ``time_column`` is
    shown unsigned, as a time rather than a difference."""
    if not paired:
        return []
    columns = next(iter(paired.values())).keys()
    shown = [c for c in columns if any(_measured(entry[c]) > 0 for entry in paired.values())]
    lines = ["", title, "", "| variant | " + " | ".join(_heading(c) for c in shown) + " |",
             "| --- |" + " --- |" * len(shown)]
    for variant, entry in paired.items():
        lines.append(f"| {variant} - {baseline} | "
                     + " | ".join(_cell(entry[c], c, signed=c != time_column) for c in shown) + " |")
    return lines


def plot(results: list[dict], out: Path) -> dict[str, Path]:
    """Learning curves (the periodic evaluation's ground-truth means against timesteps, mean over seeds,
    per reward variant) and the final metrics with their intervals."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = {"curves": out / "learning_curves.png", "final": out / "final_metrics.png"}
    curves_have_loop_order = any(LOOP_ORDER_KEY in row for r in results for row in r["curve"])
    measures = ("coverage", "map_accuracy", "ate") + ((LOOP_ORDER_KEY,) if curves_have_loop_order else ())
    fig, axes = plt.subplots(1, len(measures), figsize=(4 * len(measures), 3.4))
    for variant in dict.fromkeys(r["job"].variant for r in results if r["job"].kind == "agent"):
        curves = [r["curve"] for r in results if r["job"].variant == variant and r["curve"]]
        if not curves:
            continue
        length = min(len(c) for c in curves)
        steps = [c["timesteps"] for c in curves[0][:length]]
        for ax, measure in zip(axes, measures, strict=False):
            values = np.array([[row[measure] for row in c[:length]] for c in curves])
            ax.plot(steps, values.mean(axis=0), marker="o", ms=3, label=variant)
    for ax, measure in zip(axes, measures, strict=False):
        ax.set_xlabel("training timesteps")
        ax.set_title(f"held-out: {TABLE_COLUMNS.get(measure, measure)}", fontsize=9)
        ax.grid(alpha=0.3)
    if axes[0].lines:
        axes[0].legend(fontsize=8)
    else:
        axes[0].text(0.5, 0.5, "no periodic evaluation yet\n(training shorter than eval.freq)", ha="center",
                     va="center", transform=axes[0].transAxes, fontsize=8)
    fig.tight_layout()
    write_atomically(files["curves"], partial(fig.savefig, dpi=110))
    plt.close(fig)

    table = summary(episode_rows(results))
    columns = measured_columns(table, ("oracle_accuracy", "wall_consistency", "map_accuracy", "ate", "coverage",
                                       "revisit_share", LOOP_ORDER_KEY))
    fig, axes = plt.subplots(1, len(columns), figsize=(3 * len(columns), 3.4))
    names = list(table)
    for ax, column in zip(axes, columns, strict=False):
        stats_ = [table[v][column] for v in names]
        means = [s[0] for s in stats_]
        errors = np.array([[s[0] - s[1] for s in stats_], [s[2] - s[0] for s in stats_]])
        ax.bar(range(len(names)), means, yerr=np.nan_to_num(errors), capsize=3, color="tab:blue", alpha=0.7)
        ax.set_xticks(range(len(names)), names, rotation=35, ha="right", fontsize=8)
        ax.set_title(TABLE_COLUMNS[column], fontsize=9)
        ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    write_atomically(files["final"], partial(fig.savefig, dpi=110))
    plt.close(fig)
    return files


def write_benchmark(results: list[dict], out_dir, header: str) -> dict[str, Path]:
    """``benchmark_episodes.csv`` (every evaluation episode), ``benchmark_traces.csv`` (their ground-truth scores
    after every decision, :mod:`~emmi_gym.tools.evaluation.robot_time`), ``benchmark_summary.md`` and the plots."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = {"episodes": out / "benchmark_episodes.csv", "traces": out / "benchmark_traces.csv",
             "summary": out / "benchmark_summary.md"}
    rows = episode_rows(results)
    write_csv(files["episodes"], without_traces(rows))
    write_csv(files["traces"], trace_rows(rows, keys=("kind", "variant", "seed", "episode_seed")))
    write_text_atomically(files["summary"], markdown(rows, header))
    files.update(plot(results, out))
    return files
