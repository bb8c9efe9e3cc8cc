"""Intrinsics when the user gives none: a ranked chain of focal sources, or chessboard photos.

The chain used by ``fenestra reconstruct`` / ``pipeline.reconstruct_photo`` (:func:`resolve_K`),
first usable source wins; every source that gave a value is kept, and two that disagree (neither's
interval holds the other's value; the prior is held against the vanishing points only) give a
warning, in the user's words, naming both values (chain.disagree):

1. ``K``: the user's K (--K K.json or --fx), interval = the value itself (focal.user_focal).
2. ``exif``: the focal length the photo's EXIF states, +- 5 % (exif.exif_focal).
3. ``vanishing points``: the façade's vanishing points, with a calibrated 90 % interval, used when
   that interval is narrower than the prior's and the answer is stable (its halves agree) and
   steady (a half-size repeat and repeats with moved corners agree; vanishing.vanishing_focal).
4. ``prior``: a typical phone camera's field of view, with a wide interval (focal.prior_focal).
   Always available: the chain never fails.

Modules, one subject each: ``focal`` (the estimate type, focal length <-> field of view, the user's
K and the prior), ``exif`` (EXIF focal tags), ``gps`` (EXIF position), ``vanishing`` (the façade's
vanishing points), ``chain`` (ranking, choosing, disagreements), ``calibrate`` (chessboard
calibration, K.json). Their public names are importable from this package.
"""
from fenestra.pipeline.intrinsics.calibrate import Calibration, board_points, calibrate_chessboard, calibration_json, find_corners
from fenestra.pipeline.intrinsics.chain import ResolvedK, choose_focal, disagree, disagreements, resolve_K, resolve_K_with
from fenestra.pipeline.intrinsics.exif import (EXIF_FOV_RANGE_DEG, EXIF_IFD, EXIF_REL_INTERVAL, FULL_FRAME_WIDTH_MM,
                                               PLANE_UNIT_MM, TAG_FOCAL, TAG_FOCAL_35, TAG_PIXEL_X, TAG_PIXEL_Y,
                                               TAG_PLANE_UNIT, TAG_PLANE_XRES, exif_focal, exif_focal_of_tags, exif_in_range, exif_number,
                                               focal_from_exif, focal_from_exif_tags, read_exif_tags)
from fenestra.pipeline.intrinsics.focal import (PRIOR_FOV_DEG, PRIOR_FOV_RANGE_DEG, FocalEstimate, centred_K, focal_from_fov,
                                                fov_from_focal, prior_focal, user_focal)
from fenestra.pipeline.intrinsics.gps import GPS_IFD, gps_from_exif, gps_from_exif_tags
from fenestra.pipeline.intrinsics.vanishing import (PLAUSIBLE_FOV_DEG, VP_JITTER_FITS, VP_JITTER_MISSES, VP_JITTER_PX,
                                                    VP_SD_MULTIPLIER, VP_SPLIT_MIN_QUADS, VP_SPLIT_PARTS, VP_STABILITY_CHECK,
                                                    evidence_halves, halved_fit, jittered_quads, vanishing_estimate,
                                                    vanishing_fit, vanishing_focal, vanishing_stability,
                                                    vanishing_steadiness, vp_max_sd)

__all__ = ["Calibration", "board_points", "calibrate_chessboard", "calibration_json", "find_corners",
           "ResolvedK", "choose_focal", "disagree", "disagreements", "resolve_K", "resolve_K_with",
           "EXIF_FOV_RANGE_DEG", "EXIF_IFD", "EXIF_REL_INTERVAL", "FULL_FRAME_WIDTH_MM", "PLANE_UNIT_MM", "TAG_FOCAL",
           "TAG_FOCAL_35", "TAG_PIXEL_X", "TAG_PIXEL_Y", "TAG_PLANE_UNIT", "TAG_PLANE_XRES", "exif_focal", "exif_focal_of_tags",
           "exif_in_range", "exif_number", "focal_from_exif", "focal_from_exif_tags", "read_exif_tags",
           "PRIOR_FOV_DEG", "PRIOR_FOV_RANGE_DEG", "FocalEstimate", "centred_K", "focal_from_fov", "fov_from_focal",
           "prior_focal", "user_focal",
           "GPS_IFD", "gps_from_exif", "gps_from_exif_tags",
           "PLAUSIBLE_FOV_DEG", "VP_JITTER_FITS", "VP_JITTER_MISSES", "VP_JITTER_PX", "VP_SD_MULTIPLIER",
           "VP_SPLIT_MIN_QUADS", "VP_SPLIT_PARTS", "VP_STABILITY_CHECK", "evidence_halves", "halved_fit", "jittered_quads", "vanishing_estimate", "vanishing_fit",
           "vanishing_focal", "vanishing_stability", "vanishing_steadiness", "vp_max_sd"]
