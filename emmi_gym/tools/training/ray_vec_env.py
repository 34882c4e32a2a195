"""Vectorised envs whose workers are Ray actors, so that training spreads its envs over a cluster.

:class:`RayVecEnv` is Stable-Baselines3's ``SubprocVecEnv`` with each env in a Ray actor instead of
a local subprocess. The actor runs SB3's own worker loop (``subproc_vec_env._worker``) on a queue
instead of a pipe, so stepping, automatic resets, ``terminal_observation``, seeding and every
``env_method`` / ``get_attr`` call behave exactly as with subprocesses: the same seeds give the
same episodes.
"""

from __future__ import annotations

import queue
import threading

from stable_baselines3.common.vec_env import SubprocVecEnv, VecEnv
from stable_baselines3.common.vec_env.base_vec_env import CloudpickleWrapper
from stable_baselines3.common.vec_env.subproc_vec_env import _worker

from ...concurrency.parallel import one_kernel_thread
from ...concurrency.ray_cluster import LOCAL, connect_ray

#: Seconds ``close`` waits for the actors to close their envs before it kills them.
CLOSE_TIMEOUT = 10.0


class _QueuePipe:
    """The worker's end of a pipe, as SB3's worker loop reads and writes it, on two queues."""

    def __init__(self):
        self.inbox, self.outbox = queue.Queue(), queue.Queue()

    def recv(self):
        return self.inbox.get()

    def send(self, message) -> None:
        self.outbox.put(message)

    def close(self) -> None:
        pass


class _WorkerFailed:
    """What the worker loop raised, carried back to the caller of :meth:`_EnvActor.call`."""

    def __init__(self, error: BaseException):
        self.error = error


class _EnvActor:
    """One env in a Ray actor: SB3's worker loop on a thread, fed one command per :meth:`call`."""

    def __init__(self, env_fn: CloudpickleWrapper):
        one_kernel_thread()  # the actors are the parallelism
        self._pipe = _QueuePipe()
        self._thread = threading.Thread(target=self._serve, args=(env_fn,), daemon=True)
        self._thread.start()

    def _serve(self, env_fn: CloudpickleWrapper) -> None:
        try:
            _worker(self._pipe, _QueuePipe(), env_fn)
        except BaseException as error:  # noqa: BLE001 - any failure goes back to the trainer
            self._pipe.send(_WorkerFailed(error))

    def call(self, command: tuple):
        """Run ``(cmd, data)`` in the worker loop and return its reply (``None`` for ``close``)."""
        if not self._thread.is_alive():
            raise RuntimeError("the env worker has stopped")
        self._pipe.inbox.put(command)
        if command[0] == "close":
            self._thread.join(CLOSE_TIMEOUT)
            return None
        reply = self._pipe.outbox.get()
        if isinstance(reply, _WorkerFailed):
            raise reply.error
        return reply


class _ActorConnection:
    """The trainer's end of one actor, with the ``send``/``recv`` of a pipe that ``SubprocVecEnv`` uses."""

    def __init__(self, ray, actor):
        self._ray, self.actor, self._reply = ray, actor, None

    def send(self, command: tuple) -> None:
        self._reply = self.actor.call.remote(command)

    def recv(self):
        reply, self._reply = self._reply, None
        return self._ray.get(reply)

    def close(self) -> None:
        pass


class RayVecEnv(SubprocVecEnv):
    """``SubprocVecEnv`` with its envs in Ray actors (one CPU each) on the cluster at ``address``
    (``"local"``: a Ray instance started on this machine; ``None``: ``RAY_ADDRESS``, else local).

    Build it as SB3 builds any vectorised env:
    ``make_vec_env(env_fn, n_envs, seed=seed, vec_env_cls=RayVecEnv, vec_env_kwargs={"address": ...})``.
    The env functions are pickled to the actors (cloudpickle), so they may be closures.
    """

    def __init__(self, env_fns, address: str | None = LOCAL):
        self.waiting, self.closed = False, False
        self._ray, self._started_ray = connect_ray(address)
        actor_class = self._ray.remote(num_cpus=1)(_EnvActor)
        self.actors = [actor_class.remote(CloudpickleWrapper(env_fn)) for env_fn in env_fns]
        self.remotes = [_ActorConnection(self._ray, actor) for actor in self.actors]
        self.processes = []
        self.remotes[0].send(("get_spaces", None))
        observation_space, action_space = self.remotes[0].recv()
        VecEnv.__init__(self, len(env_fns), observation_space, action_space)

    def close(self) -> None:
        """Close every env (waiting up to :data:`CLOSE_TIMEOUT` s), then end the actors, and the Ray
        instance if this env started it. Safe after an interrupt left a step half done."""
        if self.closed:
            return
        closing = [actor.call.remote(("close", None)) for actor in self.actors]
        self._ray.wait(closing, num_returns=len(closing), timeout=CLOSE_TIMEOUT)
        for actor in self.actors:
            self._ray.kill(actor)
        if self._started_ray:
            self._ray.shutdown()
        self.closed = True
