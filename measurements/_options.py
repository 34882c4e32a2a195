"""Shared helper of the scripts that take options as JSON (``--slam '{"insertion_range": 8}'``) or as a
preset name: parse and check them once, before any work, and stop with the option's name and what was
wrong (not a traceback, nor an error from a worker process half-way through a run)."""

from __future__ import annotations

import argparse
import json

from emmi_gym.inputs.errors import excerpt
from emmi_gym.inputs.validation import OptionError, build
from emmi_gym.slam import RBPFConfig
from emmi_gym.slam.config import PRESETS


def json_object(parser: argparse.ArgumentParser, option: str, text: str) -> dict:
    """The JSON object ``text`` given to ``option``, or ``parser.error`` saying what it is instead."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        parser.error(f"{option}: not JSON ({exc.msg} at character {exc.pos}) in {excerpt(text)}")
    if not isinstance(value, dict):
        parser.error(f"{option}: expected a JSON object of fields ({{\"name\": value, ...}}), got {excerpt(text)}")
    return value


def preset_or_fields(parser: argparse.ArgumentParser, option: str, text: str) -> str | dict:
    """A preset name as it is; JSON fields (``{...}``, with an optional ``"preset"``) parsed."""
    return json_object(parser, option, text) if text.lstrip().startswith("{") else text


def checked(parser: argparse.ArgumentParser, make, *args, **kwargs):
    """``make(*args, **kwargs)``, its :class:`OptionError` (which names the option and the field) turned
    into ``parser.error``."""
    try:
        return make(*args, **kwargs)
    except OptionError as exc:
        parser.error(str(exc))


def rbpf_config(parser: argparse.ArgumentParser, slam_json: str, preset: str | None = None, **fields) -> RBPFConfig:
    """The filter's configuration: ``preset``'s fields (None: the defaults), then ``fields``, then the
    ``--slam`` JSON's; an unknown name or a bad value is ``parser.error`` naming the field."""
    if preset is not None and preset not in PRESETS:
        parser.error(f"--preset: expected one of {sorted(PRESETS)} or 'none', got {excerpt(preset)}")
    options = {**PRESETS.get(preset, {}), **fields, **json_object(parser, "--slam", slam_json)}
    return checked(parser, build, RBPFConfig, options, "", source="--slam")
