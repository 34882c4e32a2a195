"""Ship a trained agent with the package: copy a run's model into emmi_gym/tools/pretrained/NAME/ and write its
model card (configuration, budget, seed, training time, and its evaluation beside scripted baselines).

    python scripts/ship_agent.py runs/ppo_emmi_seed0 loop_corridor_emmi --episodes 30 \\
        --baselines close_loop_first explore_first frontier

The evaluation is ``emmi-gym evaluate --pretrained NAME`` with the same options, on held-out seeds (and,
with ``--world``, on the maps given, e.g. ``dungeon_maps/test``); the card says how to reproduce it.
``--episodes-csv`` takes the episodes from ``emmi-gym evaluate --out`` files instead (run elsewhere, e.g.
on a larger machine, named by ``--evaluated-on``), the model's rows named ``agent`` there. ``--into`` ships it
into another folder than the package's (to look at the card first).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import time
from pathlib import Path

import yaml

from emmi_gym import pretrained
from emmi_gym.env.reward_registry import reward_named
from emmi_gym.tools.commands import arguments
from emmi_gym.tools.evaluation.comparison import format_table, markdown_table, policy_means
from emmi_gym.tools.experiments.report import read_csv
from emmi_gym.tools.training.evaluate import EVALUATION_SEED, OWN_WORLD, compare_model
from emmi_gym.tools.training.run_folders import RunFolder
from emmi_gym.tools.training.run_folders.model_files import saved_decisions
from emmi_gym.tools.training.run_folders.training_record import (
    TRAINING_RECORD,
    TrainingRecordError,
    machine_description,
)

MAX_MODEL_BYTES = 10 * 2**20


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="run folder of 'emmi-gym train' (model.zip, config.yaml)")
    parser.add_argument("name", help="the agent's name in the package")
    parser.add_argument("--episodes", type=arguments.EPISODES, default=30)
    parser.add_argument("--seed", type=arguments.SEED, default=EVALUATION_SEED)
    parser.add_argument("--world", default=None, help="world, map set, folder or glob (default: the run's own)")
    parser.add_argument("--baselines", nargs="*", default=["frontier", "active_loop_closing"])
    parser.add_argument("--training-seconds", type=arguments.number(0.0, unit="s"), default=None,
                        help=f"wall time of training, for a run folder without {TRAINING_RECORD}")
    arguments.add_workers(parser)
    parser.add_argument("--episodes-csv", nargs="+", type=Path, default=None,
                        help="episodes.csv files of 'emmi-gym evaluate --out' with these options, "
                             "instead of evaluating")
    parser.add_argument("--evaluated-on", default=None, help="the machine the --episodes-csv files were made on")
    parser.add_argument("--note", default="", help="a paragraph for the card (e.g. what the run started from)")
    parser.add_argument("--into", type=Path, default=pretrained.FOLDER,
                        help="the folder of the shipped agents (default: the package's, where emmi_gym.pretrained "
                             "finds them)")
    args = parser.parse_args()
    if args.episodes_csv and not args.evaluated_on:
        parser.error("--episodes-csv needs --evaluated-on")
    model = args.run / "model.zip"
    if not model.is_file():
        parser.error(f"no model.zip in {args.run}")
    if model.stat().st_size > MAX_MODEL_BYTES:
        parser.error(f"{model} has {model.stat().st_size} bytes; a shipped agent has at most {MAX_MODEL_BYTES}")
    try:
        record = RunFolder(args.run).record()
    except TrainingRecordError as exc:  # damaged or hand-edited: said in a line, before anything is copied
        parser.error(str(exc))
    if record is None and args.training_seconds is None:
        parser.error(f"{args.run} has no {TRAINING_RECORD}: give --training-seconds")

    folder = args.into / args.name
    folder.mkdir(parents=True, exist_ok=True)
    for name in ("model.zip", "config.yaml", TRAINING_RECORD):
        if (args.run / name).is_file():
            shutil.copyfile(args.run / name, folder / name)
    config = RunFolder.config_of_model(folder / "model.zip")

    started = time.perf_counter()
    if args.episodes_csv:
        rows = [dict(row, policy=args.name if row["policy"] == "agent" else row["policy"])
                for path in args.episodes_csv for row in read_csv(path)]
        rows = [row for row in rows if row["policy"] in (args.name, *args.baselines)]
        found = {policy: sum(r["policy"] == policy for r in rows) for policy in [args.name, *args.baselines]}
        if any(count != args.episodes for count in found.values()):
            parser.error(f"--episodes-csv: expected {args.episodes} episodes of each policy, found {found}")
        evaluated_on = args.evaluated_on
    else:
        rows = compare_model(folder / "model.zip", args.name, OWN_WORLD if args.world is None else args.world,
                             args.episodes, args.seed, args.baselines, workers=args.workers)
        minutes = (time.perf_counter() - started) / 60
        evaluated_on = f"{machine_description()} ({minutes:.0f} min)"
    means = policy_means(rows)
    tables = [markdown_table(rows, args.name, b, f"{args.name} - {b}") for b in args.baselines]

    command = (f"emmi-gym evaluate --pretrained {args.name} --episodes {args.episodes} --seed {args.seed}"
               f"{f' --world {args.world}' if args.world else ''} --baselines {' '.join(args.baselines)}")
    seconds = record["wall_seconds"] if record else args.training_seconds
    trained_on = record["machine"] if record else "the machine below"
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    reward = config.env_kwargs.get("reward", "emmi")
    privileged = (" It is a privileged reward: trained with the ground truth as teacher (in simulation only), the "
                  "agent acts on the filter's belief alone." if reward_named(reward).privileged else "")
    card = f"""# {args.name}

{config.algorithm} ({config.policy}) on `{config.env_id}` with the `{reward}` reward.{privileged}

- Budget: {saved_decisions(folder / 'model.zip')} decisions, seed {config.seed}, {config.n_envs} envs.
- Training time: {seconds / 60:.1f} min of wall time on {trained_on}.
- Load it: `model = emmi_gym.pretrained.load("{args.name}")`; play it: `{command}`.
{f"{chr(10)}{args.note}{chr(10)}" if args.note else ""}
## Configuration

```yaml
{yaml.safe_dump(config.as_yaml_dict(), sort_keys=False).strip()}
```

## Evaluation

{args.episodes} held-out episodes (seeds from {args.seed}{f', maps of {args.world}' if args.world else ''}), the
scripted baselines on the same episodes; measured on {time.strftime('%Y-%m-%d')} at commit {commit} on
{evaluated_on}. Reproduce: `{command}`.

Means over episodes:

```
{format_table(means)}
```

""" + "\n\n".join(tables) + "\n"
    (folder / "MODEL_CARD.md").write_text(card)
    print(card)
    print(f"wrote {folder}")


if __name__ == "__main__":
    main()
