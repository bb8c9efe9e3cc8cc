"""The top floor, fenestra/app/cli.py: the `fenestra` command's own options."""
from __future__ import annotations

import importlib.metadata
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_version_is_the_installed_package_version():
    r = subprocess.run([sys.executable, "-m", "fenestra", "--version"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip() == f"fenestra {importlib.metadata.version('fenestra')}"
