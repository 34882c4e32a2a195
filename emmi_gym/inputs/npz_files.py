"""Reading ``.npz`` archives of arrays (numpy's ``savez``) bounded: what each array declares is read first,
then the data streamed into arrays the caller allocated.

``np.load`` trusts an array's header: a few bytes declaring 10^12 rows ask for terabytes before a byte of
data is read, and an archive's members are only known to be damaged once they are read whole. Here
:func:`npz_arrays` reads each member's header alone (``numpy.lib.format``, the few hundred bytes at
the start of the member), refuses Python objects, Fortran order and foreign byte order, and checks
the bytes the header declares against the size the zip directory records for the member, so a caller
can check shapes, types and the total before anything is allocated; :func:`read_array_into` then
streams a member's data into (a slice of) an array, a MB at a time, and checks its CRC-32.
"""

from __future__ import annotations

import math
import tokenize
import zipfile
import zlib
from dataclasses import dataclass

import numpy as np

from .errors import FieldError
from .user_paths import input_file, with_article

#: The most arrays an archive may hold.
MAX_NPZ_MEMBERS = 256
#: The longest array header read (numpy's own limit for headers it trusts).
MAX_HEADER_BYTES = 10_000
_CHUNK_BYTES = 2**20


@dataclass(frozen=True)
class NpzArray:
    """What one member of an ``.npz`` declares: its array's ``name``, ``shape`` and ``dtype``."""

    name: str
    shape: tuple[int, ...]
    dtype: np.dtype

    @property
    def nbytes(self) -> int:
        return math.prod(self.shape) * self.dtype.itemsize


def npz_arrays(path, what: str, max_bytes: int, error=FieldError) -> dict[str, NpzArray]:
    """The arrays of the ``.npz`` file ``path`` by name, as their headers declare them, without reading their
    data: ``error`` naming the file (and the member) unless it is a zip of at most :data:`MAX_NPZ_MEMBERS`
    ``.npy`` members of numbers or booleans in C order and this machine's byte order, each as large as
    its header says, ``max_bytes`` in all. ``what`` names the file in messages ("demonstrations file")."""
    path = input_file(path, what, error)
    source = str(path)
    arrays = {}
    with _archive(path, what, error) as archive:
        members = archive.infolist()
        if len(members) > MAX_NPZ_MEMBERS:
            raise error(source, "", f"{with_article(what)} of at most {MAX_NPZ_MEMBERS} arrays",
                        f"{len(members)} members")
        total = sum(member.file_size for member in members)
        if total > max_bytes:
            raise error(source, "", f"{with_article(what)} of at most {max_bytes / 2**30:g} GiB unpacked",
                        f"members that unpack to {total / 2**30:,.1f} GiB")
        for member in members:
            if not member.filename.endswith(".npy"):
                raise error(source, member.filename, "an array (.npy) member, as numpy's savez writes")
            name = member.filename[:-4]
            with _reading(source, name, error):
                with archive.open(member) as stream:
                    array = _header(stream, name, source, error)
                    header_bytes = stream.tell()
            if header_bytes + array.nbytes != member.file_size:
                raise error(source, name, f"an array of the {header_bytes + array.nbytes:,} bytes its header "
                            f"declares (shape {array.shape}, {array.dtype})",
                            f"a member of {member.file_size:,} bytes")
            arrays[name] = array
    return arrays


def read_array_into(path, array: NpzArray, out: np.ndarray, error=FieldError) -> np.ndarray:
    """Stream the data of ``array`` (one of :func:`npz_arrays`'s) in the ``.npz`` file ``path`` into ``out``, a
    C-contiguous array (or slice of rows of one) of its shape and dtype; ``error`` naming the file and
    member if the data is cut short or damaged (its CRC-32 does not match)."""
    if out.shape != array.shape or out.dtype != array.dtype or not out.flags.c_contiguous:
        raise ValueError(f"read_array_into: {out.shape} {out.dtype} array for {array}")
    source = str(path)
    target = out.reshape(-1).view(np.uint8)
    with _archive(path, "array file", error) as archive, _reading(source, array.name, error):
        with archive.open(f"{array.name}.npy") as stream:
            _header(stream, array.name, source, error)
            filled = 0
            while filled < target.size:
                chunk = stream.read(min(_CHUNK_BYTES, target.size - filled))
                if not chunk:
                    raise error(source, array.name, f"{array.nbytes:,} bytes of data", f"{filled:,} bytes")
                target[filled:filled + len(chunk)] = np.frombuffer(chunk, np.uint8)
                filled += len(chunk)
            if stream.read(1):  # the end of the member, where zipfile checks its CRC-32
                raise error(source, array.name, f"{array.nbytes:,} bytes of data", "more")
    return out


def _archive(path, what: str, error):
    try:
        return zipfile.ZipFile(path)
    except zipfile.BadZipFile:
        raise error(str(path), "", f"{with_article(what)}: an .npz archive as numpy's savez writes (this is not a zip "
                    "file)") from None
    except (OSError, EOFError, zipfile.LargeZipFile, ValueError) as exc:
        raise error(str(path), "", f"{with_article(what)}: a zip file that can be read ({exc})") from None


class _reading:
    """A context that turns what zipfile, zlib and numpy raise on a damaged member into ``error``."""

    def __init__(self, source: str, name: str, error):
        self.source, self.name, self.error = source, name, error

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, traceback):
        if kind is None or issubclass(kind, FieldError):
            return False
        if issubclass(kind, zipfile.BadZipFile) and "CRC" in str(exc):
            raise self.error(self.source, self.name, "an undamaged member (its CRC-32 does not match its data: "
                             "the file is damaged)") from None
        if issubclass(kind, (zipfile.BadZipFile, zlib.error, EOFError, OSError, NotImplementedError)):
            raise self.error(self.source, self.name, f"a member that can be unpacked ({type(exc).__name__}: "
                             f"{str(exc)[:120]})") from None
        return False


def _header(stream, name: str, source: str, error) -> NpzArray:
    """The array header at the start of a member's ``stream`` (numpy.lib.format), checked."""
    try:
        version = np.lib.format.read_magic(stream)
        read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        if version not in ((1, 0), (2, 0)):
            raise ValueError(f"format version {version}")
        shape, fortran_order, dtype = read(stream, max_header_size=MAX_HEADER_BYTES)
    except (ValueError, SyntaxError, TypeError, OverflowError, MemoryError, tokenize.TokenError) as exc:
        raise error(source, name, f"an array header as numpy writes it ({str(exc).splitlines()[0][:120]})") from None
    if dtype.hasobject or dtype.kind not in "biuf" or dtype.fields is not None:
        raise error(source, name, "an array of numbers or booleans", f"dtype {dtype}")
    if fortran_order:
        raise error(source, name, "an array in C order, as numpy's savez writes it", "Fortran order")
    if not dtype.isnative:
        raise error(source, name, "an array in this machine's byte order", f"dtype {dtype.str}")
    return NpzArray(name, tuple(int(n) for n in shape), dtype)

