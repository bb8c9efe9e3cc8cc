"""What a bench house is to a learned detector: trained on it, of its generator, or held out."""
from __future__ import annotations

# The houses each shipped learned detector was trained on (lab/scripts/make_data.sh: its bundled
# training houses; its procedural houses use other seeds than the bench's). samplehouse4 is held
# out. tests/lab/test_docs.py checks this against make_data.sh.
TRAINED_ON: dict[str, tuple[str, ...]] = {
    "default": ("fzk-haus", "duplex", "jasmin-sun", "niedriha"),
    "quadnet": ("fzk-haus", "duplex", "jasmin-sun", "niedriha"),
    "winnet": ("fzk-haus", "duplex", "jasmin-sun", "niedriha"),
    "maskrcnn": ("fzk-haus", "duplex", "jasmin-sun", "niedriha"),
}
# "trained on" (TRAINED_ON), "same generator" (the bench's procedural houses: fenestra.scenes.generate
# made the training houses too, so a held-out seed is not a held-out family) or "held out" (neither
# the house nor its generator trained it: samplehouse4, office-a, the authored houses). Figures on
# "held out" houses are the ones quoted.
ROLES = ("held out", "same generator", "trained on")
ROLE_GROUPS = {"held out": "held-out families", "same generator": "same generator", "trained on": "trained-on houses"}
PROCEDURAL_PREFIX = "procedural"  # the bench's name of a generated house: procedural-<seed>


def house_role(detector: str, house: str) -> str:
    """One of ROLES: what ``house`` (a bench house name) is to ``detector``'s training."""
    if house in TRAINED_ON.get(detector, ()):
        return "trained on"
    return "same generator" if house.startswith(PROCEDURAL_PREFIX) else "held out"
