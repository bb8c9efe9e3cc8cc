"""``python -m fenestra``: the `fenestra` command line (the console script ``fenestra`` runs the same)."""
from fenestra.app.cli import main

if __name__ == "__main__":  # guarded: spawned worker processes import this module too
    main()
