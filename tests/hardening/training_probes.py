"""The training side's probes of ``tests/hardening/hardening_audit.py``: runs, clones, resumes, model and demonstration
files, training records and the tools' CSVs, each tried as a hostile but realistic user would, and each
given a verdict: a clear error (exit status not 0, no traceback, the message naming what is wrong), a
success that did what it should, or one of the failures the audit counts: a silent wrong result (exit
0 where the input should have been refused, or an output that is wrong), data loss (a file of an earlier
run changed), a raw traceback, or a probe over 1 GB or 120 s.

Every probe gets its own copy of a small finished run R (MaskablePPO on LoopCorridor-v1, 16 decisions).
"""

from __future__ import annotations

import base64
import hashlib
import io
import json
import os
import pickle
import re
import shutil
import subprocess
import sys
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

#: A probe passes under these (the issue's criteria).
LIMIT_SECONDS, LIMIT_MB = 120.0, 1024.0

CORRIDOR = {"env": {"id": "emmi_gym/LoopCorridor-v1", "kwargs": {"particles": 3, "max_decisions": 3}},
            "algorithm": "MaskablePPO", "policy": "MultiInputPolicy",
            "hyperparameters": {"n_steps": 8, "batch_size": 8, "n_epochs": 1, "policy_kwargs": {"net_arch": [8]}},
            "n_envs": 1, "vec_env": "dummy", "total_timesteps": 16, "seed": 3, "eval": {"freq": 0},
            "checkpoint_freq": 8}
MEASURES = "timesteps,oracle_accuracy,ate,sim_steps,coverage\n"
CURVE = MEASURES + "8,0.5,0.2,100,0.4\n16,0.6,0.1,90,0.5\n"


@dataclass
class Probe:
    """A command and what it must do: ``error`` (a regex the last line of a refusal must match) or, with
    ``success`` set, exit 0 and ``success(last line, peak MB)`` return None (else what is wrong);
    ``either``: a clear error matching ``error`` or a success; ``keep``: files that must stay as they were."""

    label: str
    command: list[str]
    error: str = ""
    success: Callable | None = None
    either: bool = False
    keep: list[Path] = field(default_factory=list)


def verdict(probe: Probe, result: dict, changed: list[str]) -> tuple[str, str]:
    """(kind, words): kind one of "clear error", "ok", "SILENT WRONG", "DATA LOSS", "TRACEBACK", "LIMIT"."""
    if result["killed"] or result["seconds"] > LIMIT_SECONDS or result["peak_mb"] > LIMIT_MB:
        return "LIMIT", f"{result['seconds']:.0f} s, {result['peak_mb']:.0f} MB"
    if result["traceback"]:
        return "TRACEBACK", "a raw traceback"
    if changed:
        return "DATA LOSS", f"changed {', '.join(changed)}"
    if result["rc"] == 0:
        if probe.success is None and not probe.either:
            return "SILENT WRONG", "exit 0: should have been refused"
        wrong = probe.success(result["last"], result["peak_mb"]) if probe.success else None
        return ("SILENT WRONG", wrong) if wrong else ("ok", "did what it should")
    if probe.success is not None and not probe.either:
        return "SILENT WRONG", f"exit {result['rc']}: should have succeeded"
    if not re.search(probe.error, result["last"]):
        return "SILENT WRONG", f"the message does not say /{probe.error}/"
    return "clear error", "names what is wrong"


def digest(paths: list[Path]) -> dict[str, str]:
    return {str(p): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "absent" for p in paths}


def _copy(run: Path, to: Path) -> Path:
    shutil.copytree(run, to)
    return to


