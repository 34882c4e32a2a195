"""Environment steps per second for each id at default settings, and where the time goes.

    python scripts/bench_env.py [--seconds 20] [--ids ExploreVelocity-v0 ...]

Single process. For each id: reset (seed 0), then act until ``--seconds`` of time
inside ``step()`` (random valid waypoint actions; random velocities), counting env
steps and simulator steps; resets (and LoopCorridor's drive to the decision point)
are not counted. The split times the simulator (physics and odometry), the laser,
the RBPF update, its metrics (EMMI and the other certainty measures: once per step by
default, see the env's ``update_records``), the expected-map products (coverage, accuracy,
planning and candidates) and the observation; each part's time excludes the parts timed
inside it.
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict

import gymnasium as gym
import numpy as np

import emmi_gym
from emmi_gym.env import ENV_IDS, EmmiEnv
from emmi_gym.slam import RBPF
from emmi_gym.world import Simulator

gym.register_envs(emmi_gym)


_OPEN: list = []  # the timed calls under way, innermost last


def timed(cls, name: str, bucket: dict, key: str) -> None:
    """Accumulate the wall time of every call of ``cls.name`` into ``bucket[key]``, less the time of the
    timed calls made inside it (which go to their own keys)."""
    original = getattr(cls, name)

    def wrapper(*args, **kwargs):
        _OPEN.append(0.0)
        t0 = time.perf_counter()
        try:
            return original(*args, **kwargs)
        finally:
            spent = time.perf_counter() - t0
            inner = _OPEN.pop()
            bucket[key] += spent - inner
            if _OPEN:
                _OPEN[-1] += spent

    setattr(cls, name, wrapper)


SPENT: dict = defaultdict(float)
timed(Simulator, "step", SPENT, "physics")
timed(Simulator, "scan", SPENT, "laser")
timed(RBPF, "process", SPENT, "rbpf")
timed(RBPF, "_measure", SPENT, "rbpf metrics")
timed(EmmiEnv, "_refresh", SPENT, "map products")
timed(EmmiEnv, "_observation", SPENT, "observation")


def bench(env_id: str, seconds: float) -> None:
    env = gym.make(env_id)
    core = env.unwrapped
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    steps = sim_steps = 0
    wall = 0.0
    SPENT.clear()
    while wall < seconds:
        if core.config.action_mode == "waypoint":
            action = int(rng.choice(np.flatnonzero(core.action_masks())))
        else:
            action = rng.uniform(-1, 1, 2).astype(np.float32)
        t0 = time.perf_counter()
        _, _, terminated, truncated, info = env.step(action)
        wall += time.perf_counter() - t0
        steps += 1
        sim_steps += info["sim_steps_this_step"]
        if terminated or truncated:
            saved = dict(SPENT)
            env.reset(seed=steps)  # reset time (the preamble) is not counted
            SPENT.clear()
            SPENT.update(saved)
    spent = dict(SPENT)
    spent["other"] = max(0.0, wall - sum(spent.values()))
    print(f"{env_id}: {steps / wall:.1f} env steps/s, {sim_steps / wall:.0f} simulator steps/s "
          f"({steps} env steps, {sim_steps} simulator steps in {wall:.1f} s of step())")
    print("  time share: " + ", ".join(f"{k} {100 * v / wall:.0f}%" for k, v in spent.items()))
    env.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--ids", nargs="+", choices=ENV_IDS, default=list(ENV_IDS), help="which environments")
    args = parser.parse_args()
    for name in args.ids:
        bench(f"emmi_gym/{name}", args.seconds)


if __name__ == "__main__":
    main()
