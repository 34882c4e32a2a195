"""What an A/B experiment wrote: per-run measures, intervals over seeds, CSVs, a markdown table and
the figures in the layout of the paper's Fig. 6 (c)-(e) maps and (f)-(h) metrics."""

from __future__ import annotations

import csv
import math
from functools import partial
from pathlib import Path

import numpy as np

from ...formats.atomic_files import write_atomically, write_csv, write_text_atomically
from ..evaluation.directions import better_side, count_better, digits
from ..evaluation.intervals import difference_interval, measure_interval
from .ab import POLICIES, ABRun

#: Measures plotted per RBPF update, as the paper's Fig. 6 (f), (g), (h).
FIGURE_MEASURES = (("emmi", "EMMI (bits/cell)"), ("pose_entropy", "pose entropy (nats)"),
                   ("joint_entropy", "joint entropy (nats)"))
#: Per-run columns of the summary, with their labels.
SUMMARY_COLUMNS = {
    "emmi_change": "EMMI change after the decision (bits/cell)",
    "pose_entropy_change": "pose entropy change (nats)",
    "joint_entropy_change": "joint entropy change (nats)",
    "resamplings": "resamplings after the decision",
    "map_accuracy": "final map accuracy",
    "oracle_accuracy": "final accuracy against the oracle map",
    "wall_consistency": "final wall consistency",
    "new_area_accuracy_on_arrival": "new-area map accuracy on arriving there",
    "new_area_accuracy": "new-area map accuracy at the end",
    "ate": "final ATE (m)",
    "loop_ate": "ATE of the loop before the decision, final best particle (m)",
    "closure_error": "pose error on getting back to the loop's start (m)",
    "loop_closed": "loop closed within the matcher's capture radius",
    "loop_hypotheses": "hypotheses of the loop left as the robot nears its start",
    "coverage": "final coverage",
    "completed": "reached both goals",
}


def horizons(runs: list[ABRun]) -> dict[int, int | None]:
    """Per seed, the number of updates A took from the decision to close the loop (its first goal).

    The paper compares the two actions step by step (Fig. 6 (f)-(h)); the changes of a
    seed's A and B runs are both read this many updates after the decision, where A's loop
    closes. None where A never got there.
    """
    return {run.seed: (None if run.first_goal is None else run.first_goal - run.decision)
            for run in runs if run.arm == "A"}


def run_measures(run: ABRun, horizon: int | None) -> dict:
    """One run's row of the summary: changes over ``horizon`` updates after the decision, final scores."""
    row = {"seed": run.seed, "arm": run.arm, "policy": run.policy, "decision_update": run.decision,
           "first_goal_update": run.first_goal, "second_goal_update": run.second_goal, "horizon": horizon}
    at_decision = run.rows[run.decision]
    if horizon is None:
        later = None
    else:
        later = run.rows[min(run.decision + horizon, len(run.rows) - 1)]
    for measure in ("emmi", "pose_entropy", "joint_entropy"):
        row[f"{measure}_change"] = math.nan if later is None else later[measure] - at_decision[measure]
    window = run.rows[run.decision + 1: run.decision + 1 + (horizon or 0)]
    row["resamplings"] = sum(bool(r["resampled"]) for r in window) if horizon is not None else math.nan
    row.update({k: run.final[k] for k in ("map_accuracy", "oracle_accuracy", "wall_consistency",
                                           "new_area_accuracy_on_arrival", "new_area_accuracy", "ate", "loop_ate",
                                           "closure_error", "loop_closed", "loop_hypotheses", "coverage", "sim_steps",
                                           "decisions", "collisions")})
    row["completed"] = float(run.final["completed"])
    return row


def summary_rows(runs: list[ABRun]) -> list[dict]:
    """:func:`run_measures` of every run, with each seed's horizon."""
    horizon = horizons(runs)
    return [run_measures(run, horizon.get(run.seed)) for run in runs]