def _write_zip(path: Path, members: dict[str, bytes]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return path


def _npy(value=None, header_shape=None) -> bytes:
    buffer = io.BytesIO()
    if header_shape is not None:
        np.lib.format.write_array_header_1_0(buffer, {"descr": "|u1", "fortran_order": False, "shape": header_shape})
        return buffer.getvalue() + bytes(512)
    np.save(buffer, value)
    return buffer.getvalue()


def _demonstrations(n=3, **changes) -> dict:
    """Arrays of demonstrations of the corridor config's env, ``changes`` replacing (None: dropping) some."""
    arrays = {"masks": np.ones((n, 8), bool), "actions": np.zeros(n, np.int64), "episodes": np.int64(1),
              "obs_map": np.zeros((n, 2, 64, 64), np.uint8), "obs_pose": np.zeros((n, 3), np.float32)}
    arrays.update(changes)
    return {name: value for name, value in arrays.items() if value is not None}


def _bad_crc(model: Path, to: Path) -> Path:
    """A copy of ``model`` whose ``policy.pth`` has a wrong CRC-32 in its local and central headers."""
    raw = bytearray(model.read_bytes())
    with zipfile.ZipFile(model) as archive:
        info = archive.getinfo("policy.pth")
    raw[info.header_offset + 14:info.header_offset + 18] = bytes(4)
    central = raw.rfind(b"PK\1\2", 0, raw.rfind(b"policy.pth")) + 16
    raw[central:central + 4] = bytes(4)
    to.parent.mkdir(parents=True, exist_ok=True)
    to.write_bytes(bytes(raw))
    return to


def training_probes(folder: Path) -> list[Probe]:
    """Make the inputs (R trained here, ~30 s) and return the probes."""
    py, cli = [sys.executable, "-c"], [sys.executable, "-m", "emmi_gym.tools.cli"]
    score, plot = [*cli, "score-checkpoints"], [*cli, "learning-curves"]
    f = folder
    configs = {"corridor": CORRIDOR, "corridor24": dict(CORRIDOR, total_timesteps=24),
               "ppo": dict(CORRIDOR, algorithm="PPO"),
               "explore": dict(CORRIDOR, env={"id": "emmi_gym/Explore-v1", "kwargs": CORRIDOR["env"]["kwargs"]}),
               "plans": dict(CORRIDOR, env={"id": "emmi_gym/ExplorePlans-v1", "kwargs": {"particles": 3}}),
               "obs32": dict(CORRIDOR, env={"id": "emmi_gym/LoopCorridor-v1",
                                            "kwargs": dict(CORRIDOR["env"]["kwargs"], obs_size=32)})}
    for name, data in configs.items():
        (f / f"{name}.yaml").write_text(yaml.safe_dump(data))
    cfg = {name: str(f / f"{name}.yaml") for name in configs}
    run = f / "R"
    subprocess.run([*cli, "train", cfg["corridor"], "--out", str(run), "--quiet"], check=True, capture_output=True)
    model = run / "model.zip"
    with zipfile.ZipFile(model) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}

    def run_copy(name: str) -> Path:
        return _copy(run, f / name)

    def model_folder(name: str, model_members: dict | None = None, source: Path | None = None) -> Path:
        target = f / name / "model.zip"
        if source is not None:
            target.parent.mkdir(parents=True)
            shutil.copyfile(source, target)
        else:
            _write_zip(target, model_members)
        shutil.copyfile(run / "config.yaml", target.parent / "config.yaml")
        return target

    def wrote(expected: Path):
        return lambda last, _: None if last == f"wrote {expected}" and expected.is_file() else f"said {last!r}"

    probes = []
    # 1. --resume with another configuration
    for other in ("ppo", "explore"):
        r1 = run_copy(f"R1_{other}")
        what = "algorithm" if other == "ppo" else "env id"
        probes.append(Probe(f"1. train {other}.yaml --resume --out R (another {what})",
                            [*cli, "train", cfg[other], "--resume", "--out", str(r1), "--quiet"],
                            r"config|algorithm|env", keep=[r1 / "config.yaml", r1 / "model.zip", r1 / "training.yaml"]))
    # 2. clone into a finished run
    r2 = run_copy("R2")
    probes.append(Probe("2. clone --out EXISTING run",
                        [*cli, "clone", cfg["corridor"], "--policy", "frontier", "--episodes", "1", "--workers", "1",
                         "--out", str(r2), "--quiet"],
                        r"R2|exist|overwrite", keep=[r2 / "model.zip", r2 / "config.yaml", r2 / "training.yaml"]))
    # 3. a new run into an interrupted one
    r3 = run_copy("R3")
    (r3 / "model.zip").unlink()
    probes.append(Probe("3. train CFG --out R (R holds an interrupted run)",
                        [*cli, "train", cfg["corridor"], "--out", str(r3), "--quiet"], r"resume|overwrite|R3",
                        keep=[r3 / "checkpoints" / "model_8_steps.zip", r3 / "training.yaml"]))
    # 4. --init-from a model of another env id
    probes.append(Probe("4. train plans.yaml --init-from the corridor agent",
                        [*cli, "train", cfg["plans"], "--init-from", str(model), "--out", str(f / "T4"), "--quiet"],
                        r"LoopCorridor|ExplorePlans|env"))
    # 5. score-checkpoints --episodes 0 / -1
    for episodes in ("0", "-1"):
        r5 = run_copy(f"R5_{episodes}")
        (r5 / "checkpoint_scores.csv").write_text(CURVE)
        probes.append(Probe(f"5. score-checkpoints R --episodes {episodes}",
                            [*score, str(r5), "--episodes", episodes],
                            r"--episodes: expected an integer in \[1, 100000\]", keep=[r5 / "checkpoint_scores.csv"]))
    # 6 and 13. learning-curves and score-checkpoints
    csvs = {"empty": "", "header_only": MEASURES, "all_nan": MEASURES + "8,nan,nan,nan,nan\n16,,,,\n",
            "no_ate_column": "timesteps,oracle_accuracy,sim_steps,coverage\n8,0.5,100,0.4\n",
            "text_in_a_number": MEASURES + "8,0.5,fast,100,0.4\n",
            "131_KB_field": MEASURES + '8,"' + "x" * 131_100 + '"\n',
            "good": CURVE}
    for name, text in csvs.items():
        (f / f"csv_{name}").mkdir()
        (f / f"csv_{name}" / "eval_ground_truth.csv").write_text(text)
    (f / "csv_utf16").mkdir()
    (f / "csv_utf16" / "eval_ground_truth.csv").write_bytes(CURVE.encode("utf-16"))
    (f / "csv_latin1").mkdir()
    (f / "csv_latin1" / "eval_ground_truth.csv").write_bytes((MEASURES + "8,0.5,0.2,100,0.4\n").encode() + b"\xe9\n")
    (f / "garbage.csv").write_bytes(bytes(range(256)) * 4)
    (f / "a_file").write_text("x")
    good = str(f / "csv_good")
    expected = {"empty": "the file is empty", "header_only": "holds only the header",
                "all_nan": "expected a finite value in at least one row",
                "no_ate_column": r"with the columns \['ate'\]",
                "text_in_a_number": r":2: field 'ate': expected a number",
                "131_KB_field": "field larger than field limit", "utf16": "UTF-8", "latin1": "UTF-8"}
    for name, pattern in expected.items():
        out = f / f"plot_{name}.png"
        item = "13" if name in ("no_ate_column", "text_in_a_number", "131_KB_field", "latin1") else "6"
        probes.append(Probe(f"{item}. learning-curves: {name.replace('_', ' ')} CSV",
                            [*plot, str(f / f"csv_{name}"), "--out", str(out)], f"eval_ground_truth.csv.*{pattern}"))
    probes += [
        Probe("6. learning-curves --baselines-csv garbage", [*plot, good, "--baselines-csv",
                                                                     str(f / "garbage.csv"), "--out", str(f / "b.png")],
              r"garbage\.csv: expected"),
        Probe("6. learning-curves --out NAME (no suffix)", [*plot, good, "--out", str(f / "NAME")],
              success=wrote(f / "NAME.png")),
        Probe("13. learning-curves: a run folder without the CSV", [*plot, str(f / "R"), "--out",
                                                                          str(f / "c.png")],
              r"eval_ground_truth\.csv does not exist"),
        Probe("13. learning-curves --out in an unwritable place", [*plot, good, "--out",
                                                                          str(f / "a_file" / "c.png")],
              r"--out .*a_file: expected a folder that can be made and written to"),
        Probe("13. score-checkpoints MISSING_FOLDER", [*score, str(f / "missing")],
              r"^emmi-gym score-checkpoints: error: run folder .*missing does not exist$"),
    ]
    # 7. non-finite demonstrations and models
    inf = _demonstrations(obs_pose=np.array([[np.inf, 0, 0]] + [[0, 0, 0]] * 2, np.float32))
    np.savez(f / "inf.npz", **inf)
    probes.append(Probe("7. clone --demos with one inf in the observations",
                        [*cli, "clone", cfg["corridor"], "--demos", str(f / "inf.npz"), "--out", str(f / "C7"),
                         "--quiet"],
                        r"inf\.npz: field 'obs_pose': expected finite observations"))
    nan_model = f / "nan" / "model.zip"
    nan_model.parent.mkdir()
    shutil.copyfile(run / "config.yaml", nan_model.parent / "config.yaml")
    subprocess.run([*py, f"from sb3_contrib import MaskablePPO; m = MaskablePPO.load({str(model)!r}); "
                         f"next(m.policy.parameters()).data.fill_(float('nan')); m.save({str(nan_model)!r})"],
                   check=True, capture_output=True)
    probes.append(Probe("7. train --init-from a model with NaN parameters",
                        [*cli, "train", cfg["corridor24"], "--init-from", str(nan_model), "--out", str(f / "T7"),
                         "--quiet"], r"NaN|finite"))
    # 8. training.yaml
    records = {"garbage": "\0\1\2garbage", "a list": "- 1\n- 2\n",
               "100,000-deep": "wall_seconds: " + "[" * 100_000 + "]" * 100_000 + "\n",
               "wall_seconds abc": "timesteps: 16\nwall_seconds: abc\n",
               "wall_seconds -100000": "timesteps: 16\nwall_seconds: -100000\n",
               "wall_seconds .nan": "timesteps: 16\nwall_seconds: .nan\n"}
    for k, (name, text) in enumerate(records.items()):
        r8 = run_copy(f"R8_{k}")
        (r8 / "training.yaml").write_text(text)
        probes.append(Probe(f"8. train --resume with training.yaml: {name}",
                            [*cli, "train", cfg["corridor24"], "--resume", "--out", str(r8), "--quiet"],
                            r"training\.yaml", keep=[r8 / "model.zip", r8 / "training.yaml"]))
    # 9. demonstrations
    demos = {"float masks": _demonstrations(masks=np.ones((3, 8), np.float32)),
             "0-d actions": _demonstrations(actions=np.int64(0)),
             "string actions": _demonstrations(actions=np.array(["a", "b", "c"])),
             "zero decisions": _demonstrations(n=0), "1-D masks": _demonstrations(masks=np.ones(3, bool))}
    for name, arrays in demos.items():
        path = f / f"demos_{name.replace(' ', '_')}.npz"
        np.savez(path, **arrays)
        probes.append(Probe(f"9. clone --demos: {name}", [*cli, "clone", cfg["corridor"], "--demos", str(path),
                                                          "--out", str(f / "C9"), "--quiet"],
                            rf"{path.name}: field '(masks|actions|episodes)'"))
    npy_members = {f"{k}.npy": _npy(v) for k, v in _demonstrations().items()}
    _write_zip(f / "trillion.npz", dict(npy_members, **{"obs_map.npy": _npy(header_shape=(10**12, 2, 64, 64))}))
    np.savez(f / "small_map.npz", **_demonstrations(obs_map=np.zeros((3, 2, 32, 32), np.uint8)))
    np.savez(f / "good.npz", **_demonstrations())
    probes += [
        Probe("9. clone --demos: a header declaring 10^12 rows", [*cli, "clone", cfg["corridor"], "--demos",
                                                                  str(f / "trillion.npz"), "--out", str(f / "C9")],
              r"trillion\.npz: field 'obs_map': expected an array of the .* bytes its header declares"),
        Probe("9. clone --demos: two files that do not match", [*cli, "clone", cfg["corridor"], "--demos",
                                                                str(f / "good.npz"), str(f / "small_map.npz"),
                                                                "--out", str(f / "C9")],
              r"small_map\.npz: field 'obs_map': expected the members and shapes of"),
    ]
    # 10. memory and episode counts
    big = f / "big.npz"
    rows = 75_000  # 0.6 GB of observations in a few MB
    np.savez_compressed(big, **_demonstrations(n=rows, obs_map=np.zeros((rows, 2, 64, 64), np.uint8)))
    probes += [
        Probe("10. load demonstrations of 0.6 GB from a few MB (under 1 GB: read once, not copied)",
              [*py, "from emmi_gym.tools.training.imitation import Demonstrations; "  # as clone --demos loads one file
                    f"d = Demonstrations.joined([Demonstrations.load({str(big)!r})]); print(len(d), 'decisions')"],
              success=lambda last, _: None if last == f"{rows} decisions" else last),
        Probe("10. clone --episodes 10**9", [*cli, "clone", cfg["corridor"], "--episodes", str(10**9), "--out",
                                             str(f / "C10")], r"--episodes: expected an integer in \[1, 100000\]"),
        Probe("10. evaluate --episodes 10**9 --baselines frontier", [*cli, "evaluate", str(model), "--episodes",
                                                                     str(10**9), "--baselines", "frontier"],
              r"--episodes: expected an integer in \[1, 100000\]"),
    ]
    # 11. model zips
    data = dict(json.loads(members["data"]), deep="DEEP")
    deep = json.dumps(data).replace('"DEEP"', "[" * 200_000 + "]" * 200_000).encode()
    bad_models = {"data nested 200,000 deep": (model_folder("M_deep", dict(members, data=deep)),
                                               r"nested at most 100 deep"),
                  "garbage policy.pth": (model_folder("M_garbage", dict(members, **{"policy.pth": b"garbage" * 100})),
                                         r"field 'policy\.pth': expected PyTorch weights"),
                  "a 250 MB policy.pth bomb": (model_folder("M_bomb", dict(members,
                                                                           **{"policy.pth": bytes(250 * 10**6)})),
                                               r"field 'policy\.pth': expected PyTorch weights"),
                  "a bad CRC": (model_folder("M_crc", source=_bad_crc(model, f / "crc.zip")), r"CRC-32 does not match")}
    for name, (path, pattern) in bad_models.items():
        probes += [
            Probe(f"11. train --init-from a model: {name}", [*cli, "train", cfg["corridor24"], "--init-from", str(path),
                                                           "--out", str(f / "T11"), "--quiet"], pattern),
            Probe(f"11. benchmark --init-from a model: {name}",
                  [*cli, "benchmark", "--config", cfg["corridor"], "--init-from", str(path), "--rewards", "emmi",
                   "--seeds", "1", "--episodes", "1", "--baselines", "--out", str(f / "B11"), "--quiet"], pattern),
            Probe(f"11. evaluate MODEL: {name}", [*cli, "evaluate", str(path), "--episodes", "1"], pattern),
        ]
    # 12. obs_size at its lower bound
    probes.append(Probe("12. train with obs_size: 32", [*cli, "train", cfg["obs32"], "--out", str(f / "T12"),
                                                         "--quiet"], r"obs_size", success=lambda *_: None, either=True))
    probes += _fault_probes(f, cli, cfg, run, run_copy)
    probes += _third_audit_probes(f, cli, cfg, run, run_copy, members)
    # the pretrained agents as the README loads them
    probes += [
        Probe("README: import emmi_gym; emmi_gym.pretrained.load(NAME)",
              [*py, "import emmi_gym; m = emmi_gym.pretrained.load('loop_corridor_emmi'); print('loaded', "
                    "type(m).__name__)"], success=lambda last, _: None if last == "loaded MaskablePPO" else last),
        Probe("README: emmi_gym.pretrained.make_env(NAME) is the env it was trained in",
              [*py, "import emmi_gym; name = 'explore_plans_emmi'; env = emmi_gym.pretrained.make_env(name); "
                    "wanted = emmi_gym.pretrained.config(name).env_kwargs; "
                    "print('same keywords' if all(env.spec.kwargs.get(k) == v for k, v in wanted.items()) else "
                    "'other keywords')"], success=lambda last, _: None if last == "same keywords" else last),
    ]
    return probes


