"""Training an agent from its configuration: vectorised envs, TensorBoard, a progress bar,
periodic held-out evaluation with the ground-truth metrics, checkpoints, resuming, Ctrl-C safety.

The run folder, its files and what a run checks before it writes anything (a folder in use, a resumed
configuration, the model it starts from) are :class:`~emmi_gym.tools.training.run_folders.RunFolder`'s; every file
is written under a temporary name and renamed into place (:func:`~emmi_gym.formats.atomic_files.write_atomically`),
and training stops at the first non-finite number (:class:`~emmi_gym.tools.training.callbacks.StopOnNonFinite`),
so no file of a run is ever half written or holds NaN weights.
"""

from __future__ import annotations

import copy
import gc
import os
import signal
import sys
import threading
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import gymnasium as gym
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv
from torch.optim.optimizer import register_optimizer_step_post_hook, register_optimizer_step_pre_hook

from ...concurrency.interrupts import RunStopped
from ...concurrency.parallel import ActorFailed, leave_terminal_signals, one_kernel_thread
from ...formats.atomic_files import write_atomically
from ..evaluation.loop_order import LoopOrderInfo
from .callbacks import (
    DecisionProgress,
    NonFiniteError,
    OnRunSchedule,
    StopOnNonFinite,
    check_weights,
    eval_callback_class,
)
from .config import AgentConfig, algorithm_class, policy_argument, rollout_workers, sb3_policy_kwargs
from .run_folders import RunFolder, RunStart
from .run_folders.model_files import load_model_file
from .run_folders.training_record import earlier_parts
from .semi_markov import SemiMarkovDiscounts, rollout_buffer_class
from .update_boundaries import UpdateBoundaries

OFF_POLICY = ("DQN", "SAC")


@dataclass(frozen=True)
class TrainResult:
    run_dir: Path
    model_path: Path
    timesteps: int
    wall_seconds: float
    interrupted: bool = False


#: torch threads of the learner unless told otherwise, beside env processes and in evaluations: the
#: envs need the cores (torch's default threads beside busy env workers slow PPO several times over).
DEFAULT_TORCH_THREADS = 1


def training_torch_threads(config: AgentConfig) -> int:
    """torch threads for training ``config``: :data:`DEFAULT_TORCH_THREADS` beside env subprocesses and
    rollout workers, one per core when the envs run in this process (the learner and the envs then take
    turns, never competing for the cores). Rollout workers wait while the learner updates, but an update
    of the waypoint agents on two threads took 2-10 times as long as on one (256 decisions of
    ``ppo_plans_emmi.yaml``, 2-core VM)."""
    return DEFAULT_TORCH_THREADS if _subprocesses(config.n_envs, config.vec_env) else max(1, os.cpu_count() or 1)


def set_torch_threads(threads: int | None = None) -> int:
    """Set torch's intra-op threads (``None``: :data:`DEFAULT_TORCH_THREADS`); returns the number set."""
    import torch

    threads = DEFAULT_TORCH_THREADS if threads is None else threads
    if not (isinstance(threads, int) and 1 <= threads <= 1024):
        raise ValueError(f"--torch-threads: expected an integer in [1, 1024], got {threads!r}")
    torch.set_num_threads(threads)
    return threads


def make_agent_env(env_id: str, kwargs: dict, render_mode: str | None = None, *, vec_worker: bool = False) -> gym.Env:
    """``gym.make`` of an emmi_gym id, wrapped to report the episode's loop order (:class:`LoopOrderInfo`);
    importable by reference, so spawned workers can build it. In a ``vec_worker`` (a subprocess of
    vectorised envs) Ctrl-C is ignored and the terminal's process group left (the main process handles Ctrl-C
    and SIGTERM and closes the workers) and the kernels run on one thread (the processes are the parallelism)."""
    import emmi_gym  # noqa: F401  (registers the ids in a fresh worker process)

    if vec_worker:
        leave_terminal_signals()
        one_kernel_thread()
    return LoopOrderInfo(gym.make(env_id, render_mode=render_mode, **kwargs))


