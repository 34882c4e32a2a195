"""Decisions per second of ``emmi-gym train`` against what its workers could make alone, where the wall
time goes, and the efficiency to expect on more cores.

    python measurements/bench_train.py [--config agents/ppo_plans_emmi.yaml] [--timesteps N] [--n-envs W]
                                  [--vec-env workers|subproc|dummy] [--policy-lag 0|1] [--single N] [--out DIR]

1. **One worker alone**: a rollout worker in a process of its own (kernels and torch on one thread,
   as in training) plays the first ``--single`` decisions (default ``n_steps``) of each env of
   the run with the model's initial weights, one env after another, one decision at a time, resets
   included; each decision's wall time is kept. These are the very decisions the workers play
   first in training (the same seeds, weights and sampling generators: with ``--timesteps`` =
   ``n_envs x n_steps``, all of them), so the single-thread decisions/s is that of the same work.
2. **Training**, exactly as ``emmi-gym train`` does (same envs, vectorisation, threads, callbacks),
   ``--timesteps`` decisions into ``--out`` (a temporary folder by default). It times the waits for
   the envs (the rollout workers' fragments, or a synchronous vector env's steps and resets), the
   algorithm's ``train()`` (the update), the periodic evaluation and the rest. The decisions/s of
   training (the update included) is compared with ``W x`` the single-thread decisions/s
   (``W`` = ``n_envs``): the efficiency. The learner's share is the wall time not spent waiting
   for the envs (the update, the replay of the fragments into the buffer, checkpoints, logging).
3. **Predicted efficiency** at ``W`` = ``n_envs``, 16 and 64 workers, from the measured decision
   times ``t`` (mean ``m``) and the learner's measured seconds per decision ``u``:

   - rollout workers (one wait per fragment): each of the ``W`` workers plays ``n = n_steps``
     decisions, taking ``T_k`` (a sum of ``n`` decision times), and the learner then updates
     on the ``W n`` decisions, taking ``u W n``::

         efficiency(W) = n m / (E[max_k T_k] + u W n)

   - rollout workers with ``policy_lag: 1``: the workers play the next fragments while the learner
     updates, so a round lasts the longer of the slowest fragment and the update; the update's CPU
     time is taken from the workers' cores (``u n`` on each of ``W``)::

         efficiency(W) = n m / max(E[max_k T_k] + u n, u W n)

   - a synchronous vector env (one wait per decision): every step waits for the slowest of
     ``W`` decisions, and the learner's share is the same ``u`` per decision::

         efficiency(W) = m / (E[max_k t_k] + u W)

   ``E[max]`` is estimated by drawing the ``t`` (resampling the measured times, 2000 draws). A
   decision's time is heavy-tailed (a waypoint drive is 10 ms to a second): the maximum of ``W``
   single decisions grows quickly with ``W``, the maximum of ``W`` sums of ``n`` decisions barely.
   The learner's update grows with ``W`` (its batch is ``W n`` decisions) while a fragment's time
   does not, so ``u W`` must stay well under ``m``: each model is printed with ``u`` as measured
   on this machine (the update on its cores) and with ``u = 0`` (a learner whose update does not
   hold up the workers, such as one on a GPU).
"""

from __future__ import annotations

import argparse
import copy
import tempfile
from collections import defaultdict
from dataclasses import replace
from functools import partial
from pathlib import Path

import _arguments as arguments
import numpy as np
from _timing import call_seconds, inside, timed
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

from emmi_gym.concurrency.parallel import ProcessActor
from emmi_gym.tools.training import callbacks
from emmi_gym.tools.training.config import algorithm_class, load_agent_config, rollout_workers
from emmi_gym.tools.training.rollout_workers import RolloutWorker, RolloutWorkers, acting_of, is_masked
from emmi_gym.tools.training.train import make_agent_env, model_of, set_torch_threads, train, training_torch_threads

SPENT: dict = defaultdict(float)
#: Worker counts the efficiency is predicted for (besides the run's own).
PREDICTED_WORKERS = (16, 64)


def single_thread_decision_seconds(config, decisions: int) -> np.ndarray:
    """The wall time of each decision of one rollout worker playing alone (see the docstring): the first
    ``decisions`` of every env of the run, one env after another."""
    env_fn = partial(make_agent_env, config.env_id, config.env_kwargs)
    model = model_of(config, DummyVecEnv([env_fn]))  # the initial weights of the run's model (same seed)
    weights, acting = model.policy.state_dict(), acting_of(model, is_masked(model))
    times = []
    for rank in range(config.n_envs):
        worker = ProcessActor(f"worker {rank} alone", RolloutWorker, env_fn, range(rank, rank + 1), config.seed)
        try:
            worker.submit("set_policy", copy.deepcopy(model.policy).to("cpu"), acting)
            worker.submit("reset")
            worker.result()

            def decide(worker=worker):
                worker.submit("play", weights, 1)
                worker.result()

            times.append(call_seconds(decide, decisions, warmup=0))
        finally:
            worker.close(5.0)
    return np.concatenate(times)


def expected_max(times: np.ndarray, workers: int, steps: int, rng, draws: int = 2000) -> float:
    """E[max over ``workers`` of a sum of ``steps`` decision times], the times drawn from ``times``."""
    sums = np.zeros((draws, workers))
    for _ in range(steps):
        sums += rng.choice(times, size=(draws, workers))
    return float(sums.max(axis=1).mean())


