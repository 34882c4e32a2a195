"""Rollout workers: each env in a worker of its own (a local process or a Ray actor) that plays whole
rollout fragments with a CPU copy of the policy, while the learner waits once per fragment.

A synchronous vector env steps every env together and waits for the slowest at each decision; a
decision's time is heavy-tailed (a waypoint drive takes 10 ms to a second), so with many envs the
cores idle most of the time. Here, as in Ray RLlib's env runners and Sample Factory's rollout
workers, the learner sends the policy's weights (through Ray's object store on a cluster) and each
worker plays ``n_steps`` decisions on its own: it samples the actions (with the action masks for
MaskablePPO), steps its env (Stable-Baselines3's ``DummyVecEnv``, so automatic resets,
``terminal_observation`` and ``Monitor``'s episode records are SB3's own), and sends back the
fragment: observations, actions, values, log-probabilities, masks, rewards, ends and infos. The
waits are then one per fragment, and the sum of many decisions varies far less than one decision.

:class:`RolloutWorkers` is the learner's handle on the workers, a ``VecEnv`` for SB3 (spaces,
``reset``, attribute calls) that does not step. :func:`algorithm_with_workers` gives an
on-policy algorithm (PPO, A2C, MaskablePPO) whose ``collect_rollouts`` takes the fragments and
replays them step by step exactly as SB3's own loop does: the callbacks see each step's locals
(the semi-Markov discounts, checkpoints, evaluations, the progress bar), a truncated episode's
reward is bootstrapped with the value of its terminal observation, the buffer gets the same
entries SB3 would have stored for the same actions, and the algorithm's own ``train()`` learns
from it. Models of that class save and load as the algorithm itself.

``collect_rollouts`` is the method SB3's developer guide names for how an algorithm gathers its
samples (sb3-contrib's MaskablePPO and RecurrentPPO override it too), and the override uses SB3's
public names only: a fragment carries the observations and episode starts its first step was
played from (the workers hold the envs' state, so the learner keeps no copy), and ended episodes
go to the model's public ``ep_info_buffer`` and ``ep_success_buffer`` (:func:`record_episodes`).

With ``policy_lag=1`` the workers do not wait for the update: as soon as the learner has a rollout's
fragments it sends the weights it holds and the workers play the next fragment with them while it
updates, so the update no longer holds up the workers (Sample Factory's asynchronous PPO, Petrenko et
al. 2020, and IMPALA-style learners, Espeholt et al. 2018, do the same). Each rollout is then played
with the weights of one update before the learner's: the buffer keeps the behaviour policy's
log-probabilities and values, so PPO's clipped ratio ``pi_theta / pi_behaviour`` (Schulman et al. 2017,
Eq. 7) bounds the step from the policy that acted, as Sample Factory's does. The default, 0, is SB3's
on-policy schedule exactly.

The envs are made as SB3's ``make_vec_env`` makes them (env ``i`` seeded ``seed + i``, its action
space too), and each worker samples its actions from a torch generator seeded from ``(seed, i)``:
the same seeds give the same rollouts with local processes and with Ray actors, on any nodes.
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass
from functools import cache

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.utils import obs_as_tensor
from stable_baselines3.common.vec_env import VecEnv

from ...concurrency.parallel import ProcessActor, beat, one_kernel_thread
from ...concurrency.ray_cluster import RayActor, connect_ray

#: Seconds :meth:`RolloutWorkers.close` lets a worker finish the fragment under way before it is ended.
CLOSE_TIMEOUT = 5.0


@dataclass(frozen=True)
class Acting:
    """How a worker turns the policy's outputs into env actions, as the algorithm's ``collect_rollouts``
    does: masks (MaskablePPO), gSDE noise resampled every ``sde_sample_freq`` decisions, Box actions
    unscaled (squashing policies) or clipped to the action space."""

    masking: bool
    use_sde: bool
    sde_sample_freq: int


@dataclass
class Fragment:
    """``n_steps`` decisions of a worker's envs, arrays ``(n_steps, envs, ...)``: the observations after
    each step (``new_obs``), the sampled actions (before clipping), the values and log-probabilities of
    the acting forward pass, the masks it used (None without masking), rewards, ends and each step's
    infos (a list per step of a dict per env); and, arrays ``(envs, ...)``, the observations the first
    step was played from (``first_obs``) and whether each env's episode began there (``first_starts``:
    after a reset, or the previous fragment's last ``dones``)."""

    first_obs: dict | np.ndarray
    first_starts: np.ndarray
    new_obs: dict | np.ndarray
    actions: np.ndarray
    values: np.ndarray
    log_probs: np.ndarray
    action_masks: np.ndarray | None
    rewards: np.ndarray
    dones: np.ndarray
    infos: list