def make_vec_env(config: AgentConfig, n_envs: int, seed: int, vec_env: str, *, evaluation: bool = False,
                 ray_address: str | None = None):
    """SB3 vectorised envs (Monitor-wrapped): rollout workers (``vec_env="workers"``: local processes,
    ``"ray_workers"``: Ray actors) or subprocesses when asked and there is more than one env, Ray
    actors with ``vec_env="ray"`` (Ray on the cluster at ``ray_address``; ``None``: ``RAY_ADDRESS``, else a
    local instance); with ``evaluation``, envs made with the held-out evaluation's keywords
    (``eval.env_kwargs``)."""
    from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env

    kwargs = config.eval_env_kwargs if evaluation else config.env_kwargs
    if rollout_workers(n_envs, vec_env):
        from .rollout_workers import RolloutWorkers

        return RolloutWorkers(partial(make_agent_env, config.env_id, kwargs, vec_worker=True), n_envs, seed,
                              on_ray=vec_env == "ray_workers", ray_address=ray_address,
                              policy_lag=0 if evaluation else config.policy_lag,
                              worker_timeout=config.worker_timeout)
    if vec_env == "ray":
        from .ray_vec_env import RayVecEnv

        return sb3_make_vec_env(partial(make_agent_env, config.env_id, kwargs), n_envs=n_envs, seed=seed,
                                vec_env_cls=RayVecEnv, vec_env_kwargs={"address": ray_address})
    subprocesses = _subprocesses(n_envs, vec_env)
    return sb3_make_vec_env(partial(make_agent_env, config.env_id, kwargs, vec_worker=subprocesses),
                            n_envs=n_envs, seed=seed, vec_env_cls=SubprocVecEnv if subprocesses else DummyVecEnv)


def _subprocesses(n_envs: int, vec_env: str) -> bool:
    """Whether :func:`make_vec_env` runs the envs in other processes (subprocesses or Ray actors)."""
    return vec_env in ("ray", "ray_workers") or (vec_env in ("subproc", "workers") and n_envs > 1)


def _handles_ctrl_c() -> bool:
    """Whether this code may set a SIGINT handler: signals are the main thread's, and an ignored
    Ctrl-C (a background job) stays ignored."""
    return threading.current_thread() is threading.main_thread() and \
        signal.getsignal(signal.SIGINT) is not signal.SIG_IGN


@contextmanager
def interrupts_deferred():
    """Hold a Ctrl-C (SIGINT) that arrives inside the block until it ends, then raise it: an
    interrupted ``torch.save`` leaves a broken archive and raises its own error instead."""
    if not _handles_ctrl_c():
        yield
        return
    received = []
    previous = signal.signal(signal.SIGINT, lambda *_: received.append(True))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if received:
        raise KeyboardInterrupt


@contextmanager
def interrupts_remembered(received: list, hold=None):
    """Within the block a Ctrl-C (SIGINT) raises KeyboardInterrupt as usual and is also remembered:
    ``received`` holds True once one arrived; while ``hold()`` is true (an on-policy update under way,
    :class:`~emmi_gym.tools.training.update_boundaries.UpdateBoundaries`) it is only remembered, and
    :class:`StopOnInterrupt` raises it at the next decision.

    Python code called back from C can drop the exception: numba loads and compiles its
    kernels through llvmlite, whose ctypes callbacks discard what they raise (and print it
    as an "Exception ignored" traceback), so a Ctrl-C that arrived there was lost and
    training went on. :class:`StopOnInterrupt` raises it again at the next step;
    :func:`unraisable_interrupts_quiet` keeps what C code discarded from being printed.

    A Ctrl-C that arrives inside a torch optimiser's step is held until the step ends (global step
    hooks): Adam creates a parameter's moment estimates one after the other at its first step, and
    a checkpoint saved between the two cannot be resumed (``KeyError: 'exp_avg_sq'`` at the next
    step); between steps the weights and the optimiser's state agree.
    """
    if not _handles_ctrl_c():
        yield
        return
    stepping = []

    def held() -> bool:
        return hold is not None and hold()

    def remember(signum, frame):
        received.append(True)
        if not stepping and not held():
            raise KeyboardInterrupt

    def step_starts(optimizer, args, kwargs):
        stepping[:] = [True]

    def step_ends(optimizer, args, kwargs):
        stepping.clear()
        if received and not held():
            raise KeyboardInterrupt

    hooks = [register_optimizer_step_pre_hook(step_starts), register_optimizer_step_post_hook(step_ends)]
    previous = signal.signal(signal.SIGINT, remember)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        for hook in hooks:
            hook.remove()


