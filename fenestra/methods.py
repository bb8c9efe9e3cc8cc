"""A method: one choice per pluggable stage, as a typed value (never a string split again).

    m = Method("default", "lsd", "wall", withhold_K=True)
    m.label            # "default/lsd/wall+noK": the ``method`` column of the results tables
    m.row()            # {"detector": ..., "snapper": ..., "pose": "wall+noK", "method": ...}

detector, snapper, pose: registry names (``pipeline.detectors.DETECTORS``,
``pipeline.snappers.SNAPPERS``, ``pipeline.reconstruct.POSES``; checked where methods are planned,
since this floor imports no registry); withhold_K: the pipeline is given no K (the strategy fits
the focal length, capability ``fits_focal``); quad_source: a key of ``pipeline.quad.QUAD_SOURCES``.

The label is for display and for the tables' columns. Reading a table written earlier is the one
place a label is parsed back (:func:`read_methods`).
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

NO_K_SUFFIX = "+noK"  # the pose column of a K-withheld method: "wall+noK"
# The quad source of a method that names none (the CLI's, fenestra.conventions.DEFAULTS): the mask
# fit, and where it finds no quadrilateral four of more lines on the same mask that the detector's
# corner head confirms (``mask+lines``; a detector without a corner head gets the mask fit alone).
# ``mask+corners`` answers more windows but spoils the per-wall fits: DESIGN.md, Decisions.
DEFAULT_QUAD_SOURCE = "mask+lines"


@dataclass(frozen=True)
class Method:
    """detector x corner snapper x pose strategy, K given or withheld, quad source (pipeline.quad.QUAD_SOURCES)."""

    detector: str
    snapper: str
    pose: str
    withhold_K: bool = False
    quad_source: str = DEFAULT_QUAD_SOURCE

    def __post_init__(self) -> None:
        for key in ("detector", "snapper", "pose", "quad_source"):
            v = getattr(self, key)
            if not isinstance(v, str) or not v or "/" in v:
                raise ValueError(f"Method.{key} must be a registry name (non-empty, no '/'), got {v!r}")
        if self.pose.endswith(NO_K_SUFFIX):
            raise ValueError(f"Method.pose {self.pose!r}: say withhold_K=True instead of the {NO_K_SUFFIX!r} suffix")
        if not isinstance(self.withhold_K, bool):
            raise ValueError(f"Method.withhold_K must be a bool, got {self.withhold_K!r}")

    @property
    def pose_label(self) -> str:
        """The ``pose`` column: the strategy, with ``+noK`` when K is withheld."""
        return self.pose + (NO_K_SUFFIX if self.withhold_K else "")

    @property
    def label(self) -> str:
        """``detector/snapper/pose[+noK]`` (``/quad_source`` appended when not the mask fit)."""
        parts = [self.detector, self.snapper, self.pose_label]
        return "/".join(parts if self.quad_source == DEFAULT_QUAD_SOURCE else [*parts, self.quad_source])

    name = label  # the bench's and the reports' word for it

    def row(self) -> dict[str, str]:
        """The method columns of a results row."""
        return {"detector": self.detector, "snapper": self.snapper, "pose": self.pose_label, "method": self.label}

    @classmethod
    def from_label(cls, label: str) -> Method:
        """The method a table's label names (see :func:`read_methods`); ValueError naming it."""
        parts = str(label).split("/")
        if len(parts) not in (3, 4):
            raise ValueError(f"method label {label!r} is not detector/snapper/pose[/quad_source]")
        pose, no_k = parts[2], parts[2].endswith(NO_K_SUFFIX)
        return cls(parts[0], parts[1], pose[: -len(NO_K_SUFFIX)] if no_k else pose, no_k,
                   parts[3] if len(parts) == 4 else DEFAULT_QUAD_SOURCE)


def read_methods(labels: Iterable[str]) -> dict[str, Method]:
    """{label: Method} of the labels of a results table or summary (the one place labels are parsed)."""
    return {lab: Method.from_label(lab) for lab in dict.fromkeys(labels)}


__all__ = ["DEFAULT_QUAD_SOURCE", "NO_K_SUFFIX", "Method", "read_methods"]