def _fault_probes(f: Path, cli: list, cfg: dict, run: Path, run_copy) -> list[Probe]:
    """The second audit's mistakes: an overwrite reading its own folder, a resume below what is trained, damaged
    or hand-edited run files, a benchmark's arguments and budgets, and the smaller inputs (numbered as the
    audit numbered them)."""
    probes = []
    r1 = run_copy("F1")
    for model in (r1 / "model.zip", r1 / "checkpoints" / "model_8_steps.zip"):
        probes.append(Probe(f"F1. train --overwrite --init-from {model.relative_to(r1)} of R --out R",
                            [*cli, "train", cfg["corridor24"], "--overwrite", "--init-from", str(model), "--out",
                             str(r1), "--quiet"], r"--init-from .* is a file of the run in",
                            keep=[r1 / "model.zip", r1 / "checkpoints" / "model_8_steps.zip", r1 / "training.yaml"]))
    c1 = f / "F1_clone"
    c1.mkdir()
    np.savez(c1 / "demonstrations.npz", **_demonstrations())
    probes.append(Probe("F1. clone --overwrite --demos C/demonstrations.npz --out C",
                        [*cli, "clone", cfg["corridor"], "--overwrite", "--demos", str(c1 / "demonstrations.npz"),
                         "--out", str(c1), "--quiet"], r"--demos .* is a file of the run in",
                        keep=[c1 / "demonstrations.npz"]))
    bench = [*cli, "benchmark", "--config", cfg["corridor"], "--seeds", "1", "--episodes", "1", "--quiet"]
    b3 = f / "F3"
    (b3 / "runs" / "emmi_seed0").mkdir(parents=True)
    shutil.copytree(run, b3 / "runs" / "emmi_seed0", dirs_exist_ok=True)
    kept = yaml.safe_load((run / "config.yaml").read_text())
    kept.update(env=dict(kept["env"], kwargs=dict(kept["env"]["kwargs"], reward="emmi")), seed=0, policy_lag=0)
    (b3 / "runs" / "emmi_seed0" / "config.yaml").write_text(yaml.safe_dump(kept))
    probes += [
        Probe("F3. benchmark into its own folder with a smaller --timesteps", [*bench, "--rewards", "emmi",
                                                                              "--baselines", "--timesteps", "8",
                                                                              "--out", str(b3)],
              r"a larger budget than --timesteps 8", keep=[b3 / "runs" / "emmi_seed0" / "config.yaml"]),
        Probe("F4. benchmark --rewards emmi emmi", [*bench, "--rewards", "emmi", "emmi", "--baselines", "--out",
                                                    str(f / "F4")], r"--rewards: emmi given more than once"),
        Probe("F11. benchmark --baselines bogus", [*bench, "--rewards", "emmi", "--baselines", "bogus", "--out",
                                                   str(f / "F11")], r"--baselines: unknown \['bogus'\]"),
    ]
    r5 = run_copy("F5")
    probes.append(Probe("F5. train --resume --timesteps 8 on a finished 16-decision run",
                        [*cli, "train", cfg["corridor"], "--resume", "--timesteps", "8", "--out", str(r5), "--quiet"],
                        r"holds 16 decisions", keep=[r5 / "model.zip", r5 / "config.yaml", r5 / "training.yaml"]))
    r8 = run_copy("F8")
    record = yaml.safe_load((r8 / "training.yaml").read_text())
    (r8 / "training.yaml").write_text(yaml.safe_dump(dict(record, parts=[dict(record["parts"][0], end=4)])))
    probes.append(Probe("F8. train --resume with training.yaml parts that do not add up",
                        [*cli, "train", cfg["corridor24"], "--resume", "--out", str(r8), "--quiet"],
                        r"expected parts that add up", keep=[r8 / "config.yaml", r8 / "training.yaml"]))
    r8b = run_copy("F8b")
    edited = yaml.safe_load((r8b / "config.yaml").read_text())
    edited["hyperparameters"]["policy_kwargs"] = {"net_arch": [5]}
    (r8b / "config.yaml").write_text(yaml.safe_dump(edited))
    probes.append(Probe("F8. train --resume with a hand-edited config.yaml (another net_arch)",
                        [*cli, "train", str(r8b / "config.yaml"), "--resume", "--timesteps", "24", "--out",
                         str(r8b), "--quiet"], r"the model's network is policy_kwargs",
                        keep=[r8b / "config.yaml", r8b / "training.yaml", r8b / "model.zip"]))
    (f / "F11_curve").mkdir()
    (f / "F11_curve" / "eval_ground_truth.csv").write_text(MEASURES + "-8,0.5,0.2,100,0.4\n16,0.6,0.1,90,0.5\n")
    probes += [
        Probe("F11. learning-curves: negative timesteps", [*cli, "learning-curves", str(f / "F11_curve"), "--out",
                                                          str(f / "F11.png")], r"timesteps.*0 or more"),
        Probe("F11. compare-policies --options with a world beside --worlds",
              [*cli, "compare-policies", "--options", '{"world": "x.yaml"}', "--out", str(f / "F11_cmp")],
              r"--options: a world"),
    ]
    return probes