def _stack_steps(observations: list):
    """Each step's observations (dicts of arrays, or arrays) stacked on a new first axis."""
    if isinstance(observations[0], dict):
        return {key: np.stack([obs[key] for obs in observations]) for key in observations[0]}
    return np.stack(observations)


def _join_envs(parts: list, axis: int):
    """Observations of several workers' envs (dicts of arrays, or arrays) joined along the envs' ``axis``."""
    if isinstance(parts[0], dict):
        return {key: np.concatenate([part[key] for part in parts], axis) for key in parts[0]}
    return np.concatenate(parts, axis)


def _step_of(observations, step: int):
    """One step of observations stacked by :func:`_stack_steps`."""
    return {key: value[step] for key, value in observations.items()} if isinstance(observations, dict) \
        else observations[step]


class RolloutWorker:
    """The envs of ranks ``ranks`` and a CPU copy of the policy, in the worker's process: plays fragments.
    Its kernels and torch run on one thread (the workers are the parallelism)."""

    def __init__(self, env_fn, ranks: range, seed: int):
        one_kernel_thread()
        th.set_num_threads(1)
        self.env = make_vec_env(env_fn, n_envs=len(ranks), seed=seed, start_index=ranks.start)
        self.env.seed(seed + ranks.start)  # make_vec_env seeds seed + index: env `rank` gets seed + rank
        self.generator_seed = int(np.random.SeedSequence([seed, ranks.start]).generate_state(1)[0])
        self.policy, self.acting, self.obs, self.episode_starts = None, None, None, None

    def spaces(self) -> tuple:
        return self.env.observation_space, self.env.action_space

    def reset(self, seed: int | None = None):
        """Reset the envs (the first env with ``seed`` and the next with the next seeds, if given, else as
        seeded: ``seed + rank`` the first time); their observations."""
        if seed is not None:
            self.env.seed(seed)
        self.obs = self.env.reset()
        self.episode_starts = np.ones(self.env.num_envs, dtype=bool)
        beat()
        return self.obs

    def set_policy(self, policy, acting: Acting) -> None:
        """The policy to act with (a copy of the learner's, on the CPU), its sampling generator seeded."""
        self.policy, self.acting = policy.to("cpu"), acting
        self.policy.set_training_mode(False)
        th.manual_seed(self.generator_seed)

    def call(self, kind: str, name: str, args: tuple, indices: list):
        """``get_attr`` / ``set_attr`` / ``env_method`` of the worker's envs (``indices`` local to it)."""
        return getattr(self.env, kind)(name, *args, indices=indices)

    def play(self, weights: dict, n_steps: int) -> Fragment:
        """``n_steps`` decisions of every env with the policy's ``weights``, as SB3's ``collect_rollouts`` acts."""
        from sb3_contrib.common.maskable.utils import get_action_masks

        if self.obs is None:
            raise RuntimeError("the rollout worker's envs were not reset before its first fragment")
        self.policy.load_state_dict(weights)
        action_space, acting, n_envs = self.env.action_space, self.acting, self.env.num_envs
        first_obs, first_starts = self.obs, self.episode_starts
        if acting.use_sde:
            self.policy.reset_noise(n_envs)
        steps = []
        for step in range(n_steps):
            if acting.use_sde and acting.sde_sample_freq > 0 and step % acting.sde_sample_freq == 0:
                self.policy.reset_noise(n_envs)
            masks = get_action_masks(self.env) if acting.masking else None
            with th.no_grad():
                obs_tensor = obs_as_tensor(self.obs, "cpu")
                actions, values, log_probs = self.policy(obs_tensor, action_masks=masks) if acting.masking \
                    else self.policy(obs_tensor)
            actions = actions.numpy()
            env_actions = actions
            if isinstance(action_space, spaces.Box):
                env_actions = self.policy.unscale_action(actions) if self.policy.squash_output \
                    else np.clip(actions, action_space.low, action_space.high)
            self.obs, rewards, dones, infos = self.env.step(env_actions)
            self.episode_starts = dones
            beat()
            steps.append((self.obs, actions, values.numpy(), log_probs.numpy(), masks, rewards, dones, infos))
        new_obs, actions, values, log_probs, masks, rewards, dones, infos = zip(*steps, strict=False)
        return Fragment(first_obs, first_starts, _stack_steps(new_obs), np.stack(actions), np.stack(values),
                        np.stack(log_probs), np.stack(masks) if acting.masking else None, np.stack(rewards),
                        np.stack(dones), list(infos))

    def close(self) -> None:
        self.env.close()


