"""JSON from files users hand in (a model's ``data`` member), parsed bounded: Python's ``json`` builds nested
values by recursion, so a few hundred kB of brackets would end in a ``RecursionError``; the nesting is
measured first, outside strings, in a pass of vectorised NumPy, and refused past :data:`MAX_JSON_DEPTH`."""

from __future__ import annotations

import json
import re

import numpy as np

from .errors import FieldError

#: The deepest nesting of arrays and objects parsed (Stable-Baselines3's ``data`` nests about six deep).
MAX_JSON_DEPTH = 100
_STRING = re.compile(rb'"[^"\\]*(?:\\.[^"\\]*)*"')


def json_depth(raw: bytes) -> int:
    """How deep the arrays and objects of the JSON text ``raw`` nest (brackets inside strings not counted)."""
    code = np.frombuffer(_STRING.sub(b'""', raw), np.uint8)
    opens = np.isin(code, np.frombuffer(b"[{", np.uint8)).view(np.int8)
    steps = opens - np.isin(code, np.frombuffer(b"]}", np.uint8)).view(np.int8)
    return int(np.cumsum(steps, dtype=np.int32).max(initial=0))


def parse_json(raw: bytes, source: str, what: str, error=FieldError):
    """The value of the UTF-8 JSON text ``raw`` (``what`` names it: "a 'data' member of JSON"): ``error`` naming
    ``source`` if it nests deeper than :data:`MAX_JSON_DEPTH`, is not UTF-8 or not JSON."""
    depth = json_depth(raw)
    if depth > MAX_JSON_DEPTH:
        raise error(source, "", f"{what}, nested at most {MAX_JSON_DEPTH} deep", f"{depth:,} deep")
    try:
        return json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise error(source, "", f"{what} in UTF-8 (byte {exc.start} is not UTF-8)") from None
    except ValueError as exc:  # json.JSONDecodeError
        raise error(source, "", f"{what} ({str(exc)[:120]})") from None
