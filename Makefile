# Fenestra: set-up, tests, benchmark, reports, gates, training.
SHELL := /bin/bash
PY := .venv/bin/python
PIP := .venv/bin/pip
export PYOPENGL_PLATFORM ?= egl
export MPLBACKEND ?= Agg

.PHONY: help setup sysdeps test test-all bench smoke real heldout-gate report docs docs-check gate train train-quadnet train-maskrcnn train-winnet timing photo-speed compare clean

help:  ## list the targets
	@grep -E '^[a-z-]+:.*##' $(MAKEFILE_LIST) | awk -F':.*## ' '{printf "  make %-10s %s\n", $$1, $$2}'

sysdeps:  ## Debian packages for headless EGL rendering, mitsuba's LLVM backend and the report's browser test (if missing)
	@if ! ldconfig -p | grep -q 'libEGL.so.1' || ! ls /usr/lib/x86_64-linux-gnu/dri/*swrast* >/dev/null 2>&1 \
	    || ! ls /usr/lib/x86_64-linux-gnu/libLLVM.so.19* >/dev/null 2>&1 || ! command -v chromium >/dev/null; then \
	  echo "installing libegl1 libgl1-mesa-dri libllvm19 chromium"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && $$SUDO apt-get install -y -qq libegl1 libgl1-mesa-dri libllvm19 chromium >/dev/null; \
	else echo "system packages present"; fi

setup: sysdeps  ## virtualenv in .venv with every dependency, pinned
	test -x $(PY) || python3 -m venv .venv
	$(PIP) install -q --upgrade pip
	$(PIP) install -q -e '.[dev]'
	# pyrender 0.1.45 pins PyOpenGL==3.1.0; we run it on the pinned PyOpenGL 3.1.10 (EGL works,
	# NumPy 2 compatible), so it is installed without its dependency pins (they are in pyproject).
	$(PIP) install -q --no-deps pyrender==0.1.45
	# the lab (lab/: training scripts, weight shipping, the docs writer) is importable from this
	# checkout's venv, never installed with the package
	$(PY) -c "import pathlib, site; pathlib.Path(site.getsitepackages()[0], 'fenestra-lab.pth').write_text(str(pathlib.Path.cwd()) + chr(10))"
	$(PY) -c "import fenestra.compat, lab, pyrender, torchvision.ops; print('setup ok')"

# pytest-xdist processes for `make test` (0: one process); each test file runs whole in one of them
TEST_WORKERS ?= 2

test:  ## fast tests (the CI test command), in TEST_WORKERS parallel processes
	$(PY) -m pytest -q -m "not slow" -n $(TEST_WORKERS) --dist loadfile

test-all:  ## every test, slow ones included
	$(PY) -m pytest -q

REAL_RUN = $(if $(wildcard out/bench/real/summary.json),--real out/bench/real)

LATEST_DEFAULT = $$(ls -td out/bench/default* | head -1)

bench:  ## default profile: render, reconstruct with every strategy, report (photo column from out/bench/real when present); tracked files untouched (`make docs` regenerates them)
	$(PY) -m fenestra bench --profile default $(REAL_RUN)

smoke:  ## smoke profile (what CI gates)
	$(PY) -m fenestra bench --profile smoke --out out/bench/smoke

real:  ## real-photo profile (bundled curtain-wall photos, ../shared/real when present), sim-to-real table vs the smoke run if there is one
	SIM=$$( [ -f out/bench/smoke/summary.json ] && echo "--sim out/bench/smoke" ); \
	$(PY) -m fenestra bench --profile real --out out/bench/real $$SIM

HELDOUT_SEEDS = 0 1 2
heldout-gate:  ## the learned detector on held-out building families, once per seed (what make gate checks at its worst seed)
	for s in $(HELDOUT_SEEDS); do \
	  $(PY) -m fenestra bench --profile heldout-gate --seed $$s --out out/bench/heldout-gate-s$$s --no-report --force || exit 1; done

gate: smoke real heldout-gate  ## smoke, real and held-out-family profiles, then the accuracy gates (held out: every seed must pass)
	$(PY) -m fenestra gate out/bench/smoke
	$(PY) -m fenestra gate out/bench/real
	$(PY) -m fenestra gate $(foreach s,$(HELDOUT_SEEDS),out/bench/heldout-gate-s$(s))

timing:  ## where make bench's time goes, measured as a fresh clone would (cold, then cached renders; render views/s), written into docs/performance.md
	$(PY) tools/timing.py --json out/timing.json --markdown docs/performance.md

photo-speed:  ## CPU seconds of `fenestra reconstruct PHOTO` on 12-megapixel inputs (bundled curtain-wall photos, ../shared/real spb test photos when present) against issue 35's targets (median <= 10, max <= 30), written into docs/performance.md
	$(PY) tools/photo_speed.py --json docs/results/photo_speed.json --doc docs/performance.md --block photo-speed

compare:  ## compare two bench runs of one profile window by window: make compare A=out/bench/before B=out/bench/after (exit 1 on a significant regression of the CLI's method; page in B)
	@test -n "$(A)" -a -n "$(B)" || { echo "error: give two run folders: make compare A=RUN_A B=RUN_B"; exit 2; }
	$(PY) -m fenestra compare $(A) $(B)

report:  ## regenerate the report of the newest default run (photo column from out/bench/real when present)
	$(PY) -m fenestra report $(LATEST_DEFAULT) $(REAL_RUN)

docs:  ## docs/results.md, docs/results/summary.json and the README's answer from the newest default run (+ out/bench/real; without it the committed real-photo figures are kept, marked with their provenance); --force: a generated page a merge left unlisted is still replaced (never another file)
	$(PY) -m lab.docs $(LATEST_DEFAULT) --force $(REAL_RUN)

docs-check:  ## do the generated docs match docs/results/summary.json? (no run needed; tests/lab/test_docs.py checks the same)
	$(PY) -m lab.docs --check

train:  ## render the detector data (make_data.sh, make_data_street.sh), train the default detector (EffWin: pretrained backbone; renders + ../shared/real/spb_facades/train boxes) on the CPU into out/train/, fit its door/signboard box verifier on the train photos (minutes), ship it (reproduces the shipped weights), train and ship the quad head on it (detector v8, `quadnet`), train and ship the learned corner refinement (snapper `refine`, minutes), evaluate it
	PY=$(PY) bash lab/scripts/make_data.sh out/detector-data
	PY=$(PY) bash lab/scripts/make_data_street.sh out/detector-data
	$(PY) -m fenestra train --config fenestra/training/configs/default.toml
	PY=$(PY) bash lab/scripts/verifier_data.sh out/verifier-renders
	$(PY) -m fenestra train-verifier out/train/default.pt --yolo ../shared/real/spb_facades/train --renders out/verifier-renders --render-views 150
	$(PY) -m lab.ship out/train/default.pt
	$(PY) -m fenestra train --config fenestra/training/configs/quadnet.toml
	$(PY) -m lab.ship out/train/quadnet.pt
	PY=$(PY) bash lab/scripts/refine_data.sh out/refine-data
	$(PY) -m fenestra train-refine --data out/refine-data/train
	$(PY) -m lab.ship out/train/refine.pt
	$(PY) -m fenestra evaluate-detector --data out/detector-data/heldout-pyrender --json out/eval/default-heldout-pyrender.json
	$(PY) -m fenestra evaluate-detector --data out/detector-data/heldout-mitsuba --json out/eval/default-heldout-mitsuba.json
	$(PY) -m fenestra evaluate-detector --yolo ../shared/real/spb_facades/train --part val --json out/eval/default-spb-val.json

train-quadnet:  ## detector v8 alone: the quad head (window centres, each with its four corners) on the shipped default network, frozen (make_data*.sh renders; CPU), then ship-weights
	PY=$(PY) bash lab/scripts/make_data.sh out/detector-data
	PY=$(PY) bash lab/scripts/make_data_street.sh out/detector-data
	$(PY) -m fenestra train --config fenestra/training/configs/quadnet.toml
	$(PY) -m lab.ship out/train/quadnet.pt

train-maskrcnn:  ## the paper's detector: Mask R-CNN on an ImageNet-pretrained EfficientNet-Lite0 FPN, on the default's renders and street photos (make_data*.sh; CPU, resumable: a run stopped midway continues from its last checkpoint), then ship-weights and its figures
	PY=$(PY) bash lab/scripts/make_data.sh out/detector-data
	PY=$(PY) bash lab/scripts/make_data_street.sh out/detector-data
	$(PY) -m fenestra train --config fenestra/training/configs/maskrcnn.toml --resume
	$(PY) -m lab.ship out/train/maskrcnn.pt
	$(PY) -m fenestra evaluate-detector --detector maskrcnn --yolo ../shared/real/spb_facades/train --part val --json out/eval/maskrcnn-spb-val.json

train-winnet:  ## the from-scratch WinNet (registered as `winnet`) on the same renders: out/train/winnet.pt, then ship-weights
	PY=$(PY) bash lab/scripts/make_data.sh out/detector-data
	$(PY) -m fenestra train --config fenestra/training/configs/winnet.toml
	$(PY) -m lab.ship out/train/winnet.pt

clean:
	rm -rf out .pytest_cache
