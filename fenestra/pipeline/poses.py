"""The one registry of pose strategies, :data:`POSES`: per-window solvers (pipeline.pose) and
per-wall strategies (pipeline.walls), each a :class:`PoseStrategy` with a description and its
capabilities.

    POSES["wall+lines"].wall        # WallParams of a per-wall strategy (None for a per-window one)
    POSES.where(per_wall=False)     # ["lm", "ippe", ...]
    POSES.register(PoseStrategy.per_window(PoseSolver("mine", solve, "what it does")))
"""
from __future__ import annotations

from dataclasses import dataclass

from fenestra.pipeline.pose import SOLVERS, PoseSolver
from fenestra.pipeline.walls import WALL_STRATEGIES, WallParams
from fenestra.registry import Registry


@dataclass(frozen=True)
class PoseStrategy:
    """A pose strategy as :func:`reconstruct` offers it (``ReconstructConfig.pose``): an entry of
    :data:`POSES`.

    Exactly one of ``solver`` (a per-window :class:`~pipeline.pose.PoseSolver`: each window from its
    own quad; with K None, from the focal length of its own quad) and ``wall`` (a per-wall
    :class:`~pipeline.walls.WallParams`: windows grouped into walls, each wall fitted once; with K
    None the focal length is a parameter of that fit). description: one line for CLI help and docs.
    Capabilities (fenestra.registry): ``per_wall``, and ``fits_focal`` (the per-wall ones: the bench
    runs them with K withheld too).
    """

    name: str
    description: str
    solver: PoseSolver | None = None
    wall: WallParams | None = None

    def __post_init__(self) -> None:
        if (self.solver is None) == (self.wall is None):
            raise ValueError(f"pose strategy {self.name!r} needs exactly one of solver= (per window) or wall= (per wall)")

    @property
    def per_wall(self) -> bool:
        return self.wall is not None

    @property
    def fits_focal(self) -> bool:
        return self.wall is not None

    @property
    def per_window_pose(self) -> str:
        """The per-window solver whose results it starts from (itself, or the wall's base_pose)."""
        return self.name if self.wall is None else self.wall.base_pose

    @classmethod
    def per_window(cls, solver: PoseSolver) -> PoseStrategy:
        return cls(solver.name, solver.description, solver=solver)

    @classmethod
    def walls(cls, name: str, params: WallParams) -> PoseStrategy:
        return cls(name, params.description, wall=params)


# Every pose strategy, per-window solvers first: the one registry that the CLI, profiles, the bench,
# the gates and the reports read, at the time they read it (an entry registered later, by a plug-in
# or a test, is seen everywhere: nothing copies it). Built-ins: pipeline.pose.SOLVERS and
# pipeline.walls.WALL_STRATEGIES.
POSES: Registry[PoseStrategy] = Registry("pose strategy", [
    *(PoseStrategy.per_window(s) for s in SOLVERS),
    *(PoseStrategy.walls(n, w) for n, w in WALL_STRATEGIES.items()),
])


def pose_strategies() -> Registry[PoseStrategy]:
    """:data:`POSES` (the name it had before it was a registry)."""
    return POSES
