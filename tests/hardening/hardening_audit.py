"""Replay the hardening audits: each hostile or broken input, and what happens to it now.

Prints three markdown tables. The first: case -> outcome (the error's first line, or what was
returned), the seconds it took and the peak memory Python allocated for it (tracemalloc); every
case runs in this process under a time limit of its own. The second: the inputs of the second
audit (floor-plan images, map_server files, map sets, gzipped logs, configuration chains, model
files), each given to the command or function it targets in a process of its own, killed after
60 s or above 3 GB: its exit status, the last line it printed (the error, or the last progress
bar if it was killed), the seconds and the process's peak resident memory. Every probe should
end within the minute (or show progress) under 1 GB, with a message naming the file, field or
option. The third: the training side (``training_probes``: runs, clones, resumes, model and
demonstration files, training records, the tools' CSVs, and the third audit's cases G1-G8: resumes
whose models do not load, ``record`` over its world, bag odometry that goes back or is not finite,
model pickles that run code, ``replay`` into an earlier replay, a finished run resumed, a damaged
only checkpoint), each probe with a verdict (a clear error,
did what it should, or a silent wrong result, data loss, a raw traceback, over 1 GB or 120 s) and a
summary line counting them.

    python tests/hardening/hardening_audit.py                  # about ten minutes
    python tests/hardening/hardening_audit.py --probes-only    # the second and third tables (inputs: ~1 min to make)
    python tests/hardening/hardening_audit.py --training-side  # the third table (a small run trained first, ~30 s)
    python tests/hardening/hardening_audit.py --train          # also Ctrl-C / kill -INT of a training run (~1 min more)
"""

from __future__ import annotations

import argparse
import copy
import inspect
import json
import os
import pickle
import signal
import struct
import subprocess
import sys
import tempfile
import time
import tracemalloc
import zipfile
import zlib
from pathlib import Path
from typing import NamedTuple

import gymnasium as gym
import numpy as np
import yaml

import emmi_gym  # noqa: F401
from emmi_gym.env import ENV_IDS
from emmi_gym.formats.carmen import parse_lines, read_log
from emmi_gym.slam import RBPFConfig
from emmi_gym.tools.experiments.replay import replay
from emmi_gym.tools.training.config import load_agent_config
from emmi_gym.world import load_world

WORLD = {"name": "box", "bounds": {"xmin": -3, "ymin": -3, "xmax": 3, "ymax": 3},
         "walls": [{"rectangle": {"min": [-2, -2], "max": [2, 2]}}], "start": {"x": 0, "y": 0, "theta": 0}}
BOMB = "a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n" + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join(['*' + chr(97 + i)] * 9)}]\n" for i in range(8))
SCAN = " ".join(["2.5"] * 180)
AGENT = {"env": {"id": "emmi_gym/LoopCorridor-v1", "kwargs": {"particles": 3}}, "algorithm": "MaskablePPO",
         "policy": "MultiInputPolicy", "hyperparameters": {"n_steps": 16}, "n_envs": 1, "vec_env": "dummy"}


class Case(NamedTuple):
    """What calling a case's action did: the outcome (its error's class and message, or ``ok:`` and its
    result), its seconds, the peak memory Python allocated for it (MB) and the error itself (None if none)."""

    outcome: str
    seconds: float
    peak_mb: float
    error: BaseException | None


def run_case(action, limit: float = 120.0) -> Case:
    """:class:`Case` of calling ``action``, stopped by a ``TimeoutError`` after ``limit`` seconds."""
    def alarm(*_):
        raise TimeoutError(f"still running after {limit:.0f} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(int(limit))
    tracemalloc.start()
    started = time.perf_counter()
    error = None
    try:
        outcome = f"ok: {action()}"
    except BaseException as exc:  # noqa: BLE001  (the audit reports whatever happens)
        outcome, error = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}", exc
    finally:
        seconds = time.perf_counter() - started
        peak = tracemalloc.get_traced_memory()[1] / 1e6
        tracemalloc.stop()
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    return Case(outcome, seconds, peak, error)


