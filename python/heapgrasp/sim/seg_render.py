"""Synthetic RGB images and their 4-class label images from simulated scenes, for the
segmentation network (HEAPGrasp §V: background, transparent, specular, opaque).

The labels are exact: the world renders which object each pixel sees
(:meth:`~heapgrasp.sim.world.SimWorld.capture`, the Rust core's ray casting) and each
object's optical category gives the class. The appearance is composed in image space
from the geometry the world also gives (the depth of every pixel, hence its 3-D point
and surface normal) — not a physically based renderer:

* **table and background** — a random procedural texture (wood-like stripes, checker,
  smooth noise or plain) of a random colour on the table plane, a wall gradient beyond
  it, soft contact shadows around the objects;
* **opaque** — a random hue with a procedural texture (stripes, checker, noise,
  two-tone) fixed to the object's surface points, Lambertian shading and a faint
  highlight;
* **specular** — metallic grey: little diffuse light, a procedural environment seen in
  the mirror direction (bright window bands, a sky gradient) and sharp, bright
  highlights;
* **transparent** — what lies behind (the table) displaced along the surface normal
  (refraction-like), tinted, with bright Fresnel rims, a dark outline and highlights;
* **camera** — random light direction and colour, gain and gamma, vignetting, a slight
  blur and sensor noise.

Everything is drawn from the ``numpy.random.Generator`` passed in, so a seeded world
and generator give the same images. Rendered images are cleaner and more regular than
a real camera's (docs/segmentation.md, "The gap to real images").
"""

from __future__ import annotations

import math
from typing import Any, Final

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.motion import look_at
from heapgrasp.sim.optics import Category
from heapgrasp.sim.world import SimWorld

__all__ = ["CLASSES", "CLASS_IDS", "class_image", "random_view", "render_view", "scaled_camera"]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
U8 = npt.NDArray[np.uint8]

#: Class names in class-id order (the segmentation network's).
CLASSES: Final = ("background", "transparent", "specular", "opaque")
#: Class id of each optical category.
CLASS_IDS: Final = {Category.TRANSPARENT: 1, Category.SPECULAR: 2, Category.OPAQUE: 3}


def scaled_camera(width: int, height: int) -> CameraSpec:
    """The loop's 320×240 camera (:meth:`CameraSpec.continuous`) at another size: the
    same field of view."""
    if width < 16 or height < 16:
        raise ValueError(f"image size must be at least 16x16, got {width}x{height}")
    base = CameraSpec.continuous()
    s = width / base.width
    return CameraSpec(
        width=width,
        height=height,
        fx=base.fx * s,
        fy=base.fy * s,
        cx=(width - 1) / 2,
        cy=(height - 1) / 2,
    )


def class_image(world: SimWorld, labels: npt.NDArray[np.integer[Any]]) -> U8:
    """``(H, W)`` class ids (:data:`CLASSES`) of a frame's object-id image."""
    out = np.zeros(labels.shape, np.uint8)
    for oid, obj in world.objects.items():
        out[labels == oid] = CLASS_IDS[obj.category]
    return out


def random_view(rng: np.random.Generator, cube_size: float = 0.30) -> F64:
    """A camera pose (``cam2world``, OpenCV axes) looking at the scene: polar angle up
    to 60°, any azimuth, 0.3–0.65 m from a point near the cube's low centre, rolled by
    up to ±30° about the optical axis."""
    c = cube_size / 2
    target = np.array([c, c, 0.04]) + rng.uniform(-0.05, 0.05, 3) * np.array([1, 1, 0.5])
    polar = math.radians(rng.uniform(0.0, 60.0))
    azimuth = rng.uniform(0.0, 2 * math.pi)
    dist = rng.uniform(0.30, 0.65)
    eye = target + dist * np.array(
        [math.sin(polar) * math.cos(azimuth), math.sin(polar) * math.sin(azimuth), math.cos(polar)]
    )
    pose = look_at(eye, target)
    roll = math.radians(rng.uniform(-30.0, 30.0))
    cr, sr = math.cos(roll), math.sin(roll)
    rot = np.array([[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]])
    pose[:3, :3] = pose[:3, :3] @ rot
    return pose