def paired_differences(rows: list[dict], column: str) -> np.ndarray:
    """A minus B of ``column``, per seed that has both runs (NaN where either is missing)."""
    by_seed: dict[int, dict[str, float]] = {}
    for row in rows:
        by_seed.setdefault(row["seed"], {})[row["arm"]] = row[column]
    return np.array([d["A"] - d["B"] for _, d in sorted(by_seed.items()) if "A" in d and "B" in d], dtype=float)


def summary_table(rows: list[dict]) -> dict[str, dict[str, tuple]]:
    """Per column: the mean interval under A, under B, and of the paired difference A - B
    (with, for the difference, how the seeds fall on the better side: a
    :class:`~emmi_gym.tools.evaluation.directions.Tally`, ``None`` where the measure has no better side)."""
    table = {}
    for column in SUMMARY_COLUMNS:
        entry = {arm: measure_interval([r[column] for r in rows if r["arm"] == arm], column) for arm in POLICIES}
        diff = paired_differences(rows, column)
        finite = diff[np.isfinite(diff)]
        entry["A - B"] = difference_interval(finite, column) + (count_better(finite, column),)
        table[column] = entry
    return table


def emmi_headline(table: dict[str, dict[str, tuple]]) -> str:
    """The experiment's answer in one line (from :func:`summary_table`): the paired mean of A - B of the EMMI
    change after the decision (eq. 9 read over the same updates) and its 95% interval first, then the words
    that interval supports, then how the seeds fall (ties apart) and each arm's mean."""
    entry = table["emmi_change"]
    mean, low, high, n, tally = entry["A - B"]
    if n == 0:
        return "EMMI change after the decision: no seed has both runs with a value"
    verdict = ("higher under A (A closed the loop: more certain)" if low > 0 else "higher under B" if high < 0
               else "not told apart by these seeds (the interval holds 0)")
    return (f"EMMI change after the decision, A - B: {mean:+.3f} [{low:+.3f}, {high:+.3f}] bits/cell (95%, {n} "
            f"seeds): {verdict}; A higher on {tally.better}, B on {tally.worse}, tied on {tally.tied} "
            f"(A {entry['A'][0]:+.3f}, B {entry['B'][0]:+.3f})")


#: Rows measured where each arm first gets back to the loop's start, which the A/B page's options section
#: defines: the summary marks them and says where to read how.
EXPLAINED = ("closure_error", "loop_closed", "loop_hypotheses")


def _cell(interval: tuple, column: str, signed: bool) -> str:
    mean, low, high, n = interval[:4]
    if n == 0:
        return "n/a (n=0)"
    places = {"joint_entropy_change": 0, "pose_entropy_change": 1, "resamplings": 1}.get(column, digits(column))
    sign = "+" if signed else ""
    return f"{mean:{sign}.{places}f} [{low:{sign}.{places}f}, {high:{sign}.{places}f}] (n={n})"


def markdown_summary(rows: list[dict], settings_text: str) -> str:
    """The summary as a markdown table: mean and 95% interval per arm and of the paired difference, which
    side of each measure is better, and on how many seeds A did better."""
    table = summary_table(rows)
    seeds = sorted({r["seed"] for r in rows})
    lines = [f"A/B experiment: {settings_text}; {len(seeds)} seeds; mean [95% interval] over the n seeds with a "
             "value: Wilson's for the share that reached both goals, Student's t clipped to the measure's range "
             "for the others.",
             "A = close_loop_first (close the loop, then the new area); B = explore_first.",
             "Changes are read the same number of RBPF updates after the decision for A and B: "
             "the updates A needed to close the loop (the paper's Fig. 6 compares the two step by step).",
             "'better': which side of the measure is better; 'A better': on how many seeds A's value was on that "
             "side of B's, ties (equal values) counted apart ('-': the measure has no better side).",
             "", "| measure | better | A | B | A - B (paired) | A better |", "| --- | --- | --- | --- | --- | --- |"]
    for column, label in SUMMARY_COLUMNS.items():
        entry = table[column]
        change = column.endswith("_change")
        diff = entry["A - B"]
        count = "n/a" if not diff[3] else "-" if diff[4] is None else str(diff[4])
        shown = f"{label} (*)" if column in EXPLAINED else label
        lines.append(f"| {shown} | {better_side(column)} | {_cell(entry['A'], column, change)} | "
                     f"{_cell(entry['B'], column, change)} | {_cell(diff, column, True)} | {count} |")
    lines += ["", "(*) measured when each arm first gets back to the loop's start, A straight after the decision and B "
              "after the new area, so they compare the two closures, not the final maps (the final ATE and "
              "accuracies do): docs/ab.md, 'Options'."]
    failed = [f"seed {r['seed']} {r['arm']} ({'no goal' if r['first_goal_update'] is None else 'first goal only'})"
              for r in rows if not r["completed"]]
    if failed:
        lines += ["", f"Did not reach both goals within the decision budget ({len(failed)} of {len(rows)} runs; their "
                  f"changes and scores are in the table, as far as they got): {', '.join(failed)}."]
    return "\n".join(lines) + "\n"


