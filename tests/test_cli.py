"""The command line: inspect (text, JSON, PNG), demo, errors as one line with status 2."""

import json
import struct
import subprocess
import zlib

import numpy as np
import pytest
from click.testing import CliRunner

from hairlut import __version__
from hairlut.assets import SCHEMA, Axis, ExrPart, Variable, write_exr, write_table
from hairlut_cli.main import cli

from ._readonly import read_only_dir  # noqa: F401  (a fixture)
from ._tables import lobes_table


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def decode_png(data: bytes) -> np.ndarray:
    """Minimal PNG decoder for 8-bit grey/RGB images with filter 0 (what hairlut writes)."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        tag, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length : pos + 12 + length])
        assert crc == zlib.crc32(tag + body) & 0xFFFFFFFF
        if tag == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif tag == b"IDAT":
            idat += body
        pos += 12 + length
    w, h, depth, colour = header[:4]
    channels = {0: 1, 2: 3}[colour]
    rows = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, 1 + w * channels)
    assert np.all(rows[:, 0] == 0)
    return rows[:, 1:].reshape(h, w, channels).squeeze()


def test_version_and_help():
    assert __version__ in run("--version").output
    out = run("--help").output
    assert "inspect" in out and "demo" in out
    assert "Examples" in run("inspect", "--help").output


def test_every_command_is_listed_under_its_name():
    from hairlut_cli.main import COMMANDS

    for name in COMMANDS:
        assert cli.get_command(None, name).name == name
    assert "sh" in run("bench", "--help").output  # the parts list, built when the help is shown


def test_version_and_help_import_neither_jax_nor_hdf5():
    """``hairlut --version`` and ``--help`` import no command's heavy parts (each took ~2 CPU-s with JAX)."""
    import sys

    code = (
        "import sys; from hairlut_cli.main import cli\n"
        "try: cli(sys.argv[1:], prog_name='hairlut')\n"
        "except SystemExit as e: assert not e.code, e.code\n"
        "print(sorted({'jax', 'h5py', 'numpy', 'hairlut.bake.registry'} & set(sys.modules)))"
    )
    for args in (["--version"], ["--help"]):
        out = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, out.stderr
        assert out.stdout.splitlines()[-1] == "[]", (args, out.stdout)


def test_inspect_table_text_and_json(tmp_path):
    path, ref = lobes_table(tmp_path / "t.h5")
    res = run("inspect", path)
    assert res.exit_code == 0
    for word in (
        "kk_lobes",
        f"schema    {SCHEMA}",
        "specular",
        "2×33×17 float32",
        "dims (exponent, theta, theta_v)",
        "fletcher32 on",
        "n_theta",
    ):
        assert word in res.output, word
    doc = json.loads(run("inspect", "--json", path).output)
    spec = next(d for d in doc["datasets"] if d["name"] == "specular")
    assert spec["shape"] == [2, 33, 17] and spec["dims"] == ["exponent", "theta", "theta_v"]
    assert spec["min"] == pytest.approx(float(ref["specular"].min()))
    assert spec["max"] == pytest.approx(float(ref["specular"].max()))
    assert spec["mean"] == pytest.approx(float(ref["specular"].astype(np.float64).mean()), rel=1e-9)
    assert spec["nan"] == 0 and spec["inf"] == 0
    assert doc["axes"]["theta"]["units"] == "rad" and doc["axes"]["theta"]["max"] == pytest.approx(np.pi)
    assert doc["recipe"]["exponents"] == [8.0, 49.0]


def test_inspect_counts_nan_and_inf(tmp_path):
    y = np.arange(12, dtype=np.float32).reshape(3, 4)
    y[0, 0], y[1, 1], y[2, 2] = np.nan, np.inf, -np.inf
    write_exr(tmp_path / "n.exr", {"Y": y})
    doc = json.loads(run("inspect", "--json", tmp_path / "n.exr").output)
    ch = doc["parts"][0]["channels"][0]
    assert (ch["nan"], ch["inf"]) == (1, 2)
    finite = y[np.isfinite(y)]
    assert (ch["min"], ch["max"], ch["mean"]) == pytest.approx((finite.min(), finite.max(), finite.mean()))