# --------------------------------------------------------------------------- textures


def _hsv(h: float, s: float, v: float) -> F32:
    i = int(h * 6.0) % 6
    f = h * 6.0 - math.floor(h * 6.0)
    p, q, t = v * (1 - s), v * (1 - f * s), v * (1 - (1 - f) * s)
    rgb = [(v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q)][i]
    return np.asarray(rgb, np.float32)


def _waves(points: F32, rng: np.random.Generator, n: int, freq: tuple[float, float]) -> F32:
    """Smooth noise in [0, 1]: a sum of ``n`` random plane waves over 3-D points."""
    acc = np.zeros(points.shape[:-1], np.float32)
    for _ in range(n):
        d = rng.standard_normal(3)
        d /= np.linalg.norm(d) + 1e-12
        f = rng.uniform(*freq)
        acc += np.sin(points @ (d * f * 2 * math.pi).astype(np.float32) + rng.uniform(0, 6.3))
    return (0.5 + 0.5 * acc / max(n, 1) * 1.6).clip(0.0, 1.0).astype(np.float32)


def _pattern(points: F32, rng: np.random.Generator, kind: str) -> F32:
    """A texture in [0, 1] over 3-D points (m): ``stripes``, ``checker``, ``noise``,
    ``wood`` or ``plain``."""
    if kind == "plain":
        return np.full(points.shape[:-1], 0.5, np.float32)
    if kind == "noise":
        return _waves(points, rng, 6, (8.0, 60.0))
    d = rng.standard_normal(3)
    d /= np.linalg.norm(d) + 1e-12
    if kind == "stripes":
        f = rng.uniform(20.0, 120.0)
        return (np.sin(points @ (d * f * 2 * math.pi).astype(np.float32)) > 0).astype(np.float32)
    if kind == "checker":
        f = rng.uniform(15.0, 70.0)
        k = np.floor(points * f).astype(np.int64).sum(axis=-1)
        checker: F32 = (k % 2).astype(np.float32)
        return checker
    # wood: stripes warped by smooth noise
    f = rng.uniform(30.0, 90.0)
    warp = _waves(points, rng, 3, (3.0, 12.0)) * 4.0
    return (0.5 + 0.5 * np.sin(points @ (d * f * 2 * math.pi).astype(np.float32) + warp)).astype(
        np.float32
    )


def _environment(r: F32, rng: np.random.Generator) -> F32:
    """A procedural surrounding seen along unit directions ``r`` (``(..., 3)``, world):
    a sky-to-floor gradient, bright window bands and a few lamps (RGB in [0, ~3])."""
    up = r[..., 2:3]
    sky = np.float32(0.25) + np.float32(0.45) * (up + 1) / 2
    env = np.repeat(sky, 3, axis=-1)
    for _ in range(int(rng.integers(1, 4))):
        d = rng.standard_normal(3)
        d[2] = abs(d[2])
        d /= np.linalg.norm(d)
        width = rng.uniform(0.05, 0.25)
        band = np.abs(r @ d.astype(np.float32)) < width
        env = env + band[..., None] * np.float32(rng.uniform(0.6, 1.5))
    for _ in range(int(rng.integers(1, 3))):
        d = rng.standard_normal(3)
        d[2] = abs(d[2]) + 0.5
        d /= np.linalg.norm(d)
        lamp = np.clip((r @ d.astype(np.float32) - 0.97) / 0.03, 0.0, 1.0)
        env = env + lamp[..., None] * np.float32(2.5)
    return env.astype(np.float32)


# --------------------------------------------------------------------------- rendering


