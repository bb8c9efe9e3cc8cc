"""Where the tests find the St Petersburg street photos (../shared/real/spb_facades, or
FENESTRA_SPB): they are never shipped (their licence is unverified), so the tests that read them
skip with this reason when they are absent; CI has ../shared, so they run there."""
import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SPB = Path(os.environ.get("FENESTRA_SPB", ROOT.parent / "shared" / "real" / "spb_facades"))
NO_SPB = (f"the spb_facades photos are not in {SPB}: not shipped (their licence is unverified); "
          "point FENESTRA_SPB at a copy")


def needs_spb(part: Path) -> pytest.MarkDecorator:
    """Skip (with NO_SPB) unless ``SPB / part`` exists."""
    return pytest.mark.skipif(not (SPB / part).exists(), reason=NO_SPB)