class RolloutWorkers(VecEnv):
    """``n_envs`` envs made by ``env_fn``, each in a :class:`RolloutWorker` of its own: local processes, or
    Ray actors (one CPU each) with ``ray_address`` (``"local"``: a Ray instance on this machine; ``None``
    and ``on_ray``: ``RAY_ADDRESS``, else local). A ``VecEnv`` for SB3's model (spaces, ``reset``,
    ``get_attr``, ``env_method``); the decisions are played by :meth:`play`, not ``step``. ``policy_lag``
    (0 or 1): how many updates the weights a fragment is played with may be behind the learner's (see the
    module docstring). ``worker_timeout``: the seconds a local worker may go without playing a decision (or
    resetting its envs), and a Ray actor may take over one call (a fragment; Ray gives no progress within a
    call), before a call to it is an :class:`~emmi_gym.concurrency.parallel.ActorStalled` naming it (stopped,
    or stuck in its env); a worker that dies is an
    :class:`~emmi_gym.concurrency.parallel.ActorFailed` naming it."""

    def __init__(self, env_fn, n_envs: int, seed: int, *, on_ray: bool = False, ray_address: str | None = None,
                 policy_lag: int = 0, worker_timeout: float | None = None):
        if policy_lag not in (0, 1):
            raise ValueError(f"policy_lag: 0 or 1 updates, got {policy_lag!r}")
        self._ray, self._started_ray = connect_ray(ray_address) if on_ray else (None, False)
        self.workers = []
        self.closed = False
        self.policy_lag = policy_lag
        self.worker_timeout = worker_timeout
        self._ahead_under_way = False  # the workers are playing the next fragments (policy_lag 1)
        self._ahead: list[Fragment] | None = None  # those fragments, gathered before another call
        self._next_seeds: list[int | None] = [None] * n_envs  # the seeds of the next reset (seed())
        try:
            for rank in range(n_envs):
                args = (f"rollout worker {rank}", RolloutWorker, env_fn, range(rank, rank + 1), seed)
                self.workers.append(RayActor(self._ray, *args) if on_ray else ProcessActor(*args))
            self.workers[0].submit("spaces")
            observation_space, action_space = self.workers[0].result()
        except BaseException:
            self.close()
            raise
        self._policy_sent = False
        super().__init__(n_envs, observation_space, action_space)

    def _each(self, calls: list[tuple]) -> list:
        """Each ``(rank, method, *args)`` on the worker of env ``rank``, all at once; their results in order
        (after the fragments played ahead, if any, which are kept for the next :meth:`play`)."""
        self._gather_ahead()
        for rank, method, *args in calls:
            self.workers[rank].submit(method, *args)
        return [self.workers[rank].result(self.worker_timeout) for rank, *_ in calls]

    def _all(self, method: str, *args) -> list:
        return self._each([(rank, method, *args) for rank in range(self.num_envs)])

    def _gather_ahead(self) -> None:
        """Wait for the fragments played ahead (if under way) and keep them, so the workers take other calls."""
        if self._ahead_under_way:
            self._ahead_under_way = False
            self._ahead = [worker.result(self.worker_timeout) for worker in self.workers]

    def reset(self):
        """Reset every env (with the seeds given to ``seed``, if any); their observations. Fragments played
        ahead from the envs' earlier state are dropped."""
        self._gather_ahead()
        self._ahead = None
        observations = self._each([(rank, "reset", seed) for rank, seed in enumerate(self._next_seeds)])
        self._next_seeds = [None] * self.num_envs
        return _join_envs(observations, 0)

    def seed(self, seed: int | None = None) -> list[int | None]:
        """SB3's ``VecEnv.seed``: the envs' next reset seeds them ``seed + rank`` (a random ``seed`` if None)."""
        self._next_seeds = list(super().seed(seed))
        return self._next_seeds

    def play(self, policy, n_steps: int, acting: Acting) -> Fragment:
        """The fragments of ``n_steps`` decisions of every worker, joined along the envs in rank order:
        played with ``policy``'s current weights, or with ``policy_lag`` 1, those the workers played ahead
        with the weights of the call before (the first call plays with the current ones); with
        ``policy_lag`` 1 the workers then start the next fragments with the current weights."""
        if not self._policy_sent:
            self._all("set_policy", copy.deepcopy(policy).to("cpu"), acting)
            self._policy_sent = True
        # a snapshot: with a policy lag the learner's update must not write into what a worker reads
        weights = {name: tensor.detach().cpu().clone() for name, tensor in policy.state_dict().items()}
        if self._ray is not None:
            weights = self._ray.put(weights)  # once into the object store, read by every actor
        self._gather_ahead()
        fragments, self._ahead = self._ahead, None
        if fragments is None:
            fragments = self._all("play", weights, n_steps)
        if self.policy_lag:
            for worker in self.workers:
                worker.submit("play", weights, n_steps)
            self._ahead_under_way = True
        join = lambda name: np.concatenate([getattr(f, name) for f in fragments], 1)  # noqa: E731
        return Fragment(_join_envs([f.first_obs for f in fragments], 0),
                        np.concatenate([f.first_starts for f in fragments]),
                        _join_envs([f.new_obs for f in fragments], 1), join("actions"), join("values"),
                        join("log_probs"), join("action_masks") if acting.masking else None, join("rewards"),
                        join("dones"), [sum((f.infos[step] for f in fragments), []) for step in range(n_steps)])

    def _by_worker(self, kind: str, name, args: tuple, indices) -> list:
        """``kind`` (``get_attr``, ``set_attr``, ``env_method``, ``env_is_wrapped``) of the envs ``indices``."""
        ranks = range(self.num_envs) if indices is None else [indices] if isinstance(indices, int) else indices
        return [result[0] for result in self._each([(rank, "call", kind, name, args, [0]) for rank in ranks])]

    def get_attr(self, attr_name: str, indices=None) -> list:
        return self._by_worker("get_attr", attr_name, (), indices)

    def set_attr(self, attr_name: str, value, indices=None) -> None:
        self._by_worker("set_attr", attr_name, (value,), indices)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list:
        if method_kwargs:
            raise TypeError("rollout workers call env methods with positional arguments only")
        return self._by_worker("env_method", method_name, method_args, indices)

    def env_is_wrapped(self, wrapper_class, indices=None) -> list:
        return self._by_worker("env_is_wrapped", wrapper_class, (), indices)

    def step_async(self, actions) -> None:
        raise TypeError("rollout workers play whole fragments (RolloutWorkers.play): train them with "
                        "algorithm_with_workers(...)")

    def step_wait(self):
        raise TypeError("rollout workers play whole fragments (RolloutWorkers.play)")

    def close(self) -> None:
        """End every worker (they may finish the fragments under way within :data:`CLOSE_TIMEOUT` s in all, but
        fragments played ahead, which no update will read, are cut short), and the Ray instance if this started
        it. Safe after an interrupt left a fragment half played."""
        if self.closed:
            return
        for worker in self.workers:
            worker.ask_to_close()
        deadline = time.monotonic() + (0.0 if self._ahead_under_way else CLOSE_TIMEOUT)
        for worker in self.workers:
            worker.close(max(0.0, deadline - time.monotonic()))
        if self._started_ray:
            self._ray.shutdown()
        self.closed = True


