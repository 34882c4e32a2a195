"""The A/B experiment over a grid of settings: where does the order of closing the loop and exploring decide
the map?

A sweep file (YAML, read with the bounded reader)::

    env_id: emmi_gym/LoopCorridor-v1      # optional; the env whose defaults the settings change
    seeds: 20                             # per setting (A and B each)
    first_seed: 0
    options:                              # env options of every setting (dotted names reach into dicts)
      world: loop_order
      slam.resample_threshold: 0.5
    grid:                                 # each setting is one value of every key (their product)
      particles: [5, 15]
      generator.new_area_length: [6, 14, 22]
    figure: [generator.new_area_length, particles]   # optional: the x axis and the lines of the figure

Keys are ``gym.make`` options (:class:`~emmi_gym.env.config.EnvConfig`), dotted into the nested ones
(``laser.max_range``, ``slam.resample_threshold``, ``generator.new_area_length``): a nested option
changes the env's registered value of it, field by field. ``particles``, ``max_decisions`` and
``odometry_scale`` (a factor on every alpha and the heading drift of the odometry's noise, after its
preset) are keys too. Every setting is checked before the first run.

Each setting's runs are appended to ``sweep_runs.csv`` as they finish, and the summary is rewritten
(``sweep_summary.csv``, ``sweep.md``, ``sweep_ate.png``), so that a partial sweep is readable; run
again into the same folder, a sweep skips the settings whose runs it finds there.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, fields
from pathlib import Path

import gymnasium as gym
import numpy as np

from ...inputs.env_ids import check_env_id
from ...inputs.errors import FieldError
from ...inputs.validation import Integer, Mapping, Maybe, OptionError, Text, Tuple, build, check_fields, option
from ...inputs.yaml_files import read_yaml_file
from ...world.presets import odometry_config
from ..evaluation.intervals import difference_interval, measure_interval
from .ab import ABSettings, run_ab
from .report import paired_differences, read_csv, summary_rows, write_csv

#: The per-setting measures: A - B paired, with their labels (the robot time of each arm is reported beside).
SWEEP_MEASURES = {
    "ate": "final ATE (m)",
    "loop_ate": "ATE of the loop (m)",
    "oracle_accuracy": "accuracy against the oracle map",
    "new_area_accuracy": "new-area accuracy",
    "wall_consistency": "wall consistency",
    "loop_closed": "loop closed within the capture radius",
    "closure_error": "pose error back at the start (m)",
    "loop_hypotheses": "hypotheses of the loop left then",
    "sim_steps": "robot time (simulator steps)",
}
#: Keys of a setting that are not env options.
RUN_KEYS = ("particles", "max_decisions", "odometry_scale")
#: Env options that hold a preset name or a dict of fields: a dotted key changes one field.
NESTED = ("laser", "odometry_noise", "slam", "generator")
MAX_SETTINGS = 1000
MAX_SEEDS = 100_000


class SweepFileError(FieldError):
    """A sweep file is malformed; names the file, the field, what was expected and what was found."""


@dataclass(frozen=True)
class SweepConfig:
    """A sweep file's fields (see the module's docstring)."""

    env_id: str = option("emmi_gym/LoopCorridor-v1", Text(), help="the env whose defaults the settings change")
    seeds: int = option(20, Integer(2, MAX_SEEDS), help="seeds per setting (intervals need two)")
    first_seed: int = option(0, Integer(0, 2**32 - 1), help="the first seed")
    particles: int = option(15, Integer(1, 1000), help="particles where no setting names them")
    max_decisions: int = option(40, Integer(1, 1_000_000), help="waypoint decisions per run at most")
    options: dict = option({}, Mapping(), help="env options of every setting")
    grid: dict = option({}, Mapping(), help="key: list of values; the settings are their product")
    figure: tuple | None = option(None, Maybe(Tuple(Text(), 2), "the first two grid keys"),
                                  help="grid keys of the figure's x axis and its lines")

    def __post_init__(self):
        check_fields(self)


@dataclass(frozen=True)
class Sweep:
    """A checked sweep: its settings (each a dict of key -> value, the grid's keys first) and what they run."""

    config: SweepConfig
    settings: list[dict]
    source: str

    @property
    def seeds(self) -> range:
        return range(self.config.first_seed, self.config.first_seed + self.config.seeds)

    @property
    def figure_keys(self) -> tuple[str, ...]:
        return tuple(self.config.figure or list(self.config.grid)[:2])


def setting_label(setting: dict, keys) -> str:
    """A setting as text, its grid keys only: ``particles=5, generator.new_area_length=14``."""
    return ", ".join(f"{k}={setting[k]}" for k in keys) or "base"


def _as_fields(value) -> dict:
    """A nested option (a preset name or a dict of fields) as a dict of fields."""
    if value is None:
        return {}
    return {"preset": value} if isinstance(value, str) else dict(value)


def env_options(env_id: str, setting: dict) -> tuple[dict, dict]:
    """(gym.make options, run options) of a setting: dotted keys merged into the env's registered nested
    options, ``odometry_scale`` applied to the odometry noise."""
    registered = gym.spec(env_id).kwargs
    options, run = {}, {}
    for key, value in setting.items():
        if key in RUN_KEYS:
            run[key] = value
            continue
        head, _, rest = key.partition(".")
        if not rest:
            options[head] = value
            continue
        if head not in NESTED:
            raise OptionError("sweep", key, f"a dotted key into one of the nested options {list(NESTED)}")
        merged = options.setdefault(head, _as_fields(registered.get(head)))
        merged[rest] = value
    scale = run.pop("odometry_scale", None)
    if scale is not None:
        noise = odometry_config(options.get("odometry_noise", registered.get("odometry_noise")), "odometry_noise",
                                source="sweep")
        options["odometry_noise"] = {f.name: getattr(noise, f.name) * scale for f in fields(noise)}
    return options, run


def ab_settings(env_id: str, setting: dict, particles: int = 15, max_decisions: int = 40) -> ABSettings:
    """The :class:`ABSettings` of one setting, checked by making its env (a bad option raises the env's
    ``OptionError`` naming it; no world is drawn before a reset)."""
    options, run = env_options(env_id, setting)
    settings = ABSettings(env_id=env_id, particles=int(run.get("particles", particles)),
                          max_decisions=int(run.get("max_decisions", max_decisions)), env_options=options)
    settings.experiment_env().close()
    return settings


def read_sweep(path) -> Sweep:
    """A sweep file, checked: its fields, its grid (lists of values) and every setting's options."""
    source = str(path)
    data = read_yaml_file(path, "sweep file", SweepFileError)
    config = build(SweepConfig, data, "", source=source, error=SweepFileError)
    check_env_id(config.env_id, source, "env_id", SweepFileError)
    for key, values in config.grid.items():
        if not isinstance(values, list) or not values:
            raise SweepFileError(source, f"grid.{key}", "a non-empty list of values", values)
    count = math.prod(len(v) for v in config.grid.values())
    if count > MAX_SETTINGS:
        raise SweepFileError(source, "grid", f"at most {MAX_SETTINGS} settings (the product of the lists)", count)
    for key in config.figure or ():
        if key not in config.grid:
            raise SweepFileError(source, "figure", f"grid keys (one of {list(config.grid)})", key)
    settings = [dict(config.options, **dict(zip(config.grid, values, strict=False)))
                for values in itertools.product(*config.grid.values())]
    for setting in settings:
        try:
            ab_settings(config.env_id, setting, config.particles, config.max_decisions)
        except FieldError as exc:
            label = setting_label(setting, config.grid)
            raise SweepFileError(source, f"grid ({label}): {exc.field}", exc.expected, exc.got) from None
    return Sweep(config, settings, source)


def setting_summary(rows: list[dict]) -> dict:
    """One setting's row of the summary: A - B of every measure (mean, 95% interval, n), each arm's mean
    robot time and the share of runs that reached both goals."""
    out = {}
    for column in SWEEP_MEASURES:
        diff = paired_differences(rows, column)
        mean, low, high, n = difference_interval(diff[np.isfinite(diff)], column)
        out.update({f"{column}_diff": mean, f"{column}_low": low, f"{column}_high": high, f"{column}_n": n})
    for arm in ("A", "B"):
        arm_rows = [r for r in rows if r["arm"] == arm]
        out[f"sim_steps_{arm}"] = measure_interval([r["sim_steps"] for r in arm_rows], "sim_steps")[0]
        out[f"ate_{arm}"] = measure_interval([r["ate"] for r in arm_rows], "ate")[0]
        out[f"completed_{arm}"] = measure_interval([r["completed"] for r in arm_rows], "completed")[0]
    return out


def _interval_text(row: dict, column: str, digits: int = 3) -> str:
    mean, low, high = row[f"{column}_diff"], row[f"{column}_low"], row[f"{column}_high"]
    if not np.isfinite(mean):
        return "n/a"
    mark = " *" if low > 0 or high < 0 else ""
    return f"{mean:+.{digits}f} [{low:+.{digits}f}, {high:+.{digits}f}]{mark}"


def markdown_table(summary: list[dict], keys, header: str) -> str:
    """The sweep's summary as a markdown table: A - B per setting (* where the interval excludes zero)."""
    columns = [c for c in SWEEP_MEASURES if c != "sim_steps"]
    lines = [header, "",
             "| setting | seeds | " + " | ".join(f"A - B {SWEEP_MEASURES[c]}" for c in columns)
             + " | robot time A / B (steps) |",
             "| --- | --- | " + " | ".join("---" for _ in columns) + " | --- |"]
    for row in summary:
        cells = [_interval_text(row, c, 0 if c == "sim_steps" else 3) for c in columns]
        ratio = row["sim_steps_A"] / row["sim_steps_B"] if row["sim_steps_B"] else math.nan
        lines.append(f"| {setting_label(row, keys)} | {row['ate_n']} | " + " | ".join(cells)
                     + f" | {row['sim_steps_A']:.0f} / {row['sim_steps_B']:.0f} ({ratio - 1:+.0%}) |")
    return "\n".join(lines) + "\n"


def plot_sweep(summary: list[dict], keys, path: Path) -> None:
    """A - B of the final ATE with its 95% interval over the first key (x axis), one line per value of the
    second."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x_key, line_key = (list(keys) + [None, None])[:2]
    xs = list(dict.fromkeys(str(r.get(x_key, "")) for r in summary))
    lines = list(dict.fromkeys(str(r.get(line_key, "")) for r in summary)) if line_key else [""]
    fig, ax = plt.subplots(figsize=(7, 4.2))
    width = 0.6 / max(1, len(lines))
    for k, value in enumerate(lines):
        rows = [r for r in summary if line_key is None or str(r.get(line_key)) == value]
        pos = np.array([xs.index(str(r.get(x_key, ""))) for r in rows]) + (k - (len(lines) - 1) / 2) * width
        mean = np.array([r["ate_diff"] for r in rows])
        err = np.array([[m - r["ate_low"], r["ate_high"] - m] for m, r in zip(mean, rows, strict=False)]).T
        ax.errorbar(pos, mean, yerr=err, fmt="o-", capsize=3, label=f"{line_key}={value}" if line_key else None)
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xticks(range(len(xs)), xs)
    ax.set_xlabel(x_key or "setting")
    ax.set_ylabel("A - B final ATE (m), 95% interval")
    ax.set_title("close the loop first (A) minus explore first (B): below 0, A maps better", fontsize=9)
    if line_key:
        ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_sweep_report(sweep: Sweep, rows: list[dict], out: Path, header: str) -> dict[str, Path]:
    """The summary CSV, markdown table and figure of the runs so far."""
    keys = list(sweep.config.grid)
    summary = []
    for index, setting in enumerate(sweep.settings):
        setting_rows = [r for r in rows if r["setting"] == index]
        if setting_rows:
            summary.append({"setting": index, **{k: setting[k] for k in keys}, **setting_summary(setting_rows)})
    files = {"runs": out / "sweep_runs.csv", "summary": out / "sweep_summary.csv", "table": out / "sweep.md",
             "figure": out / "sweep_ate.png"}
    write_csv(files["summary"], summary)
    files["table"].write_text(markdown_table(summary, keys, header))
    plot_sweep(summary, sweep.figure_keys, files["figure"])
    return files


def run_sweep(sweep: Sweep, out, *, workers: int | None = None, progress: bool = True, header: str = "") -> dict:
    """Run A and B for every setting and seed, writing as each setting finishes (see the module's docstring);
    settings whose runs ``out/sweep_runs.csv`` already holds are not run again."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    runs_file = out / "sweep_runs.csv"
    rows = read_csv(runs_file) if runs_file.exists() else []
    seeds = set(sweep.seeds)
    keys = list(sweep.config.grid)
    files = {}
    for index, setting in enumerate(sweep.settings):
        label = setting_label(setting, keys)
        done = [r for r in rows if r["setting"] == index and r["label"] == label and r["seed"] in seeds]
        if len(done) == 2 * len(seeds):
            continue
        rows = [r for r in rows if r["setting"] != index]
        settings = ab_settings(sweep.config.env_id, setting, sweep.config.particles, sweep.config.max_decisions)
        runs = run_ab(sweep.seeds, settings, workers=workers, progress=progress)
        rows += [dict(setting=index, label=label, **row) for row in summary_rows(runs)]
        write_csv(runs_file, rows)
        files = write_sweep_report(sweep, rows, out, header)
    return files or write_sweep_report(sweep, rows, out, header)
