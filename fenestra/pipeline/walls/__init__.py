"""Per-wall geometry: windows of one wall share a plane, so estimate it once.

Modules, in import order (each uses only those before it):

- ``settings``: WallFitSettings (the fit's fixed algorithm settings, one instance WALL_FIT) and
  WallParams (a strategy's parameters).
- ``vanishing``: vanishing points of the windows' sides; grouping windows into walls (RANSAC);
  a wall's rotation, f from two vanishing points, walls at right angles tied.
- ``fit``: the joint Levenberg-Marquardt fit over a wall's windows (WallFit), its covariance and
  each window's uncertainty intervals.
- ``lines``: façade line segments near a wall's windows joining its vanishing points and its fit
  (the photo's segments from pipeline.segments, the pipeline's one segment detector).
- ``strategies``: the registry WALL_STRATEGIES, apply_walls, the fits with known or unknown focal
  length.

The names used outside the package are re-exported here.
"""
from fenestra.pipeline.walls.fit import WallFit, refine_walls, window_uncertainty
from fenestra.pipeline.walls.settings import WALL_FIT, WallFitSettings, WallParams
from fenestra.pipeline.walls.strategies import (WALL_STRATEGIES, apply_walls, fit_walls, fit_walls_focal, focal_from_walls,
                                       pseudo_K)
from fenestra.pipeline.walls.vanishing import FacadeError, group_walls

__all__ = ["WALL_FIT", "WALL_STRATEGIES", "FacadeError", "WallFit", "WallFitSettings", "WallParams", "apply_walls",
           "fit_walls", "fit_walls_focal", "focal_from_walls", "group_walls", "pseudo_K", "refine_walls",
           "window_uncertainty"]
