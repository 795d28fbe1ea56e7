"""Scene files (YAML) → ``World``. Every error names its path in the scene and the reason."""
import os

from .errors import ContactSimError, SceneError
from .settings import parse_material, parse_settings
from .cylinder import Cylinder
from .shapes import Box, Convex, Plane, Sphere, TriMesh
from .validate import POINTS, SCALE, check_keys
from .world import World

TOP_KEYS = {"name", "description", "gravity", "settings", "materials", "bodies", "robots"}
ROBOT_KEYS = {"urdf", "prefix", "base_pose", "joint_positions", "package_paths", "convex_meshes", "material",
              "disable_collisions", "srdf", "exclude_touching"}
BODY_KEYS = {"name", "kind", "model", "shape", "mass", "density", "position", "orientation", "velocity",
             "angular_velocity", "material", "collision"}
SHAPE_KEYS = {
    "plane": {"type", "normal", "offset"},
    "sphere": {"type", "radius"},
    "box": {"type", "size", "slab_normals"},
    "cylinder": {"type", "radius", "length", "slab_normals"},
    "convex": {"type", "points", "file", "scale", "slab_normals"},
    "mesh": {"type", "vertices", "faces", "file", "scale", "slab_normals"},
}


def default_scene_path():
    """Path of the built-in default scene shipped with the package."""
    return os.path.join(scenes_dir(), "default.yaml")


def source_scenes_dir():
    """``config/scenes`` of the source tree this package runs from (also ``pip install -e``), or
    None when the package is installed elsewhere."""
    d = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "config", "scenes"))
    return d if os.path.isdir(d) else None


def scenes_dir(search=None):
    """Folder of the shipped scenes: the first existing folder of ``search`` (a list of folders,
    e.g. the ROS package's share folder from the ament index), else ``config/scenes`` beside the
    package (source tree), else ``share/contact_sim/config/scenes`` of the Python prefix (pip)."""
    import sys

    candidates = list(search or []) + [source_scenes_dir(),
                                       os.path.join(sys.prefix, "share", "contact_sim", "config", "scenes")]
    for c in candidates:
        if c and os.path.isdir(c):
            return os.path.normpath(c)
    looked = ", ".join(c for c in candidates if c)
    raise ContactSimError(f"cannot find the shipped scenes (config/scenes; looked in {looked}); pass a scene path")


def resolve_scene(name_or_path, search=None):
    """A scene path from a path, or the name of a shipped scene (``bouncing_ball``), looked up in
    ``scenes_dir(search)``."""
    if os.path.isfile(name_or_path):
        return name_or_path
    folder = scenes_dir(search)
    shipped = os.path.join(folder, name_or_path if name_or_path.endswith(".yaml") else name_or_path + ".yaml")
    if os.path.isfile(shipped):
        return shipped
    raise ContactSimError(f"scene {name_or_path!r}: no such file, and no shipped scene of that name "
                          f"(shipped: {', '.join(list_scenes(search))})")


def list_scenes(search=None):
    """The names of the shipped scenes (``list[str]``, sorted; ``resolve_scene`` takes each), from
    ``scenes_dir(search)``."""
    return sorted(f[:-5] for f in os.listdir(scenes_dir(search)) if f.endswith(".yaml"))


def load_scene(source, base_dir=None):
    """Build a ``World`` from a scene file path or a dict of the same content.

    Mesh files resolve relative to the scene file (or ``base_dir``, default the current folder,
    for a dict). Raises ``SceneError`` naming the path (``bodies[3].mass``) and the reason; a bad
    scene never yields a half-built world.
    """
    if isinstance(source, (str, os.PathLike)):
        import yaml

        path = os.fspath(source)
        if not os.path.isfile(path):
            raise SceneError("", f"no such scene file {path!r}")
        try:
            with open(path) as fh:
                data = yaml.safe_load(fh)
        except yaml.YAMLError as exc:
            raise SceneError("", f"{path}: not valid YAML: {exc}") from None
        base_dir = os.path.dirname(os.path.abspath(path)) if base_dir is None else base_dir
    elif isinstance(source, dict):
        data = source
    else:
        raise SceneError("", f"a scene is a file path or a dict, got {type(source).__name__}")
    if data is None:
        data = {}
    base_dir = os.getcwd() if base_dir is None else base_dir
    try:   # the rules of contact_sim.validate, the same as for code; errors become scene paths
        return _build(data, base_dir)
    except SceneError:
        raise
    except ContactSimError as exc:
        raise _as_scene_error(exc) from None