def predicted_efficiency(times: np.ndarray, workers: int, n_steps: int, learner_per_decision: float) -> dict:
    """The efficiency models of the module docstring at ``workers`` workers."""
    rng, m, u = np.random.default_rng(0), float(times.mean()), learner_per_decision
    slowest_fragment = expected_max(times, workers, n_steps, rng)
    return {"rollout workers": n_steps * m / (slowest_fragment + u * workers * n_steps),
            "with policy_lag 1": n_steps * m / max(slowest_fragment + u * n_steps, u * workers * n_steps),
            "synchronous vector env": m / (expected_max(times, workers, 1, rng) + u * workers)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="agents/ppo_plans_emmi.yaml")
    parser.add_argument("--timesteps", type=arguments.integer(1), default=None, help="override total_timesteps")
    parser.add_argument("--n-envs", type=arguments.integer(1), default=None, help="override n_envs")
    parser.add_argument("--vec-env", default=None, help="override vec_env")
    parser.add_argument("--policy-lag", type=arguments.integer(0, 1), default=None, help="override policy_lag")
    parser.add_argument("--single", type=arguments.integer(1), default=None,
                        help="decisions per env of the worker playing alone (default n_steps: the first fragments)")
    parser.add_argument("--out", default=None, help="run folder (default: a temporary one, removed after)")
    args = parser.parse_args()
    config = load_agent_config(args.config)
    overrides = {"total_timesteps": args.timesteps, "n_envs": args.n_envs, "vec_env": args.vec_env,
                 "policy_lag": args.policy_lag}
    config = replace(config, **{k: v for k, v in overrides.items() if v is not None})
    if config.policy_lag and not rollout_workers(config.n_envs, config.vec_env):
        parser.error(f"--policy-lag 1 needs rollout workers (vec_env workers with n_envs > 1, or ray_workers), "
                     f"not vec_env {config.vec_env} with n_envs {config.n_envs}")

    n_steps = config.hyperparameters.get("n_steps", 2048)
    single = single_thread_decision_seconds(config, args.single or n_steps)
    single_rate = 1.0 / single.mean()

    set_torch_threads(training_torch_threads(config))  # as emmi-gym train: the same network as it trains
    cls = algorithm_class(config.algorithm)
    timed(cls, "train", SPENT, "learning")
    for vec_cls, method in ((RolloutWorkers, "play"), (RolloutWorkers, "reset"), (SubprocVecEnv, "step_wait"),
                            (SubprocVecEnv, "reset"), (DummyVecEnv, "step_wait"), (DummyVecEnv, "reset")):
        # the periodic evaluation's env steps are not the training's
        timed(vec_cls, method, SPENT, "waiting for the envs", when=lambda env, *args: not inside("evaluation"))
    timed(callbacks.GroundTruthEvalMixin, "_on_step", SPENT, "evaluation",
          when=lambda cb: cb.eval_freq > 0 and cb.n_calls % cb.eval_freq == 0)  # as the callback decides
    with tempfile.TemporaryDirectory() as scratch:
        result = train(config, Path(args.out or scratch) / "run", progress=False)
    wall, decisions, workers = result.wall_seconds, result.timesteps, config.n_envs
    waiting = SPENT["waiting for the envs"]
    rate = decisions / wall
    print(f"{config.algorithm} on {config.env_id}, {workers} env(s) ({config.vec_env}"
          f"{', policy_lag 1' if config.policy_lag else ''}), {decisions} decisions "
          f"in {wall:.1f} s: {rate:.2f} decisions/s")
    print(f"  one worker alone: {single_rate:.2f} decisions/s ({len(single)} decisions; per decision median "
          f"{np.median(single):.3f} s, p90 {np.quantile(single, 0.9):.3f} s, max {single.max():.3f} s)")
    print(f"  efficiency: {rate:.2f} / ({workers} x {single_rate:.2f}) = {100 * rate / (workers * single_rate):.0f}%")
    parts = {"waiting for the envs": waiting, "evaluation": SPENT["evaluation"],
             "learning (train())": SPENT["learning"]}
    parts["other (the learner's replay, checkpoints, logging)"] = max(0.0, wall - sum(parts.values()))
    for name, seconds in parts.items():
        print(f"  {name}: {seconds:.3f} s ({100 * seconds / wall:.0f}%)")
    learner = wall - waiting
    update = (learner - SPENT["evaluation"]) / decisions  # the evaluation is a schedule's choice (eval.freq 0)
    print(f"  the learner's share of the wall time: {100 * learner / wall:.0f}% "
          f"({1000 * update:.1f} ms per decision less the evaluation)")
    print(f"  predicted efficiency (n_steps {n_steps}), with the learner as measured ({1000 * update:.1f} ms per "
          f"decision) / with a learner that does not hold up the workers (a GPU's update):")
    for count in sorted({workers, *PREDICTED_WORKERS}):
        measured, free = (predicted_efficiency(single, count, n_steps, u) for u in (update, 0.0))
        print(f"    {count:3d} workers: " + ", ".join(f"{name} {100 * measured[name]:.0f}% / {100 * free[name]:.0f}%"
                                                 for name in measured))


if __name__ == "__main__":
    main()
