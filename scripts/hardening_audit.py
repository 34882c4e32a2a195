"""Replay the hardening audit (issue 14): each hostile or broken input, and what happens to it now.

Prints a markdown table: case -> outcome (the error's first line, or what was returned), the
seconds it took and the peak memory Python allocated for it (tracemalloc). Every case runs in
this process under a time limit of its own; nothing should come near it.

    python scripts/hardening_audit.py            # about a minute
    python scripts/hardening_audit.py --train    # also Ctrl-C / kill -INT of a training run (~1 min more)
"""

from __future__ import annotations

import argparse
import copy
import os
import pickle
import signal
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import gymnasium as gym
import numpy as np
import yaml

import emmi_gym  # noqa: F401
from emmi_gym.env import ENV_IDS
from emmi_gym.formats.carmen import parse_lines, read_log
from emmi_gym.slam import RBPFConfig
from emmi_gym.slam.replay import replay
from emmi_gym.training.config import load_agent_config
from emmi_gym.world import load_world

WORLD = {"name": "box", "bounds": {"xmin": -3, "ymin": -3, "xmax": 3, "ymax": 3},
         "walls": [{"rectangle": {"min": [-2, -2], "max": [2, 2]}}], "start": {"x": 0, "y": 0, "theta": 0}}
BOMB = "a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n" + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join(['*' + chr(97 + i)] * 9)}]\n" for i in range(8))
SCAN = " ".join(["2.5"] * 180)
AGENT = {"env": {"id": "emmi_gym/LoopCorridor-v0", "kwargs": {"particles": 3}}, "algorithm": "MaskablePPO",
         "policy": "MultiInputPolicy", "hyperparameters": {"n_steps": 16}, "n_envs": 1, "vec_env": "dummy"}


