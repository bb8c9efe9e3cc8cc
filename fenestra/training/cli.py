"""CLI commands of training/ (registered on the `fenestra` app by fenestra/app/cli.py):

    fenestra train [--config fenestra/training/configs/default.toml] [--data DIR ...] [--out W.pt]   # -> out/train/
    fenestra evaluate-detector --data DIR [--detector NAME] [--weights W.pt] [--json OUT]
    fenestra train-verifier W.pt [--yolo DIR] [--out W2.pt]   # EffWin's door/signboard box verifier into W.pt
    fenestra train-refine [--data out/refine-data/train] [--out out/train/refine.pt]  # corner refinement (python -m lab.ship ships it)

Every file is written under fenestra.outputs' rule (training.weights_file): never over a file
Fenestra did not write nor over an input; ``--force`` replaces only a file of the command's own
kind (weights, a training state, a loss log, a metrics JSON) that no manifest lists.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from fenestra.pipeline.detectors import DETECTORS


def register(app: typer.Typer) -> None:
    """Add `train`, `evaluate-detector`, `train-verifier` and `train-refine` to the top-level app
    (shipping weights into the package is the lab's: ``python -m lab.ship``)."""

    @app.command("train")
    def train_cmd(
        config: Path = typer.Option(Path("fenestra/training/configs/default.toml"), help="training config (TOML)"),
        data: Optional[list[Path]] = typer.Option(None, help="dataset folder(s); replaces the config's `data`"),
        out: Optional[Path] = typer.Option(None, help="weights file to write (default: the config's `out`, under out/train/)"),
        iterations: Optional[int] = typer.Option(None, help="override the number of iterations"),
        resume: bool = typer.Option(False, help="continue from out/train/<name>.state.pt if present"),
        device: Optional[str] = typer.Option(None, help="cpu or cuda (default: the config's `device`)"),
        workers: Optional[int] = typer.Option(None, help="processes making batches ahead (default: the config's)"),
        force: bool = typer.Option(False, help="replace weights, a training state or a loss log that no Fenestra "
                                   "manifest lists (never another file, never --init-weights)"),
    ) -> None:
        """Train a window-void detector (EffWin, WinNet or Mask R-CNN) on rendered dataset folders (EffWin: plus real box photos)."""
        from fenestra.training.train import load_config, train  # noqa: PLC0415 (fenestra.training.train loads torch: imported when first used)

        cfg = load_config(config, data=tuple(str(d) for d in data) if data else None,
                          out=str(out) if out else None, iterations=iterations, resume=resume or None,
                          device=device, workers=workers)
        path = train(cfg, log=typer.echo, force=force)
        typer.echo(f"weights: {path}  losses: {path.with_suffix('.loss.csv')}")

    @app.command("evaluate-detector")
    def evaluate_cmd(
        data: Optional[Path] = typer.Option(None, help="held-out dataset folder (with coco.json)"),
        yolo: Optional[Path] = typer.Option(None, help="instead of --data: real photos with YOLO window boxes "
                                            "(images/, labels/; bbox AP only)"),
        part: str = typer.Option("val", help="with --yolo: val (every --holdout-every th photo), train or all"),
        holdout_every: int = typer.Option(5, help="with --yolo: the validation photos' spacing"),
        detector: str = typer.Option("default", help=f"registry name: {', '.join(DETECTORS)}"),
        no_ignore: bool = typer.Option(False, "--no-ignore", help="with --data: count detections on curtain-wall "
                                       "and glazed-door glazing as false positives (drop the ignore regions)"),
        weights: Optional[Path] = typer.Option(None, help="weights file (default: the shipped one)"),
        max_images: Optional[int] = typer.Option(None, help="evaluate only the first N images"),
        json_out: Optional[Path] = typer.Option(None, "--json", help="also write the metrics as JSON (never over a "
                                                "file Fenestra did not write, nor into the dataset)"),
        device: str = typer.Option("cpu", help="cpu or cuda (learned detectors)"),
        force: bool = typer.Option(False, help="--json may replace a metrics file that no Fenestra manifest lists"),
    ) -> None:
        """COCO bbox/segm AP of a detector on a dataset, beside the paper's Table 2."""
        from fenestra import outputs  # noqa: PLC0415 (a command's own: loaded when the command runs)
        from fenestra.training.evaluate import METRICS_FILE, evaluate, evaluate_boxes, format_table  # noqa: PLC0415 (fenestra.training.evaluate loads torch: imported when the command runs)

        if (data is None) == (yolo is None):
            raise typer.BadParameter("give exactly one of --data (rendered dataset) and --yolo (real photos)")
        rule = {"inputs": (data, yolo, weights), "option": "--json", "force": force, "own": METRICS_FILE}
        if json_out is not None:
            outputs.check_file(json_out, **rule)  # before the evaluation
        opts = {"weights": weights} if weights is not None else {}
        if device != "cpu":
            opts["device"] = device
        result = (evaluate(detector, data, max_images=max_images, ignore_regions=not no_ignore, **opts) if yolo is None else
                  evaluate_boxes(detector, yolo, part, holdout_every, max_images=max_images, **opts))
        typer.echo(format_table(result))
        if json_out is not None:
            outputs.write_file(json_out, lambda p: p.write_text(json.dumps(result, indent=2)), **rule)

    @app.command("train-verifier")
    def train_verifier_cmd(
        weights: Path = typer.Argument(..., help="EffWin weights file (what `fenestra train` wrote)"),
        yolo: Path = typer.Option(Path("../shared/real/spb_facades/train"), help="real photos with YOLO boxes "
                                  "(windows 0, signboards 3, doors 5); only their train part is read"),
        holdout_every: int = typer.Option(5, help="the validation photos' spacing (never read)"),
        renders: Optional[list[Path]] = typer.Option(None, help="rendered dataset folder(s) of the detector's "
                                                     "training houses: their windows join the positives"),
        render_views: int = typer.Option(150, help="with --renders: views read, spread evenly over the datasets"),
        out: Optional[Path] = typer.Option(None, help="write here instead of into WEIGHTS"),
        force: bool = typer.Option(False, help="write over a weights file that no Fenestra manifest lists"),
    ) -> None:
        """Fit EffWin's box verifier (window vs door or signboard) on the train photos; store it in the weights file."""
        from fenestra.training.verifier import add_verifier  # noqa: PLC0415 (fenestra.training.verifier loads torch: imported when the command runs)

        f = add_verifier(weights, yolo, out, holdout_every, tuple(renders or ()), render_views, log=typer.echo,
                         force=force)
        typer.echo(f"verifier: {f.n_windows} windows, {f.n_negatives} doors/signboards/glazing from {f.n_photos} "
                   f"train photos and views; threshold {f.head.threshold:.3f}; out of fold at score >= 0.5: keeps "
                   f"{100 * f.oof_windows_kept:.1f} % of windows, drops {100 * f.oof_negatives_dropped:.1f} % of "
                   f"doors/signboards -> {out or weights}")

    @app.command("train-refine")
    def train_refine_cmd(
        data: Optional[list[Path]] = typer.Option(None, help="rendered dataset folder(s) of the detector's training "
                                                  "houses (default: out/refine-data/train, from lab/scripts/refine_data.sh)"),
        out: Path = typer.Option(Path("out/train/refine.pt"), help="weights file to write"),
        epochs: Optional[int] = typer.Option(None, help="override the number of epochs"),
    ) -> None:
        """Train the learned corner refinement (snapper `refine`): a small CNN on corner patches of rendered views."""
        import dataclasses  # noqa: PLC0415 (a command's own: loaded when the command runs)

        from fenestra.training.refine import RefineTrainConfig, train_refine  # noqa: PLC0415 (fenestra.training.refine loads SciPy: imported when first used)

        cfg = RefineTrainConfig() if epochs is None else dataclasses.replace(RefineTrainConfig(), epochs=epochs)
        meta = train_refine(tuple(data or (Path("out/refine-data/train"),)), out, cfg, log=typer.echo)
        v = meta["validation"]
        typer.echo(f"weights: {out} ({meta['train_seconds']} s); validation corners: error median "
                   f"{v['before_median_px']:.2f} -> {v['gated_median_px']:.3f} px after refinement")
