"""IFC houses -> meshes + exact window-void ground truth (see fenestra/scenes/loader.py, fenestra/scenes/ground_truth.py)."""
from fenestra.scenes.loader import list_scenes, load_scene

__all__ = ["load_scene", "list_scenes"]