class _FragmentCollection:
    """An on-policy algorithm's ``collect_rollouts`` on :class:`RolloutWorkers` (see the module docstring)."""

    def collect_rollouts(self, env, callback, rollout_buffer, n_rollout_steps: int, use_masking: bool = True) -> bool:
        """SB3's ``collect_rollouts`` (sb3-contrib's for MaskablePPO), its steps read from the workers'
        fragments instead of played here: the same callbacks, bootstrap and buffer entries."""
        if not isinstance(env, RolloutWorkers):
            raise TypeError(f"{type(self).__name__} collects from RolloutWorkers, not {type(env).__name__}")
        masking = use_masking and is_masked(self)
        self.policy.set_training_mode(False)
        rollout_buffer.reset()
        callback.on_rollout_start()
        fragment = env.play(self.policy, n_rollout_steps, acting_of(self, masking))
        last_obs, last_episode_starts = fragment.first_obs, fragment.first_starts
        masks = {}
        for n_steps in range(n_rollout_steps):
            new_obs, rewards, dones, infos = (_step_of(fragment.new_obs, n_steps), fragment.rewards[n_steps].copy(),
                                              fragment.dones[n_steps], fragment.infos[n_steps])
            actions, values = fragment.actions[n_steps], th.as_tensor(fragment.values[n_steps])
            log_probs = th.as_tensor(fragment.log_probs[n_steps])
            if masking:
                masks = {"action_masks": fragment.action_masks[n_steps]}
            self.num_timesteps += env.num_envs
            callback.update_locals(locals())
            if not callback.on_step():
                return False
            record_episodes(self, infos, dones)
            if isinstance(self.action_space, spaces.Discrete):
                actions = actions.reshape(-1, 1)
            for idx, done in enumerate(dones):  # a truncated episode: bootstrap with V(terminal observation)
                if done and infos[idx].get("terminal_observation") is not None and \
                        infos[idx].get("TimeLimit.truncated", False):
                    terminal_obs = self.policy.obs_to_tensor(infos[idx]["terminal_observation"])[0]
                    with th.no_grad():
                        terminal_value = self.policy.predict_values(terminal_obs)[0]
                    rewards[idx] += self.gamma * terminal_value
            rollout_buffer.add(last_obs, actions, rewards, last_episode_starts, values, log_probs, **masks)
            last_obs, last_episode_starts = new_obs, dones
        with th.no_grad():
            values = self.policy.predict_values(obs_as_tensor(new_obs, self.device))
        rollout_buffer.compute_returns_and_advantage(last_values=values, dones=dones)
        callback.update_locals(locals())
        callback.on_rollout_end()
        return True