def read_csv(path) -> list[dict]:
    """The rows :func:`write_csv` wrote, numbers as floats (``seed`` and ``decisions`` as ints), text as text,
    an empty cell as NaN."""
    def value(text: str):
        if text == "":
            return np.nan
        try:
            return float(text)
        except ValueError:
            return text

    with open(path, newline="") as f:
        rows = [{key: value(text) for key, text in row.items()} for row in csv.DictReader(f)]
    for row in rows:
        for key in ("seed", "decisions"):
            if isinstance(row.get(key), float) and np.isfinite(row[key]):
                row[key] = int(row[key])
    return rows


def update_rows(runs: list[ABRun]) -> list[dict]:
    """Every RBPF update of every run, with its seed, arm and index."""
    return [dict(seed=run.seed, arm=run.arm, update=i, **row) for run in runs for i, row in enumerate(run.rows)]


def _aligned(runs: list[ABRun], measure: str, decision: int) -> np.ndarray:
    """(runs, T) of ``measure`` with each run shifted so that its decision falls on ``decision``; NaN-padded."""
    shifted = [np.array([r[measure] for r in run.rows], dtype=float)[max(run.decision - decision, 0):]
               for run in runs]
    pads = [max(decision - run.decision, 0) for run in runs]
    length = max(p + s.size for p, s in zip(pads, shifted, strict=False))
    out = np.full((len(runs), length), np.nan)
    for k, (pad, series) in enumerate(zip(pads, shifted, strict=False)):
        out[k, pad:pad + series.size] = series
    return out