def test_inspect_multi_part_exr_and_several_files(tmp_path, rng):
    write_exr(tmp_path / "m.exr", [ExrPart("a", {"Y": rng.random((4, 4))}), ExrPart("b", {"Y": rng.random((2, 3))})])
    path, _ = lobes_table(tmp_path / "t.h5")
    doc = json.loads(run("inspect", "--json", tmp_path / "m.exr", path).output)
    assert [d["format"] for d in doc] == ["openexr", "hdf5"]
    assert [p["shape"] for p in doc[0]["parts"]] == [[4, 4], [2, 3]]
    assert "part b  3×2" in run("inspect", tmp_path / "m.exr").output


def test_png_preview_of_exr_layer_and_table_slice(tmp_path, rng):
    ramp = np.tile(np.linspace(0, 1, 16, dtype=np.float32), (8, 1))
    write_exr(tmp_path / "i.exr", {"R": ramp, "G": ramp, "B": ramp, "layer1.Y": ramp[:, ::-1]})
    assert run("inspect", tmp_path / "i.exr", "--png", tmp_path / "rgb.png").exit_code == 0
    rgb = decode_png((tmp_path / "rgb.png").read_bytes())
    assert rgb.shape == (8, 16, 3) and rgb[0, 0, 0] == 0 and rgb[0, -1, 0] == 255
    assert np.all(np.diff(rgb[0, :, 0].astype(int)) > 0)
    run("inspect", tmp_path / "i.exr", "--png", tmp_path / "l.png", "--channel", "layer1", "--exposure", "-1")
    grey = decode_png((tmp_path / "l.png").read_bytes())
    assert grey.shape == (8, 16) and grey[0, 0] == round(255 * (1.055 * 0.5 ** (1 / 2.4) - 0.055))

    path, ref = lobes_table(tmp_path / "t.h5")
    res = run("inspect", path, "--png", tmp_path / "s.png", "--dataset", "specular", "--slice", "1,:,:")
    assert res.exit_code == 0, res.output
    img = decode_png((tmp_path / "s.png").read_bytes())
    assert img.shape == (33, 17)
    brightest = np.unravel_index(np.argmax(ref["specular"][1]), (33, 17))
    assert img[brightest] == img.max()


@pytest.mark.parametrize(
    "args, message",
    [
        (["--dataset", "nothing"], "no dataset 'nothing'"),
        (["--dataset", "specular", "--slice", "0,0,0"], "a preview needs 2-D"),
        (["--dataset", "specular", "--slice", "a,b"], "slice="),
        (["--dataset", "specular", "--slice", "9,:,:"], "slice="),
    ],
)
def test_png_bad_options_one_line(tmp_path, args, message):
    path, _ = lobes_table(tmp_path / "t.h5")
    res = CliRunner().invoke(cli, ["inspect", str(path), "--png", str(tmp_path / "x.png"), *args])
    assert res.exit_code == 2
    assert message in res.output and len(res.output.strip().splitlines()) == 1 and "Traceback" not in res.output


