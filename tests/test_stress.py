"""hairlut stress: the quick mode passes every case (so CI runs it), and the harness can fail."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from hairlut import errors, stress
from hairlut_cli.main import cli


@pytest.fixture(scope="module")
def quick():
    return stress.run_stress(quick=True)


def test_quick_mode_passes_every_case(quick):
    assert quick.passed, "\n" + quick.table()
    names = [r.name for r in quick.results]
    assert names == stress.case_names()
    for area in ("sh", "hrir", "shadow", "storage", "gpu"):
        assert any(n.startswith(area + ".") for n in names), area
    for r in quick.results:
        assert r.status in ("pass", "skip"), r
        assert r.reason and r.non_finite == 0 and r.out_of_bounds == 0 and not r.faults, r
        if r.status == "pass" and r.tolerance is not None and r.worst is not None:
            assert r.worst <= r.tolerance


def test_gpu_row_says_so_without_a_gpu(quick):
    gpu = next(r for r in quick.results if r.area == "gpu")
    if quick.machine["gpu"]:
        assert gpu.status == "pass"
    else:
        assert gpu.status == "skip" and "no GPU present" in gpu.notes[0]
        assert "(no GPU present)" in quick.table()


def test_table_and_json_carry_every_case(quick):
    table = quick.table()
    assert table.count("\n| ") == len(quick.results) + 1  # header + one row per case
    d = json.loads(json.dumps(quick.as_dict()))
    assert d["passed"] and d["quick"] and len(d["cases"]) == len(quick.results)
    assert {"cpu", "backend", "jax", "numpy"} <= set(d["machine"])
    assert all(c["tolerance_reason"] for c in d["cases"])


def test_cli_json():
    out = CliRunner().invoke(cli, ["stress", "--quick", "--json", "--only", "sh.bad_tangents,gpu"])
    assert out.exit_code == 0, out.output
    d = json.loads(out.stdout)
    assert d["passed"] and [c["name"] for c in d["cases"]] == ["sh.bad_tangents", "gpu.float32"]


def test_a_wrong_reference_makes_a_case_fail():
    """The disc's opacity law, off by 1e-5: the tracer now disagrees by more than the tolerance."""
    case = next(c for c in stress.CASES if c.name == "hrir.densities")
    assert stress.run_case(case, quick=True).passed
    wrong = stress.run_case(case, quick=True, reference=lambda *a: np.clip(case.reference(*a) - 1e-5, 0, 1))
    assert wrong.status == "fail" and wrong.worst > case.tolerance


def test_a_wrong_storage_reference_fails():
    case = next(c for c in stress.CASES if c.name == "storage.hrir_db_f16")
    wrong = stress.run_case(case, quick=True, reference=lambda half, x: 2 * case.reference(half, x) + 1e-3)
    assert wrong.status == "fail"


def test_tally_counts_nan_bounds_and_accepted_bad_input():
    case = stress.Case("x.y", "toy", 1e-6, "toy", None, lambda t, c: None)
    t = stress.Tally(case.tolerance)
    t.finite("nan", [1.0, np.nan, np.inf])
    assert t.non_finite == 2 and t.result(case, 0.0).status == "fail"
    t = stress.Tally(case.tolerance)
    t.within("alpha", [0.0, 0.5, 1.0 + 1e-3], 0.0, 1.0)
    assert t.out_of_bounds == 1 and t.result(case, 0.0).status == "fail"
    t = stress.Tally(case.tolerance)
    t.rejects("accepts", lambda: np.array([np.nan]))
    assert t.result(case, 0.0).status == "fail" and "NaN" in t.faults[0]
    t = stress.Tally(case.tolerance)
    t.rejects("rejects", lambda: (_ for _ in ()).throw(errors.ValidationError("t", 0, "zero")))
    t.compare("close", [1.0 + 1e-7], [1.0])
    assert t.result(case, 0.0).status == "pass"
    t.compare("far", [1.1], [1.0])
    assert t.result(case, 0.0).status == "fail"


def test_a_raising_case_fails_and_the_run_goes_on():
    def boom(tally, ctx):
        raise RuntimeError("boom")

    r = stress.run_case(stress.Case("x.boom", "raises", 1.0, "toy", None, boom))
    assert r.status == "fail" and "boom" in r.faults[0]


def test_bad_usage():
    with pytest.raises(errors.ValidationError, match="only"):
        stress.run_stress(only=["nonsense"])
    with pytest.raises(errors.ValidationError, match="references"):
        stress.run_stress(only=["gpu"], references={"nonsense": abs})
    res = CliRunner().invoke(cli, ["stress", "--only", "nonsense"])
    assert res.exit_code == 2 and "only" in res.output and len(res.output.strip().splitlines()) == 1


def test_cli_exit_status_is_1_when_a_case_fails(monkeypatch):
    failed = stress.Result("x.y", "x", "fail", 1.0, 0.1, "toy", 0, 0, {}, ("too far",), (), 0.0)
    report = stress.Report((failed,), True, {"cpu": "c", "cores": 1, "jax": "j", "backend": "cpu", "gpu": False}, 0.0)
    monkeypatch.setattr(stress, "run_stress", lambda **kw: report)
    res = CliRunner().invoke(cli, ["stress", "--quick", "--no-progress"])
    assert res.exit_code == 1 and "| x.y |" in res.output and "fail" in res.output