@contextmanager
def unraisable_interrupts_quiet(received: list):
    """Within the block, once ``received`` holds a Ctrl-C (:func:`interrupts_remembered`), neither a
    KeyboardInterrupt that C code discarded nor the failing finaliser of an llvmlite object the
    interrupt left half-built (``ObjectRef.__del__`` on an object whose ``__init__`` never
    finished) is printed (``sys.unraisablehook``); anything else is. Such an object is freed when
    the interrupt's traceback is, after the code that handles the interrupt, or by the garbage
    collector: the block must cover that handling, and it collects before it ends."""
    previous_hook = sys.unraisablehook

    def quiet_when_interrupted(unraisable):
        echo = isinstance(unraisable.exc_value, KeyboardInterrupt) or \
            (getattr(unraisable.object, "__module__", None) or "").startswith("llvmlite.")
        if not (received and echo):
            previous_hook(unraisable)

    sys.unraisablehook = quiet_when_interrupted
    try:
        yield
    finally:
        if received:
            gc.collect()
        sys.unraisablehook = previous_hook


class StopOnInterrupt(BaseCallback):
    """Raise KeyboardInterrupt at the first step after a Ctrl-C that :func:`interrupts_remembered` saw,
    in case its own exception was dropped where it arrived."""

    def __init__(self, received: list):
        super().__init__()
        self.received = received

    def _on_step(self) -> bool:
        if self.received:
            raise KeyboardInterrupt
        return True


class AtomicCheckpointCallback(OnRunSchedule, CheckpointCallback):
    """SB3's checkpoints (same names; the schedule counted from the run's start, :class:`OnRunSchedule`),
    each written to a temporary file and renamed, only of finite weights; ``on_save(decisions)`` is called
    once a checkpoint is written, before it is renamed into place (the run's record then never lags behind
    its newest checkpoint). With ``at_updates`` (on-policy algorithms), a checkpoint that falls due inside a
    rollout is saved at the next update boundary, after the update (the next rollout's start, or the end
    of training), and named by the decisions counted there: it holds the weights of its own decision count,
    and resumed, it loses no update (:mod:`~emmi_gym.tools.training.update_boundaries`)."""

    def __init__(self, *args, on_save=None, at_updates: bool = False, **kwargs):
        super().__init__(*args, **kwargs)
        self.on_save = on_save
        self.at_updates = at_updates
        self.due = False

    def _on_step(self) -> bool:
        if self.n_calls % self.save_freq == 0:
            if self.at_updates:
                self.due = True
            else:
                self._save_checkpoint()
        return True

    def _on_rollout_start(self) -> None:
        if self.due:
            self._save_checkpoint()

    def _on_training_end(self) -> None:
        if self.due:
            self._save_checkpoint()

    def _save_checkpoint(self) -> None:
        self.due = False
        check_weights(self.model, "before a checkpoint")
        with interrupts_deferred():
            if self.save_replay_buffer and getattr(self.model, "replay_buffer", None) is not None:
                write_atomically(self.checkpoint_path("replay_buffer_", "pkl"), self.model.save_replay_buffer)
            write_atomically(self.checkpoint_path("", "zip"), self._save)

    def checkpoint_path(self, kind: str, extension: str) -> Path:
        """Where SB3's ``CheckpointCallback`` names a checkpoint of ``kind`` ("" for the model,
        ``"replay_buffer_"``) at the decisions counted now: ``<save_path>/<name_prefix>_<kind><N>_steps.<extension>``,
        from its public settings."""
        return Path(self.save_path, f"{self.name_prefix}_{kind}{self.num_timesteps}_steps.{extension}")

    def _save(self, path: Path) -> None:
        self.model.save(path)
        if self.on_save is not None:
            self.on_save(self.num_timesteps)


def close_vec_env(env, timeout: float = 3.0) -> None:
    """Close vectorised envs even after an interrupt left a subprocess exchange half done (SB3's
    ``close`` would wait for replies already read, for ever): ask each worker to close, wait up to
    ``timeout`` seconds, then terminate those still running."""
    if not isinstance(env, SubprocVecEnv) or not env.processes or env.closed:  # Ray actors close themselves
        env.close()
        return
    for remote in env.remotes:
        try:
            remote.send(("close", None))
        except OSError:
            pass
    deadline = time.monotonic() + timeout
    for process in env.processes:
        process.join(max(0.0, deadline - time.monotonic()))
        if process.is_alive():
            process.terminate()
            process.join()
    env.closed = True


