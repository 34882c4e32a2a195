"""Write docs/options.md, the reference of every option, from the configuration classes themselves.

    python docs/_scripts/gen_options_doc.py            # rewrite docs/options.md
    python docs/_scripts/gen_options_doc.py --check    # exit 1 if docs/options.md is out of date

Each field is declared with ``emmi_gym.inputs.validation.option(default, check, help)``: the
table shows its name, type, default, what the check accepts (the bounds) and the help line.
tests/project/test_docs.py fails when the file differs from what this script writes.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import MISSING, fields
from pathlib import Path

from emmi_gym.env.config import EnvConfig, GeneratorOptions, RewardOption
from emmi_gym.inputs import validation as v
from emmi_gym.slam.config import PRESETS as RBPF_PRESETS
from emmi_gym.slam.config import RBPFConfig
from emmi_gym.world import GeneratorConfig, LaserConfig, OdometryNoise
from emmi_gym.world.presets import LASER_PRESETS, ODOMETRY_PRESETS

OUT = Path(__file__).resolve().parents[2] / "docs" / "options.md"
COMMAND = "python docs/_scripts/gen_options_doc.py"

#: (class, heading anchor text, how the options are given)
SECTIONS = (
    (EnvConfig, "`gym.make(id, **options)`: every keyword of the environment."),
    (RBPFConfig, "`slam={...}`: the filter (`particles` and `resolution` are top-level options only)."),
    (LaserConfig, "`laser=\"preset\"` or `laser={\"preset\": ..., field: value}`: the simulated laser."),
    (OdometryNoise, "`odometry_noise=\"preset\"` or `{\"preset\": ..., field: value}`: the odometry's noise, "
                    "per 0.1 s control period."),
    (GeneratorConfig, "`generator={...}` with `world=None`: the world generated at every reset."),
)


def number(x) -> str:
    """An int as it is, a float in at most 6 significant digits that still reads as a float (2.0, 1e-06)."""
    if not isinstance(x, float) or not math.isfinite(x):
        return str(x)
    text = f"{x:.6g}"
    return text if any(c in text for c in ".e") else text + ".0"


def value_text(x, unit: str = "") -> str:
    """A default or preset value, compact: strings quoted, floats with %g, angles also in degrees."""
    if isinstance(x, str):
        return f'"{x}"'
    if isinstance(x, bool) or x is None:
        return repr(x)
    if isinstance(x, (tuple, list)):
        return "(" + ", ".join(value_text(i) for i in x) + ")"
    if isinstance(x, dict):
        return "{" + ", ".join(f'"{k}": {value_text(i)}' for k, i in x.items()) + "}"
    if isinstance(x, float) and unit in ("rad", "radians") and x:
        return f"{number(x)} ({math.degrees(x):.4g} deg)"
    return number(x)


def interval(check: v.Real) -> str:
    lo = "(-inf" if check.lo == -math.inf else ("(" if check.open_lo else "[") + number(check.lo)
    hi = "inf)" if check.hi == math.inf else number(check.hi) + (")" if check.open_hi else "]")
    return f"{lo}, {hi}" + (f" {check.unit}" if check.unit else "")


def accepted(check) -> str:
    """What a check accepts, in a few words (the type column says what kind; the error messages give the
    long form): an interval with its unit, the values to choose from."""
    if isinstance(check, RewardOption):  # the registry's names: docs/rewards.md lists them
        return '"all", or names or Rewards' if check.many else "a registered name or a Reward"
    if isinstance(check, v.Real):
        return interval(check)
    if isinstance(check, v.Integer):
        return f"[{check.lo}, {check.hi}]"
    if isinstance(check, (v.Boolean, v.Mapping)):
        return ""
    if isinstance(check, v.Choice):
        return ", ".join(value_text(x) for x in check.values)
    if isinstance(check, GeneratorOptions):
        return "dict, " + " or ".join(cls.__name__ for cls in check.classes())
    if isinstance(check, v.Options):
        presets = "preset (" + ", ".join(value_text(x) for x in check.presets) + "), " if check.presets else ""
        return f"{presets}dict or {check.cls.__name__}"
    if isinstance(check, v.Maybe):
        return accepted(check.inner) + " or None"
    if isinstance(check, v.Tuple):
        return f"{check.length} x " + accepted(check.inner)
    if isinstance(check, v.Text):
        return "non-empty string"
    return check.describe()


def default_of(f):
    return f.default if f.default is not MISSING else f.default_factory()


def cell(text: str) -> str:
    return text.replace("|", "\\|")


def field_table(cls) -> list[str]:
    rows = ["| option | type | default | bounds | meaning |", "| --- | --- | --- | --- | --- |"]
    for f in fields(cls):
        check = f.metadata.get("check")
        unit = getattr(check, "unit", "") or getattr(getattr(check, "inner", None), "unit", "")
        rows.append(f"| `{f.name}` | `{cell(str(f.type))}` | `{cell(value_text(default_of(f), unit))}` | "
                    f"{cell(accepted(check))} | {cell(f.metadata.get('help', ''))} |")
    return rows


def preset_table(presets: dict, cls) -> list[str]:
    units = {f.name: getattr(f.metadata.get("check"), "unit", "") for f in fields(cls)}
    rows = ["| preset | fields it sets |", "| --- | --- |"]
    for name, values in presets.items():
        text = ", ".join(f"`{k}={value_text(x, units.get(k, ''))}`" for k, x in values.items()) or "the defaults"
        rows.append(f"| `{value_text(name)}` | {text} |")
    return rows


def render() -> str:
    out = ["# Options", "",
           f"<!-- generated by `{COMMAND}` from the configuration classes: do not edit -->", "",
           "Every option is a typed, bounded field; a mistake, at the top level or in a nested dict, raises",
           "`OptionError` (a `ValueError`) naming the field. Distances are in metres, angles in radians.",
           "A nested option may also be given as its dataclass (`laser=LaserConfig(n_beams=90)`).", ""]
    for cls, how in SECTIONS:
        out += [f"## {cls.__name__}", "", how, ""] + field_table(cls) + [""]
        if cls is LaserConfig:
            out += ["Laser presets (`emmi_gym.world.presets.LASER_PRESETS`):", ""]
            out += preset_table(LASER_PRESETS, LaserConfig) + [""]
        if cls is OdometryNoise:
            out += ["Odometry presets (`emmi_gym.world.presets.ODOMETRY_PRESETS`):", ""]
            out += preset_table(ODOMETRY_PRESETS, OdometryNoise) + [""]
        if cls is RBPFConfig:
            out += ["Filter presets, for logs of other robots (`RBPFConfig.preset(name)`, "
                    "`emmi-gym replay --preset`):", ""]
            out += preset_table(RBPF_PRESETS, RBPFConfig) + [""]
    return "\n".join(out).rstrip() + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if the file is out of date, write nothing")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    text = render()
    if args.check:
        if not args.out.exists() or args.out.read_text() != text:
            print(f"{args.out} is out of date: run {COMMAND}", file=sys.stderr)
            return 1
        return 0
    args.out.write_text(text)
    print(f"wrote {args.out} ({len(text.encode())} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