def _build(data, base_dir):
    check_keys(data, "", TOP_KEYS)
    settings = parse_settings(data.get("settings"))
    materials = {}
    mats = data.get("materials") or {}
    if not isinstance(mats, dict):
        raise SceneError("materials", f"must be a mapping of name → material, got {type(mats).__name__}")
    for name, m in mats.items():
        materials[str(name)] = parse_material(m if m is not None else {}, f"materials.{name}")
    world = World(gravity=data.get("gravity", [0.0, 0.0, -9.81]), settings=settings, materials=materials)
    bodies = data.get("bodies") or []
    if not isinstance(bodies, list):
        raise SceneError("bodies", f"must be a list, got {type(bodies).__name__}")
    for i, b in enumerate(bodies):
        spec = parse_body(b, f"bodies[{i}]", base_dir)
        try:
            world.add_body(spec.pop("name"), spec.pop("shape"), **spec)
        except SceneError:
            raise
        except ContactSimError as exc:
            raise _as_scene_error(exc) from None
    robots = data.get("robots") or []
    if not isinstance(robots, list):
        raise SceneError("robots", f"must be a list, got {type(robots).__name__}")
    for i, r in enumerate(robots):
        add_scene_robot(world, r, f"robots[{i}]", base_dir)
    world.mark_initial()
    return world


def add_scene_robot(world, r, path, base_dir):
    """One ``robots:`` entry of a scene: ``{urdf: path (relative to the scene), prefix, base_pose:
    {position, orientation}, joint_positions: {joint: value}, package_paths: [folders] or {package:
    folder}, convex_meshes, material, disable_collisions: [[link or body, link or body], ...] (links without
    the prefix, scene bodies by name), exclude_touching (default true: pairs in contact at the initial
    configuration between links, or a link and a static body, are never tested)}``; returns the
    body names. Errors name ``path`` and the key."""
    from . import robot

    check_keys(r, path, ROBOT_KEYS)
    if "urdf" not in r:
        raise SceneError(f"{path}.urdf", "required: a URDF file path (relative to the scene)")
    urdf = r["urdf"]
    if not isinstance(urdf, str) or not urdf:
        raise SceneError(f"{path}.urdf", f"must be a file path, got {urdf!r}")
    if not urdf.lstrip().startswith("<"):
        urdf = urdf if os.path.isabs(urdf) else os.path.join(base_dir, urdf)
        if not os.path.isfile(urdf):
            raise SceneError(f"{path}.urdf", f"no such file {r['urdf']!r} (looked in {base_dir})")
    srdf = r.get("srdf")
    if srdf is not None:
        if not isinstance(srdf, str) or not srdf:
            raise SceneError(f"{path}.srdf", f"must be a file path, got {srdf!r}")
        srdf = srdf if os.path.isabs(srdf) else os.path.join(base_dir, srdf)
        if not os.path.isfile(srdf):
            raise SceneError(f"{path}.srdf", f"no such file {r['srdf']!r} (looked in {base_dir})")
    pose = r.get("base_pose")
    if pose is not None:
        check_keys(pose, f"{path}.base_pose", {"position", "orientation"})
        pose = (pose.get("position", [0.0, 0.0, 0.0]), pose.get("orientation", [0.0, 0.0, 0.0, 1.0]))
    pkg = r.get("package_paths")
    if isinstance(pkg, dict):
        pkg = {k: v if os.path.isabs(str(v)) else os.path.join(base_dir, str(v)) for k, v in pkg.items()}
    elif isinstance(pkg, list):
        pkg = [v if os.path.isabs(str(v)) else os.path.join(base_dir, str(v)) for v in pkg]
    elif pkg is not None:
        raise SceneError(f"{path}.package_paths",
                         f"must be a list of folders or a mapping package → folder, got {pkg!r}")
    prefix = r.get("prefix", "")
    pairs = r.get("disable_collisions") or []
    if not isinstance(pairs, list) or not all(isinstance(p, list) and len(p) == 2 for p in pairs):
        raise SceneError(f"{path}.disable_collisions",
                         f"must be a list of [link or body, link or body] pairs, got {pairs!r}")
    touching = r.get("exclude_touching", True)
    if not isinstance(touching, bool):
        raise SceneError(f"{path}.exclude_touching", f"must be true or false, got {touching!r}")
    saved = world._save_bodies(), world.robots, world.disabled_pairs
    try:
        names = robot.add_urdf(world, urdf, prefix, pose, r.get("joint_positions"), pkg, r.get("convex_meshes", False),
                               r.get("material"), where=path, srdf=srdf, disable_collisions=pairs,
                               exclude_touching=touching)
    except SceneError:
        raise
    except ContactSimError as exc:
        world._restore_bodies(saved[0])
        world.robots, world.disabled_pairs = saved[1], saved[2]
        raise _as_scene_error(exc) from None
    return names


