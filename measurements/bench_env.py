"""Environment steps per second for each id at default settings, and where the time goes.

    python measurements/bench_env.py [--decisions 60] [--velocity-steps 10000] [--repeats 3]
                                   [--ids ExploreVelocity-v0 ...]
                                   [--options '{"slam": {"linear_update": 1.0}}'] [--against DIR]
                                   [--with-resets] [--threads 1]

Single process. For each id: reset (seed 0), then take a fixed number of env steps
(random valid waypoint actions; random velocities; drawn from seed 0, so every run, and
the code before a change that is only speed, plays the same episodes), timing the
calls of ``step()``; resets (and LoopCorridor's drive to the decision point) are not
counted unless ``--with-resets`` (then the reset after an episode's last step counts with
that step: whole decisions, what training waits for). ``--threads`` sets the kernels'
threads (:func:`emmi_gym.concurrency.threads.set_kernel_threads`; default one per core):
``--with-resets --threads 1`` gives the decisions/s of one env on one core, as each of a
training run's env processes makes them. The median of ``--repeats`` runs is printed.

The split times the simulator (physics and odometry), the laser, the RBPF update, its
metrics (EMMI and the other certainty measures: once per step by default, see the env's
``update_records``), the oracle map's insertions (which coverage is read on), the
ground-truth scores (map labels, map accuracy, oracle accuracy, wall consistency, ATE),
the planner's cost-distance maps (for the candidate targets and for replanning), the
checks of the path ahead after each filter update, the rest of the expected-map products
(coverage, candidates) and the observation; each part's time excludes the parts timed
inside it.

This machine's speed drifts by tens of percent from minute to minute, more than most
changes gain: ``--against DIR`` (a ``git worktree`` of the code before a change) plays
the same number of steps, with actions drawn the same way, with both codes in turns, one
step each, and prints their ratio; where the other code registers an older version of the id
(``-v0`` for ``-v1``), it plays that one. ``--options`` times another setting (``gym.make``
options for every id, given to both codes with ``--against``): its episodes differ from the
defaults'.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

import gymnasium as gym
import numpy as np
from _timing import timed

import emmi_gym
from emmi_gym.concurrency.threads import set_kernel_threads
from emmi_gym.env import ENV_IDS, EmmiEnv, emmi_env
from emmi_gym.env.observation import OBSERVATION_TYPES
from emmi_gym.navigation import executor
from emmi_gym.scoring.oracle import OracleMap
from emmi_gym.slam import RBPF
from emmi_gym.world import Simulator

gym.register_envs(emmi_gym)
REPO = Path(__file__).resolve().parent.parent


SPENT: dict = defaultdict(float)


def time_the_parts() -> None:
    """Time the parts of a step into :data:`SPENT` (not in the ``--against`` workers, which time whole steps)."""
    timed(Simulator, "step", SPENT, "physics")
    timed(Simulator, "scan", SPENT, "laser")
    timed(RBPF, "process", SPENT, "rbpf")
    timed(RBPF, "measure", SPENT, "rbpf metrics")
    timed(OracleMap, "insert", SPENT, "oracle map")
    for score in ("map_labels", "accuracy_of_labels", "oracle_scores_of_labels", "absolute_trajectory_error"):
        timed(emmi_env, score, SPENT, "ground-truth scores")
    timed(executor, "travel_costs", SPENT, "planning")
    timed(executor, "path_obstructed", SPENT, "path checks")
    timed(EmmiEnv, "_refresh", SPENT, "map products")
    for observation_type in OBSERVATION_TYPES.values():
        timed(observation_type, "observe", SPENT, "observation")


def play(env_id: str, options: dict, with_resets: bool = False):
    """Step the fixed episodes of ``env_id`` (made with ``options``) for ever, yielding after each env step
    (wall seconds inside ``step()``, and with ``with_resets`` inside the reset that follows an episode's
    last step; simulator steps; filter updates); resets not counted are not timed, nor are their parts."""
    env = gym.make(env_id, **options)
    core = env.unwrapped
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    SPENT.clear()  # the first reset is not timed, nor are its parts
    step = 0
    try:
        while True:
            if core.config.action_mode == "waypoint":
                action = int(rng.choice(np.flatnonzero(core.action_masks())))
            else:
                action = rng.uniform(-1, 1, 2).astype(np.float32)
            before = core.slam.step
            t0 = time.perf_counter()
            _, _, terminated, truncated, info = env.step(action)
            wall = time.perf_counter() - t0
            step += 1
            updates = core.slam.step - before
            if terminated or truncated:
                saved = dict(SPENT)
                t0 = time.perf_counter()
                env.reset(seed=step)
                if with_resets:
                    wall += time.perf_counter() - t0
                else:
                    SPENT.clear()
                    SPENT.update(saved)
            yield wall, info["sim_steps_this_step"], updates
    finally:
        env.close()


def bench(env_id: str, n_steps: int, options: dict, with_resets: bool) -> tuple[float, float, dict, int]:
    """One run of ``n_steps`` env steps; returns (wall seconds timed, simulator steps, seconds per part,
    filter updates)."""
    SPENT.clear()
    wall = sim_steps = updates = 0
    for _, (dt, sims, ups) in zip(range(n_steps), play(env_id, options, with_resets), strict=False):
        wall, sim_steps, updates = wall + dt, sim_steps + sims, updates + ups
    spent = dict(SPENT)
    spent["other"] = max(0.0, wall - sum(spent.values()))
    return wall, sim_steps, spent, updates


def against(env_id: str, n_steps: int, code: str, with_resets: bool, threads: int | None, options: dict) -> None:
    """The same steps (the same seeds and action draws) played by this code and by the code in ``code`` (a
    checkout of another commit), in two processes that take turns, one env step each: whatever the machine
    does meanwhile slows both alike. Prints the ratio of their times, and each code's simulator steps per
    second (the robot time it simulates: where the codes' episodes differ, their decisions may drive
    farther or less far). Each process first plays the steps once untimed (both at once): a fresh
    checkout compiles each numba kernel on its first call, which may come late in an episode (a first
    resampling), and once made a fresh worktree look four times slower."""
    if not (Path(code) / "emmi_gym" / "__init__.py").is_file():  # else the worker would import this code
        raise SystemExit(f"--against {code}: no emmi_gym package there (make one with git worktree add DIR REV)")
    settings = ((["--with-resets"] if with_resets else []) + ([f"--threads={threads}"] if threads else []) +
                [f"--options={json.dumps(options)}"])
    workers = [subprocess.Popen([sys.executable, __file__, "--worker", env_id, *settings], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, text=True, env=dict(os.environ, PYTHONPATH=path))
               for path in (str(REPO), str(Path(code).resolve()))]
    for worker in workers:
        worker.stdin.write(f"warm {n_steps}\n")
        worker.stdin.flush()
    for w, worker in enumerate(workers):
        if not worker.stdout.readline():
            raise SystemExit(f"the worker running {env_id} with the code in "
                             f"{'this checkout' if w == 0 else code} stopped while warming up")
    times, sim_steps = np.zeros((2, n_steps)), np.zeros((2, n_steps))
    for k in range(n_steps):
        for w, worker in enumerate(workers):
            worker.stdin.write("step\n")
            worker.stdin.flush()
            line = worker.stdout.readline()
            if not line:  # it stopped: its traceback went to stderr
                raise SystemExit(f"the worker running {env_id} with the code in "
                                 f"{'this checkout' if w == 0 else code} stopped at step {k}")
            times[w, k], sim_steps[w, k] = map(float, line.split())
    for worker in workers:
        worker.stdin.close()
        worker.wait()
    this, other = times.sum(axis=1)
    this_rate, other_rate = sim_steps.sum(axis=1) / times.sum(axis=1)
    what = "env steps and the resets after episodes' last steps" if with_resets else "env steps"
    print(f"{env_id}: {n_steps} {what} in {this:.1f} s with this code ({n_steps / this:.2f}/s), {other:.1f} s "
          f"with {code} ({n_steps / other:.2f}/s): {other / this:.2f} times as fast; simulator steps/s "
          f"{this_rate:.0f} and {other_rate:.0f} ({this_rate / other_rate:.2f} times)"
          f"{f' (kernels on {threads} thread(s))' if threads else ''}")


def registered_version(env_id: str) -> str:
    """``env_id``, or where the code imported does not register it, the highest version of the same name it
    registers (the code before a change of version knows only the older one)."""
    if env_id in gym.registry:
        return env_id
    namespace, name, _ = gym.envs.registration.parse_env_id(env_id)
    version = gym.envs.registration.find_highest_version(namespace, name)
    if version is None:
        raise SystemExit(f"{env_id}: the code imported registers no version of {namespace}/{name}")
    return gym.envs.registration.get_env_id(namespace, name, version)


def worker(env_id: str, with_resets: bool, options: dict) -> None:
    """The other end of :func:`against`: "warm N" plays N steps untimed and starts the episodes again;
    "step" plays one step and writes its wall time and simulator steps back."""
    env_id = registered_version(env_id)
    episodes = play(env_id, options, with_resets)
    for line in sys.stdin:
        if line.startswith("warm"):
            for _ in zip(range(int(line.split()[1])), episodes, strict=False):
                pass
            episodes.close()
            episodes = play(env_id, options, with_resets)
            print("warm", flush=True)
        else:
            wall, sims, _ = next(episodes)
            print(wall, sims, flush=True)


def report(env_id: str, n_steps: int, repeats: int, options: dict, with_resets: bool) -> None:
    """The median of ``repeats`` runs of the same episodes (and the range of the rates)."""
    runs = [bench(env_id, n_steps, options, with_resets) for _ in range(repeats)]
    walls = np.array([run[0] for run in runs])
    wall, sim_steps, spent, updates = runs[int(np.argsort(walls)[len(walls) // 2])]
    rates = n_steps / walls
    print(f"{env_id}{f' {options}' if options else ''}: {n_steps / wall:.1f} env steps/s "
          f"({rates.min():.1f}-{rates.max():.1f} over {repeats} runs), "
          f"{sim_steps / wall:.0f} simulator steps/s, {1e3 * spent['rbpf'] / max(updates, 1):.2f} ms of RBPF per "
          f"update ({n_steps} env steps, {sim_steps} simulator steps, {updates} filter updates, "
          f"{wall:.1f} s of step(){' and resets' if with_resets else ''} in the median run)")
    print("  time share: " + ", ".join(f"{k} {100 * v / wall:.0f}%" for k, v in spent.items()))
    print("  ms per env step: " + ", ".join(f"{k} {1e3 * v / n_steps:.1f}" for k, v in spent.items()))


def worker_command(argv: list[str]) -> None:
    """The command line of :func:`worker`: ``--worker ENV_ID [--with-resets] [--threads N] [--options JSON]``,
    read with nothing of this checkout but this file, since the worker may run older code (which has not
    the argument types of ``_arguments``)."""
    parser = argparse.ArgumentParser()
    parser.add_argument("--worker", required=True)
    parser.add_argument("--with-resets", action="store_true")
    parser.add_argument("--threads", type=int)
    parser.add_argument("--options", default="{}")
    args = parser.parse_args(argv)
    if args.threads:
        set_kernel_threads(args.threads)
    worker(args.worker, args.with_resets, json.loads(args.options))


def main() -> None:
    import _arguments as arguments  # here, not in the workers: they may run older code

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--decisions", type=arguments.integer(1), default=60, help="env steps of each waypoint id")
    parser.add_argument("--velocity-steps", type=arguments.integer(1), default=10000,
                        help="env steps of ExploreVelocity-v0")
    parser.add_argument("--repeats", type=arguments.integer(1), default=3,
                        help="runs of the same episodes; the median is shown")
    parser.add_argument("--ids", nargs="+", choices=ENV_IDS, default=list(ENV_IDS), help="which environments")
    parser.add_argument("--against", metavar="DIR", help="a checkout of other code (git worktree add DIR REV): "
                        "play the same steps with both, in turns, and print the ratio of their times")
    parser.add_argument("--options", default="{}", help="JSON of gym.make options for every id (another "
                        "setting's speed: its episodes differ), e.g. '{\"particles\": 8}'; with --against, both codes'")
    parser.add_argument("--with-resets", action="store_true", help="count the reset after an episode's last step "
                        "with that step (whole decisions, as training waits for them)")
    parser.add_argument("--threads", type=arguments.integer(1, 256), metavar="N",
                        help="threads of the kernels (default: one per core)")
    args = parser.parse_args()
    if args.threads:
        set_kernel_threads(args.threads)
    time_the_parts()
    from _options import checked, json_object  # here, not in the workers: they may run older code

    from emmi_gym.env import EnvConfig
    from emmi_gym.inputs.validation import build

    options = json_object(parser, "--options", args.options)
    for name in args.ids:
        checked(parser, build, EnvConfig, {**ENV_IDS[name], **options}, "", source="--options")
    for name in args.ids:
        env_id = f"emmi_gym/{name}"
        velocity = gym.spec(env_id).kwargs.get("action_mode") == "velocity"
        n_steps = args.velocity_steps if velocity else args.decisions
        if args.against:
            against(env_id, n_steps, args.against, args.with_resets, args.threads, options)
        else:
            report(env_id, n_steps, args.repeats, options, args.with_resets)


if __name__ == "__main__":
    if sys.argv[1:2] == ["--worker"]:
        worker_command(sys.argv[1:])
    else:
        main()
