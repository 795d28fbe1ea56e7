"""contact_sim: collision detection and contact response for rigid bodies, in Python with numpy,
its hot loops compiled by numba.

Quick start::

    import contact_sim as cs
    world = cs.load_scene(cs.default_scene_path())
    for _ in range(60):
        world.step()
    print(world.body("ball").position)

The engine depends on numpy, numba, scipy, trimesh, PyYAML and yourdfpy; it never imports ROS.
"""
from .collision import DetectionStats, collide, vertex_inside
from .contacts import FEATURES, Contacts
from .errors import BoundsError, ContactSimError, EngineError, SceneError, StudyError
from .scene import default_scene_path, list_scenes, load_scene, resolve_scene
from .settings import Material, Settings
from .cylinder import Cylinder
from .shapes import Box, Convex, Plane, Sphere, TriMesh
from .stats import StepStats
from .study import list_studies, load_study, resolve_study, run_study
from .world import Body, World

__version__ = "0.1.0"

__all__ = [
    "Body", "BoundsError", "Box", "ContactSimError", "Contacts", "Convex", "Cylinder", "DetectionStats", "EngineError",
    "FEATURES", "Material", "Plane", "SceneError", "Settings", "Sphere", "StepStats", "StudyError", "TriMesh", "World",
    "collide", "default_scene_path", "list_scenes", "list_studies", "load_scene", "load_study", "resolve_scene",
    "resolve_study", "run_study", "vertex_inside",
]
