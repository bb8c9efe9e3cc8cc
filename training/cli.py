"""CLI commands of pipeline/detectors: `fenestra train` and `fenestra evaluate-detector`.

pipeline/cli.py's register(app) should call ``pipeline.detectors.cli.register(app)``.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer


def register(app: typer.Typer) -> None:
    """Add `train` and `evaluate-detector` to the top-level app."""

    @app.command("train")
    def train_cmd(
        config: Path = typer.Option(Path("pipeline/models/default.toml"), help="training config (TOML)"),
        data: Optional[list[Path]] = typer.Option(None, help="dataset folder(s); replaces the config's `data`"),
        out: Optional[Path] = typer.Option(None, help="weights file to write (default: the config's `out`)"),
        iterations: Optional[int] = typer.Option(None, help="override the number of iterations"),
        resume: bool = typer.Option(False, help="continue from out/train/<name>.state.pt if present"),
        device: Optional[str] = typer.Option(None, help="cpu or cuda (default: the config's `device`)"),
        workers: Optional[int] = typer.Option(None, help="processes making batches ahead (default: the config's)"),
    ) -> None:
        """Train a window-void detector (WinNet or Mask R-CNN) on rendered dataset folders."""
        from pipeline.detectors.train import load_config, train  # noqa: PLC0415

        cfg = load_config(config, data=tuple(str(d) for d in data) if data else None,
                          out=str(out) if out else None, iterations=iterations, resume=resume or None,
                          device=device, workers=workers)
        path = train(cfg, log=typer.echo)
        typer.echo(f"weights: {path}  losses: {path.with_suffix('.loss.csv')}")

    @app.command("evaluate-detector")
    def evaluate_cmd(
        data: Path = typer.Option(..., help="held-out dataset folder (with coco.json)"),
        detector: str = typer.Option("default", help="registry name: default, maskrcnn, oracle, oracle-degraded"),
        weights: Optional[Path] = typer.Option(None, help="weights file (default: the shipped one)"),
        max_images: Optional[int] = typer.Option(None, help="evaluate only the first N images"),
        json_out: Optional[Path] = typer.Option(None, "--json", help="also write the metrics as JSON"),
        device: str = typer.Option("cpu", help="cpu or cuda (learned detectors)"),
    ) -> None:
        """COCO bbox/segm AP of a detector on a dataset, beside the paper's Table 2."""
        from pipeline.detectors.evaluate import evaluate, format_table  # noqa: PLC0415

        opts = {"weights": weights} if weights is not None else {}
        if device != "cpu":
            opts["device"] = device
        result = evaluate(detector, data, max_images=max_images, **opts)
        typer.echo(format_table(result))
        if json_out is not None:
            json_out.parent.mkdir(parents=True, exist_ok=True)
            json_out.write_text(json.dumps(result, indent=2))
