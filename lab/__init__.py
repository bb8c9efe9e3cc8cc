"""The lab: what builds the repository's weights, data and generated docs. It is never installed.

    lab/scripts/      the renders the shipped detectors are trained on (make train runs them)
    lab/pack_data.py  rendered data packed small for a GPU machine
    lab/tune.py       WinNet's post-processing thresholds, scored on validation views
    lab/ship.py       a checkpoint shipped as the package's weights (``make train`` ends with it)
    lab/docs/         docs/results.md and the README's generated blocks, from a bench run

The package (``fenestra``) never imports it; ``make setup`` puts the checkout on the venv's path
(a ``.pth`` file), so ``python -m lab.docs`` and the tools import it from a checkout.
"""
