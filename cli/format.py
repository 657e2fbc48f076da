"""Human-readable rendering of ``hairlut.assets.summarize`` output."""

from __future__ import annotations

import json


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
            lines.append(f"      storage: chunks {ds['chunks']}, {ds['compression']}, fletcher32 {'on' if ds['fletcher32'] else 'off'}")
    else:
        lines.append(f"{summary['path']}  (OpenEXR image, {len(summary['parts'])} part{'s' if len(summary['parts']) > 1 else ''})")
        lines.append(f"  kind      {summary['kind'] or '-'}")
        lines.append(f"  checksum  {summary['checksum']}")
        _recipe(lines, summary)
        for part in summary["parts"]:
            h, w = part["shape"]
            comp = str(part["header"].get("compression", "?")).replace("Compression.", "")
            lines.append(f"  part {part['name'] or '(single)'}  {w}×{h}  {comp}")
            for ch in part["channels"]:
                lines.append(f"    {ch['name']:<16} {ch['dtype']:<8} {_stats(ch)}")
    return "\n".join(lines)
