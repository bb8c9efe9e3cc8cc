"""model.ifc's window bodies: parametric lining, frames and glass as swept solids, one body per
window type, mapped into each window.

    sizes = type_sizes(placed)                 # {window index: TypeSize}: the windows that share a type
    body = window_body(f, context, size, "SINGLE_PANEL", frame_style, glass_style)   # IfcRepresentationMap
    rep = mapped_body(f, context, body, size, width_m, height_m)                   # the window's Body

Types by size. A BIM modeller keeps one window type per window product: the windows of a façade
that are one size (their measured width and height within TYPE_SIZE_REL of each other: the
measurement's own spread, row_lines' agreement) are one type, its body built once at their median
size (:func:`type_sizes`), and each window maps that body (IfcMappedItem) scaled to its own measured
width and height (IfcCartesianTransformationOperator3DnonUniform; by about TYPE_SIZE_REL at most,
so the lining's section changes by about that share: 5 mm of 50 mm): the type carries the geometry, every window fills
its opening exactly. Windows of another size get another type.

The body (``ifcopenshell.api.geometry.add_window_representation``): IfcExtrudedAreaSolids for the
lining, each panel's frame and its glass (IfcShapeAspects "Lining", "Framing", "Glazing" of the
type's representation map), in the window's placement frame: x along the wall from the void's
left edge, y into the wall (the lining starts LINING_OFFSET_M behind the photographed plane), z up
from the sill. Section sizes are a typical timber window's, at most LINING_SHARE of the window's
shorter side (a 1:25 model's 9 cm pane gets a 4 mm lining). Mullions and transoms split the width
or height evenly. A partitioning that the parametric body does not build (a grid of 2 x 2 panels:
IfcWindowType USERDEFINED) is built as one panel.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fenestra.pipeline.export.geometry import COVERING_THICKNESS_M

TYPE_SIZE_REL = 0.10  # windows whose widths and heights agree within this share are one window type
LINING_M = 0.05  # lining thickness and depth, frame thickness (a timber window's section)
FRAME_DEPTH_M = 0.035
LINING_SHARE = 0.08  # ... at most this share of the window's shorter side
LINING_OFFSET_M = COVERING_THICKNESS_M + 0.05  # the lining's face behind the photographed plane
# partitionings the parametric body builds, and its panels along (width, height)
PANELS = {"SINGLE_PANEL": (1, 1), "DOUBLE_PANEL_VERTICAL": (2, 1), "DOUBLE_PANEL_HORIZONTAL": (1, 2),
          "TRIPLE_PANEL_VERTICAL": (3, 1), "TRIPLE_PANEL_HORIZONTAL": (1, 3)}


@dataclass(frozen=True)
class TypeSize:
    """A window type's size: key (its number, 0 = the first window's), width_m and height_m: the
    median of its windows' measured sizes (m)."""

    key: int
    width_m: float
    height_m: float


def type_sizes(placed, rel: float = TYPE_SIZE_REL) -> dict[int, TypeSize]:
    """{window index: TypeSize} of ``placed`` (objects with ``index``, ``width_m``, ``height_m``):
    repeatedly, the window with the most others within ``rel`` of its width and height (ties: the
    lower index) makes a type of itself and those not yet typed; each type's size is its windows'
    median; types are numbered by their first window's index."""
    left = sorted(placed, key=lambda p: p.index)

    def near(a, b) -> bool:
        return abs(b.width_m / a.width_m - 1) <= rel and abs(b.height_m / a.height_m - 1) <= rel

    groups: list[list] = []
    while left:
        seed = max(left, key=lambda a: (sum(near(a, b) for b in left), -a.index))
        group = [b for b in left if near(seed, b)]
        groups.append(group)
        left = [b for b in left if b not in group]
    groups.sort(key=lambda g: min(p.index for p in g))
    out = {}
    for key, g in enumerate(groups):
        size = TypeSize(key, float(np.median([p.width_m for p in g])), float(np.median([p.height_m for p in g])))
        out.update({p.index: size for p in g})
    return out


def lining_properties(width_m: float, height_m: float, partition: str) -> tuple[dict, list[dict]]:
    """(IfcWindowLiningProperties values, [IfcWindowPanelProperties values per panel]) for a window
    of width_m x height_m split as ``partition`` (a PANELS key), m."""
    cols, rows = PANELS[partition]
    s = min(LINING_M, LINING_SHARE * min(width_m, height_m))
    depth = min(FRAME_DEPTH_M, 0.7 * s)
    lining = {"LiningDepth": s, "LiningThickness": s, "LiningOffset": LINING_OFFSET_M,
              "LiningToPanelOffsetX": s / 2, "LiningToPanelOffsetY": s / 2,
              "MullionThickness": s, "FirstMullionOffset": width_m / cols, "SecondMullionOffset": 2 * width_m / cols,
              "TransomThickness": s, "FirstTransomOffset": height_m / rows, "SecondTransomOffset": 2 * height_m / rows}
    return lining, [{"FrameDepth": depth, "FrameThickness": s}] * (cols * rows)


def window_body(f, context, size: TypeSize, partitioning: str, frame_style, glass_style):
    """The IfcRepresentationMap of a window type of ``size``: the parametric body
    (add_window_representation, SweptSolid) split as ``partitioning`` (IfcWindowType's; one that
    PANELS lacks is built as one panel), its Lining and Framing styled ``frame_style``, its
    Glazing ``glass_style`` (IfcSurfaceStyles), shape aspects on the map."""
    import ifcopenshell.api.geometry  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)
    import ifcopenshell.api.style  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)

    partition = partitioning if partitioning in PANELS else "SINGLE_PANEL"
    lining, panels = lining_properties(size.width_m, size.height_m, partition)
    origin = f.createIfcAxis2Placement3D(f.createIfcCartesianPoint((0.0, 0.0, 0.0)), None, None)
    placeholder = f.createIfcShapeRepresentation(context, "Body", "SweptSolid", ())
    body_map = f.createIfcRepresentationMap(origin, placeholder)  # the shape aspects' owner, filled below
    rep = ifcopenshell.api.geometry.add_window_representation(
        f, context=context, overall_width=size.width_m, overall_height=size.height_m, partition_type=partition,
        lining_properties=lining, panel_properties=panels, part_of_product=body_map, unit_scale=1.0)
    body_map.MappedRepresentation = rep
    f.remove(placeholder)
    for aspect in body_map.HasShapeAspects or ():
        style = glass_style if aspect.Name == "Glazing" else frame_style
        for item in (i for r in aspect.ShapeRepresentations for i in r.Items):
            ifcopenshell.api.style.assign_item_style(f, item=item, style=style)
    return body_map


def mapped_body(f, context, body_map, size: TypeSize, width_m: float, height_m: float):
    """A window's Body: ``body_map`` (its type's, built at ``size``) mapped at its placement and
    scaled to width_m x height_m (m) along x and z, unscaled through the wall (y)."""
    origin = f.createIfcCartesianPoint((0.0, 0.0, 0.0))
    op = f.createIfcCartesianTransformationOperator3DnonUniform(
        None, None, origin, float(width_m / size.width_m), None, 1.0, float(height_m / size.height_m))
    item = f.createIfcMappedItem(body_map, op)
    return f.createIfcShapeRepresentation(context, "Body", "MappedRepresentation", (item,))