def make(env_id="emmi_gym/LoopCorridor-v1", reset=False, **options):
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


def straight_log(n_scans: int) -> list[str]:
    """A log of ``n_scans`` FLASER lines driving 0.5 m a second along the x axis."""
    return [f"FLASER 180 {SCAN} 0 0 0 {0.5 * k} 0 0 {k}.0 h {k}.0" for k in range(n_scans)]


def compile_filter_kernels() -> None:
    """Replay a two-scan log once: numba compiles the filter's kernels on their first call (a minute or more
    on a cold cache, longer while another process compiles beside it), which is not what a case's time limit
    is for (a hang on its input)."""
    log_lines(straight_log(2))()


def cases(folder: Path) -> list[tuple[str, object]]:
    straight = straight_log(5)
    (folder / "garbage.log").write_bytes(os.urandom(4096))
    (folder / "passwd").write_text("root:x:0:0:root:/root:/bin/bash\n")
    return [
        # 2. routes
        ("world whose to_decision route runs through a wall",
         world_file(folder, yaml.safe_dump(dict(WORLD, routes={"to_decision": ["start", [0, 2.5]]})))),
        # 3. alias bombs
        ("1 KB alias bomb as a world file", world_file(folder, yaml.safe_dump(WORLD) + BOMB, "bomb.yaml")),
        ("1 KB alias bomb as an agent configuration",
         agent_file(folder, yaml.safe_dump(AGENT) + BOMB, "bomb_agent.yaml")),
        # 4. sizes
        ("world bounds of 1e5 m",
         world_file(folder, yaml.safe_dump(dict(WORLD, bounds={"xmin": 0, "ymin": 0, "xmax": 1e5, "ymax": 3})))),
        ("coordinates of 1e300", world_file(folder, yaml.safe_dump(dict(WORLD, start={"x": 1e300, "y": 0})))),
        ("particles=1e9", make(particles=10**9)),
        ("obs_size=1e6", make(obs_size=10**6)),
        ("n_frontiers=1e7", make(n_frontiers=10**7)),
        ("generator nx=1e4", make("emmi_gym/Explore-v1", generator={"nx": 10**4})),
        ("generator spacing=1e6", make("emmi_gym/Explore-v1", generator={"spacing": 1e6})),
        ("laser n_beams=1e8", make(laser={"n_beams": 10**8})),
        ("resolution=1e-9", make(resolution=1e-9)),
        ("particles=1000 at resolution 0.01 in loop_corridor", make(reset=True, particles=1000, resolution=0.01)),
        # 5. huge pose estimate
        ("odometry alphas 1e6", make(odometry_noise={"rot_from_rot": 1e6, "trans_from_trans": 1e6})),
        # 6. types
        ("laser n_beams=3.0", make(laser={"n_beams": 3.0})),
        ("laser n_beams=nan", make(laser={"n_beams": float("nan")})),
        ("slam likelihood_sigma=1e-300", make(slam={"likelihood_sigma": 1e-300})),
        ("generator spacing=inf", make("emmi_gym/Explore-v1", generator={"spacing": float("inf")})),
        ("generator wall_thickness='x'", make("emmi_gym/Explore-v1", generator={"wall_thickness": "x"})),
        ("egocentric='no'", make(egocentric="no")),
        ("slam={'particles': 5}", make(slam={"particles": 5})),
        ("time_cost='cheap'", make(time_cost="cheap")),
        # 7. NaN / inf producers
        ("reward_scale=inf", make(reward_scale=float("inf"))),
        ("reward_scale=1e308", make(reward_scale=1e308)),
        ("odometry alphas 1e300", make(odometry_noise={"rot_from_rot": 1e300})),
        ("slam logodds_step=1e6", make(slam={"logodds_step": 1e6})),
        ("laser range_sigma=inf", make(laser={"range_sigma": float("inf")})),
        ("generator wall_thickness=nan", make("emmi_gym/Explore-v1", generator={"wall_thickness": float("nan")})),
        ("laser max_range=0.5: map_accuracy",
         make("emmi_gym/ExploreVelocity-v0", reset=True, laser={"max_range": 0.5}, info_scores="always")),
        # 8. world files
        ("YAML syntax error", world_file(folder, "name: box\nbounds: {xmin: 0, ymin: 0\nwalls: []\n", "syntax.yaml")),
        ("binary world file", world_file(folder, os.urandom(512).replace(b"\0", b"\1") + b"\0", "binary.yaml")),
        ("UTF-16 world file", world_file(folder, yaml.safe_dump(WORLD).encode("utf-16"), "utf16.yaml")),
        ("world='/etc/passwd' (a copy)", lambda: load_world(folder / "passwd")),
        ("duplicate keys", world_file(folder, yaml.safe_dump(WORLD) + "name: again\n", "duplicate.yaml")),
        ("1.0e1 in a world file",
         world_file(folder, yaml.safe_dump(WORLD).replace("xmax: 3", "xmax: 3.0e0"), "exp.yaml")),
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
                                                                      env={"id": "emmi_gym/LoopCorridor-v1",
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
        env.step(env.action_space.sample() if env.config.action_mode == "velocity"
                 else int(np.flatnonzero(env.action_masks())[0]))
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
            process = subprocess.Popen([sys.executable, "-m", "emmi_gym.tools.cli", "train", str(folder / "train.yaml"),
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


# --------------------------------------------------------------------------- probes in a subprocess
PROBE_LIMIT = 60.0
#: A probe is killed when its memory passes this (the criterion is 1 GB; the cap keeps the machine usable).
MEMORY_CAP_MB = 3000
GIB = 2**30



def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _deflate_repeated(chunk: bytes, times: int, wbits: int = -15) -> bytes:
    """Deflate data of ``chunk`` repeated ``times`` times, compressed once: each copy is a block after a full
    flush (no reference to the copy before), so the copies can simply be concatenated."""
    compressor = zlib.compressobj(9, zlib.DEFLATED, -15)
    block = compressor.compress(chunk) + compressor.flush(zlib.Z_FULL_FLUSH)
    body = block * times + zlib.compressobj(9, zlib.DEFLATED, -15).flush()  # an empty final block
    if wbits == -15:
        return body
    check = 1  # zlib stream: header, raw deflate, Adler-32 of the data
    for _ in range(times):
        check = zlib.adler32(chunk, check)
    return b"\x78\xda" + body + struct.pack(">I", check)


def _gzip_repeated(path: Path, chunk: bytes, times: int) -> None:
    crc = 0
    for _ in range(times):
        crc = zlib.crc32(chunk, crc)
    header = b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x02\xff"
    path.write_bytes(header + _deflate_repeated(chunk, times) + struct.pack("<II", crc, (len(chunk) * times) % 2**32))


def _png(path: Path, width: int, height: int, rows: bytes | None = None, before_idat=(), idat: bytes | None = None):
    """An 8-bit grey PNG; ``rows`` its filtered scanlines (default: all white)."""
    if idat is None:
        idat = zlib.compress(rows if rows is not None else (b"\0" + b"\xff" * width) * height, 9)
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", ihdr) + b"".join(before_idat) +
                     _png_chunk(b"IDAT", idat) + _png_chunk(b"IEND", b""))
    return path


def _plan(levels: tuple[int, int]) -> np.ndarray:
    """A 120 x 160 px room (free inside, walls 4 px thick and a pillar) at the grey levels (wall, free)."""
    wall, free = levels
    pixels = np.full((120, 160), wall)
    pixels[4:-4, 4:-4] = free
    pixels[50:70, 60:90] = wall
    return pixels


def _model_zip(path: Path, members: dict[str, bytes]):
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return path


def _zip_with_huge_member(path: Path, name: str, size: int, chunk_size: int = 64 << 20) -> Path:
    """A zip whose member ``name`` holds ``size`` zero bytes (deflated once per 64 MiB, copies concatenated)."""
    chunk = b"\0" * chunk_size
    times = size // chunk_size
    crc = 0
    for _ in range(times):
        crc = zlib.crc32(chunk, crc)
    data = _deflate_repeated(chunk, times)
    with zipfile.ZipFile(path, "w") as archive:  # written through zipfile's own header code
        info = zipfile.ZipInfo(name)
        info.compress_type = zipfile.ZIP_DEFLATED
        info.file_size, info.compress_size, info.CRC = times * chunk_size, len(data), crc
        archive.fp.write(info.FileHeader(zip64=True))
        archive.fp.write(data)
        info.header_offset = 0
        archive.filelist.append(info)
        archive.NameToInfo[name] = info
        archive.start_dir = archive.fp.tell()
    return path


def _flaser(x: float, t: float, x_text: str | None = None, sep: str = " ") -> str:
    return sep.join(["FLASER", "180", SCAN.replace(" ", sep), "0", "0", "0", x_text or repr(x), "0", "0",
                     repr(t), "h", repr(t)])


def probe_inputs(folder: Path) -> list[tuple[str, list[str]]]:
    """The hostile inputs of the second audit and the command each one is given to (run in a subprocess)."""
    py = [sys.executable, "-c"]
    cli = [sys.executable, "-m", "emmi_gym.tools.cli"]
    f = folder
    load = "from emmi_gym.world import load_world; w = load_world({!r}); print('loaded', w.name, len(w.walls), 'walls')"

    # 1. 16-bit images
    from PIL import Image

    Image.fromarray(_plan((78, 255)).astype(np.uint8)).save(f / "plan8.png")
    Image.fromarray(_plan((20000, 65535)).astype(np.uint16)).save(f / "plan16.png")
    Image.fromarray(_plan((20000, 65535)).astype(np.uint16)).save(f / "map16.pgm")
    (f / "map16.yaml").write_text("image: map16.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n")
    Image.fromarray(_plan((78, 255)).astype(np.uint8)).save(f / "jpeg.png", format="JPEG")
    free = ("from emmi_gym.world.images import dungeon_occupancy, map_server_occupancy; "
            "a = dungeon_occupancy({!r}).free; b = dungeon_occupancy({!r}).free; c = map_server_occupancy({!r}).free; "
            "print(f'free share 8-bit {{a.mean():.3f}}, 16-bit PNG {{b.mean():.3f}}, 16-bit PGM map {{c.mean():.3f}}')")
    # 2. timestamps and numbers
    logs = {"backwards": [_flaser(0.5 * k, 5.0 - k) for k in range(5)],
            "equal": [_flaser(0.5 * k, 7.0) for k in range(5)],
            "arabic_digits": [_flaser(0.5 * k, k, "\u0661.\u0665" if k == 2 else None) for k in range(5)],
            "nbsp": [_flaser(0.5 * k, k, sep="\u00a0" if k == 3 else " ") for k in range(5)],
            "pose_1e300": [_flaser(0.5 * k, k) for k in range(3)] + [_flaser(1e300, 3.0)]}
    for name, lines in logs.items():
        (f / f"{name}.log").write_text("\n".join(lines) + "\n")
    # 3. nesting
    nested = "[" * 50_000 + "]" * 50_000
    (f / "deep_world.yaml").write_text(yaml.safe_dump(WORLD) + f"places: {nested}\n")
    (f / "deep_map.yaml").write_text(f"image: plan8.png\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nstart: {nested}\n")
    (f / "deep_set").mkdir()
    (f / "deep_set" / "deep.yaml").write_text((f / "deep_map.yaml").read_text().replace("plan8.png", "../plan8.png"))
    (f / "deep_agent.yaml").write_text(yaml.safe_dump(AGENT) + f"seed: {nested}\n")
    (f / "chain").mkdir()
    for k in range(3000):
        (f / "chain" / f"c{k}.yaml").write_text(f"base: c{k + 1}.yaml\n" if k < 2999 else yaml.safe_dump(AGENT))
    # 4. Pillow's errors
    ztxt = b"Comment\0\0" + _deflate_repeated(b"\0" * (64 << 20), 16, wbits=15)  # 1 GiB of text
    _png(f / "ztxt.png", 64, 64, before_idat=[_png_chunk(b"zTXt", ztxt)])
    (f / "truncated.pgm").write_bytes(b"P5\n100 100\n255\n" + b"\xff" * 500)
    (f / "maxval0.pgm").write_bytes(b"P5\n10 10\n0\n" + b"\0" * 100)
    rows = _deflate_repeated((b"\0" + b"\xff" * 20000) * 1000, 20, wbits=15)
    _png(f / "huge.png", 20000, 20000, idat=rows)
    # 6. output folders
    (f / "a_file").write_text("x")
    (f / "straight.log").write_text("\n".join(_flaser(0.5 * k, k) for k in range(5)) + "\n")
    train_config = dict(AGENT, vec_env="dummy", hyperparameters={"n_steps": 16, "batch_size": 16, "n_epochs": 1},
                        eval={"freq": 10**6}, checkpoint_freq=10**6)
    (f / "train.yaml").write_text(yaml.safe_dump(train_config))
    # 7. configurations SB3 would break on
    for name, kwargs in (("net_arch", {"net_arch": [-5]}), ("activation", {"activation_fn": "os.system"})):
        (f / f"{name}.yaml").write_text(yaml.safe_dump(dict(train_config, hyperparameters=dict(
            train_config["hyperparameters"], policy_kwargs=kwargs))))
    # 8, 10. model files
    ppo = dict(train_config, algorithm="PPO")
    for name in ("no_data", "maskable", "bomb"):
        (f / name).mkdir()
        (f / name / "config.yaml").write_text(yaml.safe_dump(ppo))
    _model_zip(f / "no_data" / "model.zip", {"policy.pth": b"\0" * 100})
    from sb3_contrib import MaskablePPO

    MaskablePPO("MultiInputPolicy", gym.make("emmi_gym/LoopCorridor-v1", particles=3), n_steps=16,
                batch_size=16).save(f / "maskable" / "model.zip")
    _zip_with_huge_member(f / "bomb" / "model.zip", "data", 4 * GIB)
    # 9, 12. streams
    _gzip_repeated(f / "zeros.log.gz", b"\0" * (64 << 20), 9 * 16)
    (f / "long_line.log").write_text("FLASER " + "1 " * 50_000_000 + "\n")
    _gzip_repeated(f / "newlines.log.gz", b"\n" * (64 << 20), 9 * 16)
    block = "".join(_flaser(0.001 * (k % 2), k % 2) + "\n" for k in range(2))
    _gzip_repeated(f / "repeated.log.gz", block.encode() * ((64 << 20) // len(block)), 9 * 16)
    # 11. a large plan in few bytes, and a maze whose walls would be millions of segments
    Image.new("L", (5000, 5000), 255).save(f / "large.png")
    maze = np.full((2000, 2000), 255, dtype=np.uint8)
    for k in (0, 1):
        maze[k::8, :] = maze[:, k::8] = 0
    maze[0::8, 4::8] = maze[1::8, 4::8] = maze[4::8, 0::8] = maze[4::8, 1::8] = 255  # a door in every wall
    Image.fromarray(maze).save(f / "maze.png")
    # misc: messages
    (f / "no_image.yaml").write_text("resolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
                                     "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    (f / "text.png").write_text("not an image\n")
    (f / "eval_png.yaml").write_text(yaml.safe_dump(dict(AGENT, eval={"env_kwargs": {"world": str(f / "text.png")}})))
    (f / "x.png").mkdir()
    replay = [*cli, "replay", "--out", str(f / "replay_out")]
    make_step = ("import gymnasium as gym, emmi_gym; env = gym.make('emmi_gym/Explore-v1', world={!r}); "
                 "env.reset(seed=0); env.step(0); print('stepped')")
    return [
        ("1. 16-bit PNG and PGM (walls at 20000 of 65535) beside the 8-bit plan",
         [*py, free.format(str(f / "plan8.png"), str(f / "plan16.png"), str(f / "map16.yaml"))]),
        ("1. a JPEG named .png", [*py, load.format(str(f / "jpeg.png"))]),
        ("2. log timestamps going backwards", [*replay, str(f / "backwards.log"), "--max-range", "8", "--quiet"],
         "warning|tum"),
        ("2. log timestamps all equal", [*replay, str(f / "equal.log"), "--max-range", "8", "--quiet"],
         "no best_trajectory"),
        ("2. log with Arabic-Indic digits", [*replay, str(f / "arabic_digits.log"), "--max-range", "8", "--quiet"]),
        ("2. log with no-break spaces between fields", [*replay, str(f / "nbsp.log"), "--max-range", "8", "--quiet"]),
        ("3. 50,000-deep YAML: world file", [*py, load.format(str(f / "deep_world.yaml"))]),
        ("3. 50,000-deep YAML: map_server file", [*py, load.format(str(f / "deep_map.yaml"))]),
        ("3. 50,000-deep YAML: map set, at reset",
         [*py, make_step.format(str(f / "deep_set"))]),
        ("3. 50,000-deep YAML: agent configuration", [*cli, "train", str(f / "deep_agent.yaml"), "--out",
                                                      str(f / "run_deep"), "--quiet"]),
        ("3. chain of 3000 base: files", [*cli, "train", str(f / "chain" / "c0.yaml"), "--out", str(f / "run_chain"),
                                          "--quiet"]),
        ("4. PNG with a zTXt chunk inflating to 1 GiB", [*py, load.format(str(f / "ztxt.png"))]),
        ("4. truncated PGM", [*py, load.format(str(f / "truncated.pgm"))]),
        ("4. PGM with maxval 0", [*py, load.format(str(f / "maxval0.pgm"))]),
        ("4. 20000 x 20000 PNG", [*py, load.format(str(f / "huge.png"))]),
        ("4. 20000 x 20000 PNG through the CLI (record)", [*cli, "record", str(f / "huge.png"), "--out",
                                                            str(f / "rec.log")]),
        ("5. log pose of 1e300", [*replay, str(f / "pose_1e300.log"), "--max-range", "8", "--quiet"]),
        ("6. train --out /sys/x", [*cli, "train", str(f / "train.yaml"), "--out", "/sys/x", "--quiet"]),
        ("6. train --out a_file/sub", [*cli, "train", str(f / "train.yaml"), "--out", str(f / "a_file" / "sub"),
                                       "--quiet"]),
        ("6. replay --out /sys/x", [*cli, "replay", str(f / "straight.log"), "--max-range", "8", "--out", "/sys/x",
                                    "--quiet"]),
        ("7. policy_kwargs net_arch [-5]", [*cli, "train", str(f / "net_arch.yaml"), "--out", str(f / "run_arch"),
                                            "--timesteps", "16", "--quiet"]),
        ("7. policy_kwargs activation_fn os.system",
         [*cli, "train", str(f / "activation.yaml"), "--out", str(f / "run_act"), "--timesteps", "16", "--quiet"]),
        ("8. evaluate: zip without a data member", [*cli, "evaluate", str(f / "no_data" / "model.zip"),
                                                    "--episodes", "1"]),
        ("8. evaluate: MaskablePPO zip beside a PPO config", [*cli, "evaluate", str(f / "maskable" / "model.zip"),
                                                              "--episodes", "1"]),
        ("9. replay /dev/zero", [*replay, "/dev/zero", "--max-range", "8"]),
        ("9. replay 9 GiB of zeros in a 9 MB .gz", [*replay, str(f / "zeros.log.gz"), "--max-range", "8"]),
        ("9. replay one 100 MB line", [*replay, str(f / "long_line.log"), "--max-range", "8"]),
        ("10. evaluate: data member of 4 GiB", [*cli, "evaluate", str(f / "bomb" / "model.zip"), "--episodes", "1"]),
        ("11. 5000 x 5000 plan (8 KB): load_world", [*py, load.format(str(f / "large.png"))]),
        ("11. 5000 x 5000 plan: gym.make, reset, step", [*py, make_step.format(str(f / "large.png"))]),
        ("11. 2000 x 2000 maze (1.75 M boundary edges): load_world", [*py, load.format(str(f / "maze.png"))]),
        ("12. replay 9 GiB of newlines in a .gz", [*replay, str(f / "newlines.log.gz"), "--max-range", "8"]),
        ("12. replay one valid block repeated to 9 GiB", [*replay, str(f / "repeated.log.gz"), "--max-range", "8"]),
        ("replay --max-range inf", [*replay, str(f / "straight.log"), "--max-range", "inf", "--quiet"]),
        ("replay --max-range nan", [*replay, str(f / "straight.log"), "--max-range", "nan", "--quiet"]),
        ("replay --max-range -5", [*replay, str(f / "straight.log"), "--max-range", "-5", "--quiet"]),
        ("replay --seed -1", [*replay, str(f / "straight.log"), "--max-range", "8", "--seed", "-1", "--quiet"]),
        ("map_server YAML without image:", [*py, load.format(str(f / "no_image.yaml"))]),
        ("eval.env_kwargs.world: text.png", [*cli, "train", str(f / "eval_png.yaml"), "--out", str(f / "run_png"),
                                             "--quiet"]),
        ("world: a folder named x.png", [*py, load.format(str(f / "x.png"))]),
        ("world: /dev/zero", [*py, load.format("/dev/zero")]),
    ]


def _measure(command: list[str], limit: float, cap_mb: float, pick: str | None = None) -> dict:
    """Run ``command`` in its own process group (stdlib only: this runs in a small process of its own, so that
    the peak memory the kernel reports for the probe is the probe's, not inherited from the audit at fork):
    its exit status, last line of output (or the first matching ``pick``), seconds, peak RSS (MB), why it was
    killed (``limit`` seconds or ``cap_mb``), when it last printed and whether that was a progress bar."""
    import os
    import re
    import signal
    import subprocess
    import threading
    import time

    def rss_mb(pid):
        try:
            with open(f"/proc/{pid}/statm") as statm:
                return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
        except (OSError, ValueError, IndexError):
            return 0.0

    started = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
    output, last_output = bytearray(), [None]

    def read():
        for piece in iter(lambda: process.stdout.read1(65536), b""):
            output.extend(piece)
            del output[:-65536]
            last_output[0] = time.perf_counter() - started

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    killed, done = [None], threading.Event()

    def watch():  # the time limit, and a memory cap that keeps a runaway probe from taking the machine
        while not done.wait(0.05):
            over_time = time.perf_counter() - started > limit
            if over_time or rss_mb(process.pid) > cap_mb:
                killed[0] = f"{limit:.0f} s" if over_time else f"{cap_mb:.0f} MB"
                os.killpg(process.pid, signal.SIGKILL)
                return

    threading.Thread(target=watch, daemon=True).start()
    _, status, usage = os.wait4(process.pid, 0)
    seconds = time.perf_counter() - started
    done.set()
    process.returncode = os.waitstatus_to_exitcode(status)
    reader.join(5)
    text = output.decode("utf-8", "replace").replace("\r", "\n")
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    bars = [line for line in lines if re.search(r"\d+%\||[\d?.]+ ?(it|B|scan)/s|s/(it|scan)\]", line)]
    said = [line for line in lines if line not in bars]
    last = (bars or lines)[-1] if killed[0] or not said else said[-1]
    if pick is not None:
        last = next((line for line in lines if re.search(pick, line)), last)
    return {"rc": process.returncode, "seconds": seconds, "peak_mb": usage.ru_maxrss / 1024, "killed": killed[0],
            "last_output": last_output[0], "last": last, "progress": bool(bars),
            "traceback": "Traceback (most recent call last)" in text}


def run_probe(command: list[str], limit: float = PROBE_LIMIT, pick: str | None = None) -> dict:
    """:func:`_measure` of ``command``, run from a small Python process."""
    source = (f"import json, sys\n{inspect.getsource(_measure)}\n"
              f"print(json.dumps(_measure(json.loads(sys.argv[1]), {limit!r}, {MEMORY_CAP_MB!r}, {pick!r})))")
    result = subprocess.run([sys.executable, "-c", source, json.dumps(command)], capture_output=True, text=True,
                            check=False)
    lines = result.stdout.strip().splitlines()
    if not lines:  # the small process measuring the probe was killed too (the kernel's out-of-memory killer)
        return {"rc": result.returncode, "seconds": float("nan"), "peak_mb": float("nan"), "progress": False,
                "killed": "the probe's runner died (out of memory?)", "last_output": None, "last": "",
                "traceback": False}
    return json.loads(lines[-1])


def probes(folder: Path, only: str | None = None) -> None:
    print("\n| probe (subprocess) | exit | outcome (last line of output) | s | peak MB |\n"
          "| --- | --- | --- | --- | --- |", flush=True)
    for label, command, *pick in probe_inputs(folder):
        if only is not None and only not in label:
            continue
        r = run_probe(command, pick=pick[0] if pick else None)
        outcome = r["last"][:300].replace("|", "/")
        if r["killed"]:
            shown = (f"progress shown, last output at {r['last_output']:.0f} s" if r["progress"]
                     else "no progress output")
            outcome = f"KILLED at {r['killed']} ({shown}): {outcome}"
        print(f"| {label} | {r['rc']} | {outcome} | {r['seconds']:.1f} | {r['peak_mb']:.0f} |", flush=True)


def training_side(folder: Path, only: str | None = None) -> None:
    """The training side's probes (``training_probes``): a table of verdicts and a summary line."""
    from training_probes import LIMIT_MB, LIMIT_SECONDS, digest, training_probes, verdict

    print("\n| probe (training side) | exit | verdict | outcome (last line of output) | s | peak MB |\n"
          "| --- | --- | --- | --- | --- | --- |", flush=True)
    counts: dict[str, int] = {}
    for probe in training_probes(folder):
        if only is not None and only not in probe.label:
            continue
        before = digest(probe.keep)
        r = run_probe(probe.command, limit=LIMIT_SECONDS)
        after = digest(probe.keep)
        kind, words = verdict(probe, r, [Path(p).name for p in before if before[p] != after[p]])
        counts[kind] = counts.get(kind, 0) + 1
        print(f"| {probe.label} | {r['rc']} | {kind}: {words} | {r['last'][:240].replace('|', '/')} | "
              f"{r['seconds']:.1f} | {r['peak_mb']:.0f} |", flush=True)
    print(f"\ntraining side: {sum(counts.values())} probes: {counts.get('clear error', 0)} clear errors, "
          f"{counts.get('ok', 0)} did what they should; {counts.get('SILENT WRONG', 0)} silent wrong results, "
          f"{counts.get('DATA LOSS', 0)} data loss, {counts.get('TRACEBACK', 0)} raw tracebacks, "
          f"{counts.get('LIMIT', 0)} over {LIMIT_MB / 1024:.0f} GB or {LIMIT_SECONDS:.0f} s", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--train", action="store_true", help="also interrupt two training runs")
    parser.add_argument("--probes-only", action="store_true", help="only the probes run in a subprocess each")
    parser.add_argument("--training-side", action="store_true",
                        help="only the training side's probes (runs, clones, resumes, model and demonstration files, "
                             "training records, the tools' CSVs)")
    parser.add_argument("--only", default=None, metavar="TEXT", help="only the probes whose label holds TEXT")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "training").mkdir()
        if args.training_side:
            training_side(folder / "training", args.only)
            return
        if not args.probes_only:
            compile_filter_kernels()
            print("| case | outcome | s | peak MB |\n| --- | --- | --- | --- |")
            for label, action in cases(folder):
                outcome, seconds, peak, _ = run_case(action)
                print(f"| {label} | {outcome[:220].replace('|', '/')} | {seconds:.2f} | {peak:.1f} |", flush=True)
        (folder / "probes").mkdir()
        probes(folder / "probes", args.only)
        training_side(folder / "training", args.only)
        if args.train:
            for label, outcome, seconds in training_interrupts(folder):
                print(f"| {label} | {outcome} | {seconds:.1f} after SIGINT | - |", flush=True)


if __name__ == "__main__":
    main()
