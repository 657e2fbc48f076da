"""Human-readable rendering of ``hairlut.assets.summarize`` output."""

from __future__ import annotations

import json
import math


def num(x) -> str:
    if x is None:
        return "-"
    if isinstance(x, float):
        return f"{x:.6g}"
    return str(x)


def _stats(d: dict) -> str:
    return f"min {num(d['min'])}  max {num(d['max'])}  mean {num(d['mean'])}  nan {d['nan']}  inf {d['inf']}"


def _recipe(lines: list[str], summary: dict) -> None:
    if summary.get("recipe") is None:
        lines.append("  recipe    (none)")
        return
    lines.append(f"  recipe    sha256 {summary['recipe_hash']}")
    lines.extend("    " + line for line in json.dumps(summary["recipe"], indent=2, sort_keys=True).splitlines())


def _attribute(lines: list[str], key: str, value: str) -> None:
    """A further ``hairlut:<name>`` header attribute: JSON text indented (an atlas layout, a camera), else as is."""
    try:
        doc = json.loads(value)
    except ValueError:
        doc = None
    if not isinstance(doc, dict):
        lines.append(f"  attr      {key} = {value}")
        return
    lines.append(f"  attr      {key}")
    lines.extend("    " + line for line in json.dumps(doc, indent=2, sort_keys=True).splitlines())


def render(summary: dict) -> str:
    lines = []
    if summary["format"] == "hdf5":
        lines.append(f"{summary['path']}  (HDF5 table)")
        lines.append(f"  kind      {summary['kind']}" + (f"  ({summary['description']})" if summary.get("description") else ""))
        lines.append(f"  schema    {summary['schema']}   written by hairlut {summary['hairlut_version']} at {summary['created']}")
        _recipe(lines, summary)
        for key, value in summary.get("attrs", {}).items():
            lines.append(f"  attr      {key} = {value}")
        if summary["axes"]:
            lines.append("  axes")
            for name, ax in summary["axes"].items():
                periodic = "  periodic" if ax["periodic"] else ""
                lines.append(
                    f"    {name:<14} {ax['size']:>7}  [{num(ax['min'])}, {num(ax['max'])}] {ax['units']}{periodic}  ({ax['long_name']})"
                )
        lines.append("  datasets")
        for ds in summary["datasets"]:
            shape = "×".join(map(str, ds["shape"])) or "scalar"
            lines.append(f"    {ds['name']}  {shape} {ds['dtype']}  dims ({', '.join(ds['dims'])})  units {ds['units'] or '-'}")
            lines.append(f"      {ds['long_name']}")
            lines.append(f"      {_stats(ds)}")
            lines.append(
                f"      storage: chunks {ds['chunks']}, {ds['compression']}, fletcher32 {'on' if ds['fletcher32'] else 'off'}"
            )
    else:
        lines.append(
            f"{summary['path']}  (OpenEXR image, {len(summary['parts'])} part{'s' if len(summary['parts']) > 1 else ''})"
        )
        lines.append(f"  kind      {summary['kind'] or '-'}")
        lines.append(f"  checksum  {summary['checksum']}")
        _recipe(lines, summary)
        for key, value in summary.get("attributes", {}).items():
            _attribute(lines, key, value)
        for part in summary["parts"]:
            h, w = part["shape"]
            comp = str(part["header"].get("compression", "?")).replace("Compression.", "")
            lines.append(f"  part {part['name'] or '(single)'}  {w}×{h}  {comp}")
            for ch in part["channels"]:
                lines.append(f"    {ch['name']:<16} {ch['dtype']:<8} {_stats(ch)}")
    return "\n".join(lines)


def json_safe(value):
    """``value`` with every non-finite float as the string "NaN", "Infinity" or "-Infinity" (JSON has none)."""
    if isinstance(value, float) and not math.isfinite(value):
        return "NaN" if math.isnan(value) else ("Infinity" if value > 0 else "-Infinity")
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value


def dumps(value) -> str:
    """Strict JSON (RFC 8259) of an inspect summary: non-finite numbers become strings."""
    return json.dumps(json_safe(value), indent=2, allow_nan=False)
