"""Atomic file replacement: write beside the target, fsync, then ``os.replace``.

A process killed at any moment leaves either the previous complete file or no
file under the final name; at worst a stray ``.<name>.<pid>.<token>.tmp`` remains
beside it, which :func:`stale_temporaries` finds.

A full disk (``ENOSPC``, a quota's ``EDQUOT``, a file-size limit's ``EFBIG``) while
writing, syncing or moving becomes :class:`hairlut.errors.DiskFullError` naming the
final path; the temporary file is removed, so nothing partial is left under any name.
Writers whose C libraries do not survive a full disk (HDF5 can segfault) build the
file in memory and hand the bytes to :func:`write_bytes`, after :func:`ensure_space`.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import tempfile
from pathlib import Path

from .. import errors

TMP_SUFFIX = ".tmp"
FULL_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG})


def _size(n: float) -> str:
    from ..budget import describe

    return describe(n)


def disk_full(final, exc: OSError) -> errors.DiskFullError:
    """The DiskFullError for a write of ``final`` that failed with ``exc``."""
    return errors.DiskFullError(final, f"cannot write: {os.strerror(exc.errno)} (errno {errno.errorcode.get(exc.errno, exc.errno)}); "
                                       "nothing was left under this name")


def free_bytes(folder: str | os.PathLike) -> int | None:
    """Bytes an unprivileged writer may still use in ``folder``'s file system (None if unknown)."""
    try:
        st = os.statvfs(folder)
    except (AttributeError, OSError):
        return None
    return st.f_bavail * st.f_frsize


def ensure_space(final: str | os.PathLike, nbytes: int) -> None:
    """Refuse (DiskFullError) before writing ``nbytes`` beside ``final`` when they cannot fit."""
    final = Path(final)
    free = free_bytes(final.parent if final.parent.exists() else Path.cwd())
    if free is not None and nbytes > free:
        raise errors.DiskFullError(final, f"needs {_size(nbytes)} but only {_size(free)} are free on its file system; nothing was written")


def check_writable(path: str | os.PathLike) -> None:
    """Refuse (AssetError naming ``path``) before any work when files cannot be created in the folder ``path``, or,
    while it does not exist yet, in its nearest existing ancestor (where it would be made): a probe file is created
    and removed there, which also catches read-only mounts and ACLs that permission bits do not show."""
    folder = Path(path)
    if folder.exists() and not folder.is_dir():
        raise errors.AssetError(folder, "not a folder")
    probe_in = next((p for p in (folder, *folder.absolute().parents) if p.exists()), folder)
    try:
        fd, probe = tempfile.mkstemp(prefix=".hairlut-probe-", suffix=TMP_SUFFIX, dir=probe_in)
    except OSError as exc:
        where = "" if probe_in == folder else f" (in {probe_in}, where it would be made)"
        raise errors.AssetError(folder, f"cannot write here{where}: {exc.strerror or exc}") from None
    os.close(fd)
    os.unlink(probe)


def _fsync_path(path: Path) -> None:
    flags = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) if path.is_dir() else os.O_RDONLY
    fd = os.open(path, flags)
    try:
        os.fsync(fd)
    except OSError:  # some filesystems refuse fsync on directories
        pass
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path in the target's folder; on success move it into place.

    The caller writes the complete file to the yielded path (with any library).
    If the body raises, the temporary file is removed and the target is untouched.
    """
    final = Path(path)
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = final.with_name(f".{final.name}.{os.getpid()}.{secrets.token_hex(4)}{TMP_SUFFIX}")
    try:
        yield tmp
        _fsync_path(tmp)
        os.replace(tmp, final)
        _fsync_path(final.parent)
    except OSError as exc:
        if exc.errno in FULL_ERRNOS:
            raise disk_full(final, exc) from None
        raise
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def write_bytes(tmp: Path, data: bytes | memoryview) -> None:
    """Write ``data`` to ``tmp`` (a new file) and flush it to disk; OSErrors propagate."""
    with open(tmp, "xb") as fh:
        view = memoryview(data)
        for start in range(0, len(view), 1 << 24):
            fh.write(view[start : start + (1 << 24)])
        fh.flush()
        os.fsync(fh.fileno())


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (after checking that it fits)."""
    ensure_space(path, len(data))
    with atomic_path(path) as tmp:
        write_bytes(tmp, data)
    return Path(path)


def stale_temporaries(folder: str | os.PathLike) -> list[Path]:
    """Temporary files left in ``folder`` by writers that were killed."""
    return sorted(p for p in Path(folder).glob(f".*{TMP_SUFFIX}") if p.is_file())
