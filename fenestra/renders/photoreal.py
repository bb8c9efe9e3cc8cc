"""mitsuba 3 backend: path-traced daylight RGB (sky environment + sun), same materials roughly.

The instance map, depth, per-window ground truth and ignore regions come from the same exact occluder pass as
the raster backend (:func:`renders.raster.ground_truth`), so both backends share one definition.
Variant: ``llvm_ad_rgb`` (with ``DRJIT_LIBLLVM_PATH`` pointed at libLLVM 19 if present), falling
back to ``scalar_rgb``. ``RenderSettings.denoise="oidn"`` renders through a box pixel filter (OIDN
needs uncorrelated per-pixel noise) and runs Intel Open Image Denoise's RT filter on the linear HDR
radiance before the sRGB encoding; "oidn-aov" also renders albedo and shading-normal AOVs with the
same samples (mitsuba's ``aov`` integrator around the path tracer) as the denoiser's guides. OIDN is
deterministic for a given input (mitsuba's LLVM variant itself differs between runs in the last
float bits). ``python tools/photoreal_cost.py`` measures the cost and the effect.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from fenestra.renders.base import RenderOutput, RenderSettings
from fenestra.renders.camera import Camera, distort_image
from fenestra.renders.materials import Look, SceneGeometry, group_scene, sample_look, sky_colour, sun_direction
from fenestra.renders.raster import OccluderPass
from fenestra.scenes.model import Scene

AOVS = "albedo:albedo,nn:sh_normal"  # channels 3:6 and 6:9 of the aov integrator's output
LLVM_CANDIDATES = ("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1", "/usr/lib/x86_64-linux-gnu/libLLVM-19.so")
CV_TO_MITSUBA = np.diag([-1.0, -1.0, 1.0])  # mitsuba cameras: x left, y up, z forward


def import_mitsuba(variant: str = "auto"):
    """Import mitsuba with ``variant`` ("auto": llvm_ad_rgb if it works, else scalar_rgb)."""
    if "DRJIT_LIBLLVM_PATH" not in os.environ:
        for p in LLVM_CANDIDATES:
            if Path(p).exists():
                os.environ["DRJIT_LIBLLVM_PATH"] = p
                break
    import mitsuba as mi  # noqa: PLC0415 (mitsuba: imported when first used, not at the package's import)

    if variant != "auto":
        if variant not in mi.variants():
            raise ValueError(f"unknown mitsuba variant {variant!r}; available: {mi.variants()}")
        mi.set_variant(variant)
        return mi
    try:
        mi.set_variant("llvm_ad_rgb")
        mi.Float([1.0])  # forces the LLVM backend to initialise
    except Exception:  # noqa: BLE001 - any failure of the JIT backend means: use the scalar one
        mi.set_variant("scalar_rgb")
    return mi


def mitsuba_sensor(mi, cam: Camera, spp: int, rfilter: str = "gaussian") -> dict:
    """Perspective sensor dict matching a pinhole Camera (square pixels, any principal point)."""
    if cam.dist is not None:
        raise ValueError("mitsuba draws pinhole cameras only; pass camera.canvas()")
    K = cam.K
    if abs(K[0, 0] - K[1, 1]) > 1e-9 * K[0, 0] or abs(K[0, 1]) > 1e-12:
        raise ValueError(f"mitsuba needs square pixels and no skew, got fx={K[0, 0]}, fy={K[1, 1]}, skew={K[0, 1]}")
    W, H = cam.width, cam.height
    fov = float(np.degrees(2 * np.arctan(W / 2 / K[0, 0])))
    M = np.eye(4)
    M[:3, :3] = cam.R.T @ CV_TO_MITSUBA
    M[:3, 3] = cam.center
    return {"type": "perspective", "fov": fov, "fov_axis": "x",
            # mitsuba's offsets are fractions of the film size, positive = principal point left/up
            "principal_point_offset_x": float(-(K[0, 2] - (W - 1) / 2) / W),
            "principal_point_offset_y": float(-(K[1, 2] - (H - 1) / 2) / H),
            "near_clip": 0.05, "far_clip": 5000.0, "to_world": mi.ScalarTransform4f(M.tolist()),
            "sampler": {"type": "independent", "sample_count": spp},
            "film": {"type": "hdrfilm", "width": W, "height": H, "pixel_format": "rgb",
                     "rfilter": {"type": rfilter}}}


def mesh_object(mi, name: str, vertices: np.ndarray, faces: np.ndarray, bsdf: dict | None = None,
                uvs: np.ndarray | None = None, emitter: dict | None = None):
    """A mitsuba Mesh from numpy arrays (vertices (N, 3) m, faces (M, 3), uvs (N, 2))."""
    props = mi.Properties()
    if bsdf is not None:
        props["bsdf"] = mi.load_dict(bsdf)
    if emitter is not None:
        props["emitter"] = mi.load_dict(emitter)
    mesh = mi.Mesh(name, len(vertices), len(faces), props, has_vertex_texcoords=uvs is not None)
    p = mi.traverse(mesh)
    p["vertex_positions"] = mi.Float(np.asarray(vertices, np.float32).ravel())
    p["faces"] = mi.UInt32(np.asarray(faces, np.uint32).ravel())
    if uvs is not None:
        p["vertex_texcoords"] = mi.Float(np.asarray(uvs, np.float32).ravel())
    p.update()
    return mesh


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def oidn_denoise(color: np.ndarray, albedo: np.ndarray | None = None,
                 normal: np.ndarray | None = None) -> np.ndarray:
    """Open Image Denoise (RT filter, hdr, quality "high") of linear radiance (H, W, 3), optionally
    guided by albedo (H, W, 3) in [0, 1] and normals (H, W, 3) in [-1, 1] (noisy: OIDN prefilters them)."""
    import pyoidn  # noqa: PLC0415 (pyoidn: imported when first used)

    f32 = lambda a, lo, hi: None if a is None else np.ascontiguousarray(np.clip(a, lo, hi), np.float32)  # noqa: E731
    return pyoidn.denoise(f32(color, 0.0, None), f32(albedo, 0.0, 1.0), f32(normal, -1.0, 1.0),
                          hdr=True, quality="high")


def glass_diffuse(look: Look) -> list[float]:
    """The glass BSDF's diffuse (the room behind): [0.01, 0.012, 0.015] for the classic look,
    scaled by the look's interior relative to the classic interior and by its tint."""
    scale = np.asarray(look.glass_interior) / np.asarray(Look.glass_interior)
    return (np.array([0.01, 0.012, 0.015]) * scale * np.asarray(look.glass_tint)).tolist()


