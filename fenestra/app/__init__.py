"""The top floor: the `fenestra` command line, the composition root that registers every stage's
commands (fenestra/app/cli.py). It may import every package; no package imports it."""
