"""Learning curves of training runs: the held-out evaluations' ground truth against decisions trained
(``emmi-gym learning-curves``, :func:`plot`).

    emmi-gym learning-curves runs/plans_emmi_seed0=scratch runs/plans_emmi_bc_seed0=clone+RL \\
        --baselines-csv results/test50.csv --out docs/plans_learning_curves.png
    emmi-gym learning-curves runs/bench/runs/emmi_seed0=emmi runs/bench/runs/emmi_seed1=emmi \\
        runs/bench/runs/pose_entropy_seed0=pose_entropy runs/bench/runs/pose_entropy_seed1=pose_entropy --out c.png

Each run folder's ``eval_ground_truth.csv`` (written by ``emmi-gym train``; ``--scores
checkpoint_scores.csv``: the file of ``emmi-gym score-checkpoints``) gives one line per measure
(and, where every file has it, the share of episodes that closed the loop first);
runs given the same LABEL (the seeds of one configuration) are drawn as their mean over the
evaluations they all reached (:func:`common_evaluations`), at the mean of their decision counts (a
resumed run's may differ), the band spanning them; ``--baselines-csv`` (``episodes.csv`` of
``emmi-gym evaluate --out``, or ``benchmark_episodes.csv`` of ``emmi-gym benchmark``) draws each
scripted policy's mean there as a level line, for scale (its episodes are not the periodic
evaluation's). Every file is read and checked (:func:`emmi_gym.inputs.csv_files.read_csv_file`: the
columns drawn, numbers, at least one row, a finite value of each measure) and the figure's file
checked writable before anything is drawn, so that a blank figure is never written.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ...formats.atomic_files import write_atomically
from ...inputs.csv_files import CsvFileError, read_csv_file
from ...inputs.user_paths import output_file
from ..evaluation.loop_order import LOOP_ORDER_KEY
from ..policies import POLICY_NAMES
from .run_folders import RunFolder

MEASURES = {"oracle_accuracy": "accuracy against the oracle map", "ate": "ATE (m)",
            "sim_steps": "simulator steps", "coverage": "coverage"}
#: Drawn too where every file has a finite value of it (the loop worlds).
LOOP_ORDER = {LOOP_ORDER_KEY: "closed the loop first"}
BASELINES = POLICY_NAMES


def read_curve(path) -> dict[str, np.ndarray]:
    """``timesteps`` and each of :data:`MEASURES` of a run's evaluations file, as arrays: a :class:`CsvFileError`
    naming the file unless every row has a finite ``timesteps`` and each measure a finite value somewhere."""
    rows = read_csv_file(path, "learning curve (eval_ground_truth.csv or checkpoint_scores.csv)",
                         numeric=("timesteps", *MEASURES), optional_numeric=LOOP_ORDER)
    curve = {column: np.array([row[column] for row in rows]) for column in ("timesteps", *MEASURES, *LOOP_ORDER)
             if column in rows[0]}
    if not np.isfinite(curve["timesteps"]).all():
        raise CsvFileError(str(path), "timesteps", "a number of decisions on every row", "an empty or non-finite cell")
    if (curve["timesteps"] < 0).any():
        raise CsvFileError(str(path), "timesteps", "a number of decisions (0 or more) on every row",
                           float(curve["timesteps"].min()))
    _check_finite(path, curve)
    return curve


def read_baselines(path) -> dict[str, dict[str, float]]:
    """Each of the :data:`BASELINES` in an episodes file: its mean of each of :data:`MEASURES` over its episodes
    (``policy`` or, in the benchmark's, ``variant`` names it); a :class:`CsvFileError` naming the file
    unless it holds episodes of at least one of them, each measure finite in some."""
    rows = read_csv_file(path, "episodes file (episodes.csv or benchmark_episodes.csv)", numeric=tuple(MEASURES),
                         optional_numeric=LOOP_ORDER)
    column = "policy" if "policy" in rows[0] else "variant"
    if column not in rows[0]:
        raise CsvFileError(str(path), "", "an episodes file with a 'policy' (or 'variant') column naming each "
                           "episode's policy")
    means = {}
    for policy in BASELINES:
        mine = [row for row in rows if row[column] == policy]
        if mine:
            values = {measure: np.array([row[measure] for row in mine]) for measure in (*MEASURES, *LOOP_ORDER)
                      if measure in mine[0]}
            _check_finite(f"{path} ({policy})", values)
            means[policy] = {measure: float(np.nanmean(value)) if np.isfinite(value).any() else math.nan
                             for measure, value in values.items()}
    if not means:
        found = sorted({row[column] for row in rows})
        raise CsvFileError(str(path), column, f"episodes of at least one of {list(BASELINES)}", found)
    return means


def _check_finite(where, columns: dict[str, np.ndarray]) -> None:
    for measure in MEASURES:
        if not np.isfinite(columns[measure]).any():
            raise CsvFileError(str(where), measure, "a finite value in at least one row (a line to draw)",
                               "only empty or non-finite cells")


def common_evaluations(runs: list[dict]) -> list[list[int]]:
    """The evaluations that every curve of ``runs`` (the runs of one label) reached, matched by their decision
    counts: a row per evaluation, the index of its point in each curve, in order. Each point of the first
    curve is matched with the next unmatched point of every other curve within half the first curve's
    median interval (a run resumed between rollouts evaluates a little later: 1140 against 1000); a point
    that some curve lacks (an evaluation cut short, before the runs kept every evaluation) is left out,
    so that the mean is never taken over different evaluations."""
    reference = runs[0]["timesteps"]
    tolerance = float(np.median(np.diff(reference))) / 2 if len(reference) > 1 else math.inf
    following = [0] * len(runs)
    rows = []
    for index, decisions in enumerate(reference):
        row = [index]
        for curve, start in zip(runs[1:], following[1:], strict=True):
            later = np.flatnonzero(curve["timesteps"][start:] >= decisions - tolerance)
            if not len(later) or curve["timesteps"][start + later[0]] > decisions + tolerance:
                break
            row.append(start + int(later[0]))
        else:
            rows.append(row)
            following = [point + 1 for point in row]
    return rows


def figure_path(out) -> Path:
    """The file the figure goes to: ``out``, or ``out.png`` if it names no format (matplotlib would add it);
    a ``ValueError`` for a format matplotlib cannot write, and an
    :class:`~emmi_gym.inputs.user_paths.OutputFolderError` if the file cannot be written."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    out = Path(out)
    if not out.suffix:
        out = out.with_name(f"{out.name}.png")
    formats = FigureCanvasAgg.get_supported_filetypes()
    if out.suffix[1:].lower() not in formats:
        raise ValueError(f"--out {out}: expected a figure file named *.{' or *.'.join(sorted(formats))}")
    return output_file(out)


def draw(groups: dict[str, list[dict]], baselines: dict[str, dict[str, float]], out: Path) -> None:
    """The figure of the curves ``groups`` (label -> curves of :func:`read_curve`) and the ``baselines``' levels,
    written to ``out`` (renamed into place once whole)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curves = [curve for runs in groups.values() for curve in runs]
    measures = {**MEASURES, **{measure: label for measure, label in LOOP_ORDER.items()
                               if all(measure in curve and np.isfinite(curve[measure]).any() for curve in curves)}}
    fig, axes = plt.subplots(1, len(measures), figsize=(4 * len(measures), 3.4))
    for k, (label, runs) in enumerate(groups.items()):
        points = np.array(common_evaluations(runs), dtype=int).reshape(-1, len(runs))
        # runs resumed between rollouts score at their own counts (1140, 2140, ...): the mean run at the mean count
        steps = np.mean([curve["timesteps"][points[:, r]] for r, curve in enumerate(runs)], axis=0)
        for ax, measure in zip(axes, measures, strict=True):
            values = np.array([curve[measure][points[:, r]] for r, curve in enumerate(runs)])
            name = label if len(runs) == 1 else f"{label} ({len(runs)} runs)"
            ax.plot(steps, values.mean(axis=0), marker="o", ms=3, color=f"C{k}", label=name)
            if len(runs) > 1:
                ax.fill_between(steps, values.min(axis=0), values.max(axis=0), color=f"C{k}", alpha=0.15)
    for k, (policy, means) in enumerate(baselines.items()):
        for ax, measure in zip(axes, measures, strict=True):
            if math.isfinite(means.get(measure, math.nan)):
                ax.axhline(means[measure], color=f"C{len(groups) + k}", ls="--", lw=1, label=policy)
    for ax, measure in zip(axes, measures, strict=True):
        ax.set_xlabel("decisions trained")
        ax.set_title(f"held-out: {measures[measure]}", fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    write_atomically(out, lambda target: fig.savefig(target, dpi=100, format=out.suffix[1:].lower()))
    plt.close(fig)


def plot(runs, out, scores: str = "checkpoint_scores.csv", baselines_csv=None) -> Path:
    """Check the figure's file ``out`` and read every file (``runs``: run folders, each ``FOLDER`` or
    ``FOLDER=LABEL``, its curve in ``scores``; ``baselines_csv``: the scripted policies' episodes), then draw;
    the figure's path."""
    out = figure_path(out)
    groups: dict[str, list[dict]] = {}
    for run in runs:
        path, _, label = str(run).partition("=")
        folder = RunFolder(path)
        folder.check_exists()
        groups.setdefault(label or path, []).append(read_curve(folder.path / scores))
    baselines = {} if baselines_csv is None else read_baselines(baselines_csv)
    draw(groups, baselines, out)
    return out

