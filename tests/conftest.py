"""Test-session settings shared by every test module.

Thread settings: the suite runs on small shared machines and in parallel (``make test`` runs
TEST_WORKERS = 2 pytest-xdist processes), so torch/OpenMP use one thread per process and an idle
OpenMP thread sleeps instead of spinning. Without the latter a 2-thread torch step on a busy
2-core machine (or next to another worker) runs an order of magnitude slower. ``setdefault``:
a caller's explicit setting wins. Set before any test module imports torch, and inherited by the
CLI subprocesses the tests start.
"""
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
