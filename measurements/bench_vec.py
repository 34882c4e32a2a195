"""Environment steps per second of vectorised envs against a single process: which to use when.

    python measurements/bench_vec.py [--env-id emmi_gym/ExploreVelocity-v0] [--seconds 20] [--envs 2 4 8]

For each setting: reset (seeded), then random actions until ``--seconds`` have passed, counting
env steps over all envs (episode resets inside the vector envs are counted in the time). Waypoint
ids draw among the valid slots, read from each env's ``action_masks()`` before every step as
MaskablePPO reads them (through the vector env, from the worker processes where there are some). Settings:
one env in this process; gymnasium's ``make_vec(..., vectorization_mode="sync")`` and
``"async"`` (subprocesses); SB3's ``DummyVecEnv`` and ``SubprocVecEnv``, each at the given numbers
of envs. Worker processes run their kernels on one thread (as ``emmi-gym train`` sets them);
this process keeps numba's default. Prints one line per setting and a markdown table.
"""

from __future__ import annotations

import argparse
import os
import time
from functools import partial

import _arguments as arguments
import gymnasium as gym
import numpy as np

import emmi_gym
from emmi_gym.concurrency.parallel import one_kernel_thread

gym.register_envs(emmi_gym)


def _worker_env(env_id: str):
    one_kernel_thread()
    return gym.make(env_id)


def _masked_choice(rngs: list, masks) -> np.ndarray:
    """One valid action per env: a random slot among each row of ``masks`` that is True, env i's drawn
    from ``rngs[i]`` (:func:`_rngs`)."""
    return np.array([rng.choice(np.flatnonzero(mask)) for rng, mask in zip(rngs, masks, strict=True)])


def _rngs(n: int) -> list:
    """Env i's generator of actions, seeded i as the env is: within gymnasium (sync, async) and within
    SB3 (DummyVecEnv, SubprocVecEnv) env i then plays the same episodes. Across the two they differ:
    gymnasium resets an env on the step after its episode ended, spending a draw; SB3 within it."""
    return [np.random.default_rng(i) for i in range(n)]


def _rate(step, sample, seconds: float, per_step: int) -> float:
    steps, started = 0, time.perf_counter()
    while time.perf_counter() - started < seconds:
        step(sample())
        steps += per_step
    return steps / (time.perf_counter() - started)


def _waypoint(env_id: str) -> bool:
    return gym.spec(env_id).kwargs.get("action_mode", "waypoint") == "waypoint"


def single(env_id: str, seconds: float) -> float:
    env = gym.make(env_id)
    env.reset(seed=0)
    rngs = _rngs(1)

    def step(action):
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    sample = (lambda: int(_masked_choice(rngs, [env.unwrapped.action_masks()])[0])) if _waypoint(env_id) \
        else env.action_space.sample
    rate = _rate(step, sample, seconds, 1)
    env.close()
    return rate


def gymnasium_vec(env_id: str, n: int, mode: str, seconds: float) -> float:
    envs = gym.vector.AsyncVectorEnv([partial(_worker_env, env_id)] * n) if mode == "async" else \
        gym.make_vec(env_id, num_envs=n, vectorization_mode="sync")
    envs.reset(seed=0)
    rngs = _rngs(n)
    sample = (lambda: _masked_choice(rngs, envs.call("action_masks"))) if _waypoint(env_id) \
        else envs.action_space.sample
    rate = _rate(envs.step, sample, seconds, n)
    envs.close()
    return rate


def sb3_vec(env_id: str, n: int, subprocess: bool, seconds: float) -> float:
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    envs = (SubprocVecEnv if subprocess else DummyVecEnv)([partial(_worker_env, env_id)] * n)
    envs.seed(0)
    envs.reset()
    rngs = _rngs(n)
    sample = (lambda: _masked_choice(rngs, envs.env_method("action_masks"))) if _waypoint(env_id) \
        else (lambda: np.stack([envs.action_space.sample() for _ in range(n)]))
    rate = _rate(envs.step, sample, seconds, n)
    envs.close()
    return rate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="emmi_gym/ExploreVelocity-v0")
    parser.add_argument("--seconds", type=arguments.number(0.0, unit="s"), default=20.0)
    parser.add_argument("--envs", type=arguments.integer(1), nargs="+", default=[2, 4, 8])
    args = parser.parse_args()
    print(f"{args.env_id} on {os.cpu_count()} cores, {args.seconds:.0f} s per setting")
    rows = [("single process", 1, single(args.env_id, args.seconds))]
    print(f"single process: {rows[0][2]:.1f} steps/s", flush=True)
    for n in args.envs:
        for label, run in (("gymnasium sync", partial(gymnasium_vec, args.env_id, n, "sync", args.seconds)),
                           ("gymnasium async", partial(gymnasium_vec, args.env_id, n, "async", args.seconds)),
                           ("SB3 DummyVecEnv", partial(sb3_vec, args.env_id, n, False, args.seconds)),
                           ("SB3 SubprocVecEnv", partial(sb3_vec, args.env_id, n, True, args.seconds))):
            rate = run()
            rows.append((label, n, rate))
            print(f"{label}, {n} envs: {rate:.1f} steps/s", flush=True)
    print("\n| vectorisation | envs | env steps / s | vs single process |\n| --- | --- | --- | --- |")
    for label, n, rate in rows:
        print(f"| {label} | {n} | {rate:.1f} | {rate / rows[0][2]:.2f}x |")


if __name__ == "__main__":
    main()
