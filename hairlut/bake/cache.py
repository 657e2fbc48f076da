"""A content-addressed table cache: one asset per recipe hash.

Assets live in ``$HAIRLUT_CACHE`` (default ``tables/``) as
``<kind>-<first 16 hex of recipe_hash>.h5``.  :func:`ensure` returns the cached
asset when one with the same kind and full recipe hash validates, and bakes it
otherwise.  Concurrent callers with the same recipe serialise on an advisory
lock (``fcntl.flock``) beside the asset: one bakes, the others wait and reuse
its file.  Writes are atomic, so no reader ever sees a half-written asset.

The cache knows no kind: it validates files against whatever kind their declaration
(see :mod:`hairlut.bake.registry`) says they hold.  :func:`hairlut.bake.registry.ensure` is the
cached bake of a registered kind.
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from .. import errors
from ..assets import open_table, recipe_hash, stale_temporaries
from ..assets.kinds import KINDS, known_kinds

ENV = "HAIRLUT_CACHE"
STALE_SECONDS = 3600


def cache_dir(root: str | os.PathLike | None = None) -> Path:
    """The cache folder: ``root``, else ``$HAIRLUT_CACHE``, else ``./tables``."""
    return Path(root if root is not None else os.environ.get(ENV, "tables"))


def asset_path(kind: str, recipe: dict, root=None) -> Path:
    return cache_dir(root) / f"{kind}-{recipe_hash(recipe)[:16]}.h5"


@dataclass(frozen=True)
class Entry:
    """One file of the cache folder named like an asset.  ``status``: ``ok``; ``foreign``, a valid asset under
    another asset's name (its own, from its kind and recipe hash, is in ``fault``): :func:`ensure` never reuses it
    under that name; ``corrupt``, a file that fails validation (``fault`` says why; kind and recipe hash empty)."""

    path: Path
    kind: str
    recipe_hash: str
    created: str
    bytes: int
    status: str = "ok"
    fault: str = ""

    @property
    def usable(self) -> bool:
        return self.status != "corrupt"


def _validated(path: Path, kind: str | None = None) -> dict:
    """The root attributes (text) of asset ``path`` once it validates as a table (``kind`` when given), a virtual
    one with every part it reads through to; else the :class:`~hairlut.errors.AssetError` naming the fault."""
    from ..assets.virtual_write import check_virtual

    with open_table(path, kind) as f:
        attrs = {
            k: (v.decode() if isinstance(v, bytes) else str(v))
            for k, v in f.attrs.items()
            if k in ("kind", "recipe_hash", "created")
        }
    check_virtual(path)
    return attrs


def check(path: Path, kind: str, digest: str) -> None:
    """Raise the :class:`~hairlut.errors.AssetError` that says why ``path`` is not a valid ``kind`` asset with
    recipe hash ``digest`` (the one validity rule of cached and split-bake outputs); return when it is one."""
    stored = _validated(path, kind)["recipe_hash"]
    if stored != digest:
        raise errors.CorruptAssetError(path, f"holds another recipe (hash {stored[:16]}, not {digest[:16]})")


def is_valid(path: Path, kind: str, digest: str) -> bool:
    """Whether ``path`` is a valid ``kind`` asset with recipe hash ``digest`` (:func:`check`)."""
    try:
        check(path, kind, digest)
    except (errors.AssetError, OSError):
        return False
    return True


@contextlib.contextmanager
def _locked(path: Path):
    """Hold ``<asset>.lock`` (:func:`hairlut.assets.parts.lock_file`: flock, no symlink followed, removed on release)."""
    from ..assets.parts import lock_file

    with lock_file(path.with_name(path.name + ".lock"), "cache"):
        yield


def ensure(kind: str, recipe: dict, bake: Callable[[Path], object], root=None) -> tuple[Path, str]:
    """The cached asset for (kind, recipe), baking it with ``bake(path)`` if needed.

    Returns (path, status) with status ``"reused"`` or ``"baked"``.  ``bake`` must
    write the complete asset to ``path`` (atomically, as hairlut writers do).
    """
    path = asset_path(kind, recipe, root)
    digest = recipe_hash(recipe)
    if is_valid(path, kind, digest):
        return path, "reused"
    with _locked(path):
        if is_valid(path, kind, digest):  # another process baked it while we waited
            return path, "reused"
        bake(path)
        if not is_valid(path, kind, digest):
            raise errors.CorruptAssetError(path, f"the bake did not produce a valid {kind} with recipe hash {digest[:16]}")
        return path, "baked"


def recipe_of(path) -> dict:
    """The recipe stored in a cached asset."""
    with open_table(path) as f:
        r = f.attrs["recipe"]
        return json.loads(r.decode() if isinstance(r, bytes) else r)


def entries(root=None) -> list[Entry]:
    """Every file of the cache folder named like an asset (``*-*.h5``), newest first, each with its status
    (:class:`Entry`): valid assets under their own names, valid ones under another's name (``foreign``), and files
    that fail validation (``corrupt``, last).  Callers that use the assets take the ``usable`` ones."""
    out = []
    for path in sorted(cache_dir(root).glob("*-*.h5")):
        size = path.lstat().st_size
        try:
            attrs = _validated(path)
        except errors.AssetError as exc:
            out.append(Entry(path, "", "", "", size, "corrupt", exc.fault))
            continue
        kind, digest = attrs["kind"], attrs["recipe_hash"]
        own = f"{kind}-{digest[:16]}.h5"
        out.append(
            Entry(
                path,
                kind,
                digest,
                attrs.get("created", ""),
                size,
                *(("ok", "") if path.name == own else ("foreign", f"its kind and recipe hash name it {own}")),
            )
        )
    return sorted(out, key=lambda e: (e.usable, e.created), reverse=True)


def prune(
    root=None, *, kinds=None, older_than_days: float | None = None, everything: bool = False, dry_run: bool = False
) -> list[Path]:
    """Remove cached assets (by kind and/or age, or all; without kinds, the groom cache's entries too), stale
    temporaries, unused locks and orphaned parts folders."""
    for kind in kinds or ():
        if kind not in KINDS:
            raise errors.ValidationError("kind", kind, f"unknown asset kind; known: {', '.join(known_kinds())}")
    if not (everything or kinds or older_than_days is not None):
        victims = []
    else:
        now = time.time()
        victims = [
            e.path
            for e in entries(root)
            if e.usable
            and (everything or not kinds or e.kind in kinds)
            and (older_than_days is None or now - e.path.stat().st_mtime > older_than_days * 86400)
        ]
        if not kinds:  # the groom cache's entries (hairlut.scene: fits and sectors of grooms) go with the assets
            from ..scene import groom_cache_entries

            victims += [
                p
                for p in groom_cache_entries(cache_dir(root))
                if older_than_days is None or now - p.stat().st_mtime > older_than_days * 86400
            ]
    folder = cache_dir(root)
    now = time.time()
    # a temporary younger than STALE_SECONDS may belong to a bake that is still running
    victims += [p for p in (stale_temporaries(folder) if folder.is_dir() else []) if now - p.stat().st_mtime > STALE_SECONDS]
    if not dry_run:
        for p in victims:
            with contextlib.suppress(FileNotFoundError):
                p.unlink()
    return victims + _leftovers(folder, victims, dry_run, everything)


def _leftovers(folder: Path, removed: list[Path], dry_run: bool, everything: bool = False) -> list[Path]:
    """Lock files killed bakes left (``X.h5.lock``, ``X.h5.parts.lock[.K]``) that nobody holds, and the parts folders
    (``X.h5.parts/``, hairlut's own) of assets that are gone, when no bake of them holds a lock and (unless
    ``everything``) they are older than :data:`STALE_SECONDS` (a killed bake's parts resume it)."""
    from ..assets.parts import MARKER, remove_folder, remove_if_unused

    if not folder.is_dir():
        return []
    gone, held = [], []
    for p in sorted({*folder.glob("*.h5.lock"), *folder.glob("*.h5.parts.lock"), *folder.glob("*.h5.parts.lock.*")}):
        (gone if remove_if_unused(p, dry_run) else held).append(p)
    now = time.time()
    for d in sorted(folder.glob("*.h5.parts")):
        asset = d.with_name(d.name[: -len(".parts")])
        if d.is_symlink() or not (d / MARKER).is_file() or (asset.exists() and asset not in removed):
            continue
        if any(p.name.startswith(asset.name + ".") for p in held):
            continue  # a bake of it holds (or waits for) a lock
        if not everything and now - d.stat().st_mtime <= STALE_SECONDS:
            continue
        gone.append(d)
        if not dry_run:
            remove_folder(d)
    return gone
