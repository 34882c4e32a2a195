"""Connecting to Ray: a Ray instance started on this machine is a new one, binds the loopback address only and runs
its workers at the priority of the process that started it."""

import ipaddress
from pathlib import Path

import pytest

from emmi_gym.concurrency.ray_cluster import LOCAL_SYSTEM_CONFIG, LOOPBACK, ray_init_arguments


def test_a_local_ray_instance_is_started_on_the_loopback_address_without_a_dashboard():
    local = {"address": "local", "include_dashboard": False, "logging_level": "ERROR", "log_to_driver": False,
             "_node_ip_address": "127.0.0.1", "_system_config": {"worker_niceness": 0}}
    assert ray_init_arguments("local", {}) == local
    assert ray_init_arguments(None, {}) == local  # no RAY_ADDRESS: a local instance, as --ray without an address
    assert ray_init_arguments("local", {"RAY_ADDRESS": "10.0.0.2:6379"}) == local



def test_what_ray_adds_to_a_system_config_reaches_neither_the_default_nor_the_next_start():
    first = ray_init_arguments("local", {})
    first["_system_config"]["automatic_object_spilling_enabled"] = True  # as ray.init fills in the dict it gets
    assert ray_init_arguments("local", {})["_system_config"] == {"worker_niceness": 0}
    with pytest.raises(TypeError):  # handed to Ray as it is, the default itself would take Ray's keys
        LOCAL_SYSTEM_CONFIG["automatic_object_spilling_enabled"] = True

def test_joining_a_cluster_leaves_its_addresses_to_it():
    joined = ray_init_arguments("10.0.0.2:6379", {})
    assert joined["address"] == "10.0.0.2:6379" and "_node_ip_address" not in joined
    assert not joined["include_dashboard"]
    assert ray_init_arguments(None, {"RAY_ADDRESS": "10.0.0.2:6379"})["address"] is None  # Ray reads the variable


def listening() -> set[tuple[str, int]]:
    """The TCP sockets listening on this machine, ``(address, port)``, from ``/proc/net/tcp`` and ``tcp6``."""
    found = set()
    for name, size in (("tcp", 4), ("tcp6", 16)):
        table = Path(f"/proc/net/{name}")
        for row in table.read_text().splitlines()[1:] if table.exists() else []:
            local, state = row.split()[1], row.split()[3]
            if state != "0A":  # LISTEN
                continue
            address, port = local.split(":")
            raw = bytes.fromhex(address)
            raw = b"".join(raw[k:k + 4][::-1] for k in range(0, size, 4))  # each 32-bit word in host order
            found.add((str(ipaddress.ip_address(raw)), int(port, 16)))
    return found


#: Run in a fresh interpreter: Ray reads its switch for one machine when it is imported (another test may have).
LOCAL_INSTANCE = """
import ipaddress, json, os
from test_ray_cluster import listening
from emmi_gym.concurrency.ray_cluster import connect_ray
before = listening()
ray, started = connect_ray("local")
try:
    opened = listening() - before
    nodes = [node["NodeManagerAddress"] for node in ray.nodes()]
    gcs = ray.get_runtime_context().gcs_address
    niceness = ray.get(ray.remote(num_cpus=1)(lambda: os.nice(0)).remote()) - os.nice(0)
finally:
    ray.shutdown()
wide = [(host, port) for host, port in opened if not (lambda ip: (getattr(ip, "ipv4_mapped", None) or ip).is_loopback)(
    ipaddress.ip_address(host))]
print(json.dumps({"started": started, "nodes": nodes, "opened": len(opened), "wide": wide, "gcs": gcs,
                  "niceness": niceness}))
"""
#: The address an uncleanly killed Ray left in its address file: a cluster no longer there.
STALE_ADDRESS = "127.0.0.1:9"


@pytest.mark.slow
def test_a_local_ray_instance_is_new_on_the_loopback_address_only_and_its_workers_at_our_priority():
    """A new instance whatever a leftover address file names (the file ``ray.init()`` joins: here in a
    ``RAY_TMPDIR`` of its own, not the machine's ``/tmp/ray``), which listens on the loopback address only and
    runs its workers at the niceness of the process that started it (Ray's default: 15 more)."""
    import json
    import os
    import subprocess
    import sys

    from helpers import ray_temp_dir

    pytest.importorskip("ray")
    if not Path("/proc/net/tcp").exists():
        pytest.skip("needs Linux's /proc/net/tcp")
    with ray_temp_dir() as temp:
        (temp / "ray").mkdir()
        (temp / "ray" / "ray_current_cluster").write_text(STALE_ADDRESS)
        env = dict(os.environ, RAY_TMPDIR=str(temp),
                   PYTHONPATH=os.pathsep.join([str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")]))
        env.pop("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", None)
        env.pop("RAY_ADDRESS", None)
        done = subprocess.run([sys.executable, "-c", LOCAL_INSTANCE], capture_output=True, text=True, env=env,
                              timeout=300)
        sessions = list((temp / "ray").glob("session_*"))
    assert done.returncode == 0, done.stderr[-2000:]
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    assert sessions and seen["started"] and seen["gcs"] != STALE_ADDRESS  # Ray's files went there: a new instance
    assert seen["nodes"] == [LOOPBACK] and seen["wide"] == [] and seen["opened"] > 0
    assert seen["niceness"] == 0
