"""The threaded chunk writer (hairlut.assets.chunks) against HDF5's own filter pipeline.

References: a literal Python port of HDF5's ``H5_checksum_fletcher32`` loop, and h5py writing
the same data through HDF5's shuffle → deflate → fletcher32 pipeline; chunks are compared
byte for byte with ``read_direct_chunk``.
"""

from __future__ import annotations

import io
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

from hairlut import errors
from hairlut.assets import Axis, Variable, read_table, register_kind, write_table
from hairlut.assets.chunks import ChunkWriter, filter_chunk, fletcher32, shuffle, workers

KW = dict(compression="gzip", compression_opts=4, shuffle=True, fletcher32=True, track_times=False)


def fletcher32_loop(data: bytes) -> int:
    """HDF5's H5_checksum_fletcher32, statement for statement (src/H5checksum.c)."""
    n, i = len(data) // 2, 0
    s1 = s2 = 0
    while n:
        t = min(n, 360)
        n -= t
        for _ in range(t):
            s1 += (data[i] << 8) | data[i + 1]
            i += 2
            s2 += s1
        s1 = (s1 & 0xFFFF) + (s1 >> 16)
        s2 = (s2 & 0xFFFF) + (s2 >> 16)
    if len(data) % 2:
        s1 += data[i] << 8
        s2 += s1
        s1 = (s1 & 0xFFFF) + (s1 >> 16)
        s2 = (s2 & 0xFFFF) + (s2 >> 16)
    s1 = (s1 & 0xFFFF) + (s1 >> 16)
    s2 = (s2 & 0xFFFF) + (s2 >> 16)
    return (s2 << 16) | s1


def test_fletcher32_equals_hdf5s_loop():
    rng = np.random.default_rng(3)
    assert fletcher32(b"") == 0
    assert fletcher32(b"\x00\x01") == 0x00010001
    cases = [bytes(n) for n in (1, 2, 719, 720, 721)] + [b"\xff" * n for n in (1, 2, 720, 721, 5000)]
    cases += [rng.integers(0, 256, n, dtype=np.uint8).tobytes() for n in (1, 3, 359, 360, 361, 720, 721, 7777, 65537)]
    for data in cases:
        assert fletcher32(data) == fletcher32_loop(data), len(data)


def test_shuffle_groups_bytes_of_equal_rank():
    x = np.array([0x0102, 0x0304], "<u2")
    assert shuffle(x.tobytes(), 2) == bytes([0x02, 0x04, 0x01, 0x03])
    assert shuffle(b"abc", 1) == b"abc"


def _both(data, chunks, threads=3, **kw):
    """(h5py's file, the chunk writer's file) holding dataset x of ``data``."""
    files = []
    for direct in (False, True):
        buf = io.BytesIO()
        with h5py.File(buf, "w") as f:
            if direct:
                ds = f.create_dataset("x", shape=data.shape, dtype=data.dtype, chunks=chunks, **{**KW, **kw})
                with ChunkWriter(threads) as w:
                    w.add(ds, data)
            else:
                f.create_dataset("x", data=data, chunks=chunks, **{**KW, **kw})
        files.append(buf)
    return files


CASES = [
    ((37, 5, 9), (16, 5, 4), np.float32),
    ((100,), (7,), np.float64),
    ((3, 33), (2, 10), np.float16),
    ((65,), (64,), np.int64),
    ((13, 3), (4, 3), np.int8),
    ((1000,), True, np.uint16),
    ((5,), (5,), np.bool_),
    ((2, 32, 32, 64), (1, 32, 32, 64), np.float32),
    ((40, 6), True, np.int32),
]


