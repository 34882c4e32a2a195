"""Connecting to Ray (https://www.ray.io), the distributed engine that spreads work over a cluster:
benchmark jobs as Ray tasks, training envs as Ray actors."""

from __future__ import annotations

#: The address that starts a Ray instance on this machine instead of joining a cluster.
LOCAL = "local"


def connect_ray(address: str | None = LOCAL):
    """Connect to the Ray cluster at ``address`` (``"local"``: start one on this machine; ``None``:
    Ray's own default, the ``RAY_ADDRESS`` environment variable, else a local instance) unless this
    process is connected already. Returns ``(ray, started_here)``: the caller shuts down what it started."""
    try:
        import ray
    except ImportError:
        raise ValueError("Ray is not installed: pip install 'emmi-gym[ray]'") from None
    if ray.is_initialized():
        return ray, False
    ray.init(address=None if address in (None, LOCAL) else address, include_dashboard=False,
             logging_level="ERROR", log_to_driver=False)
    return ray, True
