"""hairlut bench: the harness (ratios, Pareto front, files written, bad part names) and one real part."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from hairlut import errors
from hairlut.bench import PARTS, Figure, Part, derive, pareto_front, run_bench, strand_transmittance

from ._readonly import read_only_dir  # noqa: F401  (a fixture)


def test_pareto_front_hand_made():
    pts = [(1.0, 10.0), (2.0, 5.0), (3.0, 5.0), (4.0, 1.0), (5.0, 2.0), (0.5, 20.0), (2.0, 5.0), (None, 0.1), (1.0, None)]
    #      front       front       dominated   front       dominated   front        tie: front  no time      no error
    assert pareto_front(pts) == [True, True, False, True, False, True, True, False, False]
    assert pareto_front([]) == []
    assert pareto_front([(1.0, 0.0)]) == [True]


def _fig(label, sec, err, **kw):
    return Figure("fake", "t", label, sec, err, "err", **kw)


def test_ratios_against_the_same_run_baseline():
    figs = derive([_fig("a", 2.0, 0.5, baseline=True), _fig("b", 1.0, 0.25), _fig("c", None, 1.0), _fig("d", 4.0, None)])
    assert [f.time_ratio for f in figs] == [1.0, 0.5, None, 2.0]
    assert [f.error_ratio for f in figs] == [1.0, 0.5, 2.0, None]
    assert [f.pareto for f in figs] == [False, True, False, False]
    with pytest.raises(errors.ValidationError, match="fake.t"):
        derive([_fig("a", 1.0, 1.0), _fig("b", 1.0, 1.0)])
    with pytest.raises(errors.ValidationError, match="baseline"):
        derive([_fig("a", 1.0, 1.0, baseline=True), _fig("b", 1.0, 1.0, baseline=True)])


def _fake_run(ctx):
    ctx.note("fake", "a made-up part")
    return [
        _fig("slow exact", 1.0, 1e-6),
        _fig("straightforward", 0.5, 1e-3, baseline=True),
        _fig("fast", 0.01, 1e-2, paper=True),
        _fig("stored as float16", None, 2e-3),
    ]


def _boom(ctx):
    raise RuntimeError("part exploded")


def test_run_bench_writes_report_results_and_plots(tmp_path):
    registry = {
        "fake": Part("fake", "a fake part", _fake_run),
        "broken": Part("broken", "fails", _boom),
        "absent": Part("absent", "cannot run", _fake_run, lambda: "no such device"),
    }
    res = run_bench(tmp_path / "out", registry=registry)
    out = tmp_path / "out"
    doc = json.loads((out / "results.json").read_text())
    assert doc["machine"]["cpus"] and "numpy" in doc["machine"]["versions"]
    assert {k: v["status"] for k, v in doc["parts"].items()} == {"fake": "ok", "broken": "failed", "absent": "skipped"}
    assert "part exploded" in doc["parts"]["broken"]["reason"] and doc["parts"]["absent"]["reason"] == "no such device"
    by = {f["label"]: f for f in doc["figures"]}
    assert by["slow exact"]["time_ratio"] == 2.0 and math.isclose(by["slow exact"]["error_ratio"], 1e-3)
    assert by["fast"]["time_ratio"] == 0.02 and by["fast"]["pareto"] and by["slow exact"]["pareto"]
    assert by["straightforward"]["pareto"] and not by["stored as float16"]["pareto"]  # no time: never on the front
    png = out / res["plots"]["fake/t"]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (out / "report.md").read_text()
    assert "## fake: a fake part" in md and "a made-up part" in md and "part exploded" in md and "no such device" in md
    assert "| fast | - | 10 ms | 0.02 |" in md and "baseline" in md and "paper Pareto" in md
    assert f"]({res['plots']['fake/t']})" in md


def test_the_report_names_no_local_path(tmp_path, monkeypatch):
    """`hairlut bench --out docs/bench` writes the documentation's bench page: its plots are referenced relatively and
    no absolute path of this machine is in it (the package's folder and the working folder are dropped, the
    temporary folder reads $TMPDIR)."""
    import tempfile
    from pathlib import Path

    import hairlut

    monkeypatch.chdir(tmp_path)
    here = Path(hairlut.__file__).resolve().parent / "bench" / "_run.py"
    scratch = Path(tempfile.gettempdir()) / "hairlut-bench-x" / "db.h5"

    def run(ctx):
        ctx.note("fake", f"read {tmp_path / 'scenes' / 'a.toml'}, code {here}, scratch {scratch}")
        return [_fig("base", 1.0, 1e-2, baseline=True), _fig("fast", 0.5, 2e-2)]

    def boom(ctx):
        raise FileNotFoundError(f"{tmp_path / 'missing.tfx'}")

    run_bench(tmp_path / "docs" / "bench", registry={"fake": Part("fake", "made up", run), "gone": Part("gone", "x", boom)})
    for name in ("report.md", "results.json"):
        text = (tmp_path / "docs" / "bench" / name).read_text()
        assert str(tmp_path) not in text and str(here.parents[2]) not in text, name
        assert "scenes/a.toml" in text and "hairlut/bench/_run.py" in text and "$TMPDIR/hairlut-bench-x/db.h5" in text
        assert "missing.tfx" in text
    md = (tmp_path / "docs" / "bench" / "report.md").read_text()
    assert "](plots/fake-t.png)" in md and (tmp_path / "docs" / "bench" / "plots" / "fake-t.png").is_file()


def test_every_part_can_run_without_the_repository():
    """Only the scale part may be unavailable (it needs two cores); no part needs the clone's benchmarks/ folder."""
    assert set(PARTS) == {"sh", "hair_bsdf", "hrir", "maps", "render", "picture", "shadows", "plan", "scale"}
    assert all(p.unavailable() is None for n, p in PARTS.items() if n != "scale")