class PhotorealRenderer:
    """mitsuba backend: ``render(camera) -> RenderOutput``; the scene is built once. like: another
    renderer of the same scene (another look) whose materials.SceneGeometry and occluder pass this one shares
    (as renders.raster.RasterRenderer's ``like``)."""

    name = "mitsuba"

    def __init__(self, scene: Scene, settings: RenderSettings = RenderSettings(),
                 like: "PhotorealRenderer | None" = None):
        self.mi = mi = import_mitsuba(settings.variant)
        self.scene, self.settings = scene, settings
        rng = np.random.default_rng(settings.seed)
        self.look = look = sample_look(rng, settings.look)  # same draws as the raster backend: same palette
        self.geometry = SceneGeometry(scene) if like is None else like.geometry
        groups = group_scene(scene, look, rng, self.geometry)
        objs = {}
        for i, g in enumerate(groups):
            m = g.material
            if m.texture is not None:
                refl = {"type": "bitmap", "bitmap": mi.Bitmap((srgb_to_linear(m.texture.astype(np.float32) / 255.0)
                        * np.asarray(m.rgb, np.float32)).astype(np.float32)), "raw": True, "wrap_mode": "repeat"}
            else:
                refl = {"type": "rgb", "value": srgb_to_linear(np.asarray(m.rgb)).tolist()}
            if m.kind == "glass":
                bsdf = {"type": "plastic", "diffuse_reflectance": {"type": "rgb", "value": glass_diffuse(look)},
                        "int_ior": 1.5}
            else:
                bsdf = {"type": "twosided", "material": {"type": "diffuse", "reflectance": refl}}
            objs[f"g{i}"] = mesh_object(mi, f"g{i}", g.vertices, g.faces, bsdf, g.uvs)
        # sky: equirectangular environment from the same gradient as the raster sky, + the sun
        h, w = 64, 128
        theta = (np.arange(h) + 0.5) / h * np.pi  # from +y (mitsuba envmap up) down
        phi = (np.arange(w) + 0.5) / w * 2 * np.pi
        th, ph = np.meshgrid(theta, phi, indexing="ij")
        d_env = np.stack([np.sin(th) * np.cos(ph), np.cos(th), np.sin(th) * np.sin(ph)], -1)  # y up
        sky = srgb_to_linear(sky_colour(np.stack([d_env[..., 0], d_env[..., 2], d_env[..., 1]], -1), look))
        sky[d_env[..., 1] < 0] = 0.05
        env_to_world = np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, 1, 0, 0], [0, 0, 0, 1]], float)  # y up -> z up
        objs["sky"] = {"type": "envmap", "bitmap": mi.Bitmap(sky.astype(np.float32)), "scale": 1.0,
                       "to_world": mi.ScalarTransform4f(env_to_world.tolist())}
        sun = sun_direction(look)
        objs["sun"] = {"type": "directional", "direction": (-sun).tolist(),
                       "irradiance": {"type": "rgb", "value": (np.array([1.0, 0.95, 0.85]) * np.asarray(look.sun_tint)
                                                         * look.sun_intensity).tolist()}}
        objs["type"] = "scene"
        objs["integrator"] = {"type": "path", "max_depth": settings.max_depth}
        self._scene = mi.load_dict(objs)
        self._aov = None if settings.denoise != "oidn-aov" else mi.load_dict(
            {"type": "aov", "aovs": AOVS, "inner": objs["integrator"]})
        shared = None if like is None else like.occluders.share(like.occluders.positions)  # the scene's own order
        self.occluders = shared or OccluderPass(scene)

    def render_linear(self, canvas: Camera, spp: int | None = None, seed: int | None = None,
                      denoise: bool = True) -> np.ndarray:
        """(H, W, 3) float32 linear radiance of a pinhole camera, denoised if settings.denoise says
        so and ``denoise``; spp/seed (the sampler's) default to the settings' (references use others)."""
        mi = self.mi
        # OIDN needs uncorrelated per-pixel noise: a box pixel filter. A gaussian one blurs the noise into
        # blobs the denoiser keeps as detail (test wall, 4 spp, sRGB RMSE raw -> denoised: box 17 -> 4.5,
        # gaussian 9.3 -> 7.9, each against a 256-spp render through the same filter)
        rfilter = "gaussian" if self.settings.denoise == "none" else "box"
        sensor = mi.load_dict(mitsuba_sensor(mi, canvas, self.settings.spp if spp is None else spp, rfilter))
        img = np.array(mi.render(self._scene, sensor=sensor, integrator=self._aov,
                                 seed=self.settings.seed if seed is None else seed))
        if self.settings.denoise == "none" or not denoise:
            return img[..., :3]
        return oidn_denoise(img[..., :3], *((img[..., 3:6], img[..., 6:9]) if self._aov is not None else ()))

    def render_rgb(self, camera: Camera) -> np.ndarray:
        """(H, W, 3) uint8 path-traced image (distortion applied)."""
        rgb = (linear_to_srgb(self.render_linear(camera.canvas())) * 255 + 0.5).astype(np.uint8)
        return distort_image(camera, rgb)

    def render(self, camera: Camera) -> RenderOutput:
        inst, depth, wins, (ign, regions) = self.occluders.truth(camera)
        return RenderOutput(camera, self.render_rgb(camera), inst, depth, wins, ign if regions else None, regions)

    def close(self) -> None:
        self.occluders.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