def _normals(points: F32, valid: npt.NDArray[np.bool_], eye: F64) -> F32:
    """Unit surface normals (world) from per-pixel 3-D points, facing the camera."""
    du = np.gradient(points, axis=1)
    dv = np.gradient(points, axis=0)
    n = np.cross(du, dv)
    n /= np.linalg.norm(n, axis=-1, keepdims=True) + 1e-12
    view = eye.astype(np.float32) - points
    flip = (n * view).sum(-1) < 0
    n[flip] *= -1
    n[~valid] = (0.0, 0.0, 1.0)
    return n.astype(np.float32)


def render_view(
    world: SimWorld,
    cam2world: F64,
    camera: CameraSpec,
    rng: np.random.Generator,
) -> tuple[U8, U8]:
    """One synthetic frame of ``world`` from ``cam2world``: ``(rgb, classes)``, an
    ``(H, W, 3)`` uint8 image and its ``(H, W)`` uint8 class ids (module docstring)."""
    pose = np.asarray(cam2world, dtype=np.float64)
    frame = world.capture(pose, camera, depth=False)
    ids = frame.labels
    classes = class_image(world, ids)
    h, w = ids.shape
    obj_depth = np.asarray(world.object_scene.render_depth(camera.core(), pose), np.float32)
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    rays = np.stack([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, np.ones_like(u)], -1)
    d_world = (rays @ pose[:3, :3].T).astype(np.float32)
    eye = pose[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        t_table = (-eye[2] / d_world[..., 2]).astype(np.float32)
    on_table = np.isfinite(t_table) & (t_table > 0) & (t_table < 5.0)
    t_table = np.where(on_table, t_table, 0.0).astype(np.float32)
    eye32 = eye.astype(np.float32)
    table_pts = eye32 + d_world * t_table[..., None]
    obj = ids > 0
    obj_pts = eye32 + d_world * obj_depth[..., None]
    view_dir = -d_world / np.linalg.norm(d_world, axis=-1, keepdims=True)

    # lighting
    light = rng.standard_normal(3)
    light[2] = abs(light[2]) + 0.8
    light = (light / np.linalg.norm(light)).astype(np.float32)
    light_rgb = (1.0 + rng.uniform(-0.12, 0.12, 3)).astype(np.float32)
    ambient = np.float32(rng.uniform(0.25, 0.5))
    half = view_dir + light
    half /= np.linalg.norm(half, axis=-1, keepdims=True) + 1e-12

    # table and background
    kind = str(rng.choice(["wood", "checker", "noise", "plain", "stripes"]))
    c1 = _hsv(rng.uniform(0, 1), rng.uniform(0.05, 0.6), rng.uniform(0.35, 0.9))
    c2 = (
        c1 * np.float32(rng.uniform(0.5, 0.9))
        if kind != "checker"
        else _hsv(rng.uniform(0, 1), rng.uniform(0.0, 0.4), rng.uniform(0.15, 0.95))
    )
    tex = _pattern(table_pts, rng, kind)[..., None]
    table = c1 * tex + c2 * (1 - tex)
    table = table * (ambient + (1 - ambient) * max(float(light[2]), 0.2))
    wall = _hsv(rng.uniform(0, 1), rng.uniform(0.0, 0.3), rng.uniform(0.3, 0.8))
    grad = (v / max(h - 1, 1))[..., None].astype(np.float32)
    back = np.where(on_table[..., None], table, wall * (0.7 + 0.3 * grad)).astype(np.float32)
    casts = (classes > 1).astype(np.float32) + np.float32(0.3) * (classes == 1)
    shadow = ndimage.gaussian_filter(casts, sigma=max(h, w) / 60)
    back = back * (1.0 - np.float32(rng.uniform(0.2, 0.5)) * shadow[..., None])
    image = back.copy()

    normals = _normals(obj_pts, obj, eye)
    ndl = np.clip((normals * light).sum(-1), 0.0, 1.0)[..., None]
    ndh = np.clip((normals * half).sum(-1), 0.0, 1.0)[..., None]
    ndv = np.clip((normals * view_dir).sum(-1), 0.0, 1.0)[..., None]

    for oid, sobj in world.objects.items():
        m = ids == oid
        if not m.any():
            continue
        if sobj.category == Category.OPAQUE:
            a = _hsv(rng.uniform(0, 1), rng.uniform(0.3, 0.95), rng.uniform(0.35, 0.95))
            b = (
                a * np.float32(rng.uniform(0.3, 0.8))
                if rng.random() < 0.5
                else _hsv(rng.uniform(0, 1), rng.uniform(0.0, 0.9), rng.uniform(0.2, 1.0))
            )
            pk = str(rng.choice(["stripes", "checker", "noise", "plain", "wood"]))
            pts = obj_pts[m]
            t = _pattern(pts, rng, pk)[:, None]
            albedo = a * t + b * (1 - t)
            spec = np.float32(rng.uniform(0.0, 0.25)) * ndh[m] ** 30
            image[m] = albedo * (ambient + (1 - ambient) * ndl[m]) * light_rgb + spec
        elif sobj.category == Category.SPECULAR:
            n = normals[m]
            vd = view_dir[m]
            r = 2 * (n * vd).sum(-1, keepdims=True) * n - vd
            env = _environment(r.astype(np.float32), rng)
            tint = (np.float32(rng.uniform(0.55, 0.95)) * (1 + rng.uniform(-0.08, 0.08, 3))).astype(
                np.float32
            )
            hi = np.float32(rng.uniform(2.0, 4.0)) * ndh[m] ** float(rng.uniform(80, 300))
            image[m] = tint * (0.08 + 0.12 * ndl[m] + 0.75 * env) * light_rgb + hi
    # transparent last: they show what is behind them (the table here), refracted
    trans = classes == 1
    if trans.any():
        n_cam = normals @ pose[:3, :3].astype(np.float32)  # world → camera axes
        strength = rng.uniform(4.0, 14.0) * w / 320
        du = n_cam[..., 0] * strength + rng.uniform(-2, 2)
        dv = n_cam[..., 1] * strength + rng.uniform(-2, 2)
        su = np.clip(np.round(u + du), 0, w - 1).astype(np.int64)
        sv = np.clip(np.round(v + dv), 0, h - 1).astype(np.int64)
        behind = back[sv, su]
        tint = (1.0 - rng.uniform(0.0, 0.25, 3)).astype(np.float32)
        fresnel = (1.0 - ndv) ** 3
        hi = np.float32(rng.uniform(1.0, 3.0)) * ndh ** float(rng.uniform(60, 200))
        glass = behind * tint * np.float32(rng.uniform(0.75, 0.95)) + 0.6 * fresnel + hi
        edge = trans & ~ndimage.binary_erosion(trans, iterations=1)
        glass[edge] *= np.float32(rng.uniform(0.4, 0.8))
        image[trans] = glass[trans]

    # camera: gain, gamma, vignetting, blur, noise
    gain = np.float32(rng.uniform(0.75, 1.3))
    gamma = float(rng.uniform(0.8, 1.25))
    r2 = ((u - w / 2) / (w / 2)) ** 2 + ((v - h / 2) / (h / 2)) ** 2
    vignette = (1.0 - rng.uniform(0.0, 0.25) * r2 / 2).astype(np.float32)[..., None]
    out = np.clip(image * gain * vignette, 0.0, 1.0) ** np.float32(1.0 / gamma)
    sigma = rng.uniform(0.0, 0.8)
    if sigma > 0.2:
        out = ndimage.gaussian_filter(out, sigma=(sigma, sigma, 0))
    noise = rng.normal(0.0, rng.uniform(0.003, 0.02), out.shape).astype(np.float32)
    rgb = np.clip((out + noise) * 255.0 + 0.5, 0, 255).astype(np.uint8)
    return rgb, classes