def test_bad_only_names_are_refused(tmp_path):
    with pytest.raises(errors.ValidationError, match="nosuch"):
        run_bench(tmp_path, registry=PARTS, only=["sh", "nosuch"])
    from hairlut_cli.main import cli

    r = CliRunner().invoke(cli, ["bench", "--only", "sh,nosuch", "--out", str(tmp_path / "x")])
    assert r.exit_code == 2 and "nosuch" in r.output and "sh" in r.output
    assert not (tmp_path / "x").exists()


def test_strand_transmittance_of_one_strand_across_the_light():
    """One long straight strand across the light, a point straight behind it: Ω is the line integral of
    the normalised 2-D Gaussian across its axis, 1 / (√(2π) σ); a point in front of it sees no hair."""
    from hairlut.geometry import Strands

    x = np.linspace(-50.0, 50.0, 401)
    strand = np.stack([x, np.zeros_like(x), np.zeros_like(x)], 1)[None]
    light, kappa, sigma = np.array([0.0, 0.0, 1.0]), 0.3, 0.25
    pts = np.array([[0.0, 0.0, -1.0], [3.0, 0.1, -2.0], [0.0, 0.0, 1.0], [0.0, 5.0, -1.0]])
    t = strand_transmittance(Strands.from_padded(strand), light, pts, kappa, sigma)
    behind = np.exp(-kappa / (np.sqrt(2 * np.pi) * sigma))
    off = np.exp(-kappa * np.exp(-0.5 * 0.1**2 / sigma**2) / (np.sqrt(2 * np.pi) * sigma))
    np.testing.assert_allclose(t, [behind, off, 1.0, 1.0], rtol=2e-3)


def test_a_real_part_at_its_quick_size(tmp_path):
    res = run_bench(tmp_path, registry=PARTS, only=["hrir"], quick=True)
    assert res["parts"]["hrir"]["status"] == "ok", res["parts"]["hrir"]
    figs = res["figures"]
    base = [f for f in figs if f["baseline"]]
    assert len(base) == 1 and base[0]["label"].startswith("NumPy")
    tracer = [f for f in figs if f["label"].startswith("tracer") and f["seconds"]]
    assert tracer and all(f["error"] > 0 and math.isclose(f["time_ratio"], f["seconds"] / base[0]["seconds"]) for f in tracer)
    assert (tmp_path / "report.md").is_file() and list((tmp_path / "plots").glob("hrir-*.png"))


def _recording_registry(ran: list, interrupt_in: str | None = None) -> dict:
    """Three fake parts that record that they ran; ``interrupt_in`` raises KeyboardInterrupt (Ctrl-C) in that one."""

    def runner(name):
        def run(ctx):
            ran.append(name)
            if name == interrupt_in:
                raise KeyboardInterrupt
            return [Figure(name, "t", "base", 1.0, 1e-2, "err", baseline=True), Figure(name, "t", "fast", 0.5, 2e-2, "err")]

        return run

    return {n: Part(n, f"the {n} part", runner(n)) for n in ("one", "two", "three")}