class _MakesAFolder:
    """Unpickled, makes the folder ``path``: code a model file's pickle runs (its class is not in the pickle)."""

    def __init__(self, path: Path):
        self.path = str(path)

    def __reduce__(self):
        return os.mkdir, (self.path,)


def _odometry_bag(path: Path, odometry: list[tuple[float, float]]) -> Path:
    """A ROS 2 bag of ``/odom`` (Odometry at each ``(stamp, x)``, in that order) and one ``/scan`` at 0.5 s."""
    from emmi_gym.formats.ros_messages import LASER_SCAN, ODOMETRY, header, odometry_message
    from emmi_gym.formats.ros_writers import open_bag

    with open_bag(path) as bag:
        for k, (stamp, x) in enumerate(odometry):
            bag.write("/odom", ODOMETRY, k, odometry_message(bag.store, int(stamp * 1e9), "odom", "base_link",
                                                             (x, 0.0, 0.0)))
        bag.write("/scan", LASER_SCAN, len(odometry), bag.store.types[LASER_SCAN](
            header=header(bag.store, 500_000_000, "base_link"), angle_min=-1.0, angle_max=-0.5, angle_increment=0.5,
            time_increment=0.0, scan_time=0.0, range_min=0.1, range_max=30.0,
            ranges=np.array([1.0, 2.0], np.float32), intensities=np.zeros(0, np.float32)))
    return path


