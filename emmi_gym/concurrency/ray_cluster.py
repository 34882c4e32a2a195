"""Connecting to Ray (https://www.ray.io), the distributed engine that spreads work over a cluster:
benchmark jobs as Ray tasks, training envs and rollout workers as Ray actors."""

from __future__ import annotations

import ipaddress
import os
import signal
import socket
import sys
import threading
import warnings
from types import MappingProxyType
from urllib.parse import urlsplit

from ..inputs.extras import missing_extra

#: The address that starts a Ray instance on this machine instead of joining a cluster.
LOCAL = "local"
#: The address a Ray instance started here binds: the loopback one, so that nothing beyond this machine reaches it.
LOOPBACK = "127.0.0.1"
#: Ray's switch for a machine without clusters, read when Ray is imported: off, its node's address is the loopback
#: one, which its GCS, raylet and workers then bind (Ray turns a ``_node_ip_address`` of 127.0.0.1 into the
#: machine's reachable address unless it is off; on, they bind every interface).
SINGLE_MACHINE_VARIABLE = ("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
#: Ray's settings (its ``_system_config``) for a Ray instance started here. Ray runs its workers at a niceness 15
#: above its raylet's (``worker_niceness``, in Ray's ``ray_config_def.h``), so that on a shared cluster node its
#: own daemons stay responsive; a local instance is this process's own work, so its workers run at this process's
#: priority (beside two busy loops on two cores, an actor got 7% of a core at Ray's default, 35% at ours).
#: Read-only: Ray adds its own keys to the dict it is given, so each start gets a copy.
LOCAL_SYSTEM_CONFIG = MappingProxyType({"worker_niceness": 0})


def public_host(address: str) -> str | None:
    """The host of a Ray ``address`` (``host:port`` or ``ray://host:port``) if it is neither a private nor a
    loopback address (nor a name that resolves only to such); None otherwise, or if it does not resolve."""
    host = urlsplit(address if "://" in address else f"ray://{address}").hostname
    if host is None:
        return None
    try:
        found = {ipaddress.ip_address(info[4][0].split("%")[0]) for info in socket.getaddrinfo(host, None)}
    except (OSError, UnicodeError):
        return None
    return None if all(ip.is_private or ip.is_loopback for ip in found) else host


def ray_init_arguments(address: str | None, environ=None) -> dict:
    """The keywords of ``ray.init`` that :func:`connect_ray` passes for ``address``: no dashboard, Ray's logs kept
    out of the terminal, and for a Ray instance started on this machine (``"local"``, or ``None`` where the
    ``environ`` (default ``os.environ``) sets no ``RAY_ADDRESS``) a new instance (Ray's ``address="local"``: never
    the cluster an earlier ``ray start``, or one killed uncleanly, left its address for) whose node, GCS and
    raylet bind the loopback address only (:data:`LOOPBACK`; a Ray cluster has no authentication) and whose
    workers run at this process's priority (:data:`LOCAL_SYSTEM_CONFIG`)."""
    environ = os.environ if environ is None else environ
    arguments = {"address": address, "include_dashboard": False, "logging_level": "ERROR", "log_to_driver": False}
    if address == LOCAL or (address is None and not environ.get("RAY_ADDRESS")):
        arguments.update(address=LOCAL, _node_ip_address=LOOPBACK, _system_config=dict(LOCAL_SYSTEM_CONFIG))
    return arguments


def connect_ray(address: str | None = LOCAL):
    """Connect to the Ray cluster at ``address`` (``"local"``: start a new one on this machine, bound to the
    loopback address, its workers at this process's priority; ``None``: the ``RAY_ADDRESS`` environment variable,
    else a local instance) unless this process is connected already, with a warning if the address is not a
    private or loopback one (a Ray cluster has no authentication: whoever reaches its ports runs code on its
    nodes). Returns ``(ray, started_here)``: the caller shuts down what it started."""
    arguments = ray_init_arguments(address)
    local = "_node_ip_address" in arguments
    if local and "ray" not in sys.modules:  # before Ray is imported, here and in the processes it starts
        os.environ.setdefault(*SINGLE_MACHINE_VARIABLE)
    try:
        import ray
    except ModuleNotFoundError as error:
        raise missing_extra(error, "Ray") or error from None
    if ray.is_initialized():
        return ray, False
    if local and ray.util.get_node_ip_address() != LOOPBACK:
        warnings.warn(f"Ray was imported before {SINGLE_MACHINE_VARIABLE[0]}={SINGLE_MACHINE_VARIABLE[1]} was set: "
                      f"the local Ray instance listens on {ray.util.get_node_ip_address()} and every interface, not "
                      "on the loopback address only", stacklevel=2)
    host = None if address in (None, LOCAL, "auto") else public_host(address)
    if host is not None:
        warnings.warn(f"--ray {address}: {host} is not a private or loopback address; a Ray cluster has no "
                      "authentication (whoever reaches its ports runs code on every node): keep its head on a "
                      "private network (see docs/scaling.md)", stacklevel=2)
    own_sigterm = signal.getsignal(signal.SIGTERM) if threading.current_thread() is threading.main_thread() else None
    ray.init(**arguments)
    if own_sigterm is not None:  # Ray's driver handler exits at once; a run saves a checkpoint first (as Ctrl-C)
        signal.signal(signal.SIGTERM, own_sigterm)
    return ray, True


class RayActor:
    """An object built by ``factory(*args)`` in a Ray actor (one CPU) with the calls of
    :class:`emmi_gym.concurrency.parallel.ProcessActor`: :meth:`submit` a method, read its :meth:`result`
    (what the actor raised, raised here as :class:`~emmi_gym.concurrency.parallel.ActorFailed` naming it),
    :meth:`close`. Arguments may be Ray object references (``ray.put``), which the actor receives resolved."""

    def __init__(self, ray, name: str, factory, *args):
        self._ray, self.name = ray, name
        self.actor = ray.remote(num_cpus=1)(factory).remote(*args)
        self._reply = None
        self._call = "it to be built"

    def submit(self, method: str, *args) -> None:
        self._reply = getattr(self.actor, method).remote(*args)
        self._call = f"its reply to {method}"

    def result(self, heartbeat_timeout: float | None = None):
        """What the submitted call returned; what the actor raised, or its end, as an
        :class:`~emmi_gym.concurrency.parallel.ActorFailed`. Ray watches its actors' processes itself but gives
        no sign of progress within a call, so ``heartbeat_timeout`` bounds the whole call here (a
        :class:`~emmi_gym.concurrency.parallel.ActorStalled` if it has not ended by then)."""
        from .parallel import ActorFailed, ActorStalled

        reply, self._reply = self._reply, None
        if heartbeat_timeout is not None and not self._ended(reply, heartbeat_timeout):
            raise ActorStalled(f"{self.name} (a Ray actor) has not ended its call within {heartbeat_timeout:g} s: "
                               "it was stopped, or is stuck in its env")
        try:
            return self._ray.get(reply)
        except self._ray.exceptions.RayError as error:
            cause = getattr(error, "cause", None) or error
            raise ActorFailed(f"{self.name}: {type(cause).__name__}: {str(cause).strip().splitlines()[-1]}") from None

    def _ended(self, reply, timeout: float) -> bool:
        """Whether the call of ``reply`` ends within ``timeout`` seconds; a warning if it has not after
        :data:`~emmi_gym.concurrency.parallel.SILENCE_NOTICE` seconds of a longer ``timeout``."""
        from .parallel import SILENCE_NOTICE, warn_of_silence

        if timeout > SILENCE_NOTICE:
            if self._ray.wait([reply], timeout=SILENCE_NOTICE)[0]:
                return True
            warn_of_silence(f"{self.name} (a Ray actor) has not ended its call", self._call, timeout)
            timeout -= SILENCE_NOTICE
        return bool(self._ray.wait([reply], timeout=timeout)[0])

    def ask_to_close(self) -> None:
        """Nothing to ask: :meth:`close` ends the actor."""

    def close(self, timeout: float) -> None:
        """End the actor, after the call under way if it ends within ``timeout`` seconds."""
        if self._reply is not None:
            self._ray.wait([self._reply], timeout=timeout)
        self._ray.kill(self.actor)
