"""CLI commands of scenes/ (registered on the `fenestra` app by fenestra/cli.py)."""
from __future__ import annotations

import typer


def register(app: typer.Typer) -> None:
    """Add this stage's commands to the top-level app."""