def _bad_files(tmp_path):
    path, _ = lobes_table(tmp_path / "t.h5")
    raw = path.read_bytes()
    (tmp_path / "trunc.h5").write_bytes(raw[: len(raw) // 2])
    (tmp_path / "text.h5").write_text("hello")
    write_exr(tmp_path / "ok.exr", {"Y": np.ones((8, 8))})
    exr = (tmp_path / "ok.exr").read_bytes()
    (tmp_path / "trunc.exr").write_bytes(exr[: len(exr) - 10])
    return {
        "missing.h5": "no such file",
        "trunc.h5": "truncated",
        "text.h5": "neither HDF5 nor OpenEXR",
        "trunc.exr": "truncated or damaged EXR",
    }


def test_bad_files_give_one_line_and_status_2(tmp_path):
    for name, fault in _bad_files(tmp_path).items():
        res = CliRunner().invoke(cli, ["inspect", str(tmp_path / name)])
        assert res.exit_code == 2, name
        lines = res.output.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("hairlut: error: ") and name in lines[0] and fault in lines[0], res.output


def test_usage_errors_are_status_2(tmp_path):
    assert CliRunner().invoke(cli, ["inspect"]).exit_code == 2
    assert CliRunner().invoke(cli, ["inspect", "--bogus", "x"]).exit_code == 2
    assert CliRunner().invoke(cli, ["nonsense"]).exit_code == 2


@pytest.mark.parametrize(
    "command",
    [
        ["render", "{missing}/s.toml", "--out", "{out}/r.exr"],
        ["render", "{missing}/s.toml", "--strands", "--out", "{out}/sub/r.exr", "--png"],
        ["compare", "{missing}/a.exr", "{missing}/b.exr", "--png", "{out}/d.png"],
        ["strands", "convert", "{missing}/a.tfx", "{out}/a.hair"],
        ["synth", "{missing}/s.toml", "--out", "{out}/maps"],
    ],
)
@pytest.mark.parametrize("folder", ["read_only", "under_a_file"])
def test_outputs_are_checked_before_any_work(tmp_path, read_only_dir, command, folder):
    """Issue 29 m5: an output that cannot be written is refused first, one line naming the user's path (render
    computed the whole frame, then named a hidden temporary file).  The inputs do not exist: a command that read
    them (did any work) before checking its output would name them instead."""
    (tmp_path / "file").write_bytes(b"")
    out = read_only_dir if folder == "read_only" else tmp_path / "file"
    args = [a.format(missing=tmp_path / "missing", out=out) for a in command]
    target = next(a for a in args if a.startswith(str(out)))
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 2 and r.stdout == "", r.output
    assert r.stderr.startswith(f"hairlut: error: {target}: cannot write") and r.stderr.count("\n") == 1, r.stderr
    assert "missing" not in r.stderr and ".tmp" not in r.stderr


def test_demo_writes_and_inspects(tmp_path):
    from .test_plan import _write_toml, scene

    # 4 light bands, not "auto": the choice against a 30-band reference (test_env_bands.py checks it) would bake
    # 13 here and costs a quarter of this end-to-end run
    path = _write_toml(tmp_path / "tiny.toml", scene({"map": "sky", "bands": 4}))
    res = run("demo", "--scene", path, "--out", tmp_path / "d", "--cache", tmp_path / "c", "--no-progress", "--json")
    assert res.exit_code == 0, res.output
    (doc,) = json.loads(res.output)["scenes"]
    steps = {s["name"]: s["action"] for s in doc["plan"]}
    assert steps["hrir_db"] == steps["sh_tables"] == "bake" and steps["transmittance"] == "skip"
    assert doc["accuracy"]["chebyshev_tail"] < 1e-13 and doc["accuracy"]["hrir_query_self_check"] < 1e-5
    info = json.loads(run("inspect", "--json", *[a["path"] for a in doc["assets"].values()], *doc["files"]["exr"]).output)
    assert [i["kind"] for i in info] == ["hrir_db", "sh_tables", "synth_maps", "synth_maps"]
    alpha = next(c for c in info[2]["parts"][0]["channels"] if c["name"] == "layer1.A")
    assert 0 <= alpha["min"] and alpha["max"] <= 1 and alpha["nan"] == 0
    prev = decode_png((tmp_path / "d" / "tiny" / "preview.png").read_bytes())
    assert prev.shape == (32, 32, 3) and (prev.sum(-1) > 0).mean() > 0.05


def test_real_subprocess(tmp_path, hairlut_exe):
    # a fresh process knows only the kinds hairlut ships (kk_lobes is the tests' own), so inspect an sh_light
    path = write_table(
        tmp_path / "t.h5",
        "sh_light",
        {"lmax": 0},
        [Axis("sh_i", np.arange(1), "1", "i"), Axis("channel", np.arange(3), "1", "c")],
        [Variable("a", np.ones((1, 3)), ("sh_i", "channel"), "1", "a")],
    )
    ok = subprocess.run([hairlut_exe, "inspect", "--json", str(path)], capture_output=True, text=True, timeout=120)
    assert ok.returncode == 0 and json.loads(ok.stdout)["kind"] == "sh_light"
    bad = subprocess.run([hairlut_exe, "inspect", str(tmp_path / "none.exr")], capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and bad.stdout == ""
    assert bad.stderr.strip() == f"hairlut: error: {tmp_path / 'none.exr'}: no such file"
    quiet = subprocess.run([hairlut_exe, "-q", "--version"], capture_output=True, text=True, timeout=120)
    assert quiet.returncode == 0 and __version__ in quiet.stdout
