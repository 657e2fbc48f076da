"""Issue 17's list of stress cases (and the cases later issues added), item by item: each item names the cases that cover it and the sweep
constants that must reach the issue's ends (runs no case: tests/test_stress.py runs the quick mode)."""

from __future__ import annotations

import numpy as np

from hairlut import stress
from hairlut.stress import _density, _sh, _shadows

#: issue 17, "hairlut stress", in its order: item -> the cases that cover it.
ITEMS = {
    "SH up to lmax 40 in float32 and float64": ("sh.basis_f32", "sh.basis_f64"),
    "specular exponents 1 to 10,000": ("sh.kk_exponents",),
    "tangents exactly at the poles and along ±x, ±y, ±z": ("sh.tables_poles", "sh.basis_f64", "sh.radiance_f32"),
    "θ′ at 0, π/2 and π": ("sh.kk_exponents", "sh.tables_poles"),
    "non-unit and zero tangents rejected, not NaN": ("sh.bad_tangents",),
    "densities from 0 to 1e6 (α saturating)": ("hrir.densities",),
    "a single strand at a sector's corner": ("hrir.corner_strand",),
    "grazing in-plane angles": ("hrir.grazing",),
    "empty, single-voxel and one-strand grooms": ("shadow.empty_groom", "shadow.single_voxel", "shadow.one_strand"),
    "transmittances that underflow exp()": ("shadow.underflow",),
    "float16 storage of every table": (
        "storage.hrir_db_f16",
        "storage.sh_tables_f16",
        "storage.scene_maps_f16",
        "storage.hair_bsdf_f16",
    ),
    "the same cases on a GPU, where present": ("gpu.float32",),
    "issue 29 m16: the Kajiya–Kay cosine form at t ∥ ω with fractional p": ("sh.kk_cosine_edge",),
}


def test_every_item_of_the_issue_has_its_cases():
    names = stress.case_names()
    for item, cases in ITEMS.items():
        assert set(cases) <= set(names), (item, sorted(set(cases) - set(names)))
    covered = {c for cases in ITEMS.values() for c in cases}
    assert covered == set(names), sorted(set(names) ^ covered)  # no case outside the issue's list, none missing
    for case in stress.CASES:
        assert case.reason and (case.tolerance is None or case.tolerance >= 0), case.name


def test_the_sweeps_reach_the_issues_ends():
    assert _sh.LMAX == 40
    assert min(_sh.EXPONENTS) == 1 and max(_sh.EXPONENTS) == 1e4
    assert min(_sh.EXPONENTS_QUICK) == 1 and max(_sh.EXPONENTS_QUICK) == 1e4
    assert {0.0, np.pi / 2, np.pi} <= set(_sh.THETA_V)
    t = _sh.axis_tangents()
    for axis in np.concatenate([np.eye(3), -np.eye(3)]):
        assert np.any(np.all(t == axis, axis=1)), axis  # exactly on ±x, ±y, ±z (±z: the poles)
    assert min(_density.DENSITIES) == 0 and max(_density.DENSITIES) >= 1e6
    assert any(abs(a - np.pi / 2) < 1e-5 for a in _density.GRAZING)  # tangent to the shell
    assert max(_shadows.UNDERFLOW_KAPPAS) >= 1e6  # exp(−κτ) underflows float64 from κτ ≈ 745: any τ > 1e-3 here


def test_every_table_kind_has_a_float16_case():
    from hairlut.bake import registry

    kinds = registry.kinds()
    assert kinds, "no table kinds registered"
    for kind in kinds:
        assert f"storage.{kind}_f16" in stress.case_names(), kind