def sb3_hyperparameters(config: AgentConfig, env) -> dict:
    """The keywords of ``config``'s SB3 algorithm for a model on ``env``: its hyperparameters, the policy's
    keywords as SB3 takes them, and the semi-Markov rollout buffer where ``discount_unit`` is set."""
    hyperparameters = copy.deepcopy(config.hyperparameters)  # SB3 adds to policy_kwargs in place
    if hyperparameters.get("policy_kwargs"):
        hyperparameters["policy_kwargs"] = sb3_policy_kwargs(hyperparameters["policy_kwargs"])
    if config.discount_unit is not None:
        hyperparameters["rollout_buffer_class"] = rollout_buffer_class(
            config.algorithm, isinstance(env.observation_space, gym.spaces.Dict))
    return hyperparameters


def model_of(config: AgentConfig, env, **kwargs):
    """A fresh SB3 model of ``config`` (algorithm, policy, hyperparameters, seed) on ``env``; ``kwargs`` to SB3."""
    from .rollout_workers import algorithm_for

    return algorithm_for(algorithm_class(config.algorithm), env)(policy_argument(config.policy), env,
                                                                 seed=config.seed, **kwargs,
                                                                 **sb3_hyperparameters(config, env))


def train(config: AgentConfig, run_dir, *, resume: bool = False, overwrite: bool = False, progress: bool = True,
          verbose: int = 0, ray_address: str | None = None, init_from=None, allow_no_training: bool = False,
          report=None) -> TrainResult:
    """Train ``config`` into the run folder ``run_dir`` (:class:`~emmi_gym.tools.training.run_folders.RunFolder`),
    after every check of :meth:`~emmi_gym.tools.training.run_folders.RunFolder.plan` (a new run needs an empty folder,
    or ``overwrite``, which first removes the run files there); with ``resume``, continue the folder's run from its
    latest checkpoint up to ``config.total_timesteps``; ``ray_address``: the Ray cluster of ``vec_env:
    ray`` (see :func:`make_vec_env`). ``init_from``: a model (of the same algorithm, env id, spaces and
    network) whose weights a new run starts from, as rl-baselines3-zoo's ``--trained-agent``: it trains
    on with this configuration's env and hyperparameters, and its decisions count towards
    ``total_timesteps`` (if none is left to train: refused unless ``allow_no_training``). ``report``: called
    with a sentence saying where the run starts and how many decisions it will train."""
    from stable_baselines3.common.callbacks import CallbackList

    folder = RunFolder(run_dir)
    start = folder.plan(config, resume=resume, overwrite=overwrite, init_from=init_from,
                        allow_no_training=allow_no_training)
    if start.overwrite:
        folder.clear()
    folder.write_config(config)

    env = make_vec_env(config, config.n_envs, config.seed, config.vec_env, ray_address=ray_address)
    eval_env = make_vec_env(config, 1, config.eval.seed, "dummy", evaluation=True) if config.eval.freq else None
    model = _start_model(config, start, env, folder, verbose)
    first = int(model.num_timesteps)
    earlier = earlier_parts(start.record, first)
    if report is not None:
        report(start.summary(first, config.total_timesteps))
    started = time.perf_counter()

    def record(decisions: int) -> None:
        folder.write_record(earlier, first, decisions, time.perf_counter() - started, start.init_from,
                            start.init_decisions)

    if start.model is not None and start.model == start.init_from and not earlier:  # names its start from now on
        folder.write_record([], first, first, None, start.init_from, start.init_decisions)
    per_env = max(1, config.n_envs)
    on_policy = config.algorithm not in OFF_POLICY
    boundaries = UpdateBoundaries() if on_policy else None
    checkpointing = AtomicCheckpointCallback(max(config.checkpoint_freq // per_env, 1), str(folder.checkpoint_dir),
                                             name_prefix="model", save_replay_buffer=not on_policy, on_save=record,
                                             run_origin=start.init_decisions, at_updates=on_policy)
    callbacks = [StopOnNonFinite(), checkpointing] + ([boundaries] if on_policy else [])
    if eval_env is not None:
        callbacks.append(eval_callback_class(config.algorithm)(
            eval_env, eval_freq=max(config.eval.freq // per_env, 1), n_eval_episodes=config.eval.episodes,
            log_path=str(folder.eval_dir), best_model_save_path=str(folder.eval_dir), deterministic=True,
            verbose=verbose, eval_seed=config.eval.seed, ground_truth_csv=folder.ground_truth_path,
            run_origin=start.init_decisions))
    if config.discount_unit is not None:
        callbacks.append(SemiMarkovDiscounts(config.discount_unit))
    remaining = max(config.total_timesteps - first, 0)
    shown = DecisionProgress(remaining, first) if progress else None
    if shown is not None:
        callbacks.append(shown)
    interrupted = False
    interrupts: list[bool] = []
    with unraisable_interrupts_quiet(interrupts):
        try:
            hold = None if boundaries is None else lambda: boundaries.updating
            with warnings.catch_warnings(), interrupts_remembered(interrupts, hold):
                # the held-out evaluation runs in this process (a DummyVecEnv) while training may use
                # subprocesses: intended, and the same env either way, so SB3's type warning says nothing
                warnings.filterwarnings("ignore", message="Training and eval env are not of the same type")
                model.learn(remaining, callback=CallbackList([StopOnInterrupt(interrupts), *callbacks]),
                            reset_num_timesteps=start.model is None, tb_log_name="run")
            check_weights(model, "at the end")
            with interrupts_deferred():
                model_path = write_atomically(folder.model_path, partial(_save, model, record))
        except KeyboardInterrupt:  # Ctrl-C, kill -INT or SIGTERM: keep what was learnt, as a checkpoint to resume
            interrupted = True
            model_path = _save_checkpoint(model, config, folder, record, "at the interruption", boundaries)
        except ActorFailed as exc:  # a worker died or made no progress: keep what was learnt, say how to go on
            saved = _save_checkpoint(model, config, folder, record, "when a worker failed", boundaries)
            raise RunStopped(f"{exc}. The run stopped and saved {saved}; continue it with: emmi-gym train "
                             f"{config.source} --resume --out {folder.path}") from None
        except NonFiniteError as exc:
            newest = folder.latest_checkpoint()
            raise NonFiniteError(f"{folder.path}: {exc}. Nothing of it was saved; the newest checkpoint, of finite "
                                 f"weights, is {newest if newest is not None else 'none yet'}") from None
        finally:
            if shown is not None:
                shown.close()
            close_vec_env(env)
            if eval_env is not None:
                close_vec_env(eval_env)
    return TrainResult(folder.path, model_path, int(model.num_timesteps), time.perf_counter() - started, interrupted)


def _save_checkpoint(model, config: AgentConfig, folder: RunFolder, record, when: str,
                     boundaries: UpdateBoundaries | None = None) -> Path:
    """Save ``model`` as a checkpoint of the run in ``folder`` (with its replay buffer, off-policy) that ``--resume``
    continues from, once its weights are checked finite (``when`` says when, for the error), and record the run; a
    second Ctrl-C must not cut the save short. Its path. On-policy (``boundaries``), the model is saved under the
    decisions of its last update, which its weights are: the decisions collected since, which no update used, are
    played again when the run resumes, so no update is lost."""
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if _handles_ctrl_c() else None
    try:
        check_weights(model, when)
        if boundaries is not None and boundaries.resumable_decisions() is not None:
            model.num_timesteps = boundaries.resumable_decisions()
        checkpoint = folder.checkpoint_path(int(model.num_timesteps))
        checkpoint.parent.mkdir(parents=True, exist_ok=True)
        if config.algorithm in OFF_POLICY:
            write_atomically(folder.replay_buffer_path(checkpoint), model.save_replay_buffer)
        return write_atomically(checkpoint, partial(_save, model, record))
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def _save(model, record, path: Path) -> None:
    """Save ``model`` to ``path`` and record the run (``record(decisions)``) before the file is renamed into place."""
    model.save(path)
    record(int(model.num_timesteps))


def _start_model(config: AgentConfig, start: RunStart, env, folder: RunFolder, verbose: int):
    """The model a run starts with: the run's own checkpoint (with its replay buffer), the weights of the model
    it starts from (``init_from``: the network is the saved one's, every other setting this configuration's),
    or a fresh model of ``config``."""
    tensorboard_log = str(folder.tensorboard_dir)
    if start.model is None:
        return model_of(config, env, tensorboard_log=tensorboard_log, verbose=verbose)
    if start.model == start.init_from:
        hyperparameters = sb3_hyperparameters(config, env)
        hyperparameters.pop("policy_kwargs", None)
        return load_model_file(start.model, config.algorithm, env=env, seed=config.seed,
                               tensorboard_log=tensorboard_log, verbose=verbose, **hyperparameters)
    model = load_model_file(start.model, config.algorithm, env=env, tensorboard_log=tensorboard_log)
    buffer = folder.replay_buffer_path(start.model)
    if config.algorithm in OFF_POLICY and buffer.exists():
        model.load_replay_buffer(buffer)
    return model
