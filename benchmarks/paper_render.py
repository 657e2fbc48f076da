"""The layered render of the paper-scale procedural model at 1024 × 1024 (issue 13's target: ≤ 100 ms on a 2-core
CPU, maps excluded).

    python -m benchmarks.paper_render [--resolution 1024] [--texels 64] [--frames 5]

The model is ``hairlut.bench.ring_model`` (17 clusters × 3 layers, s_t = 64, s_u = 16, ``--texels``² texels per
layer, direct maps).  Timed: the maps (first call with compile, then warm), the camera pass (``draw_layers``' plan,
once per camera and geometry), the frame (``draw_plan``: texturing and composite, the best of ``--frames`` warm
calls, wall and process time; compile separate), and the one-pass reference rasteriser (``rasterise``) on the same
textures: its warm time as a ratio to the frame's, and the largest difference between the two frames.  The camera
renders of the vendored grooms against the strand reference are the render part of ``hairlut bench``
(``hairlut.bench.render_study``).  Prints a table and writes results/paper_render.json.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from hairlut.bench import ring_model

from ._common import best_wall_cpu, save, table


def paper_model(resolution: int, texels: int = 64, frames: int = 5) -> dict:
    """The figures of the module docstring for one frame size ``resolution``²."""
    from hairlut.geometry import ClusterGeometry
    from hairlut.render import draw_layers, draw_plan, layer_textures, layout, lengthen, oblique_path, rasterise, scene_camera
    from hairlut.scene import resolve_scene
    from hairlut.synth import prepare, render_view

    cfg = ring_model(17, 64, 16, texels, 200)
    cfg["render"]["method"] = "direct"
    cfg["camera"]["resolution"] = [resolution, resolution]
    prep = prepare(resolve_scene(cfg, "paper-scale model"))
    t0 = time.perf_counter()
    result = render_view(prep)
    maps_first = time.perf_counter() - t0
    maps, _ = best_wall_cpu(lambda: render_view(prep), 1)
    cam = scene_camera(prep.scene)
    meshes, tile, origins, _ = layout(cam, ClusterGeometry([pc.spec for pc in prep.clusters]))
    tex = lengthen(
        layer_textures(result),
        oblique_path(cam, np.stack([pc.tangent for pc in prep.clusters]), np.stack([pc.position for pc in prep.clusters])),
    )
    args = (cam, meshes.vertices, meshes.triangles, meshes.uv)
    rgba, _, sec, plan = draw_layers(*args, tex, tile=tile, origins=origins)
    plan_s, plan_cpu = best_wall_cpu(lambda: draw_layers(*args, tex, tile=tile, origins=origins), 1)  # warm camera pass
    frame, frame_cpu = best_wall_cpu(lambda: draw_plan(plan, tex), frames)
    old_rgba, _, old_sec, _ = rasterise(*args, tex, tile=tile, origins=origins, repeat=2)
    _, old_cpu = best_wall_cpu(lambda: rasterise(*args, tex, tile=tile, origins=origins), 1)
    print(
        f"  paper-scale {resolution}²: {plan.info['fragments']:,} fragments in {plan.info['slabs']} slabs over "
        f"{plan.info['pixels']:,} pixels; frame {1e3 * frame:.0f} ms (cpu {1e3 * frame_cpu:.0f} ms), one-pass "
        f"{1e3 * old_sec['raster']:.0f} ms, camera pass {plan_s:.1f} s, maps {maps:.1f} s"
    )
    return {
        "scene": "paper-scale",
        "method": "layered direct",
        "resolution": resolution,
        "texels": texels,
        "frame_ms": 1e3 * frame,
        "cpu_ms": 1e3 * frame_cpu,
        "compile_s": sec["raster_first"] - frame,
        "camera_pass_ms": 1e3 * plan_s,
        "camera_pass_cpu_ms": 1e3 * plan_cpu,
        "one_pass_ms": 1e3 * old_sec["raster"],
        "one_pass_compile_s": old_sec["raster_first"] - old_sec["raster"],
        "one_pass_ratio": old_sec["raster"] / frame,
        "one_pass_cpu_ms": 1e3 * old_cpu,
        "one_pass_cpu_ratio": old_cpu / frame_cpu,
        "max_abs_diff_one_pass": float(np.abs(rgba - old_rgba).max()),
        "maps_ms": 1e3 * maps,
        "maps_first_ms": 1e3 * maps_first,
        "fragments": plan.info["fragments"],
        "triangles": int(meshes.triangles.shape[0] * tex.shape[0] * tex.shape[1]),
        "target_ms": 100.0,
        "ratio_to_target": frame / 0.1,
    }


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resolution", type=int, default=1024, help="the frame's side (default 1024)")
    ap.add_argument("--texels", type=int, default=64, help="the model's texels per layer side")
    ap.add_argument("--frames", type=int, default=5, help="best of this many warm frames")
    a = ap.parse_args(argv)
    row = paper_model(a.resolution, a.texels, a.frames)
    print("\nPaper-scale layered render (frame: texturing and composite for a planned camera; maps separate):")
    print(
        table(
            [row],
            [
                ("resolution", "px", ""),
                ("texels", "texels", ""),
                ("fragments", "fragments", ","),
                ("frame_ms", "frame ms", ".0f"),
                ("cpu_ms", "frame cpu ms", ".0f"),
                ("compile_s", "compile s", ".1f"),
                ("one_pass_ms", "one-pass ms", ".0f"),
                ("one_pass_ratio", "one-pass / frame", ".1f"),
                ("one_pass_cpu_ms", "one-pass cpu ms", ".0f"),
                ("one_pass_cpu_ratio", "cpu ratio", ".1f"),
                ("camera_pass_ms", "camera pass ms", ".0f"),
                ("maps_ms", "maps ms", ".0f"),
                ("max_abs_diff_one_pass", "max |Δ| vs one-pass", ".1e"),
            ],
        )
    )
    save("paper_render", {"rows": [row], "resolution": a.resolution, "texels": a.texels})
    return row


if __name__ == "__main__":
    main()
