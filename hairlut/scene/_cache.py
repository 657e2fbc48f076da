"""The groom cache: a groom's cluster fit, its sector tables and their measures, kept on disk beside the tables.

Fitting clusters to a groom (:func:`~hairlut.geometry.fit_clusters`) and cutting its strands into sectors
(:func:`~hairlut.scene.scene_sectors`) cost seconds to minutes on a production groom (100,000 strands), and every
``hairlut plan``, ``bake --scene`` and ``render`` of the scene needs them.  Both are pure functions of their inputs,
so a ``[groom]`` scene's are kept in the table cache folder (``root``: the scene functions' ``cache_root``, else the
folder last given for the scene in the process; else ``$HAIRLUT_CACHE``, else ``tables/``: the rule of
``hairlut.bake.cache.cache_dir``) and keyed by the CONTENT of those inputs, never by a path or a time (generated
``[[clusters]]`` strands keep nothing on disk):

* ``groom-fit-<16 hex>.bin``: the fit's cluster specs and label per strand.  Key: the SHA-256 of the strands'
  points and counts (:func:`strands_digest`), every argument given to ``fit_clusters`` (so the entry stays right
  whatever chose them, e.g. the cluster count) and :func:`code_digest`;
* ``groom-choice-<16 hex>.bin``: the cluster count chosen from the strands (``cluster_count``: their turns), keyed
  like the fit by the strands and the value the scene gives;
* ``groom-tables-<16 hex>.bin``: each cluster's :class:`~hairlut.geometry.SectorTable` (the sector assignment: the
  strands' crossings and splats), which the planner, the scene-maps bake and ``hairlut.synth.prepare`` read;
* ``groom-sectors-<16 hex>.bin``: what :class:`~hairlut.scene.SceneSectors` measures that does not depend on the
  view or the lights (shape, strand counts, relative strand radius; and each sector's in-plane axes, from which the
  view's and lights' azimuths are computed afresh), so that a warm plan reads no table.  Key of both: each
  cluster's spec and strands (points, counts, thickness) and :func:`code_digest`.

The same groom at another path, or copied, hits; a changed byte of its strands, a changed fit argument or a change
to the code that fits and cuts (any source file of ``hairlut.geometry`` and ``hairlut.scene``, or the NumPy, SciPy
or JAX version) misses.

File: :data:`MAGIC`, one line of JSON (format, entry, full key, array manifest, SHA-256 of the payload, metadata),
then the raw arrays.  An entry is trusted only when all of that verifies and the arrays rebuild valid objects; one
that starts with :data:`MAGIC` but does not verify (damaged, truncated, stale) is hairlut's and is rebuilt in place
(atomically, :mod:`hairlut.atomic`); anything else under an entry's name (a file without the magic, a folder, a
link, a FIFO) is left untouched, never deleted or overwritten, and the result is computed without the cache, with a
warning naming the file.  A cache folder that cannot be written costs the cache, not the result.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import os
import stat
from pathlib import Path

import numpy as np

from .. import errors

log = logging.getLogger(__name__)

#: The first bytes of every entry: what marks a file as hairlut's own.
MAGIC = b"hairlut groom cache\n"
FORMAT = 1
PREFIX = "groom-"
ENV = "HAIRLUT_CACHE"  # the table cache's folder rule (hairlut.bake.cache, a floor above this one)
#: The largest entry read back (a larger file under an entry's name is not one).
MAX_BYTES = 1 << 30


def cache_folder(root=None) -> Path:
    """The table cache folder: ``root``, else ``$HAIRLUT_CACHE``, else ``./tables``."""
    return Path(root if root is not None else os.environ.get(ENV, "tables"))


@functools.lru_cache(maxsize=4)
def code_digest(packages: tuple = ("geometry", "scene"), *, backend: bool = True) -> str:
    """SHA-256 over the source files of hairlut's ``packages`` (by default ``geometry`` and ``scene``: what fits and
    cuts a groom) and the versions of hairlut, NumPy, SciPy and JAX, with JAX's backend unless ``backend`` is False
    (asking for it starts JAX's backend, which a process must not do before ``jax.distributed.initialize``)."""
    import jax
    import scipy

    from .. import __version__

    base = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for package in packages:
        for path in sorted((base / package).rglob("*.py")):
            h.update(path.relative_to(base).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    versions = [__version__, np.__version__, scipy.__version__, jax.__version__]
    h.update(json.dumps(versions + [jax.default_backend()] if backend else versions).encode())
    return h.hexdigest()


def strands_digest(strands, thickness: bool = True) -> str:
    """SHA-256 of a :class:`~hairlut.geometry.Strands`' points and counts (and thickness, when ``thickness``), as
    stored (dtype and shape included)."""
    h = hashlib.sha256()
    arrays = [strands.points, strands.counts] + ([strands.thickness] if thickness else [])
    for a in arrays:
        if a is None:
            h.update(b"none\0")
            continue
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}\0".encode())
        h.update(memoryview(a).cast("B"))
    return h.hexdigest()


def digest(doc) -> str:
    """SHA-256 of a JSON document (sorted keys)."""
    return hashlib.sha256(json.dumps(doc, sort_keys=True, separators=(",", ":"), default=_plain).encode()).hexdigest()


def _plain(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"cannot key a {type(x).__name__}")


def entry_path(entry: str, key: str, root=None) -> Path:
    return cache_folder(root) / f"{PREFIX}{entry}-{key[:16]}.bin"


class _Foreign(Exception):
    """Something under an entry's name that hairlut did not write: left alone."""


class _Damaged(Exception):
    """An entry of hairlut's that does not verify: rebuilt."""


def encode(entry: str, key: str, arrays: dict, meta: dict) -> bytes:
    """An entry's bytes (module docstring)."""
    blobs, manifest, offset = [], [], 0
    for name, a in arrays.items():
        a = np.ascontiguousarray(a)
        if a.dtype.kind not in "biuf":
            raise TypeError(f"{name}: cannot keep a {a.dtype} array")
        b = a.tobytes()
        manifest.append({"name": name, "dtype": a.dtype.str, "shape": list(a.shape), "offset": offset, "bytes": len(b)})
        blobs.append(b)
        offset += len(b)
    payload = b"".join(blobs)
    head = {
        "format": FORMAT,
        "entry": entry,
        "key": key,
        "arrays": manifest,
        "payload_sha256": hashlib.sha256(payload).hexdigest(),
        "meta": meta,
    }
    return MAGIC + json.dumps(head, sort_keys=True, default=_plain).encode() + b"\n" + payload


def decode(data: bytes, entry: str, key: str) -> tuple[dict, dict]:
    """(arrays, meta) of an entry's bytes; raises _Foreign (no magic) or _Damaged (anything else wrong)."""
    if not data.startswith(MAGIC):
        raise _Foreign("it does not start with hairlut's groom-cache marker")
    end = data.find(b"\n", len(MAGIC))
    if end < 0:
        raise _Damaged("no header")
    try:
        head = json.loads(data[len(MAGIC) : end])
        if head["format"] != FORMAT or head["entry"] != entry:
            raise _Damaged(f"format {head['format']!r}, entry {head['entry']!r}")
        if head["key"] != key:
            raise _Damaged("it holds another key (stale)")
        payload = memoryview(data)[end + 1 :]
        if hashlib.sha256(payload).hexdigest() != head["payload_sha256"]:
            raise _Damaged("its payload's checksum does not verify")
        arrays = {}
        for m in head["arrays"]:
            dt = np.dtype(m["dtype"])
            if dt.kind not in "biuf" or dt.hasobject:
                raise _Damaged(f"array {m['name']!r} has dtype {dt}")
            n = int(np.prod(m["shape"], dtype=np.int64))
            if m["offset"] < 0 or m["bytes"] != n * dt.itemsize or m["offset"] + m["bytes"] > len(payload):
                raise _Damaged(f"array {m['name']!r} does not fit the payload")
            arrays[m["name"]] = np.frombuffer(payload, dt, n, m["offset"]).reshape(m["shape"]).copy()
        return arrays, head["meta"]
    except _Damaged:
        raise
    except (ValueError, KeyError, TypeError, UnicodeDecodeError) as exc:
        raise _Damaged(f"its header does not parse ({exc})") from None


def decode_key(data: bytes) -> str | None:
    """The full key an entry's header names (None when it has none): what ``decode`` compares with the key asked for."""
    if not data.startswith(MAGIC):
        return None
    try:
        return json.loads(data[len(MAGIC) : data.index(b"\n", len(MAGIC))])["key"]
    except (ValueError, KeyError, TypeError):
        return None


def _read(path: Path) -> bytes | None:
    """The bytes at ``path``: None when nothing is there; _Foreign for a link, a folder, a FIFO, too large a file."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return None
    if not stat.S_ISREG(st.st_mode):
        raise _Foreign("it is not a regular file")
    if st.st_size > MAX_BYTES:
        raise _Foreign(f"it holds {st.st_size} bytes, more than an entry")
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    with os.fdopen(fd, "rb") as f:
        return f.read()


def groom_cache_entries(root=None) -> list[Path]:
    """The groom cache's entries in the cache folder: regular files named like one that start with :data:`MAGIC`
    (hairlut's own; anything else under such a name is not), what ``hairlut cache prune`` may remove."""
    out = []
    for path in sorted(cache_folder(root).glob(f"{PREFIX}*-*.bin")):
        try:
            if not stat.S_ISREG(os.lstat(path).st_mode):
                continue
            with open(path, "rb") as f:
                if f.read(len(MAGIC)) == MAGIC:
                    out.append(path)
        except OSError:
            continue
    return out


def cached(entry: str, key: str, compute, to_arrays, from_arrays, root=None):
    """``from_arrays(arrays, meta)`` of the entry (``entry``, ``key``) under ``root`` when it holds a valid one; else
    ``compute()``, stored as ``to_arrays(result)`` = (arrays, meta) and returned (module docstring).  An entry whose
    arrays ``from_arrays`` refuses (it raises) is damaged and rebuilt."""
    path = entry_path(entry, key, root)
    writable = True
    try:
        data = _read(path)
        if data is not None:
            arrays, meta = decode(data, entry, key)
            try:
                return from_arrays(arrays, meta)
            except (errors.HairlutError, ValueError, KeyError, TypeError, IndexError) as exc:
                raise _Damaged(f"its arrays do not rebuild ({exc})") from None
    except _Foreign as exc:
        log.warning("not using or replacing %s (%s); the groom's %s is computed afresh", path, exc, entry)
        writable = False
    except _Damaged as exc:
        log.warning("rebuilding the groom cache entry %s: %s", path, exc)
    except OSError as exc:
        log.warning("cannot read the groom cache entry %s (%s); it is computed afresh", path, exc.strerror or exc)
    result = compute()
    if writable:
        try:
            arrays, meta = to_arrays(result)
            _write(path, encode(entry, key, arrays, meta))
        except (errors.HairlutError, OSError) as exc:  # a read-only or full cache folder costs the cache
            log.warning("cannot keep the groom's %s in the cache (%s)", entry, exc)
    return result


def _write(path: Path, data: bytes) -> None:
    from ..atomic import atomic_write_bytes

    if os.path.lexists(path):  # replace only a regular file (hairlut's own: decode found its magic)
        if not stat.S_ISREG(os.lstat(path).st_mode):
            raise errors.AssetError(path, "is not a regular file; left as it is")
    atomic_write_bytes(path, data)


# ----------------------------------------------------------------------------- the fit


def _spline_arrays(prefix: str, sp, out: dict) -> int:
    out[f"{prefix}.control"] = sp.control
    out[f"{prefix}.knots"] = sp.knots
    return int(sp.degree)


def fit_arrays(result) -> tuple[dict, dict]:
    """(arrays, meta) of a fit's (batch, labels)."""
    batch, labels = result
    arrays, specs = {"labels": np.asarray(labels, np.int64)}, []
    for c, s in enumerate(batch.specs):
        deg = {name: _spline_arrays(f"{c}.{name}", getattr(s, name), arrays) for name in SPLINES}
        arrays[f"{c}.layer_radii"] = s.layer_radii
        specs.append({"degree": deg, "core_radius": s.core_radius, "s_t": s.s_t, "s_v": s.s_v, "s_u": s.s_u})
    return arrays, {"specs": specs}


SPLINES = ("trajectory", "half_axis_a", "half_axis_b", "twist")


def fit_from_arrays(n_strands: int):
    """The rebuilder of a fit entry for a groom of ``n_strands`` strands: (batch, labels), or it raises."""

    def rebuild(arrays: dict, meta: dict):
        from ..geometry import BSpline, ClusterBatch, ClusterSpec

        specs = []
        for c, m in enumerate(meta["specs"]):
            sp = {
                name: BSpline.make(
                    arrays[f"{c}.{name}.control"],
                    arrays[f"{c}.{name}.knots"],
                    int(m["degree"][name]),
                    field=name,
                    dim=arrays[f"{c}.{name}.control"].shape[1],
                )
                for name in SPLINES
            }
            for name in SPLINES[1:]:  # 1-D splines are (n, 1) control values; ClusterSpec takes them as such
                if sp[name].dim != 1:
                    raise ValueError(f"{name} is not a 1-D spline")
            specs.append(
                ClusterSpec(
                    sp["trajectory"],
                    sp["half_axis_a"],
                    sp["half_axis_b"],
                    sp["twist"],
                    layer_radii=arrays[f"{c}.layer_radii"],
                    core_radius=float(m["core_radius"]),
                    s_t=int(m["s_t"]),
                    s_v=int(m["s_v"]),
                    s_u=int(m["s_u"]),
                )
            )
        labels = arrays["labels"]
        if labels.shape != (n_strands,) or labels.min(initial=-1) < -1 or labels.max(initial=-1) >= len(specs):
            raise ValueError(f"labels of shape {labels.shape} in [{labels.min(initial=-1)}, {labels.max(initial=-1)}]")
        return ClusterBatch.stack(specs), labels

    return rebuild


def cached_fit(strands, n_clusters, *, root=None, check=None, **kw):
    """:func:`~hairlut.geometry.fit_clusters` ``(strands, n_clusters, **kw)`` through the cache (module docstring):
    (batch, labels), the same arrays as a fresh fit's.  ``check()`` (raises on strands the fit cannot use) runs before
    a fit is computed; a kept fit passed it when it was made, from the same points and counts (its key)."""
    from ..geometry import fit_clusters

    def compute():
        if check is not None:
            check()
        return fit_clusters(strands, n_clusters, **kw)

    args = {"n_clusters": int(n_clusters), **kw}
    key = digest({"entry": "fit", "strands": strands_digest(strands, thickness=False), "args": args, "code": code_digest()})
    return cached("fit", key, compute, fit_arrays, fit_from_arrays(strands.n_strands), root)


def cached_choice(strands, given, choose, *, root=None):
    """``choose(strands, given)`` (a :class:`~hairlut.scene.Choice`, e.g. :func:`~hairlut.scene.cluster_count`)
    through the cache, keyed like the fit by the strands' points and counts, ``given`` and :func:`code_digest` (the
    rule's own source among it): what precedes the fit is not measured again on every plan (the cluster count's
    strand turns: 0.6 s at 100,000 strands)."""
    from ._choices import Choice

    key = digest({"entry": "choice", "strands": strands_digest(strands, thickness=False), "given": given, "code": code_digest()})

    def rebuild(arrays, meta):
        if set(meta) != {"key", "value", "given", "reason", "predicted"}:
            raise ValueError(f"a choice of fields {sorted(meta)}")
        return Choice(**meta)

    return cached("choice", key, lambda: choose(strands, given), lambda c: ({}, c.to_json()), rebuild, root)


# ----------------------------------------------------------------------------- the sectors


def spec_doc(spec) -> dict:
    """A cluster spec as plain data (its splines' control points, knots and degrees, layers, sampling, normal0)."""
    doc = {name: [getattr(spec, name).control, getattr(spec, name).knots, getattr(spec, name).degree] for name in SPLINES}
    return doc | {
        "layer_radii": spec.layer_radii,
        "core_radius": spec.core_radius,
        "sampling": [spec.s_t, spec.s_v, spec.s_u],
        "normal0": spec.normal0,
    }


def pairs_key(pairs) -> str:
    """The sectors entry's key of [(ClusterSpec, Strands)]: every spec and every cluster's strands, and the code."""
    return digest(
        {
            "entry": "sectors",
            "clusters": [[spec_doc(spec), strands_digest(s)] for spec, s in pairs],
            "code": code_digest(),
        }
    )


# ----------------------------------------------------------------------------- the sector tables


def tables_arrays(tables) -> tuple[dict, dict]:
    """(arrays, meta) of each cluster's :class:`~hairlut.geometry.SectorTable`."""
    from dataclasses import fields

    arrays, meta = {}, []
    for c, tb in enumerate(tables):
        for f in fields(tb):
            if f.name not in ("shape", "s_v"):
                arrays[f"{c}.{f.name}"] = getattr(tb, f.name)
        meta.append({"shape": list(tb.shape), "s_v": int(tb.s_v)})
    return arrays, {"tables": meta}


def tables_from_arrays(arrays: dict, meta: dict) -> list:
    """The sector tables of an entry, checked enough that nothing reads out of bounds (or it raises)."""
    from dataclasses import fields

    from ..geometry import SectorTable

    names = [f.name for f in fields(SectorTable) if f.name not in ("shape", "s_v")]
    out = []
    for c, m in enumerate(meta["tables"]):
        a = {k: arrays[f"{c}.{k}"] for k in names}
        shape = tuple(int(x) for x in m["shape"])
        n, x, j = int(np.prod(shape)), len(a["crossing_strand"]), len(a["splat_crossing"])
        per_sector = ("cluster", "t_index", "track", "layer", "u_index", "t", "v_range", "u_range", "half_axes", "twist")
        if len(shape) != 4 or any(len(a[k]) != n for k in (*per_sector, "corners")) or len(a["splat_offsets"]) != n + 1:
            raise ValueError(f"sector arrays do not match the shape {shape}")
        crossing = (
            "crossing_sector",
            "crossing_sr",
            "crossing_xy",
            "crossing_vu",
            "crossing_point",
            "crossing_radius",
            "crossing_stretch",
        )
        if any(len(a[k]) != x for k in crossing) or any(len(a[k]) != j for k in ("splat_center", "splat_sigma")):
            raise ValueError("crossing or splat arrays of different lengths")
        off = a["splat_offsets"]
        if off[0] != 0 or off[-1] != j or (np.diff(off) < 0).any():
            raise ValueError("splat offsets out of order")
        if x and (a["crossing_sector"].min() < 0 or a["crossing_sector"].max() >= n):
            raise ValueError("a crossing outside the sectors")
        if j and (a["splat_crossing"].min() < 0 or a["splat_crossing"].max() >= x):
            raise ValueError("a splat of no crossing")
        if a["hsv_sectors"].size and (a["hsv_sectors"].min() < 0 or a["hsv_sectors"].max() >= n):
            raise ValueError("an HSV outside the sectors")
        out.append(SectorTable(shape=shape, s_v=int(m["s_v"]), **a))
    return out


# ----------------------------------------------------------------------------- for the floors above


def cached_arrays(entry: str, doc: dict, compute, check=None, root=None, packages: tuple = ("geometry", "scene")) -> dict:
    """``compute()`` (a dict of arrays) through the groom cache as ``groom-<entry>-<16 hex>.bin``, keyed by ``doc``
    (plain data: what decides the arrays) and :func:`code_digest` of ``packages``.  ``check(arrays)`` raises
    ValueError on arrays read back that are not what ``compute`` makes (then they are rebuilt).  What
    ``hairlut.synth`` keeps of a groom's light-space shadows."""
    key = digest({"entry": entry, "doc": doc, "code": code_digest(tuple(packages))})

    def rebuild(arrays, meta):
        if check is not None:
            check(arrays)
        return arrays

    return cached(entry, key, compute, lambda arrays: (arrays, {}), rebuild, root)
