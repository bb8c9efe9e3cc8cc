"""Test-session settings shared by every test module.

Thread settings: the suite runs on small shared machines and in parallel (``make test`` runs
pytest-xdist workers, one per core), so torch/OpenMP use one thread per process and an idle
OpenMP thread sleeps instead of spinning. Without the latter a 2-thread torch step on a busy
2-core machine runs 10-30x slower (measured: EffWin tiny step 0.4 s -> 6-23 s). ``setdefault``:
a caller's explicit setting wins. Set before any test module imports torch, and inherited by the
CLI subprocesses the tests start.
"""
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
