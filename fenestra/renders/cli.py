"""CLI commands of renders/ (registered on the `fenestra` app by fenestra/app/cli.py).

    fenestra render --scene fzk-haus --views 50 --seed 0 --renderer pyrender --out out/renders

Option defaults are read from renders' config dataclasses (DatasetConfig, SamplerConfig,
RenderSettings), the renderer choices from renders.backends.RENDERERS.
"""
from __future__ import annotations

import json

import typer
from fenestra.config import choices
from fenestra.conventions import LIMITS
from fenestra.renders.backends import RENDERERS
from fenestra.renders.base import DENOISERS, LOOK_PER, LOOKS, RenderSettings
from fenestra.renders.dataset import DatasetConfig
from fenestra.renders.sampler import SamplerConfig


def register(app: typer.Typer) -> None:
    """Add this stage's commands to the top-level app (defaults from the config dataclasses, choices
    from the registries)."""

    D, S, R = DatasetConfig("-"), SamplerConfig(), RenderSettings()

    @app.command("render")
    def render(scene: str = typer.Option("fzk-haus", help="bundled scene name or IFC path"),
               views: int = typer.Option(D.n_views, help="number of views"),
               seed: int = typer.Option(D.seed, help="seed: cameras, look (palette, sun), sensor"),
               renderer: str = typer.Option(D.renderer, help=f"renderer: {choices(RENDERERS)}"),
               out: str = typer.Option(D.out_root, help="root folder; the dataset gets a hashed sub-folder"),
               width: int = typer.Option(S.width), height: int = typer.Option(S.height),
               hfov_min: float = typer.Option(S.hfov_deg[0]), hfov_max: float = typer.Option(S.hfov_deg[1]),
               distance_min: float = typer.Option(S.distance_m[0]), distance_max: float = typer.Option(S.distance_m[1]),
               azimuth_max: float = typer.Option(S.azimuth_deg[1], help="max |azimuth| from the window normal, deg"),
               street_fraction: float = typer.Option(S.street_fraction, help="fraction of street-level views"),
               min_visible: float = typer.Option(S.min_visible_fraction, help="min visible fraction of target windows"),
               k1: float = typer.Option(S.k1_range[1], help="max |k1| radial distortion (0 = pinhole)"),
               spp: int = typer.Option(R.spp, help="mitsuba samples per pixel"),
               denoise: str = typer.Option(R.denoise, help=f"mitsuba: {', '.join(DENOISERS)} (Open Image Denoise, "
                                           "oidn-aov guided by albedo/normal; the photoreal profile: 4 spp + oidn)"),
               look: str = typer.Option(R.look, help=f"palette, textures and lighting drawn per seed: {', '.join(LOOKS)} "
                                        "(wide: more wall colours/materials, glass variants, low sun, overcast)"),
               look_per: str = typer.Option(R.look_per, help=f"{' or '.join(LOOK_PER)}: one look drawn from --seed for "
                                            "every view, or each view its own look from its own stream"),
               no_shadows: bool = typer.Option(not R.shadows, help="raster: no sun shadows"),
               sensor: bool = typer.Option(False, help="apply realistic sensor noise/blur/JPEG to images")) -> None:
        """Render a dataset of views (images, 16-bit instance maps, view.json, coco.json)."""
        from fenestra.renders.dataset import render_dataset  # noqa: PLC0415 (a command's own: loaded when the command runs)
        from fenestra.renders.sensor import REALISTIC, SensorConfig  # noqa: PLC0415 (a command's own: loaded when the command runs)

        LIMITS.check("max_views_per_dataset", views, "--views")
        cfg = DatasetConfig(
            scene=scene, n_views=views, seed=seed, renderer=renderer, out_root=out,
            sampler=SamplerConfig(width=width, height=height, hfov_deg=(hfov_min, hfov_max),
                                  distance_m=(distance_min, distance_max), azimuth_deg=(-azimuth_max, azimuth_max),
                                  street_fraction=street_fraction, min_visible_fraction=min_visible,
                                  k1_range=(-abs(k1), abs(k1))),
            settings=RenderSettings(seed=seed, spp=spp, shadows=not no_shadows, denoise=denoise,
                                    look=look, look_per=look_per),
            sensor=REALISTIC if sensor else SensorConfig())
        root = render_dataset(cfg)
        stats = json.loads((root / "stats.json").read_text())
        rate = stats["rendered"] / stats["seconds"] if stats["seconds"] > 0 else float("nan")
        typer.echo(f"{root}: {stats['rendered']} views rendered, {stats['reused']} reused; "
                   f"{rate:.2f} views/s")
