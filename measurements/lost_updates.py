"""The PPO updates a model file holds against the decisions it counts: how many updates an on-policy run
(PPO, MaskablePPO) lost when it was stopped and resumed before resumes went on from the last update (one a
stop), or how far a checkpoint's weights lag its count (a checkpoint written before its last rollout's update).

    python measurements/lost_updates.py [MODEL ...] [--earlier DECISIONS:N_ENVS:N_STEPS:BATCH_SIZE:N_EPOCHS ...]

Without MODEL: every model zip git tracks (the shipped agents), each with the earlier stages its model card
names (:data:`EARLIER_STAGES`). ``--earlier``: the stages a MODEL's lineage went through before its own
configuration (``train --init-from`` keeps a model's counts), oldest first. Read from each zip, with no code
unpickled: SB3's ``data`` JSON (``num_timesteps``, ``_n_updates``, ``n_envs``, ``n_steps``, ``batch_size``,
``n_epochs``) and the step count of its Adam optimizer (``policy.optimizer.pth``, through torch's weights-only
loader). SB3 adds one to ``_n_updates`` for each epoch of an update (``PPO.train``), so an update counts
``n_epochs``, and ``ceil(n_envs * n_steps / batch_size)`` optimizer steps an epoch: with two stages of different
minibatch counts, the two counts give the updates made in each stage.
"""

from __future__ import annotations

import argparse
import io
import itertools
import math
import subprocess
import zipfile
from dataclasses import dataclass
from pathlib import Path

import _arguments as arguments

from emmi_gym.tools.training.run_folders.model_files import saved_data


@dataclass(frozen=True)
class Stage:
    """A part of a model's training under one configuration: its decisions and how it updates."""

    decisions: int
    n_envs: int
    n_steps: int
    batch_size: int
    n_epochs: int

    @property
    def rollout(self) -> int:
        """Decisions an update."""
        return self.n_envs * self.n_steps

    @property
    def expected(self) -> int:
        """The updates of the stage's whole rollouts."""
        return self.decisions // self.rollout

    @property
    def optimizer_steps(self) -> int:
        """Optimizer steps an update: a minibatch each, every epoch."""
        return self.n_epochs * math.ceil(self.rollout / self.batch_size)


#: The stages before its own configuration of each shipped agent trained from another model (its model card's
#: "Trained in three stages"): explore_plans_emmi's stage 2, the emmi agent of seed 2 of `emmi-gym benchmark
#: --config agents/ppo_plans_rewards.yaml`, 2,560 decisions of 4 x 128 (its stage 1, behaviour cloning, makes no
#: PPO update and fits with an optimizer of its own).
EARLIER_STAGES = {"explore_plans_emmi": (Stage(2560, n_envs=4, n_steps=128, batch_size=128, n_epochs=10),)}


def parse_stage(text: str) -> Stage:
    """A ``--earlier`` stage, ``DECISIONS:N_ENVS:N_STEPS:BATCH_SIZE:N_EPOCHS``."""
    parts = text.split(":")
    if len(parts) != 5 or not all(part.isdigit() for part in parts) or min(map(int, parts[1:])) < 1:
        raise argparse.ArgumentTypeError(f"expected DECISIONS:N_ENVS:N_STEPS:BATCH_SIZE:N_EPOCHS, got {text!r}")
    return Stage(*map(int, parts))


def optimizer_steps(path: Path) -> int | None:
    """The step count of the Adam optimizer saved in model zip ``path`` (the same for every parameter), None if
    it holds none. Torch's weights-only loader builds tensors and plain containers only."""
    import torch

    with zipfile.ZipFile(path) as archive:
        if "policy.optimizer.pth" not in archive.namelist():
            return None
        state = torch.load(io.BytesIO(archive.read("policy.optimizer.pth")), weights_only=True, map_location="cpu")
    steps = {int(entry["step"]) for entry in state["state"].values() if "step" in entry}
    if len(steps) != 1:
        raise ValueError(f"{path}: its optimizer's parameters were stepped {sorted(steps)} times, not once each alike")
    return steps.pop()


def stages_of(data: dict, earlier: tuple[Stage, ...], where: Path) -> list[Stage]:
    """The stages of a model: ``earlier``, then its own configuration's for the rest of its decisions."""
    missing = [key for key in ("num_timesteps", "_n_updates", "n_envs", "n_steps", "batch_size", "n_epochs")
               if not isinstance(data.get(key), int)]
    if missing:
        raise ValueError(f"{where}: not an on-policy model (its data has no {', '.join(missing)})")
    if data.get("target_kl") is not None:
        raise ValueError(f"{where}: target_kl {data['target_kl']}: an update may stop before its n_epochs")
    own = data["num_timesteps"] - sum(stage.decisions for stage in earlier)
    if own < 0:
        raise ValueError(f"{where}: its {data['num_timesteps']} decisions are fewer than its earlier stages'")
    return [*earlier, Stage(own, data["n_envs"], data["n_steps"], data["batch_size"], data["n_epochs"])]


def updates_made(stages: list[Stage], epochs: int, steps: int | None) -> list[tuple[int, ...]]:
    """Every count of updates per stage (each at most the stage's whole rollouts) that gives ``epochs`` (SB3's
    ``_n_updates``) and, if known, the optimizer's ``steps``."""
    return [made for made in itertools.product(*(range(stage.expected + 1) for stage in stages))
            if sum(u * stage.n_epochs for u, stage in zip(made, stages, strict=True)) == epochs
            and (steps is None or sum(u * stage.optimizer_steps for u, stage in zip(made, stages, strict=True))
                 == steps)]


def report(args: argparse.Namespace) -> int:
    if args.earlier and not args.models:
        raise ValueError("--earlier: the stages of the MODEL files given (the shipped ones' are known)")
    models = args.models or [Path(name) for name in subprocess.run(
        ["git", "ls-files", "*.zip"], capture_output=True, text=True, check=True).stdout.split()]
    rows = []  # every model read before the table, so that a bad file is its one line
    for path in models:
        earlier = tuple(args.earlier) if args.models else EARLIER_STAGES.get(path.parent.name, ())
        data = saved_data(path)
        stages = stages_of(data, earlier, path)
        found = updates_made(stages, data["_n_updates"], optimizer_steps(path))
        name = str(path) if args.models else path.parent.name
        for k, stage in enumerate(stages):  # "?": no count fits; "a or b": more than one does
            made = sorted({solution[k] for solution in found})
            lost = str(stage.expected - made[0]) if len(made) == 1 else "?"
            rows.append(f"| {name} | {k + 1} of {len(stages)} | {stage.decisions} | {stage.rollout} | "
                        f"{stage.expected} | {' or '.join(map(str, made)) or '?'} | {lost} |")
    print("| model | stage | decisions | decisions an update | updates expected | updates made | lost |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    print("\n".join(rows))
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", type=Path, nargs="*", help="model zips (default: every zip git tracks)")
    parser.add_argument("--earlier", type=parse_stage, nargs="+", default=(), metavar="STAGE",
                        help="with MODEL: the stages before its own configuration, "
                             "DECISIONS:N_ENVS:N_STEPS:BATCH_SIZE:N_EPOCHS, oldest first")
    return arguments.run_command(parser, report)


if __name__ == "__main__":
    raise SystemExit(main())
