"""Atomic file replacement: write beside the target, fsync, then ``os.replace``.

A process killed at any moment leaves either the previous complete file or no
file under the final name; at worst a stray ``.<name>.<pid>.<token>.tmp`` remains
beside it, which :func:`stale_temporaries` finds.

A full disk (``ENOSPC``, a quota's ``EDQUOT``, a file-size limit's ``EFBIG``) while
writing, syncing or moving becomes :class:`hairlut.errors.DiskFullError` naming the
final path; the temporary file is removed, so nothing partial is left under any name.
A refused write (permissions, a read-only file system) is an AssetError naming the final
path too; commands check their outputs with :func:`check_writable` before any work.
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

from . import errors

TMP_SUFFIX = ".tmp"
FULL_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG})
#: A folder that refuses the write (permissions, a read-only file system).
DENIED_ERRNOS = frozenset({errno.EACCES, errno.EPERM, errno.EROFS})


def _size(n: float) -> str:
    from .budget import describe

    return describe(n)


def disk_full(final, exc: OSError) -> errors.DiskFullError:
    """The DiskFullError for a write of ``final`` that failed with ``exc``."""
    return errors.DiskFullError(
        final,
        f"cannot write: {os.strerror(exc.errno)} (errno {errno.errorcode.get(exc.errno, exc.errno)}); "
        "nothing was left under this name",
    )


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
        raise errors.DiskFullError(
            final, f"needs {_size(nbytes)} but only {_size(free)} are free on its file system; nothing was written"
        )


def check_writable(path: str | os.PathLike, *, folder: bool = False) -> Path:
    """Refuse an output hairlut could not write, before any work is done: an AssetError naming ``path`` (the
    user's name, never a temporary one).  ``path`` is a file (``folder`` False: not an existing folder) or a
    folder (``folder``: not an existing file).  The folder that must take the file is the nearest one that exists
    (:func:`atomic_path` creates the rest): it must be a folder, on a writable file system, writable by this user.
    Nothing is left behind: a probe file, made and removed, finds what the permission bits do not show."""
    target = Path(path)
    if not folder and target.is_dir():
        raise errors.AssetError(target, "is a folder; give a file name")
    if folder and target.exists() and not target.is_dir():
        raise errors.AssetError(target, "is a file; give a folder")
    where = (target if folder else target.parent).absolute()
    while not where.exists() and where.parent != where:
        where = where.parent
    if not where.is_dir():
        raise errors.AssetError(target, f"cannot write: {where} is a file, not a folder")
    try:
        read_only = bool(os.statvfs(where).f_flag & os.ST_RDONLY)
    except (AttributeError, OSError):
        read_only = False
    if read_only:
        raise errors.AssetError(target, f"cannot write: {where} is on a read-only file system; nothing was written")
    if not os.access(where, os.W_OK | os.X_OK):
        raise errors.AssetError(
            target, f"cannot write: the folder {where} is not writable (permission denied); nothing was written"
        )
    try:  # what the bits do not show (ACLs, sysfs, root on some mounts): a probe file, made and removed
        fd, probe = tempfile.mkstemp(prefix=".hairlut-probe-", suffix=TMP_SUFFIX, dir=where)
    except OSError as exc:
        raise errors.AssetError(
            target, f"cannot write: the folder {where} refuses new files ({exc.strerror or exc}); nothing was written"
        ) from None
    os.close(fd)
    os.unlink(probe)
    return target


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
        if exc.errno in DENIED_ERRNOS:  # name the user's file, not the temporary one
            raise errors.AssetError(final, f"cannot write: {os.strerror(exc.errno)}; nothing was written") from None
        raise
    finally:
        with contextlib.suppress(OSError):  # never made (a refused folder), or moved into place
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
