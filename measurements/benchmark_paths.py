"""Where the agents of a reward benchmark go, beside the scripted policies: one held-out episode of each
reward's agent and of each scripted policy on the same world and seed, their paths on their final maps
(one panel each, after the oracle map), and what each did in that episode.

    python measurements/benchmark_paths.py BENCHMARK_DIR [--seed S] \\
        [--agent-seed 0] [--baselines close_loop_first explore_first frontier] [--out paths.png]

``BENCHMARK_DIR`` is the ``--out`` of ``emmi-gym benchmark``: the agent of each reward is
``runs/<reward>_seed<agent-seed>/model.zip``; the episode is seeded ``S`` (default: the benchmark's
first held-out episode, from its ``benchmark_episodes.csv``). It serves any benchmark whose env plays
the scripted policies (``LoopCorridor-v1``, ``LoopOrder-v1``). Every policy plays the env of the emmi agent's held-out
evaluation (the reward changes what an agent learns, not what an episode shows it), so the episodes
share the world, the start and the random draws up to the first decision
(:func:`emmi_gym.tools.evaluation.comparison.play_on_world`). The panels mark the revisit targets each
chose (where it went back); the printed table gives, per policy, whether it closed the loop first,
its decisions, revisit targets, robot time, ATE and accuracy against the oracle map.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import _arguments as arguments

from emmi_gym.tools.evaluation.comparison import format_table, play_on_world, plot_pair
from emmi_gym.tools.evaluation.loop_order import LOOP_ORDER_KEY
from emmi_gym.tools.experiments.report import read_csv
from emmi_gym.tools.training.evaluate import TrainedAgent, comparison_settings
from emmi_gym.tools.training.run_folders import RunFolder


def agents_of(benchmark: Path, agent_seed: int) -> dict[str, Path]:
    """Each reward's model of training seed ``agent_seed`` in the benchmark folder, by reward."""
    models = {path.parent.name.removesuffix(f"_seed{agent_seed}"): path
              for path in sorted((benchmark / "runs").glob(f"*_seed{agent_seed}/model.zip"))}
    if not models:
        raise SystemExit(f"{benchmark / 'runs'}: no <reward>_seed{agent_seed}/model.zip (a finished benchmark's "
                         f"--out is expected)")
    return models


def first_held_out_seed(benchmark: Path) -> int:
    """The seed of the first episode the benchmark's agents and scripted policies were evaluated on."""
    episodes = benchmark / "benchmark_episodes.csv"
    if not episodes.is_file():
        raise SystemExit(f"{episodes}: not found (a finished benchmark's --out is expected); or give --seed")
    return min(int(row["episode_seed"]) for row in read_csv(episodes))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("benchmark", type=Path, help="the --out folder of 'emmi-gym benchmark'")
    parser.add_argument("--seed", type=arguments.SEED, default=None,
                        help="the episode's seed (default: the benchmark's first held-out episode)")
    parser.add_argument("--agent-seed", type=arguments.SEED, default=0, help="which training seed's agents")
    parser.add_argument("--baselines", nargs="*", default=["close_loop_first", "explore_first", "frontier"],
                        help="scripted policies and shipped agents played beside the agents")
    parser.add_argument("--out", type=Path, default=Path("benchmark_paths.png"))
    args = parser.parse_args()
    try:
        baselines = arguments.baseline_policies(args.baselines)
    except ValueError as error:
        parser.error(str(error))
    models = agents_of(args.benchmark, args.agent_seed)
    seed = first_held_out_seed(args.benchmark) if args.seed is None else args.seed
    reference = models.get("emmi", next(iter(models.values())))
    settings, world = comparison_settings(RunFolder.config_of_model(reference))
    policies = [TrainedAgent(str(path), f"{reward} agent") for reward, path in models.items()] + baselines
    rows = [play_on_world(world, seed, policy, settings, keep_maps=True, keep_steps=True) for policy in policies]
    for row in rows:
        row["revisit_targets"] = sum(step["target_kind"] == "revisit" for step in row["steps"])
    print(format_table(rows, ["policy", LOOP_ORDER_KEY, "decisions", "revisit_targets", "sim_steps", "ate",
                              "oracle_accuracy"]))
    plot_pair(rows, args.out, columns=4)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
