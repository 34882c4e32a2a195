"""Where the wall time of ``emmi-gym train`` goes: collecting decisions, learning, evaluating.

    python scripts/bench_train.py [--config agents/ppo_emmi.yaml] [--timesteps N] [--out DIR]

Trains the configuration exactly as ``emmi-gym train`` does (same envs, vectorisation,
threads, callbacks) into ``--out`` (a temporary folder by default), timing in this process:
the algorithm's rollout collection (the env workers' steps and resets as the learner waits for
them), the periodic held-out evaluation (its episodes run in this process, inside the
collection), the gradient updates, and the rest of ``learn`` (checkpoints, logging). Prints each part's
seconds and share of the wall time, and the decisions collected per second.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections import defaultdict
from dataclasses import replace
from pathlib import Path

from emmi_gym.training import callbacks
from emmi_gym.training.config import algorithm_class, load_agent_config
from emmi_gym.training.train import set_torch_threads, train, training_torch_threads

SPENT: dict = defaultdict(float)


def timed(cls, name: str, key: str, when=lambda self: True) -> None:
    """Add the wall time of every call of ``cls.name`` (for which ``when(self)`` holds) to ``SPENT[key]``."""
    original = getattr(cls, name)

    def wrapper(self, *args, **kwargs):
        if not when(self):
            return original(self, *args, **kwargs)
        t0 = time.perf_counter()
        try:
            return original(self, *args, **kwargs)
        finally:
            SPENT[key] += time.perf_counter() - t0

    setattr(cls, name, wrapper)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="agents/ppo_emmi.yaml")
    parser.add_argument("--timesteps", type=int, default=None, help="override total_timesteps")
    parser.add_argument("--out", default=None, help="run folder (default: a temporary one, removed after)")
    args = parser.parse_args()
    config = load_agent_config(args.config)
    if args.timesteps is not None:
        config = replace(config, total_timesteps=args.timesteps)
    set_torch_threads(training_torch_threads(config))  # as emmi-gym train: the same network as it trains
    cls = algorithm_class(config.algorithm)
    timed(cls, "collect_rollouts", "collection")
    timed(cls, "train", "learning")
    timed(callbacks.GroundTruthEvalMixin, "_on_step", "evaluation",
          when=lambda cb: cb.eval_freq > 0 and cb.n_calls % cb.eval_freq == 0)  # as the callback decides
    with tempfile.TemporaryDirectory() as scratch:
        result = train(config, Path(args.out or scratch) / "run", progress=False)
        wall = result.wall_seconds
    parts = {"collection (less evaluation)": SPENT["collection"] - SPENT["evaluation"],
             "evaluation": SPENT["evaluation"], "learning": SPENT["learning"]}
    parts["other"] = max(0.0, wall - sum(parts.values()))
    print(f"{config.algorithm} on {config.env_id}, {config.n_envs} env(s) ({config.vec_env}), "
          f"{result.timesteps} decisions in {wall:.0f} s: "
          f"{result.timesteps / (SPENT['collection'] - SPENT['evaluation']):.1f} collected per second")
    for name, seconds in parts.items():
        print(f"  {name}: {seconds:.1f} s ({100 * seconds / wall:.0f}%)")


if __name__ == "__main__":
    main()
