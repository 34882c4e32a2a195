"""Text files users hand in, read bounded: capped in size before they are read, and UTF-8 (a UTF-16
file, a binary file or bytes that are not UTF-8 named as what they are, with the byte's offset)."""

from __future__ import annotations

from .errors import FieldError
from .user_paths import input_file


def read_text_file(path, what: str, max_bytes: int, error=FieldError) -> str:
    """The text of the file ``path`` (``what`` names it in messages: "world file"): ``error`` naming the file
    if it is larger than ``max_bytes``, UTF-16, binary (a NUL byte) or not UTF-8; FileNotFoundError if
    there is nothing there."""
    path = input_file(path, what, error)
    size = path.stat().st_size
    if size > max_bytes:
        raise error(str(path), "", f"a {what} of at most {max_bytes:,} bytes", f"{size:,} bytes")
    with open(path, "rb") as f:
        raw = f.read(max_bytes + 1)
    if len(raw) > max_bytes:  # grew since it was measured
        raise error(str(path), "", f"a {what} of at most {max_bytes:,} bytes")
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise error(str(path), "", "UTF-8 text (the file is UTF-16: save it as UTF-8)")
    nul = raw.find(b"\0")
    if nul >= 0:
        raise error(str(path), "", f"a text file (byte {nul} is NUL: a binary file?)")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(str(path), "", f"UTF-8 text (byte {exc.start} is not UTF-8)") from None