def _third_audit_probes(f: Path, cli: list, cfg: dict, run: Path, run_copy, members: dict) -> list[Probe]:
    """The third audit's cases (2026-12-01): a resume whose models do not load, record writing over its world, odometry
    that goes back or is not finite, model files whose pickles run code, replay into an earlier replay's folder, a
    finished run resumed and a run whose only checkpoint is damaged (numbered as the issue numbered them)."""
    probes = []
    dqn = dict(CORRIDOR, algorithm="DQN", hyperparameters={"buffer_size": 100, "learning_starts": 8,
                                                           "policy_kwargs": {"net_arch": [8]}})
    (f / "dqn.yaml").write_text(yaml.safe_dump(dqn))
    g1 = run_copy("G1_dqn")
    shutil.copyfile(f / "dqn.yaml", g1 / "config.yaml")
    g1_cut = run_copy("G1_cut")
    for model in [g1_cut / "model.zip", *(g1_cut / "checkpoints").glob("model_*_steps.zip")]:
        model.write_bytes(model.read_bytes()[:5000])
    for label, folder, config in (("config.yaml replaced by a DQN one", g1, str(f / "dqn.yaml")),
                                  ("every model file cut to 5 kB", g1_cut, cfg["corridor24"])):
        probes.append(Probe(f"G1. train --resume --out R ({label})",
                            [*cli, "train", config, "--resume", "--timesteps", "24", "--out", str(folder), "--quiet"],
                            r"none of the \d+ model files of the run in .* is a whole .* model.*--overwrite",
                            keep=[folder / "config.yaml", folder / "model.zip", folder / "training.yaml",
                                  *sorted((folder / "checkpoints").glob("*"))]))
    # 3. record and its own world
    from emmi_gym.formats.map_server import write_map_server
    from emmi_gym.geometry.grid import GridGeometry
    from emmi_gym.world.loader import world_path

    shutil.copyfile(world_path("loop_corridor"), f / "w.yaml")
    room = np.zeros((40, 40), np.int8)
    room[[0, -1], :] = room[:, [0, -1]] = 100
    lab = write_map_server(f / "lab_map.yaml", room, GridGeometry(0.1, 0.0, 0.0, 40, 40))
    record = [*cli, "record", "--route", "explore", "--beams", "30"]
    probes += [
        Probe("G3. record w.yaml --out w.yaml", [*record, str(f / "w.yaml"), "--out", str(f / "w.yaml")],
              r"--out .*w\.yaml: expected a file apart from the world file", keep=[f / "w.yaml"]),
        Probe("G3. record lab_map.yaml --out lab.log", [*record, str(lab), "--out", str(f / "lab.log")],
              r"the map of --out .*lab_map\.yaml: expected a file apart from the world file",
              keep=[lab, lab.with_suffix(".pgm")]),
        Probe("G3. record --out run.log --bag-out run.log", [*record, str(f / "w.yaml"), "--out", str(f / "run.log"),
                                                            "--bag-out", str(f / "run.log")],
              r"--bag-out .*run\.log: expected a file apart from --out", keep=[f / "run.log"]),
    ]
    # 4. odometry that goes back, or is not finite
    replay = [*cli, "replay", "--odom", "/odom", "--quiet"]
    for label, odometry, pattern in (
            ("odometry stamps that go back", [(0.0, 0.0), (1.0, 1.0), (0.5, 2.0)], r"stamps never go back"),
            ("NaN odometry", [(0.0, 0.0), (1.0, float("nan"))], r"finite x, y and orientation"),
            ("infinite odometry", [(0.0, 0.0), (1.0, float("inf"))], r"finite x, y and orientation")):
        bag = _odometry_bag(f / f"G4_{label.replace(' ', '_')}", odometry)
        probes.append(Probe(f"G4. replay a bag of {label}", [*replay, str(bag), "--out", str(f / "G4_out")],
                            rf"field '/odom': expected odometry.*{pattern}.*message"))
    # 5. model files whose pickles run code
    ran = f / "G5_ran"
    data = json.loads(members["data"])
    data["lr_schedule"] = {":type:": "<class 'function'>",
                           ":serialized:": base64.b64encode(pickle.dumps(_MakesAFolder(ran), protocol=4)).decode()}
    hostile = run_copy("G5")
    shutil.rmtree(hostile / "checkpoints")
    _write_zip(hostile / "checkpoints" / "model_16_steps.zip", dict(members, data=json.dumps(data).encode()))
    shutil.copyfile(hostile / "checkpoints" / "model_16_steps.zip", hostile / "model.zip")
    refused = r"field 'data\.lr_schedule': expected a pickle naming only classes of .*--trust-model"
    probes += [
        Probe("G5. evaluate MODEL whose pickle runs code", [*cli, "evaluate", str(hostile / "model.zip"),
                                                             "--episodes", "1"], refused, keep=[ran]),
        Probe("G5. train --init-from MODEL whose pickle runs code",
              [*cli, "train", cfg["corridor24"], "--init-from", str(hostile / "model.zip"), "--out", str(f / "T_G5"),
               "--quiet"], refused, keep=[ran]),
        Probe("G5. score-checkpoints R (R's checkpoint's pickle runs code)",
              [*cli, "score-checkpoints", str(hostile), "--episodes", "1", "--workers", "1", "--quiet"], refused,
              keep=[ran]),
    ]
    # 7. replay into an earlier replay's folder
    log = f / "G7.log"
    scan = " ".join(["2.5"] * 180)
    log.write_text("".join(f"FLASER 180 {scan} 0 0 0 {0.5 * k} 0 0 {k}.0 h {k}.0\n" for k in range(4)))
    earlier = f / "G7_out"
    subprocess.run([*cli, "replay", str(log), "--max-range", "8", "--particles", "2", "--out", str(earlier),
                    "--quiet"], check=True, capture_output=True)
    probes.append(Probe("G7. replay --out O (O holds an earlier replay)",
                        [*cli, "replay", str(log), "--max-range", "8", "--particles", "2", "--seed", "1", "--out",
                         str(earlier), "--quiet"], r"is not empty .*--overwrite",
                        keep=sorted(earlier.glob("*"))))
    # 8. a finished run resumed; a run whose only checkpoint is damaged
    finished = run_copy("G8_finished")
    probes.append(Probe("G8. train --resume on a finished run", [*cli, "train", cfg["corridor"], "--resume", "--out",
                                                                  str(finished), "--quiet"],
                        success=lambda last, _: None if "already trained to 16 decisions; nothing to do" in last
                        else f"said {last!r}",
                        keep=[finished / "model.zip", finished / "training.yaml", finished / "config.yaml"]))
    damaged = run_copy("G8_damaged")
    (damaged / "model.zip").unlink()
    checkpoints = sorted((damaged / "checkpoints").glob("model_*_steps.zip"))
    for extra in checkpoints[1:]:
        extra.unlink()
    checkpoints[0].write_bytes(checkpoints[0].read_bytes()[:5000])
    probes.append(Probe("G8. score-checkpoints R (R's only checkpoint is damaged)",
                        [*cli, "score-checkpoints", str(damaged), "--episodes", "1", "--quiet"],
                        rf"are all damaged, the last: .*{checkpoints[0].name}"))
    return probes
