"""The training lab: a stage after renders/, making and measuring the detectors that pipeline/ ships.

    train.py       TrainConfig, train() (one loop for every architecture)     `fenestra train`
    recipes/       one training recipe per trainable detector (recipes/<arch>.py: RECIPE)
    augment.py     domain randomisation at training time
    houses.py      the procedural training houses (varied, facade, street) every data script shares
    dataset.py     reading rendered dataset folders (views, instance maps, coco.json)
    evaluate.py    COCO bbox/segm AP of a detector on a dataset              `fenestra evaluate-detector`
    ship.py        checked copy of trained weights into fenestra/pipeline/models      `fenestra ship-weights`
    tune.py        WinNet post-processing thresholds on validation views     `python -m lab.tune`
    pack_data.py   rendered data packed small for a GPU machine              `python lab/pack_data.py`
    configs/       the detectors' training configs (default.toml: EffWin, the shipped default; quadnet.toml; winnet.toml;
                   maskrcnn.toml: the paper's Mask R-CNN on EfficientNet-Lite0, CPU; maskrcnn-r50-gpu.toml: its ResNet-50, GPU)
    scripts/       make_data.sh (the fenestra/training/validation/held-out renders), gpu_*.sh (GPU machine runs)

training/ may import fenestra, scenes, renders and pipeline; pipeline/ never imports training/
(a test checks it). Outputs go under out/ (out/train/, out/detector-data/, out/eval/); shipping
weights into fenestra/pipeline/models is the explicit `fenestra ship-weights` step. The model card is
fenestra/pipeline/models/README.md; the experiments behind it are in docs/experiments.md.
"""