@pytest.mark.parametrize("shape,chunks,dtype", CASES)
def test_chunks_are_the_bytes_hdf5_writes(shape, chunks, dtype):
    rng = np.random.default_rng(sum(shape))
    data = (rng.standard_normal(shape) * 100).astype(dtype)
    data.reshape(-1)[: data.size // 3] = 0  # runs of zeros compress: sizes of both parities
    ref, mine = _both(data, chunks)
    with h5py.File(ref, "r") as f1, h5py.File(mine, "r") as f2:
        a, b = f1["x"], f2["x"]
        assert a.chunks == b.chunks and a.id.get_num_chunks() == b.id.get_num_chunks() > 0
        for i in range(a.id.get_num_chunks()):
            offset = a.id.get_chunk_info(i).chunk_offset
            assert a.id.read_direct_chunk(offset) == b.id.read_direct_chunk(offset), offset
        out = b[()]
        assert out.dtype == data.dtype and out.tobytes() == data.tobytes()  # bit for bit, through HDF5's reader


def test_file_does_not_depend_on_the_thread_count():
    data = np.random.default_rng(0).standard_normal((70, 9)).astype(np.float32)
    files = [_both(data, (8, 9), threads=t)[1].getvalue() for t in (1, 2, 5)]
    assert files[0] == files[1] == files[2]


def test_a_damaged_chunk_fails_its_checksum():
    data = np.arange(4096, dtype=np.float32)
    buf = _both(data, (1024,))[1]
    with h5py.File(buf, "r") as f:
        stored = f["x"].id.read_direct_chunk((1024,))[1]
        where = f["x"].id.get_chunk_info(1).byte_offset
    raw = bytearray(buf.getvalue())
    raw[where + len(stored) // 2] ^= 0x10
    with h5py.File(io.BytesIO(bytes(raw)), "r") as f:
        f["x"][:1024]  # the other chunks still read
        with pytest.raises(OSError):
            f["x"][1024:2048]


def test_other_filters_and_shapes_are_refused():
    with h5py.File(io.BytesIO(), "w") as f:
        ds = f.create_dataset("x", shape=(10,), dtype="f4", chunks=(5,), compression="lzf")
        with ChunkWriter(1) as w, pytest.raises(errors.ValidationError, match="filters"):
            w.add(ds, np.zeros(10, "f4"))
        ds = f.create_dataset("y", shape=(10,), dtype="f4", chunks=(5,), **KW)
        with ChunkWriter(1) as w, pytest.raises(errors.ValidationError):
            w.add(ds, np.zeros(9, "f4"))
    assert filter_chunk(np.zeros(4, "f4"), 4)[-4:] == fletcher32(filter_chunk(np.zeros(4, "f4"), 4)[:-4]).to_bytes(4, "little")


def test_thread_count_from_the_environment(monkeypatch):
    monkeypatch.setenv("HAIRLUT_WRITE_THREADS", "3")
    assert workers() == 3
    for bad in ("0", "x", "-2"):
        monkeypatch.setenv("HAIRLUT_WRITE_THREADS", bad)
        with pytest.raises(errors.ValidationError, match="HAIRLUT_WRITE_THREADS"):
            workers()
    monkeypatch.delenv("HAIRLUT_WRITE_THREADS")
    assert workers() >= 1


register_kind("chunk_toy", ("x",), "a table for the chunk writer's tests")


def _table(path):
    rng = np.random.default_rng(1)
    axes = [Axis("a", np.arange(40.0), "1", "a"), Axis("b", np.arange(6.0), "1", "b")]
    variables = [
        Variable("x", rng.standard_normal((40, 6)).astype(np.float32), ("a", "b"), "1", "x", chunks=(16, 6)),
        Variable("g/y", np.arange(40, dtype=np.int16), ("a",), "1", "y"),
    ]
    write_table(path, "chunk_toy", {"r": 1}, axes, variables)
    return variables


def test_write_table_reads_back_and_is_the_same_file_for_any_thread_count(tmp_path):
    code = (
        "import os, sys; sys.path.insert(0, {tests!r}); os.environ['SOURCE_DATE_EPOCH'] = '0'; "
        "from test_chunk_writer import _table; _table(sys.argv[1])"
    )
    for t in (1, 4):
        env = {**os.environ, "HAIRLUT_WRITE_THREADS": str(t)}
        subprocess.run(
            [sys.executable, "-c", code.format(tests=os.path.dirname(__file__)), str(tmp_path / f"{t}.h5")], check=True, env=env
        )
    assert (tmp_path / "1.h5").read_bytes() == (tmp_path / "4.h5").read_bytes()
    variables = _table(tmp_path / "here.h5")
    t = read_table(tmp_path / "1.h5", "chunk_toy")
    for v in variables:
        assert t[v.name].dtype == v.data.dtype and t[v.name].tobytes() == v.data.tobytes()