@pytest.mark.parametrize("only", ["", ",", " , ,"])
def test_an_empty_selection_runs_no_part(tmp_path, monkeypatch, only):
    """m6: `--only ""` and `--only ,` ran every part; they name none, so they are refused in one line naming the value
    and listing the parts, before anything runs or is written."""
    import hairlut.bench
    from hairlut.bench import select
    from hairlut_cli.main import cli

    ran = []
    monkeypatch.setattr(hairlut.bench, "PARTS", _recording_registry(ran))
    r = CliRunner().invoke(cli, ["bench", "--only", only, "--out", str(tmp_path / "x")])
    assert r.exit_code == 2 and ran == [] and not (tmp_path / "x").exists(), r.output
    line = r.output.strip()
    assert "\n" not in line and line.startswith("hairlut: error: --only=") and repr(only) in line
    assert "one, two, three" in line
    with pytest.raises(errors.ValidationError, match="names no part"):
        select(PARTS, [])
    with pytest.raises(errors.ValidationError, match="names no part"):
        run_bench(tmp_path / "y", registry=PARTS, only=only)
    assert [p.name for p in select(PARTS, " sh , hrir")] == ["sh", "hrir"]


def test_ctrl_c_writes_the_finished_parts_report_marked_partial(tmp_path):
    """m7: Ctrl-C during a part wrote no report at all; now report.md and results.json hold the parts that finished,
    marked partial with the part interrupted and the parts not run, and BenchInterrupted (a KeyboardInterrupt) follows."""
    from hairlut.bench import BenchInterrupted

    ran = []
    with pytest.raises(BenchInterrupted) as info:
        run_bench(tmp_path, registry=_recording_registry(ran, interrupt_in="two"))
    assert ran == ["one", "two"] and isinstance(info.value, KeyboardInterrupt)
    doc = json.loads((tmp_path / "results.json").read_text())
    assert doc == json.loads(json.dumps(info.value.results))
    assert doc["partial"] == {"interrupted": "two", "not_run": ["three"]}
    assert {k: v["status"] for k, v in doc["parts"].items()} == {"one": "ok", "two": "interrupted", "three": "not run"}
    assert {f["part"] for f in doc["figures"]} == {"one"} and len(doc["figures"]) == 2
    md = (tmp_path / "report.md").read_text()
    assert "**Partial run**" in md and "`two`" in md and "`three`" in md and "### t" in md
    assert "*not run*" in md and "*interrupted*" in md
    complete = run_bench(tmp_path / "all", registry=_recording_registry([]))
    assert complete["partial"] is None and "Partial" not in (tmp_path / "all" / "report.md").read_text()


def test_ctrl_c_in_the_cli_exits_130_with_one_line(tmp_path, monkeypatch):
    import hairlut.bench
    from hairlut_cli.main import cli

    ran = []
    monkeypatch.setattr(hairlut.bench, "PARTS", _recording_registry(ran, interrupt_in="two"))
    out = tmp_path / "b"
    r = CliRunner().invoke(cli, ["bench", "--out", str(out), "--no-progress"])
    assert r.exit_code == 130 and ran == ["one", "two"], r.output
    line = r.output.strip()
    assert "\n" not in line and "interrupted while two ran" in line and f"{out}/report.md" in line
    assert "for one;" in line and "not run: three" in line
    assert json.loads((out / "results.json").read_text())["partial"]["not_run"] == ["three"]


def test_a_read_only_out_is_refused_before_any_part_runs(tmp_path, monkeypatch, read_only_dir):
    """m5: `bench --out` onto a read-only folder ran every part, then failed on the report; the folder (or where it
    would be made) is now checked first, and the error names the user's path."""
    import hairlut.bench
    from hairlut_cli.main import cli

    ran = []
    monkeypatch.setattr(hairlut.bench, "PARTS", _recording_registry(ran))
    for out in (read_only_dir, read_only_dir / "new" / "bench"):
        r = CliRunner().invoke(cli, ["bench", "--out", str(out), "--no-progress"])
        assert r.exit_code == 2 and ran == [], r.output
        line = r.output.strip()
        assert "\n" not in line and line.startswith(f"hairlut: error: {out}: cannot write") and "Traceback" not in line
    with pytest.raises(errors.AssetError, match="cannot write"):
        run_bench(read_only_dir, registry=_recording_registry(ran))
    assert ran == [] and not (read_only_dir / "new").exists()
