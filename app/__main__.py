"""``python -m app``: the `fenestra` command line (the console script ``fenestra`` runs the same)."""
from app.cli import main

if __name__ == "__main__":  # guarded: spawned worker processes import this module too
    main()
