"""CLI commands of renders/ (registered on the `fenestra` app by fenestra/cli.py).

    fenestra render --scene fzk-haus --views 50 --seed 0 --renderer pyrender --out out/renders
"""
from __future__ import annotations

import json

import typer


def register(app: typer.Typer) -> None:
    """Add this stage's commands to the top-level app."""

    @app.command("render")
    def render(scene: str = typer.Option("fzk-haus", help="bundled scene name or IFC path"),
               views: int = typer.Option(20, help="number of views"),
               seed: int = typer.Option(0, help="seed: cameras, look (palette, sun), sensor"),
               renderer: str = typer.Option("pyrender", help="pyrender | mitsuba"),
               out: str = typer.Option("out/renders", help="root folder; the dataset gets a hashed sub-folder"),
               width: int = typer.Option(640), height: int = typer.Option(480),
               hfov_min: float = typer.Option(50.0), hfov_max: float = typer.Option(70.0),
               distance_min: float = typer.Option(3.0), distance_max: float = typer.Option(12.0),
               azimuth_max: float = typer.Option(50.0, help="max |azimuth| from the window normal, deg"),
               street_fraction: float = typer.Option(0.3, help="fraction of street-level views"),
               min_visible: float = typer.Option(0.5, help="min visible fraction of target windows"),
               k1: float = typer.Option(0.0, help="max |k1| radial distortion (0 = pinhole)"),
               spp: int = typer.Option(16, help="mitsuba samples per pixel"),
               denoise: str = typer.Option("none", help="mitsuba: none | oidn | oidn-aov (Open Image Denoise, "
                                           "oidn-aov guided by albedo/normal; the photoreal profile: 4 spp + oidn)"),
               no_shadows: bool = typer.Option(False, help="raster: no sun shadows"),
               sensor: bool = typer.Option(False, help="apply realistic sensor noise/blur/JPEG to images")) -> None:
        """Render a dataset of views (images, 16-bit instance maps, view.json, coco.json)."""
        from renders.base import RenderSettings
        from renders.dataset import DatasetConfig, render_dataset
        from renders.sampler import SamplerConfig
        from renders.sensor import REALISTIC, SensorConfig

        cfg = DatasetConfig(
            scene=scene, n_views=views, seed=seed, renderer=renderer, out_root=out,
            sampler=SamplerConfig(width=width, height=height, hfov_deg=(hfov_min, hfov_max),
                                  distance_m=(distance_min, distance_max), azimuth_deg=(-azimuth_max, azimuth_max),
                                  street_fraction=street_fraction, min_visible_fraction=min_visible,
                                  k1_range=(-abs(k1), abs(k1))),
            settings=RenderSettings(seed=seed, spp=spp, shadows=not no_shadows, denoise=denoise),
            sensor=REALISTIC if sensor else SensorConfig())
        root = render_dataset(cfg)
        stats = json.loads((root / "stats.json").read_text())
        rate = stats["rendered"] / stats["seconds"] if stats["seconds"] > 0 else float("nan")
        typer.echo(f"{root}: {stats['rendered']} views rendered, {stats['reused']} reused; "
                   f"{rate:.2f} views/s")
