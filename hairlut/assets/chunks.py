"""HDF5's filter pipeline in NumPy and zlib, run on every core: shuffle → gzip → fletcher32.

Every table dataset hairlut writes is chunked with the byte shuffle, gzip (deflate) and
HDF5's fletcher32 checksum, in that order (DESIGN.md, Assets).  HDF5 runs that pipeline
one chunk after another on the writing thread.  Here each chunk is filtered in a thread
pool (``zlib.compress`` and NumPy's copies release the GIL) and the finished bytes are
handed to HDF5 with ``dataset.id.write_direct_chunk``, in chunk order, from the calling
thread; so the file does not depend on the number of threads.

The bytes of each chunk are the bytes HDF5's own pipeline writes for the same data
(``tests/test_chunk_writer.py`` compares both with ``read_direct_chunk``), when both use
the same zlib (h5py's HDF5 links the system's libz, as Python's ``zlib`` does):

- shuffle (``H5Z_FILTER_SHUFFLE``): byte k of every element, for k = 0 … size − 1, one
  after another; a no-op for 1-byte elements;
- deflate (``H5Z_FILTER_DEFLATE``): zlib's ``compress2`` at the dataset's level, which
  is ``zlib.compress(data, level)``;
- fletcher32 (``H5Z_FILTER_FLETCHER32``): :func:`fletcher32` of the compressed bytes,
  appended little-endian.

Edge chunks (past the dataset's extent) are written whole, the part outside the extent
filled with zeros, as HDF5 does for a dataset without a user fill value.
"""

from __future__ import annotations

import collections
import os
import zlib
from concurrent.futures import ThreadPoolExecutor
from itertools import product

import h5py
import numpy as np

from .. import errors

#: Words summed exactly in one int64 pass of :func:`fletcher32` (65535 · n² / 2 stays below 2⁶³).
_FLETCHER_BLOCK = 1 << 22
#: Chunks queued at most before the oldest is written (a constant: the file must not depend on the core count).
WINDOW = 64


def workers() -> int:
    """Threads that filter chunks: ``HAIRLUT_WRITE_THREADS`` when set, else the cores this process may use."""
    given = os.environ.get("HAIRLUT_WRITE_THREADS")
    if given is not None:
        try:
            n = int(given)
        except ValueError:
            n = 0
        if n < 1:
            raise errors.ValidationError("HAIRLUT_WRITE_THREADS", given, "must be an integer ≥ 1")
        return n
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def shuffle(raw: bytes | np.ndarray, itemsize: int) -> bytes:
    """HDF5's byte shuffle of ``raw`` (whole elements of ``itemsize`` bytes)."""
    b = np.frombuffer(raw, np.uint8) if not isinstance(raw, np.ndarray) else raw.reshape(-1).view(np.uint8)
    if itemsize <= 1 or b.size == 0:
        return b.tobytes()
    if b.size % itemsize:
        raise ValueError(f"{b.size} bytes are not whole {itemsize}-byte elements")
    return b.reshape(-1, itemsize).T.tobytes()


def fletcher32(raw: bytes) -> int:
    """HDF5's fletcher32 checksum (``H5_checksum_fletcher32``) of ``raw``.

    HDF5 sums big-endian 16-bit words (an odd last byte is the high byte of a last word) into
    sum1 and sum2 = Σ of the running sum1, folding each back to 16 bits (end-around carry) every 360
    words and twice at the end.  A fold keeps a value's residue mod 65535 and maps only 0 to 0, so
    the result is, from the exact sums S1 = Σ wᵢ and S2 = Σ (n − i) wᵢ: each sum is 0 when its
    exact value is 0, else 1 + (S − 1) mod 65535; the checksum is (sum2 << 16) | sum1.
    """
    b = np.frombuffer(raw, np.uint8)
    if b.size % 2:
        b = np.concatenate([b, np.zeros(1, np.uint8)])  # the last byte, high half of a last word
    w = b.view(">u2")
    n = w.size
    s1 = s2 = 0
    for lo in range(0, n, _FLETCHER_BLOCK):  # exact integer sums, one int64 pass per block
        part = w[lo : lo + _FLETCHER_BLOCK].astype(np.int64)
        total = int(part.sum())
        # word i of the block enters sum2 once per word from i to the block's end, after the earlier blocks' sum1
        s2 += part.size * (s1 + total) - int(np.dot(part, np.arange(part.size, dtype=np.int64)))
        s1 += total

    def fold(s: int) -> int:
        return 0 if s == 0 else 1 + (s - 1) % 65535

    return (fold(s2) << 16) | fold(s1)


