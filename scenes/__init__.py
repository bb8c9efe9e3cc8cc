"""IFC houses -> meshes + exact window-void ground truth (see scenes/loader.py, scenes/ground_truth.py)."""
from scenes.loader import list_scenes, load_scene

__all__ = ["load_scene", "list_scenes"]