def plot_metrics(runs: list[ABRun], path: Path) -> None:
    """The paper's Fig. 6 (f)-(h): EMMI, pose entropy and joint entropy per RBPF update, A solid and B
    dashed, mean over seeds with a band of one standard deviation, the decision point (and the
    median update at which A closed the loop) marked; drawn while two thirds of the runs last."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    decision = int(round(np.mean([run.decision for run in runs])))
    closures = [h for h in horizons(runs).values() if h is not None]
    fig, axes = plt.subplots(len(FIGURE_MEASURES), 1, figsize=(8, 8.5), sharex=True)
    for ax, (measure, label) in zip(axes, FIGURE_MEASURES, strict=False):
        for arm, style, colour in (("A", "-", "tab:blue"), ("B", "--", "tab:red")):
            values = _aligned([run for run in runs if run.arm == arm], measure, decision)
            present = np.isfinite(values)
            steps = np.flatnonzero(present.sum(axis=0) * 3 >= 2 * values.shape[0])  # two thirds of the seeds
            values = values[:, steps]
            mean = np.nanmean(values, axis=0)
            spread = np.nanstd(values, axis=0)
            ax.plot(steps, mean, style, color=colour, lw=1.6,
                    label=f"{arm}: {POLICIES[arm]} ({values.shape[0]} runs; drawn while 2/3 of them last)")
            ax.fill_between(steps, mean - spread, mean + spread, color=colour, alpha=0.2, lw=0)
        ax.axvline(decision, color="k", lw=0.8, ls=":")
        if closures:
            ax.axvline(decision + float(np.median(closures)), color="tab:blue", lw=0.8, ls=":")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].annotate("decision", (decision, 1.0), xycoords=("data", "axes fraction"), xytext=(3, -12),
                     textcoords="offset points", fontsize=8)
    if closures:
        axes[0].annotate("A: loop closed", (decision + float(np.median(closures)), 1.0),
                         xycoords=("data", "axes fraction"), xytext=(3, -12), textcoords="offset points",
                         fontsize=8, color="tab:blue")
    axes[0].legend(loc="lower left", fontsize=8)
    axes[-1].set_xlabel("RBPF update (step)")
    n_seeds = len({run.seed for run in runs})
    fig.suptitle(f"A (close the loop first) vs B (explore first): mean ± 1 s.d. over {n_seeds} seeds",
                 fontsize=10)
    fig.tight_layout()
    write_atomically(path, partial(fig.savefig, dpi=110))
    plt.close(fig)


def plot_maps(runs: list[ABRun], seed: int, path: Path) -> None:
    """The paper's Fig. 6 (c)-(e) for one seed: the expected map at the decision point, after A closed
    the loop and after B entered the new area, with the best particle's path (orange) over the true
    walls (cyan)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    by_arm = {run.arm: run for run in runs if run.seed == seed}
    panels = [("(c) decision point", by_arm["A"], "decision"),
              ("(d) after A: loop closed", by_arm["A"], "first_goal"),
              ("(e) after B: new area entered", by_arm["B"], "first_goal")]
    panels = [(title, run, event) for title, run, event in panels if event in run.maps]
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 3.4))
    for ax, (title, run, event) in zip(np.atleast_1d(axes), panels, strict=False):
        ax.imshow(run.maps[event], cmap="gray_r", vmin=0, vmax=1, origin="lower", extent=run.extent,
                  interpolation="nearest")
        for ax_, ay, bx, by, _ in run.walls:
            ax.plot([ax_, bx], [ay, by], color="tab:cyan", lw=0.5, alpha=0.7)
        path_xy = run.paths[event]
        ax.plot(path_xy[:, 0], path_xy[:, 1], color="tab:orange", lw=0.9)
        measures = run.at(event)
        ax.set_title(f"{title}\nseed {run.seed}, update {getattr(run, event)}: EMMI {measures['emmi']:.3f} bits/cell",
                     fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    from matplotlib.lines import Line2D

    fig.legend([Line2D([], [], color="tab:cyan", lw=1.5), Line2D([], [], color="tab:orange", lw=1.5)],
               ["true walls", "best particle's path"], loc="lower center", ncol=2, fontsize=8, frameon=False,
               title="expected map: white free, black occupied, grey unknown", title_fontsize=8)
    fig.tight_layout(rect=(0, 0.1, 1, 1))
    # the panels keep the world's aspect, which tight_layout does not leave room above for: the titles
    # would be cut, so the saved area is what is drawn
    write_atomically(path, partial(fig.savefig, dpi=110, bbox_inches="tight"))
    plt.close(fig)


def write_report(runs: list[ABRun], out_dir, settings_text: str, map_seed: int | None = None) -> dict[str, Path]:
    """Write the CSVs, the markdown summary and both figures into ``out_dir``; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = summary_rows(runs)
    files = {"updates": out / "ab_updates.csv", "runs": out / "ab_runs.csv", "summary": out / "ab_summary.md",
             "metrics_figure": out / "ab_fig6_metrics.png", "maps_figure": out / "ab_fig6_maps.png"}
    write_csv(files["updates"], update_rows(runs))
    write_csv(files["runs"], rows)
    write_text_atomically(files["summary"], markdown_summary(rows, settings_text))
    plot_metrics(runs, files["metrics_figure"])
    plot_maps(runs, runs[0].seed if map_seed is None else map_seed, files["maps_figure"])
    return files