def filter_chunk(block: np.ndarray, level: int, *, shuffled: bool = True, checksum: bool = True) -> bytes:
    """One chunk's stored bytes: shuffle, gzip at ``level``, fletcher32 appended little-endian."""
    raw = np.ascontiguousarray(block)
    data = shuffle(raw, raw.dtype.itemsize) if shuffled else raw.tobytes()
    data = zlib.compress(data, level)
    if checksum:
        data += int(fletcher32(data)).to_bytes(4, "little")
    return data


def _pipeline(ds: h5py.Dataset) -> tuple[int, bool, bool]:
    """(gzip level, shuffle, fletcher32) of ``ds``; refuses any other filter pipeline."""
    plist = ds.id.get_create_plist()
    filters = [plist.get_filter(i) for i in range(plist.get_nfilters())]
    ids = [f[0] for f in filters]
    want = [h5py.h5z.FILTER_SHUFFLE, h5py.h5z.FILTER_DEFLATE, h5py.h5z.FILTER_FLETCHER32]
    if ids not in (want, want[1:], want[:2], want[1:2]):
        raise errors.ValidationError("filters", ids, "the chunk writer runs shuffle, gzip and fletcher32 (in HDF5's order)")
    level = int(filters[ids.index(h5py.h5z.FILTER_DEFLATE)][2][0])
    return level, ids[0] == h5py.h5z.FILTER_SHUFFLE, ids[-1] == h5py.h5z.FILTER_FLETCHER32


def chunk_slices(shape: tuple[int, ...], chunks: tuple[int, ...]):
    """(offset, slices) of every chunk of a dataset, in row-major chunk order."""
    grids = [range(0, s, c) for s, c in zip(shape, chunks)]
    for offset in product(*grids):
        yield offset, tuple(slice(o, min(o + c, s)) for o, c, s in zip(offset, chunks, shape))


def _chunk(data: np.ndarray, sl: tuple[slice, ...], chunks: tuple[int, ...]) -> np.ndarray:
    part = data[sl]
    if part.shape == tuple(chunks):
        return part
    whole = np.zeros(chunks, data.dtype)  # an edge chunk: the rest is the fill value, zero
    whole[tuple(slice(0, n) for n in part.shape)] = part
    return whole


class ChunkWriter:
    """Filter the chunks of datasets on every core and write them in order (:meth:`add`, :meth:`flush`).

    ``with ChunkWriter() as w: w.add(ds, data)`` leaves every chunk written when the block ends (a
    failure in a worker is raised there).  Chunks are written in the order added, from the calling
    thread, at most :data:`WINDOW` of them waiting (compressed or not), so the file is the same for
    any thread count as long as nothing else writes to it between :meth:`add` and :meth:`flush`.
    """

    def __init__(self, threads: int | None = None):
        self.threads = workers() if threads is None else max(1, int(threads))
        self._pool = ThreadPoolExecutor(self.threads, thread_name_prefix="hairlut-chunks") if self.threads > 1 else None
        self._pending: collections.deque = collections.deque()

    def add(self, ds: h5py.Dataset, data: np.ndarray) -> None:
        """Queue every chunk of ``data`` (the dataset's whole extent) for ``ds``."""
        data = np.asarray(data, dtype=ds.dtype)
        if data.shape != ds.shape or ds.chunks is None:
            raise errors.ValidationError(ds.name, data.shape, f"the chunk writer fills a chunked dataset of shape {ds.shape}")
        level, shuffled, checksum = _pipeline(ds)
        kw = {"shuffled": shuffled, "checksum": checksum}
        for offset, sl in chunk_slices(ds.shape, ds.chunks):
            block = _chunk(data, sl, ds.chunks)
            job = self._pool.submit(filter_chunk, block, level, **kw) if self._pool else filter_chunk(block, level, **kw)
            self._pending.append((ds, offset, job))
            self._write(WINDOW)

    def _write(self, keep: int) -> None:
        """Write the oldest queued chunks until at most ``keep`` wait."""
        while len(self._pending) > keep:
            ds, offset, job = self._pending.popleft()
            ds.id.write_direct_chunk(offset, job if isinstance(job, bytes) else job.result(), 0)

    def flush(self) -> None:
        """Write every queued chunk, in the order added."""
        self._write(0)

    def close(self) -> None:
        """Drop what is still queued and stop the threads (:meth:`flush` first to keep it)."""
        self._pending.clear()
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)

    def __enter__(self) -> ChunkWriter:
        return self

    def __exit__(self, kind, value, tb) -> None:
        try:
            if kind is None:
                self.flush()
        finally:
            self.close()