def run_case(action, limit: float = 120.0) -> tuple[str, float, float]:
    """(outcome, seconds, peak MB) of calling ``action``; the outcome is its error's message or its result."""
    def alarm(*_):
        raise TimeoutError(f"still running after {limit:.0f} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(int(limit))
    tracemalloc.start()
    started = time.perf_counter()
    try:
        outcome = f"ok: {action()}"
    except BaseException as exc:  # noqa: BLE001  (the audit reports whatever happens)
        outcome = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
    finally:
        seconds = time.perf_counter() - started
        peak = tracemalloc.get_traced_memory()[1] / 1e6
        tracemalloc.stop()
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    return outcome, seconds, peak


def make(env_id="emmi_gym/LoopCorridor-v0", reset=False, **options):
    def action():
        env = gym.make(env_id, **options)
        if reset:
            _, info = env.reset(seed=0)
            env.step(env.action_space.sample() if "Velocity" in env_id else 0)
            return f"stepped; map_accuracy {info['map_accuracy']:.3f}"
        return "made"
    return action


_files = iter(range(10**6))


def world_file(folder: Path, text: str | bytes, name=None):
    path = folder / (name or f"world{next(_files)}.yaml")
    (path.write_bytes if isinstance(text, bytes) else path.write_text)(text)
    return lambda: load_world(path).name


def agent_file(folder: Path, data: dict | str, name=None):
    path = folder / (name or f"agent{next(_files)}.yaml")
    path.write_text(data if isinstance(data, str) else yaml.safe_dump(data))
    return lambda: load_agent_config(path).algorithm


def log_lines(lines, **kwargs):
    return lambda: len(replay(parse_lines(lines), RBPFConfig(particles=2), max_range=8.0, **kwargs).rows)


def cases(folder: Path) -> list[tuple[str, object]]:
    straight = [f"FLASER 180 {SCAN} 0 0 0 {0.5 * k} 0 0 {k}.0 h {k}.0" for k in range(5)]
    (folder / "garbage.log").write_bytes(os.urandom(4096))
    (folder / "passwd").write_text("root:x:0:0:root:/root:/bin/bash\n")
    return [
        # 2. routes
        ("world whose to_decision route runs through a wall",
         world_file(folder, yaml.safe_dump(dict(WORLD, routes={"to_decision": ["start", [0, 2.5]]})))),
        # 3. alias bombs
        ("1 KB alias bomb as a world file", world_file(folder, yaml.safe_dump(WORLD) + BOMB, "bomb.yaml")),
        ("1 KB alias bomb as an agent configuration", agent_file(folder, yaml.safe_dump(AGENT) + BOMB, "bomb_agent.yaml")),
        # 4. sizes
        ("world bounds of 1e5 m", world_file(folder, yaml.safe_dump(dict(WORLD, bounds={"xmin": 0, "ymin": 0, "xmax": 1e5, "ymax": 3})))),
        ("coordinates of 1e300", world_file(folder, yaml.safe_dump(dict(WORLD, start={"x": 1e300, "y": 0})))),
        ("particles=1e9", make(particles=10**9)),
        ("obs_size=1e6", make(obs_size=10**6)),
        ("n_frontiers=1e7", make(n_frontiers=10**7)),
        ("generator nx=1e4", make("emmi_gym/Explore-v0", generator={"nx": 10**4})),
        ("generator spacing=1e6", make("emmi_gym/Explore-v0", generator={"spacing": 1e6})),
        ("laser n_beams=1e8", make(laser={"n_beams": 10**8})),
        ("resolution=1e-9", make(resolution=1e-9)),
        ("particles=1000 at resolution 0.01 in loop_corridor", make(reset=True, particles=1000, resolution=0.01)),
        # 5. huge pose estimate
        ("odometry alphas 1e6", make(odometry_noise={"rot_from_rot": 1e6, "trans_from_trans": 1e6})),
        # 6. types
        ("laser n_beams=3.0", make(laser={"n_beams": 3.0})),
        ("laser n_beams=nan", make(laser={"n_beams": float("nan")})),
        ("slam likelihood_sigma=1e-300", make(slam={"likelihood_sigma": 1e-300})),
        ("generator spacing=inf", make("emmi_gym/Explore-v0", generator={"spacing": float("inf")})),
        ("generator wall_thickness='x'", make("emmi_gym/Explore-v0", generator={"wall_thickness": "x"})),
        ("egocentric='no'", make(egocentric="no")),
        ("slam={'particles': 5}", make(slam={"particles": 5})),
        ("time_cost='cheap'", make(time_cost="cheap")),
        # 7. NaN / inf producers
        ("reward_scale=inf", make(reward_scale=float("inf"))),
        ("reward_scale=1e308", make(reward_scale=1e308)),
        ("odometry alphas 1e300", make(odometry_noise={"rot_from_rot": 1e300})),
        ("slam logodds_step=1e6", make(slam={"logodds_step": 1e6})),
        ("laser range_sigma=inf", make(laser={"range_sigma": float("inf")})),
        ("generator wall_thickness=nan", make("emmi_gym/Explore-v0", generator={"wall_thickness": float("nan")})),
        ("laser max_range=0.5: map_accuracy", make("emmi_gym/ExploreVelocity-v0", reset=True, laser={"max_range": 0.5})),
        # 8. world files
        ("YAML syntax error", world_file(folder, "name: box\nbounds: {xmin: 0, ymin: 0\nwalls: []\n", "syntax.yaml")),
        ("binary world file", world_file(folder, os.urandom(512).replace(b"\0", b"\1") + b"\0", "binary.yaml")),
        ("UTF-16 world file", world_file(folder, yaml.safe_dump(WORLD).encode("utf-16"), "utf16.yaml")),
        ("world='/etc/passwd' (a copy)", lambda: load_world(folder / "passwd")),
        ("duplicate keys", world_file(folder, yaml.safe_dump(WORLD) + "name: again\n", "duplicate.yaml")),
        ("1.0e1 in a world file", world_file(folder, yaml.safe_dump(WORLD).replace("xmax: 3", "xmax: 3.0e0"), "exp.yaml")),
        ("base: ../../../../etc/passwd", agent_file(folder, {"base": "../../../../etc/passwd"})),
        ("base: .", agent_file(folder, {"base": "."}, "base_dot.yaml")),
        # 9. agent configurations
        ("learning_rate: fast", agent_file(folder, dict(AGENT, hyperparameters={"learning_rate": "fast"}))),
        ("n_steps: sixty-four", agent_file(folder, dict(AGENT, hyperparameters={"n_steps": "sixty-four"}))),
        ("learning_rate: nan", agent_file(folder, dict(AGENT, hyperparameters={"learning_rate": float("nan")}))),
        ("SAC on a waypoint env", agent_file(folder, dict(AGENT, algorithm="SAC", hyperparameters={}))),
        ("DQN on a velocity env", agent_file(folder, dict(AGENT, algorithm="DQN", hyperparameters={},
                                                        env={"id": "emmi_gym/ExploreVelocity-v0"}))),
        ("MaskablePPO on a velocity env", agent_file(folder, dict(AGENT, env={"id": "emmi_gym/ExploreVelocity-v0"}))),
        ("bad env kwargs with subprocess envs", agent_file(folder, dict(AGENT, n_envs=2, vec_env="subproc",
                                                                      env={"id": "emmi_gym/LoopCorridor-v0",
                                                                           "kwargs": {"laser": {"n_beams": -1}}}))),
        ("n_envs: 100000", agent_file(folder, dict(AGENT, n_envs=100000))),
        # 10. logs
        ("log driving straight along an axis", log_lines(straight)),
        ("log with an inf laser pose", log_lines([f"FLASER 180 {SCAN} 0 0 0 inf 0 0 1.0 h 1.0"])),
        ("log with maximum range inf", log_lines(["RAWLASER1 0 -1.57 3.14 0.0175 inf 0.01 0 3 1 1 1 0 1.0 h 1.0"])),
        ("log with a pose of 1e6 m", log_lines(straight[:2] + [f"FLASER 180 {SCAN} 0 0 0 1e6 0 0 9.0 h 9.0"])),
        ("log path is a folder", lambda: read_log(folder)),
        ("log of binary garbage", lambda: read_log(folder / "garbage.log")),
        ("FLASER line with too few beams for its count", log_lines(["FLASER 5 1 1 1 0 0 0 0 0 0 1.0 emmi-gym 1.0"])),
        ("trailing tokens (two lines glued)", log_lines([straight[0] + " " + straight[1]])),
        ("negative range", log_lines(["FLASER 3 1 -1 1 0 0 0 0 0 0 1.0 h 1.0"])),
        ("all-zero scans", lambda: parse_lines([f"FLASER 180 {' '.join(['0'] * 180)} 0 0 0 0 0 0 1.0 h 1.0"]).report()),
        ("maximum range 0", log_lines(["RAWLASER1 0 -1.57 3.14 0.0175 0 0.01 0 3 1 1 1 0 1.0 h 1.0"])),
        ("angular resolution -0.0175 (angles not increasing)",
         log_lines(["RAWLASER1 0 -1.57 3.14 -0.0175 8 0.01 0 3 1 1 1 0 1.0 h 1.0"])),
        # 11. pickling
        *[(f"pickle and deepcopy {name} after reset and a step", _pickling(name)) for name in ENV_IDS],
    ]


def _pickling(name: str):
    def action():
        env = gym.make(f"emmi_gym/{name}", particles=3).unwrapped
        env.reset(seed=0)
        env.step(env.action_space.sample() if env.config.action_mode == "velocity" else int(np.flatnonzero(env.action_masks())[0]))
        pickle.loads(pickle.dumps(env))
        copy.deepcopy(env)
        return "both copies made"
    return action


def training_interrupts(folder: Path) -> list[tuple[str, str, float]]:
    """Ctrl-C (the process group) and kill -INT (the main process) of `emmi-gym train` with subprocess envs."""
    data = {"env": {"id": "emmi_gym/ExploreVelocity-v0", "kwargs": {"particles": 3, "max_sim_steps": 150,
                                                                   "generator": {"nx": 2, "ny": 2, "n_loops": 1}}},
            "algorithm": "PPO", "hyperparameters": {"n_steps": 16, "batch_size": 32, "n_epochs": 1},
            "n_envs": 2, "vec_env": "subproc", "total_timesteps": 100000, "checkpoint_freq": 32}
    (folder / "train.yaml").write_text(yaml.safe_dump(data))
    rows = []
    for label, group in (("Ctrl-C during train (the process group gets SIGINT)", True),
                         ("kill -INT of the main training process only", False)):
        run = folder / f"run_{group}"
        previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # not inherited as ignored
        try:
            process = subprocess.Popen([sys.executable, "-m", "emmi_gym.cli", "train", str(folder / "train.yaml"),
                                        "--out", str(run), "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                       text=True, start_new_session=True)
        finally:
            signal.signal(signal.SIGINT, previous)
        while not list((run / "checkpoints").glob("model_*_steps.zip")) and process.poll() is None:
            time.sleep(0.2)
        sent = time.perf_counter()
        (os.killpg if group else os.kill)(process.pid, signal.SIGINT)
        try:
            out, err = process.communicate(timeout=60)
            outcome = f"exit {process.returncode}: {out.strip().splitlines()[-1]}"
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            outcome = "HUNG (killed after 60 s)"
        rows.append((label, outcome, time.perf_counter() - sent))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--train", action="store_true", help="also interrupt two training runs")
    args = parser.parse_args()
    print("| case | outcome | s | peak MB |\n| --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for label, action in cases(folder):
            outcome, seconds, peak = run_case(action)
            print(f"| {label} | {outcome[:220].replace('|', '/')} | {seconds:.2f} | {peak:.1f} |", flush=True)
        if args.train:
            for label, outcome, seconds in training_interrupts(folder):
                print(f"| {label} | {outcome} | {seconds:.1f} after SIGINT | - |", flush=True)


if __name__ == "__main__":
    main()
