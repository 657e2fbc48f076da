"""Which paths hairlut reads and writes: inputs are regular files, and an output is never one of its inputs.

Opening a FIFO for reading blocks until a writer comes, and reading a character device may never end, so every
reader (table and image assets, the parts of a virtual asset, groom files, scene, recipe and environment files)
calls :func:`regular_file` before it opens a path: a FIFO, a folder, a device or a socket is refused with one
error naming the path, before anything could wait on it.  The module sits beside :mod:`hairlut.errors`, below
every subpackage (geometry included), so that each reader can import it without reaching up the data flow.

A command that reads some files and writes another calls :func:`not_an_input` first: writing a result over one
of the files it was computed from would destroy the input without a word.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from . import errors

#: What a path that is not a regular file is, by its ``st_mode`` test.
_KINDS = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a FIFO"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def not_regular(mode: int) -> str | None:
    """None when ``mode`` (an ``st_mode``) is a regular file's, else what it is: 'not a regular file (a FIFO)' ..."""
    if stat.S_ISREG(mode):
        return None
    what = next((name for test, name in _KINDS if test(mode)), "not a file")
    return f"not a regular file ({what})"


def regular_file(path: str | os.PathLike, what: str = "a file", missing: str = "no such file") -> Path:
    """``path`` as a Path when it is a regular file (a symlink to one is followed); otherwise the
    :mod:`hairlut.errors` exception naming the path: AssetNotFoundError (``missing``) when nothing is there,
    FormatError 'not a regular file (a FIFO), so not ``what``' for anything else.  Call it before opening."""
    try:
        mode = os.stat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):
        raise errors.AssetNotFoundError(path, missing) from None
    except (OSError, ValueError) as exc:  # permission, a symlink loop, a name too long, a NUL byte
        raise errors.AssetError(path, f"cannot be read ({getattr(exc, 'strerror', None) or exc})") from None
    fault = not_regular(mode)
    if fault:
        raise errors.FormatError(path, f"{fault}, so not {what}")
    return Path(path)


def not_an_input(out: str | os.PathLike | None, inputs, field: str = "out") -> None:
    """Refuse (ValidationError naming ``field``) an output path that is one of ``inputs``: the same file
    (``os.path.samefile``: a hard link or symlink to it too) or the same resolved path."""
    if out is None:
        return
    for given in inputs:
        same = os.path.realpath(out) == os.path.realpath(given)
        if not same and os.path.exists(out) and os.path.exists(given):
            same = os.path.samefile(out, given)
        if same:
            raise errors.ValidationError(
                field,
                os.fspath(out),
                f"is the input {os.fspath(given)}; writing there would overwrite it: choose another output path",
            )