def parse_body(b, path, base_dir="."):
    """One body mapping of a scene → ``add_body`` arguments (a dict with ``name``, ``shape`` and
    ``where``), errors naming ``path`` (``bodies[3].shape.radius``)."""
    check_keys(b, path, BODY_KEYS)
    if "name" not in b:
        raise SceneError(f"{path}.name", "required")
    if "shape" not in b:
        raise SceneError(f"{path}.shape", "required")
    shape = parse_shape(b["shape"], f"{path}.shape", base_dir)
    collision = b.get("collision") or {}
    check_keys(collision, f"{path}.collision", {"group", "mask"})
    spec = {k: b[k] for k in ("name", "kind", "model", "mass", "density", "position", "orientation", "velocity",
                              "angular_velocity", "material") if k in b}
    spec.update({k: collision[k] for k in ("group", "mask") if k in collision}, shape=shape, where=path)
    return spec


def add_scene_bodies(world, bodies, base_dir=None, path="bodies"):
    """Add a list of bodies written as in a scene file (``bodies:`` entries) to ``world``, all or
    nothing; returns their indices. Mesh files resolve relative to ``base_dir`` (default the
    current folder). Errors are ``SceneError`` naming ``<path>[i].<key>``; a refused list leaves
    the world as it was."""
    if not isinstance(bodies, list):
        raise SceneError(path, f"must be a list of bodies, got {type(bodies).__name__}")
    base_dir = os.getcwd() if base_dir is None else base_dir
    specs = [parse_body(b, f"{path}[{i}]", base_dir) for i, b in enumerate(bodies)]
    try:
        return world.add_bodies(specs)
    except SceneError:
        raise
    except ContactSimError as exc:
        raise _as_scene_error(exc) from None


def _as_scene_error(exc):
    text = str(exc)
    path, _, reason = text.partition(": ")
    return SceneError(path, reason) if reason else SceneError("", text)


def parse_shape(d, path, base_dir="."):
    """A shape from its scene mapping (``{type: box, size: [...]}``), errors naming ``path``.
    ``slab_normals: [[x, y, z], ...]`` sets the bounding-slab directions of a polyhedron."""
    shape = _parse_shape(d, path, base_dir)
    if isinstance(d, dict) and "slab_normals" in d:
        try:
            shape.with_slabs(d["slab_normals"], name=path)
        except ContactSimError as exc:
            raise _as_scene_error(exc) from None
    return shape


def _parse_shape(d, path, base_dir):
    if not isinstance(d, dict) or "type" not in d:
        raise SceneError(f"{path}.type", f"required: one of {', '.join(SHAPE_KEYS)}")
    t = d["type"]
    if t not in SHAPE_KEYS:
        raise SceneError(f"{path}.type", f"must be one of {', '.join(SHAPE_KEYS)}; got {t!r}")
    check_keys(d, path, SHAPE_KEYS[t])
    try:
        if t == "plane":
            return Plane(d.get("normal", [0, 0, 1]), d.get("offset", 0.0), name=path)
        if t == "sphere":
            if "radius" not in d:
                raise SceneError(f"{path}.radius", "required")
            return Sphere(d["radius"], name=path)
        if t == "box":
            if "size" not in d:
                raise SceneError(f"{path}.size", "required")
            return Box(d["size"], name=path)
        if t == "cylinder":
            for key in ("radius", "length"):
                if key not in d:
                    raise SceneError(f"{path}.{key}", "required")
            return Cylinder(d["radius"], d["length"], name=path)
        scale = SCALE.check(d.get("scale", 1.0), f"{path}.scale")
        if "file" in d:
            other = {"points"} if t == "convex" else {"vertices", "faces"}
            if other & set(d):
                raise SceneError(path, f"give file or {' and '.join(sorted(other))}, not both")
            f = d["file"]
            full = f if os.path.isabs(str(f)) else os.path.join(base_dir, str(f))
            if not os.path.isfile(full):
                raise SceneError(f"{path}.file", f"no such file {str(f)!r} (looked in {base_dir})")
            cls = Convex if t == "convex" else TriMesh
            return cls.from_file(full, scale, name=path)
        if t == "convex":
            if "points" not in d:
                raise SceneError(f"{path}.points", "required (or file)")
            # checked before scaling, so the product stays finite; the shape checks the result
            return Convex(POINTS.check(d["points"], f"{path}.points", what="points") * scale, name=path)
        if "vertices" not in d or "faces" not in d:
            raise SceneError(path, "mesh needs vertices and faces (or file)")
        return TriMesh(POINTS.check(d["vertices"], f"{path}.vertices", what="points") * scale, d["faces"], name=path)
    except SceneError:
        raise
    except ContactSimError as exc:
        raise _as_scene_error(exc) from None