def record_episodes(model, infos: list, dones: np.ndarray) -> None:
    """What SB3's own loop keeps of a step's ``infos`` for its logs, through the model's public buffers: each
    ended episode's ``Monitor`` record (``info["episode"]``) in ``ep_info_buffer``, and the ``is_success`` of
    each env whose episode ended in ``ep_success_buffer``."""
    for info, done in zip(infos, dones, strict=True):
        if info.get("episode") is not None:
            model.ep_info_buffer.extend([info["episode"]])
        if info.get("is_success") is not None and done:
            model.ep_success_buffer.append(info["is_success"])


def is_masked(model) -> bool:
    """Whether ``model`` acts with action masks (MaskablePPO)."""
    from sb3_contrib import MaskablePPO

    return isinstance(model, MaskablePPO)


def acting_of(model, masking: bool) -> Acting:
    """How a worker acts for ``model`` (an on-policy algorithm), with masks or not."""
    return Acting(masking, model.use_sde, model.sde_sample_freq)


@cache
def algorithm_with_workers(algorithm_class):
    """``algorithm_class`` (an on-policy SB3 algorithm) collecting its rollouts from :class:`RolloutWorkers`."""
    return type(algorithm_class.__name__, (_FragmentCollection, algorithm_class),
                {"__module__": __name__, "__qualname__": algorithm_class.__name__,
                 "__doc__": f"{algorithm_class.__name__} collecting its rollouts from rollout workers."})


def algorithm_for(algorithm_class, env):
    """The class to make or load a model of ``algorithm_class`` on ``env``: with rollout workers, one that
    collects from them."""
    return algorithm_with_workers(algorithm_class) if isinstance(env, RolloutWorkers) else algorithm_class
