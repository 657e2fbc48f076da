"""The scene's camera: the ``[camera]`` table and its projection (world → clip → pixels).

``[camera]`` keys (every one but ``view`` optional; ``view`` too when ``position`` and ``look_at`` are both given):

``view``        the direction *toward* the viewer (DESIGN.md); the online maps' view angle; missing, with
                ``position`` and ``look_at`` both given, the direction from look_at to position (:func:`derive_view`);
``projection``  ``"orthographic"`` (default) or ``"perspective"``;
``look_at``     the point the camera looks at (default: the centre of the groom's bounds);
``position``    the eye (default: on the line look_at + d·view, d fitted so the groom is in front
                and in frame); given, it must lie on that line (it fixes d);
``up``          the world direction shown upward (default +y; must not be parallel to ``view``);
``fov``         perspective: the vertical field of view in degrees, in (0, 180);
``extent``      orthographic: the height of the frame in world units (default: the groom's projected
                bounds with a 5 % margin, widened to the frame's aspect);
``resolution``  ``[w, h]`` pixels (default 768 × 768), refused when a frame's buffers would not fit
                in the memory budget ($HAIRLUT_MEMORY_LIMIT, default half the machine's memory; the
                estimate is in the message).

:class:`Camera` holds the resolved camera.  Its ``matrix`` is the 4 × 4 world-to-clip matrix in the
OpenGL convention (right-handed eye space looking down −z; clip w = eye distance for a perspective
camera, 1 for an orthographic one; NDC in [−1, 1]); pixel (x, y) of NDC (X, Y) is
((X + 1)/2 · w, (1 − Y)/2 · h): x to the right, y downward from the top row, pixel centres at
integers + ½.  ``depth`` is the eye-space distance along the viewing axis (the EXR ``Z``).

*Precision.*  Both renderers work in float32 world coordinates (the strand render marches rays from the eye;
the rasteriser projects and depth-sorts from it), so a float32 step at the eye's distance D from the hair,
ε₃₂·D, is their resolution there.  :func:`make_camera` refuses, naming the key that placed the eye or the frame
(``position``; ``fov``, whose fitted eye stands at radius / sin(fov/2); ``look_at``; ``extent``):

- an eye so far that ε₃₂·D exceeds 1/16 of the thinnest strand's radius (``position`` 1e12 away; ``fov`` 1e-6,
  which fits the eye 1e8 radii away): the strand render would lose the strands and the rasteriser the depth order;
- a pixel at the nearest hair narrower than 16 such steps (``extent`` 1e-30): neither could place an edge in it.

A frame that is legal but catches no hair (``extent`` 1e30 or ``fov`` 179.9999, where the hair shrinks below a
pixel and no pixel centre falls on it) is a correct, empty frame: α = 0 everywhere, and ``hairlut render`` says so.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .. import budget, errors
from ..recipes import Field
from ..validate import direction

PROJECTIONS = ("orthographic", "perspective")
#: Frame bytes per pixel and sample a render holds at once (RGBA, depth, the per-sample and tile buffers).
BYTES_PER_SAMPLE = 256
#: Most pixels on a side.
MAX_SIDE = 16384
MARGIN = 0.05
#: float32's relative spacing (the renderers' precision, module docstring *Precision*).
FLOAT32_EPS = float(np.finfo(np.float32).eps)
#: A length the frame must show spans at least this many float32 steps (about 1e-3 α RMSE in the strand render).
RESOLVE = 16
#: Without a strand radius, the detail a frame must resolve is the hair's radius over this.
DETAIL = 1024


def _finite3(x, allow_zero=True):
    if (
        not isinstance(x, list)
        or len(x) != 3
        or not all(isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in x)
    ):
        return "need 3 finite numbers"
    if not allow_zero and not any(c != 0 for c in x):
        return "a direction cannot be zero"
    return None


def _auto_or_point(x):
    return None if x == "auto" else _finite3(x)


def _fov(x):
    return None if math.isfinite(x) and 0 < x < 180 else "the vertical field of view lies in (0, 180) degrees"


def _extent(x):
    if x == "auto":
        return None
    if isinstance(x, str) or not (math.isfinite(x) and x > 0):
        return "'auto' (fitted to the groom) or a frame height > 0"
    return None


def _resolution(x):
    if len(x) != 2 or not all(isinstance(c, int) and not isinstance(c, bool) for c in x):
        return "need [w, h]: 2 integers"
    if min(x) < 1:
        return "pixels on a side must be ≥ 1"
    if max(x) > MAX_SIDE:
        return f"at most {MAX_SIDE} pixels on a side"
    return None


CAMERA = {
    "view": Field(None, (list,), lambda x: _finite3(x, allow_zero=False), "direction toward the viewer"),
    "projection": Field(
        "orthographic",
        (str,),
        lambda x: None if x in PROJECTIONS else "'orthographic' or 'perspective'",
        "orthographic or perspective",
    ),
    "position": Field("auto", (list, str), _auto_or_point, "the eye ('auto': on look_at + d·view, fitted)"),
    "look_at": Field("auto", (list, str), _auto_or_point, "the point looked at ('auto': the groom's centre)"),
    "up": Field([0.0, 1.0, 0.0], (list,), lambda x: _finite3(x, allow_zero=False), "world direction shown upward"),
    "fov": Field(40.0, (float, int), _fov, "perspective: vertical field of view, degrees"),
    "extent": Field("auto", (float, int, str), _extent, "orthographic: frame height in world units ('auto': fitted)"),
    "resolution": Field([768, 768], (list,), _resolution, "[w, h] pixels"),
}


def frame_bytes(width: int, height: int, samples: int = 1) -> int:
    """Estimated bytes a render of w × h pixels with ``samples`` per pixel holds at once."""
    return int(width) * int(height) * max(int(samples), 1) * BYTES_PER_SAMPLE


def check_memory(resolution, samples: int = 1, key: str = "camera.resolution") -> None:
    """Refuse a frame whose buffers (:func:`frame_bytes`) exceed the memory budget
    (:func:`hairlut.budget.memory_limit`: ``$HAIRLUT_MEMORY_LIMIT`` or half the machine's memory)."""
    budget.check(key, list(resolution), frame_bytes(*resolution, samples), f"the frame's buffers ({samples} sample(s) per pixel)")


def _unit(x) -> np.ndarray:
    return direction(x, "camera")  # normalised without overflow (view = [1e300, 1e300, 1e300])


def _toward(position, look_at) -> np.ndarray | None:
    """The unit direction from ``look_at`` to ``position`` (None where they coincide), taken without overflow for
    coordinates near the float64 limit."""
    p, q = np.asarray(position, np.float64), np.asarray(look_at, np.float64)
    scale = max(float(np.abs(p).max()), float(np.abs(q).max()), 1e-300)
    d = p / scale - q / scale
    n = float(np.hypot(np.hypot(d[0], d[1]), d[2]))
    return d / n if n > 0 else None


def derive_view(given):
    """The ``[camera]`` table as given, with ``view`` filled in where it is missing and both ``position`` and
    ``look_at`` are points: the unit direction from look_at to position (a perspective camera placed by its eye
    and target needs nothing more).  Where ``view`` is given too, :func:`check_camera` refuses it unless the
    three agree."""
    if not isinstance(given, Mapping) or "view" in given or "position" not in given or "look_at" not in given:
        return given
    if "auto" in (given["position"], given["look_at"]):
        return given
    for key in ("position", "look_at"):
        if reason := _finite3(given[key]):
            raise errors.ValidationError(f"camera.{key}", given[key], reason)
    view = _toward(given["position"], given["look_at"])
    if view is None:
        raise errors.ValidationError("camera.position", given["position"], "equals camera.look_at: no view direction")
    return {**given, "view": view.tolist()}


def check_camera(cam: dict) -> None:
    """Checks across ``[camera]`` keys (each key alone is checked by :data:`CAMERA`): ``up`` not parallel
    to ``view``; a frame that fits in memory; a given ``position`` on the line look_at + d·view, d > 0."""
    view, up = _unit(cam["view"]), _unit(cam["up"])
    if abs(float(view @ up)) > 1.0 - 1e-6:
        raise errors.ValidationError("camera.up", cam["up"], f"parallel to camera.view {cam['view']}: no way to tell up")
    check_memory(cam["resolution"])
    if cam["position"] != "auto" and cam["look_at"] != "auto":
        d = _toward(cam["position"], cam["look_at"])
        if d is None:
            raise errors.ValidationError("camera.position", cam["position"], "equals camera.look_at: no view direction")
        if float(d @ view) < 1.0 - 1e-6:
            raise errors.ValidationError(
                "camera.position",
                cam["position"],
                f"disagrees with camera.view {cam['view']}: "
                f"the eye must lie on camera.look_at {cam['look_at']} + d·view with d > 0 (the "
                f"direction from look_at to position is {np.round(d, 6).tolist()}; give view "
                "or drop it to derive it)",
            )


@dataclass(frozen=True, eq=False)
class Camera:
    """A resolved camera (module docstring): eye, unit ``right``/``up``/``back`` (= view) axes, and the
    frame: ``extent`` (orthographic frame height) or ``fov`` (degrees), ``near``/``far`` and pixels."""

    projection: str
    eye: np.ndarray
    right: np.ndarray
    up: np.ndarray
    back: np.ndarray
    width: int
    height: int
    extent: float
    fov: float
    near: float
    far: float

    @property
    def aspect(self) -> float:
        return self.width / self.height

    @property
    def view_matrix(self) -> np.ndarray:
        m = np.eye(4)
        m[:3, :3] = np.stack([self.right, self.up, self.back])
        m[:3, 3] = -m[:3, :3] @ self.eye
        return m

    @property
    def projection_matrix(self) -> np.ndarray:
        n, f = self.near, self.far
        p = np.zeros((4, 4))
        if self.projection == "perspective":
            c = 1.0 / math.tan(math.radians(self.fov) / 2)
            p[0, 0], p[1, 1] = c / self.aspect, c
            p[2, 2], p[2, 3], p[3, 2] = (f + n) / (n - f), 2 * f * n / (n - f), -1.0
        else:
            h = self.extent / 2
            p[0, 0], p[1, 1] = 1 / (h * self.aspect), 1 / h
            p[2, 2], p[2, 3], p[3, 3] = -2 / (f - n), -(f + n) / (f - n), 1.0
        return p

    @property
    def matrix(self) -> np.ndarray:
        """The 4 × 4 world-to-clip matrix."""
        return self.projection_matrix @ self.view_matrix

    def project(self, points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pixel x, y (float, module docstring) and eye depth of world points (…, 3)."""
        p = np.asarray(points, np.float64)
        clip = np.einsum("ij,...j->...i", self.matrix[:, :3], p) + self.matrix[:, 3]
        ndc = clip[..., :2] / clip[..., 3:4]
        return (ndc[..., 0] + 1) / 2 * self.width, (1 - ndc[..., 1]) / 2 * self.height, self.depth(p)

    def depth(self, points) -> np.ndarray:
        """Distance of ``points`` (…, 3) in front of the eye, along the viewing direction."""
        return (self.eye - np.asarray(points, np.float64)) @ self.back

    def rays(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Origins and unit directions (…, 3) of the rays through pixel coordinates (x, y) (float, pixel centres
        at integers + ½); an orthographic ray starts on the eye plane, a perspective one at the eye."""
        x, y = np.broadcast_arrays(np.asarray(x, np.float64), np.asarray(y, np.float64))
        sx, sy = (2 * x / self.width - 1), (1 - 2 * y / self.height)
        if self.projection == "perspective":
            c = math.tan(math.radians(self.fov) / 2)
            d = (sx * c * self.aspect)[..., None] * self.right + (sy * c)[..., None] * self.up - self.back
            return np.broadcast_to(self.eye, d.shape).copy(), d / np.linalg.norm(d, axis=-1, keepdims=True)
        h = self.extent / 2
        o = self.eye + (sx * h * self.aspect)[..., None] * self.right + (sy * h)[..., None] * self.up
        return o, np.broadcast_to(-self.back, o.shape).copy()

    def to_json(self) -> dict:
        """The camera as a JSON object (projection, resolution, ``world_to_clip`` and the frame): what a render's
        EXR stores as ``hairlut:camera``."""
        return {
            "projection": self.projection,
            "resolution": [self.width, self.height],
            "world_to_clip": self.matrix.tolist(),
            "eye": self.eye.tolist(),
            "right": self.right.tolist(),
            "up": self.up.tolist(),
            "view": self.back.tolist(),
            "extent": self.extent,
            "fov": self.fov,
            "near": self.near,
            "far": self.far,
        }

    @classmethod
    def from_json(cls, d) -> Camera:
        """The camera of a :meth:`to_json` record (an EXR's ``hairlut:camera``), every field checked: its type, finite,
        in range, the axes orthonormal and the stored ``world_to_clip`` the one the fields give.  A ValidationError
        names ``hairlut:camera.<field>`` and the value."""
        return cls(*_record(d))


#: The fields of :meth:`Camera.to_json`, in the order the record is checked.
RECORD_FIELDS = ("projection", "resolution", "eye", "right", "up", "view", "extent", "fov", "near", "far", "world_to_clip")


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _record(d) -> tuple:
    """:class:`Camera`'s fields from a ``to_json`` record (:meth:`Camera.from_json`)."""
    where = "hairlut:camera"
    if not isinstance(d, dict):
        raise errors.ValidationError(where, type(d).__name__, "not a JSON object (a camera record is one)")
    missing = [k for k in RECORD_FIELDS if k not in d]
    if missing:
        raise errors.ValidationError(where, sorted(d)[:12], f"missing field(s) {', '.join(missing)}")

    def bad(key, reason):
        return errors.ValidationError(f"{where}.{key}", d[key], reason)

    if d["projection"] not in PROJECTIONS:
        raise bad("projection", "'orthographic' or 'perspective'")
    if not isinstance(d["resolution"], list) or (reason := _resolution(d["resolution"])):
        raise bad("resolution", "need [w, h]: 2 integers" if not isinstance(d["resolution"], list) else reason)
    axes = {}
    for key in ("eye", "right", "up", "view"):
        if reason := _finite3(d[key], allow_zero=key == "eye"):
            raise bad(key, reason)
        axes[key] = np.asarray(d[key], np.float64)
        if key != "eye" and abs(float(np.linalg.norm(axes[key])) - 1.0) > 1e-6:
            raise bad(key, "an axis of the camera is a unit vector")
    gram = np.stack([axes["right"], axes["up"], axes["view"]])
    if np.abs(gram @ gram.T - np.eye(3)).max() > 1e-6:
        raise bad("right", f"right, up and view must be orthogonal (up {d['up']}, view {d['view']})")
    for key in ("extent", "fov", "near", "far"):
        if not _number(d[key]):
            raise bad(key, "need a finite number")
    if not d["extent"] > 0:
        raise bad("extent", "the frame height must be > 0")
    if reason := _fov(d["fov"]):
        raise bad("fov", reason)
    if not (d["near"] > 0 if d["projection"] == "perspective" else d["near"] >= 0):
        raise bad("near", "the near plane lies in front of the eye (> 0; ≥ 0 orthographic)")
    if not d["far"] > d["near"]:
        raise bad("far", f"the far plane lies beyond the near plane ({d['near']})")
    w, h = d["resolution"]
    cam = (
        d["projection"],
        axes["eye"],
        axes["right"],
        axes["up"],
        axes["view"],
        w,
        h,
        float(d["extent"]),
        float(d["fov"]),
        float(d["near"]),
        float(d["far"]),
    )
    m = d["world_to_clip"]
    if not (isinstance(m, list) and len(m) == 4 and all(isinstance(r, list) and len(r) == 4 and all(map(_number, r)) for r in m)):
        raise bad("world_to_clip", "need a 4 x 4 matrix of finite numbers")
    want = Camera(*cam).matrix
    if not np.allclose(np.asarray(m, np.float64), want, rtol=1e-6, atol=1e-9 * float(np.abs(want).max())):
        raise bad("world_to_clip", "not the matrix the record's eye, axes and frame give")
    return cam


def make_camera(cam: dict, points, detail: float | None = None) -> Camera:
    """The :class:`Camera` of a resolved ``[camera]`` table, fitted to the hair's ``points`` (n, 3) where
    keys are 'auto'.  Raises when a given eye lies inside the hair's bounds (or, perspective, any hair lies
    behind the near plane), and when float32 cannot draw the frame (module docstring, *Precision*; ``detail``:
    the smallest length the frame must resolve, the thinnest strand's radius; default the hair's radius / 1024)."""
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    lo, hi = pts.min(0), pts.max(0)
    back = _unit(cam["view"])
    right = np.cross(_unit(cam["up"]), back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    w, h = cam["resolution"]
    aspect = w / h
    given_eye = cam["position"] != "auto"
    centre = 0.5 * (lo + hi) if cam["look_at"] == "auto" else np.asarray(cam["look_at"], np.float64)
    if cam["look_at"] == "auto" and given_eye:  # the look_at point on the line through the eye along view
        eye = np.asarray(cam["position"], np.float64)
        centre = eye - back * float((eye - 0.5 * (lo + hi)) @ back)
    rel = pts - centre
    along = rel @ back  # toward the viewer
    radius = float(np.linalg.norm(rel, axis=1).max()) or 1.0
    if cam["projection"] == "orthographic":
        xs, ys = rel @ right, rel @ up
        ext = cam["extent"]
        if ext == "auto":
            ext = (1 + 2 * MARGIN) * max(2 * np.abs(ys).max(), 2 * np.abs(xs).max() / aspect, 1e-12)
        dist = (
            float(along.max()) + MARGIN * radius + 1e-9
            if not given_eye
            else float((np.asarray(cam["position"], np.float64) - centre) @ back)
        )
        fov = float(cam["fov"])
    else:
        fov = float(cam["fov"])
        half = math.radians(fov) / 2
        half = min(half, math.atan(math.tan(half) * aspect))
        dist = (
            radius * (1 + MARGIN) / math.sin(half)
            if not given_eye
            else float((np.asarray(cam["position"], np.float64) - centre) @ back)
        )
        ext = float(cam["extent"]) if cam["extent"] != "auto" else 2 * dist * math.tan(math.radians(fov) / 2)
    eye = centre + back * dist
    # a given eye inside the hair's box is refused; the fitted one lies past every strand along the view (orthographic:
    # just past the nearest point, which for an oblique view can be inside the axis-aligned box but never in the hair)
    if given_eye and np.all((eye >= lo) & (eye <= hi)):
        raise errors.ValidationError("camera.position", eye.tolist(), f"inside the hair's bounds {lo.tolist()}–{hi.tolist()}")
    depth = (eye - pts) @ back
    near_need = float(depth.min())
    if near_need <= 0:
        raise errors.ValidationError("camera.position", eye.tolist(), "hair lies behind the camera")
    near = near_need * 0.5 if cam["projection"] == "perspective" else 0.0
    far = float(depth.max()) * 1.5 + 1e-9
    camera = Camera(cam["projection"], eye, right, up, back, int(w), int(h), float(ext), fov, near, far)
    _check_precision(
        cam,
        camera,
        pts,
        centre,
        near_need,
        *(
            (radius / DETAIL, f"the hair's radius / {DETAIL}")
            if detail is None
            else (float(detail), "the thinnest strand's radius")
        ),
    )
    return camera


def _check_precision(
    cam: dict, camera: Camera, pts: np.ndarray, centre: np.ndarray, nearest: float, detail: float, what: str
) -> None:
    """Refuse a camera the float32 renderers cannot draw (module docstring, *Precision*), naming the key that put
    the eye or the frame there: float32's spacing at the eye's distance from the farthest hair must be at most
    ``detail`` / :data:`RESOLVE`, and at most a 1 / :data:`RESOLVE` of a pixel at the nearest hair."""
    reach = float(np.linalg.norm(camera.eye - pts, axis=1).max())
    spacing = FLOAT32_EPS * reach
    if spacing * RESOLVE > detail:  # the eye is given far away, or fitted far for a tiny fov, or beside a far look_at
        fitted = float(np.linalg.norm(camera.eye - centre))
        key = (
            "position"
            if cam["position"] != "auto"
            else "fov"
            if camera.projection == "perspective" and FLOAT32_EPS * RESOLVE * fitted > detail
            else "look_at"
        )
        raise errors.ValidationError(
            f"camera.{key}",
            cam[key],
            f"puts the eye {reach:.3g} from the hair: float32 (the "
            f"renderers' precision) then resolves only {spacing:.2g} there, coarser than "
            f"1/{RESOLVE} of the detail the frame must show ({detail:.2g}, {what}); keep the eye within {detail / (RESOLVE * FLOAT32_EPS):.3g} of the hair"
            + (" (a wider fov fits it closer)" if key == "fov" else ""),
        )
    if camera.projection == "perspective":
        pixel = 2 * nearest * math.tan(math.radians(camera.fov) / 2) / camera.height
        key = "position" if cam["position"] != "auto" else "fov"
    else:
        pixel, key = camera.extent / camera.height, "extent"
    if spacing * RESOLVE > pixel:
        raise errors.ValidationError(
            f"camera.{key}",
            cam[key],
            f"makes a pixel {pixel:.2g} wide at the hair, but float32 "
            f"(the renderers' precision) steps by {spacing:.2g} at {reach:.3g} from the eye, and "
            f"a pixel must span {RESOLVE} steps",
        )
