"""Hash a few seeded episodes of every registered id and one log replay.

A refactoring that must not change behaviour prints the same hashes before and after::

    python scripts/episode_hashes.py > after.txt     # and the same on the code before

A change that does change an id's episodes gives that id a new version (as Gymnasium does); compare
the two codes' lines by name, without the version, to see which ids changed::

    diff <(sed 's/-v[0-9]* / /' before.txt) <(sed 's/-v[0-9]* / /' after.txt)

(0.2.0's planner changed the four waypoint ids, now -v1; ``ExploreVelocity-v0`` and the replay kept
their hashes.)

Each line is ``<what> <sha256 of every observation, reward, flag and numeric info value>``.
Only the public Gymnasium API and the ``emmi-gym replay`` command are used, so the script
runs unchanged on any version of the package.

A change to what ``info`` holds changes the hashes while the episodes stay the same: ``--no-info`` hashes
the observations, rewards and flags alone (what an id's version answers for), ``--drop-info KEY ...``
leaves the keys given out of the hash, and ``--options JSON`` makes every id with further ``gym.make``
options (the newer code asked for an ``info`` the older one gave unasked)::

    python scripts/episode_hashes.py --no-info > after.txt

``--ids NAME ...`` hashes only those ids (``LoopCorridor-v1``, without the namespace).
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import gymnasium as gym
import numpy as np

import emmi_gym

try:
    from emmi_gym.tools.commands import arguments
except ImportError:  # 0.2.0 and earlier kept the argument types in emmi_gym.inputs
    from emmi_gym.inputs import arguments

ROOT = Path(__file__).resolve().parent.parent
LOG = ROOT / "tests" / "data" / "intel-first-loop.log.gz"


def _hash_into(digest, value) -> None:
    """Update ``digest`` with ``value``: dicts by sorted key, sequences item by item, numbers and arrays by
    their bytes, text by its UTF-8."""
    if isinstance(value, dict):
        for key in sorted(value):
            digest.update(str(key).encode())
            _hash_into(digest, value[key])
    elif isinstance(value, (list, tuple)):
        for item in value:
            _hash_into(digest, item)
    elif isinstance(value, (bool, int, float, np.number, np.bool_, np.ndarray)):
        digest.update(np.ascontiguousarray(np.asarray(value)).tobytes())
    elif isinstance(value, str):
        digest.update(value.encode())


def episode_hash(env_id: str, seed: int, steps: int, options: dict | None = None, info: bool = True,
                 drop_info: tuple[str, ...] = ()) -> str:
    """Play ``steps`` seeded random actions (masked for waypoint envs); hash everything seen (``info`` less
    the keys ``drop_info``; none of it without ``info``)."""
    env = gym.make(env_id, **(options or {}))
    digest = hashlib.sha256()

    def kept(found: dict) -> dict:
        return {k: v for k, v in found.items() if k not in drop_info} if info else {}

    obs, found = env.reset(seed=seed)
    _hash_into(digest, obs)
    _hash_into(digest, kept(found))
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        masks = getattr(env.unwrapped, "action_masks", None)
        if isinstance(env.action_space, gym.spaces.Discrete) and masks is not None:
            allowed = np.flatnonzero(masks())
            action = int(rng.choice(allowed)) if allowed.size else 0
        else:
            low, high = env.action_space.low, env.action_space.high
            action = rng.uniform(low, high).astype(env.action_space.dtype)
        obs, reward, terminated, truncated, found = env.step(action)
        for value in (obs, reward, terminated, truncated, kept(found)):
            _hash_into(digest, value)
        if terminated or truncated:
            break
    env.close()
    return digest.hexdigest()


def replay_hash() -> str:
    """Replay the test log with the command line and hash its measures per update and its trajectory."""
    with tempfile.TemporaryDirectory() as out:
        subprocess.run([sys.executable, "-m", "emmi_gym.tools.cli", "replay", str(LOG), "--particles", "8",
                        "--max-range", "30", "--out", out, "--quiet"], check=True, capture_output=True)
        digest = hashlib.sha256()
        with open(Path(out) / "metrics.csv", newline="") as f:
            for row in csv.DictReader(f):  # the measures, not the timings (``*_ms``), which vary run to run
                _hash_into(digest, {k: v for k, v in row.items() if not k.endswith("_ms")})
        digest.update((Path(out) / "best_trajectory.tum").read_bytes())
        return digest.hexdigest()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_seed_range(parser, 2)
    parser.add_argument("--decisions", type=arguments.integer(1), default=12, help="steps per waypoint episode")
    parser.add_argument("--velocity-steps", type=arguments.integer(1), default=400, help="steps per velocity episode")
    parser.add_argument("--no-info", action="store_true", help="hash the observations, rewards and flags only")
    parser.add_argument("--drop-info", nargs="+", default=[], metavar="KEY", help="info keys left out of the hash")
    parser.add_argument("--options", default="{}", help="JSON of further gym.make options for every id")
    parser.add_argument("--no-replay", action="store_true", help="leave out the log replay")
    parser.add_argument("--ids", nargs="+", metavar="NAME", help="only these ids (default: every registered one)")
    args = parser.parse_args()
    options = json.loads(args.options)
    gym.register_envs(emmi_gym)
    ids = sorted(i for i in gym.registry if i.startswith("emmi_gym/"))
    if args.ids:
        unknown = sorted(set(args.ids) - {i.removeprefix("emmi_gym/") for i in ids})
        if unknown:
            parser.error(f"--ids: no id {unknown} is registered; the ids: {[i.removeprefix('emmi_gym/') for i in ids]}")
        ids = [i for i in ids if i.removeprefix("emmi_gym/") in args.ids]
    for env_id in ids:
        steps = args.velocity_steps if "Velocity" in env_id else args.decisions
        for seed in arguments.seed_range(args):
            digest = episode_hash(env_id, seed, steps, options, not args.no_info, tuple(args.drop_info))
            print(f"{env_id} seed={seed} {digest}", flush=True)
    if not args.no_replay:
        print(f"replay {LOG.name} {replay_hash()}", flush=True)


if __name__ == "__main__":
    main()
