"""Robots from URDF: collision geometry from the description, link poses from joint positions.

``World.add_urdf`` parses a URDF (yourdfpy: a path or the XML text) and adds one kinematic body per
``<collision>`` element of every link, named by the link (with the prefix): the first element of
link ``L`` is body ``L``, further ones ``L#1``, ``L#2``, ... (the engine has no compound bodies; the
bodies of one link always move together). Each body's frame is its element's frame: link pose ∘
element ``origin``, so every shape stays centred as the engine's exact kernels expect.

``World.set_joint_positions`` keeps each joint's own stamp, as robot_state_publisher does: a joint's
velocity is the finite difference of its consecutive positions over their stamps, so two publishers
(an arm driver and a gripper driver) each move their own joints at their own times. Forward
kinematics (revolute, continuous, prismatic, fixed and mimic joints; floating and planar joints stay
at their origin) gives every link's pose, and the joint velocities propagated down the tree its
velocity; every body of the robot is set at once (``World.set_states``). Bad input is refused by
name before anything changes.

Links joined by a joint never collide with each other (MoveIt's "Adjacent"; a link without
geometry in between is skipped, so its geometric neighbours are adjacent); nor do the bodies of one
link. ``World.disable_collisions`` turns off further pairs.
"""
import io
import math
import os
from collections.abc import Mapping

import numpy as np

from .errors import ContactSimError
from .jit import njit
from .quat import rotate as quat_rotate
from .validate import ANGULAR_VELOCITIES, POSITIONS, VELOCITIES, show
from .constants import LIMIT_TOLERANCE, MIMIC_TOLERANCE, CONVEX_MESH_TOLERANCE

MOVABLE = ("revolute", "continuous", "prismatic")
PACKAGE_PATH_ENV = "CONTACT_SIM_PACKAGE_PATH"   # folders holding ROS packages, os.pathsep-separated


# ---------------------------------------------------------------- small rigid-transform helpers
def rotation_about(axis, angle):
    """``(3, 3)`` rotation by ``angle`` about the unit ``axis (3,)`` (Rodrigues)."""
    x, y, z = axis
    c, s = np.cos(angle), np.sin(angle)
    C = 1.0 - c
    return np.array([[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
                     [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
                     [z * x * C - y * s, z * y * C + x * s, c + z * z * C]])


def matrix_to_quat(R):
    """Quaternions ``(M, 4)`` x, y, z, w (w >= 0) of rotation matrices ``R (M, 3, 3)`` (Shepperd's
    method: the largest of the four squared components is taken first, so no division is small)."""
    R = np.asarray(R, float)
    tr = R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2]
    cand = np.stack([tr, R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    pick = np.argmax(cand, axis=1)
    q = np.empty((len(R), 4))
    for k in range(4):
        m = pick == k
        if not m.any():
            continue
        r = R[m]
        if k == 0:
            s = 2.0 * np.sqrt(1.0 + tr[m])
            q[m] = np.stack([(r[:, 2, 1] - r[:, 1, 2]) / s, (r[:, 0, 2] - r[:, 2, 0]) / s,
                             (r[:, 1, 0] - r[:, 0, 1]) / s, 0.25 * s], axis=1)
        else:
            i = k - 1
            j, l = (i + 1) % 3, (i + 2) % 3
            s = 2.0 * np.sqrt(1.0 + r[:, i, i] - r[:, j, j] - r[:, l, l])
            out = np.empty((len(r), 4))
            out[:, i] = 0.25 * s
            out[:, j] = (r[:, j, i] + r[:, i, j]) / s
            out[:, l] = (r[:, l, i] + r[:, i, l]) / s
            out[:, 3] = (r[:, l, j] - r[:, j, l]) / s
            q[m] = out
    q *= np.where(q[:, 3:4] < 0, -1.0, 1.0)
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def pose_matrix(position, orientation):
    """``(4, 4)`` homogeneous transform of a position ``(3,)`` and quaternion ``(4,)`` x, y, z, w."""
    x, y, z, w = np.asarray(orientation, float) / np.linalg.norm(orientation)
    T = np.eye(4)
    T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    T[:3, 3] = position
    return T


# ---------------------------------------------------------------- mesh files
def resolve_uri(uri, base_dir, package_paths=None):
    """The file a URDF mesh ``uri`` names, and the places looked in: ``(path or None, looked)``.

    ``package://pkg/rest``: ``package_paths[pkg]/rest`` (a mapping), ``DIR/pkg/rest`` for each
    ``DIR`` of ``package_paths`` (a list) and of ``$CONTACT_SIM_PACKAGE_PATH`` / ``$ROS_PACKAGE_PATH``,
    then the package's share folder from the ament index when ``ament_index_python`` is installed
    (it imports no ROS client library), then ``base_dir/pkg/rest`` and ``base_dir/rest``: a URDF
    written for another simulator names folders beside it as packages (pybullet_data's Panda:
    ``package://meshes/collision/link0.obj``), and pybullet and yourdfpy look there too;
    ``file://`` an absolute path; anything else a path relative to ``base_dir`` (the URDF file's
    folder)."""
    looked = []
    if uri.startswith("package://"):
        pkg, _, rest = uri[len("package://"):].partition("/")
        if isinstance(package_paths, Mapping):
            if pkg in package_paths:
                looked.append(os.path.join(str(package_paths[pkg]), rest))
            dirs = []
        else:
            dirs = [str(d) for d in (package_paths or [])]
        for var in (PACKAGE_PATH_ENV, "ROS_PACKAGE_PATH"):
            dirs += [d for d in os.environ.get(var, "").split(os.pathsep) if d]
        looked += [os.path.join(d, pkg, rest) for d in dirs]
        for p in looked:
            if os.path.isfile(p):
                return p, looked
        beside = [os.path.join(base_dir, pkg, rest), os.path.join(base_dir, rest)]
        try:
            from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
        except ImportError:
            looked.append("(ament index: ament_index_python not installed)")
        else:
            try:
                p = os.path.join(get_package_share_directory(pkg), rest)
            except (PackageNotFoundError, LookupError, ValueError, OSError):   # OSError: no AMENT_PREFIX_PATH
                looked.append(f"(ament index: no package {pkg!r})")
            else:
                looked.append(p)
                if os.path.isfile(p):
                    return p, looked
        for p in beside:
            looked.append(p)
            if os.path.isfile(p):
                return p, looked
        return None, looked
    path = uri[len("file://"):] if uri.startswith("file://") else uri
    if not os.path.isabs(path):
        path = os.path.join(base_dir, path)
    looked.append(path)
    return (path if os.path.isfile(path) else None), looked


def _mesh_shape(path, scale, convex, what):
    """A ``Convex`` (the mesh is convex, or ``convex`` asks for its hull) or ``TriMesh`` of a mesh
    file (STL, OBJ, DAE, ... through trimesh), vertices multiplied by ``scale (3,)``."""
    import trimesh

    from .shapes import Convex, TriMesh

    try:
        mesh = trimesh.load(path, force="mesh", process=True)
    except Exception as exc:   # trimesh raises many types for bad files
        raise ContactSimError(f"{what}: cannot read mesh {path!r}: {exc}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ContactSimError(f"{what}: mesh {path!r} has no triangles")
    v = np.asarray(mesh.vertices, float) * scale
    f = np.asarray(mesh.faces, np.int64)
    if np.linalg.det(np.diag(scale)) < 0:   # a mirroring scale turns the faces inside out
        f = f[:, ::-1]
    if convex or mesh.is_convex or _on_its_hull(v, f):
        return Convex(v, name=what)
    return TriMesh(v, f, name=what)


def _on_its_hull(v, f):
    """Whether the mesh of vertices ``v (V, 3)`` and triangles ``f (F, 3)`` is its own convex hull, to
    ``CONVEX_MESH_TOLERANCE`` of its size: no vertex and no triangle's centroid more than that inside
    the hull (a concavity's faces cut into it: an L's inner corner by a third of its size). Robots'
    collision meshes usually are their links' hulls, saved with seams and rounded coordinates:
    pybullet_data's Panda's are within 0.23 mm (1.2e-3 of their size) of their hulls but trimesh
    calls them neither watertight nor convex, so they became open ``TriMesh`` bodies (the mesh
    kernels, a one-sided inside). Such a mesh becomes its hull, as pybullet makes every one."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(v)
    except (QhullError, ValueError):   # flat or degenerate: not a solid's surface
        return False
    size = float(np.ptp(v, axis=0).max())
    pts = np.vstack([v, v[f].mean(axis=1)])
    # qhull's equations: n·x + d ≤ 0 inside; a point's depth inside is its distance to the nearest plane
    depth = -(pts @ hull.equations[:, :3].T + hull.equations[:, 3])
    return bool(depth.min(axis=1).max() <= CONVEX_MESH_TOLERANCE * size)


# ---------------------------------------------------------------- the model
class RobotModel:
    """A robot's kinematic tree and the world bodies of its collision elements.

    ``joints``: movable and fixed joints in tree order (parents first) as dicts; ``q``: position of
    every movable joint by (prefixed) name; ``bodies`` / ``body_link`` / ``body_origin (B, 4, 4)``:
    each collision body, its link and its frame in the link's."""

    def __init__(self, name, prefix, root, joints, base, bodies, body_link, body_origin, q):
        self.name, self.prefix, self.root = name, prefix, root
        self.joints, self.base = joints, base
        self.bodies, self.body_link, self.body_origin = bodies, body_link, body_origin
        self.q = dict(q)
        self.q_initial = dict(q)
        self.by_name = {j["name"]: j for j in joints}
        self.exclusions = {}   # body-name pair -> why it is never tested (adjacent links, SRDF, given, touching)
        self._tree = None      # the kinematic tree as arrays for _forward (built on first use: ``tree``)
        self.reset()

    def tree(self):
        """The tree as ``_forward``'s arrays (built once): ``(joint names of q (Q,), parent (J,),
        origin (J,4,4), axis (J,3), kind (J,) 0 fixed 1 revolute 2 prismatic, q index (J,) (-1: none),
        leader index (J,) (-1: not a mimic), multiplier (J,), offset (J,), body link index (B,),
        body origin (B,4,4))``. Link 0 is the root; joint ``j`` makes link ``j + 1``."""
        if self._tree is None:
            link_index = {self.root: 0}
            for k, j in enumerate(self.joints):
                link_index[j["child"]] = k + 1
            names = [j["name"] for j in self.joints if j["type"] in MOVABLE and j["mimic"] is None]
            qpos = {n: i for i, n in enumerate(names)}
            J = len(self.joints)
            parent, kind, qi, lead = (np.full(J, -1, np.int64) for _ in range(4))
            origin, axis, mul, off = np.zeros((J, 4, 4)), np.zeros((J, 3)), np.ones(J), np.zeros(J)
            for k, j in enumerate(self.joints):
                parent[k], origin[k], axis[k] = link_index[j["parent"]], j["origin"], j["axis"]
                kind[k] = 0 if j["type"] not in MOVABLE else (2 if j["type"] == "prismatic" else 1)
                if j["mimic"] is not None:
                    lead[k], mul[k], off[k] = qpos[j["mimic"][0]], j["mimic"][1], j["mimic"][2]
                elif kind[k]:
                    qi[k] = qpos[j["name"]]
            body_link = np.array([link_index[n] for n in self.body_link], np.int64)
            self._tree = (names, parent, origin, axis, kind, qi, lead, mul, off, body_link,
                          np.ascontiguousarray(self.body_origin, dtype=float))
        return self._tree

    def reset(self):
        """Back to ``q_initial``, at rest, with no stamp yet: each joint's next position places it."""
        self.q = dict(self.q_initial)
        self.qd = {n: 0.0 for n in self.q}     # joint velocities (rad/s or m/s)
        # per joint: its last stamp, and the position and stamp before that one (a later position at
        # the same stamp replaces the last, its velocity still taken from the one before)
        self.t = {n: None for n in self.q}
        self.before = {n: None for n in self.q}

    def restart_stamps(self):
        """Keep the positions, forget the stamps and velocities: each joint's next position places it
        at rest (after a clock jump, or a pause in the joint states)."""
        self.qd = {n: 0.0 for n in self.q}
        self.t = {n: None for n in self.q}
        self.before = {n: None for n in self.q}

    def update(self, names, positions, stamp, call):
        """The state after the joints ``names (M,)`` take ``positions (M,)`` at ``stamp`` (s), not yet
        applied: ``(q, qd, t, before)`` dicts. Refuses (``ContactSimError`` naming the joint) a position
        outside the limits, a stamp before the joint's last one, and a mimic joint's position that
        disagrees with its leader's (one that agrees within ``MIMIC_TOLERANCE`` is accepted, and
        ignored: a driver's JointState lists mimic joints too)."""
        q, qd, t, before = dict(self.q), dict(self.qd), dict(self.t), dict(self.before)
        given = {n: float(x) for n, x in zip(names, positions)}
        for n, x in given.items():
            j = self.by_name[n]
            if j["mimic"] is not None:
                continue
            lo, hi = j["limits"]
            if not (lo - LIMIT_TOLERANCE <= x <= hi + LIMIT_TOLERANCE):
                raise ContactSimError(f"{call}: joint {n!r} position {x!r} is outside its limits [{lo!r}, {hi!r}]")
            last = t[n]
            if last is not None and stamp < last:
                raise ContactSimError(f"{call}: joint {n!r}: stamp {stamp!r} is before its previous one ({last!r})")
            if last is None or stamp > last:
                before[n] = (q[n], last) if last is not None else None
            t[n], q[n] = stamp, float(x)
            b = before[n]
            qd[n] = 0.0 if b is None else (q[n] - b[0]) / (stamp - b[1])
        for n, x in given.items():
            m = self.by_name[n]["mimic"]
            if m is not None:
                want = m[1] * q[m[0]] + m[2]
                if not abs(x - want) <= MIMIC_TOLERANCE * max(1.0, abs(want)):
                    raise ContactSimError(f"{call}: joint {n!r} mimics {m[0]!r}: its position {x!r} disagrees with "
                                          f"{m[1]!r} × {m[0]} + {m[2]!r} = {want!r} (set {m[0]!r} instead)")
        return q, qd, t, before

    def link_transforms(self, q):
        """World transforms ``{link: (4, 4)}`` of every link for joint positions ``q`` (a mapping)."""
        T = {self.root: self.base}
        for j in self.joints:
            parent = T[j["parent"]]
            M = parent @ j["origin"]
            if j["type"] in MOVABLE:
                m = j["mimic"]
                x = q[j["name"]] if m is None else m[1] * q[m[0]] + m[2]
                J = np.eye(4)
                if j["type"] == "prismatic":
                    J[:3, 3] = j["axis"] * x
                else:
                    J[:3, :3] = rotation_about(j["axis"], x)
                M = M @ J
            T[j["child"]] = M
        return T

    def body_poses(self, q):
        """Positions ``(B, 3)`` and quaternions ``(B, 4)`` of the robot's bodies for ``q``."""
        T = self.link_transforms(q)
        W = np.array([T[link] for link in self.body_link]).reshape(-1, 4, 4) @ self.body_origin
        return W[:, :3, 3].copy(), matrix_to_quat(W[:, :3, :3])

    def body_states(self, q, qd):
        """Positions ``(B, 3)``, quaternions ``(B, 4)``, velocities ``(B, 3)`` and angular velocities
        ``(B, 3)`` of the robot's bodies (world frame; each body's velocity is its origin's) for joint
        positions ``q`` and velocities ``qd`` (mappings), in one compiled pass (``_forward``):
        forward kinematics, and the velocities down the tree from a base at rest (a child's angular
        velocity its parent's plus ``axis · q̇`` of a revolute joint, its origin's velocity its
        parent's plus ``ω_parent × (o_child − o_parent)`` plus ``axis · q̇`` of a prismatic one; a
        mimic joint moves at ``multiplier · q̇`` of its leader)."""
        names, *arrays = self.tree()
        qa = np.array([q[n] for n in names], float)
        qda = np.array([qd[n] for n in names], float)
        B = len(self.bodies)
        out = np.empty((B, 13))
        _forward(*arrays[:8], qa, qda, np.ascontiguousarray(self.base, dtype=float), arrays[8], arrays[9], out)
        return out[:, 0:3], out[:, 3:7], out[:, 7:10], out[:, 10:13]


@njit
def _forward(parent, origin, axis, kind, qi, lead, mul, off, q, qd, base, body_link, body_origin, out):
    """``RobotModel.body_states`` in one pass: link transforms and velocities (link 0 the root at
    ``base``, at rest; joint ``j`` makes link ``j + 1`` from link ``parent[j]``), then each body
    ``b``'s frame (its link's ∘ ``body_origin[b]``) as ``out[b] = (position (3), quaternion x y z w
    (4), velocity (3), angular velocity (3))``. Arrays as ``RobotModel.tree`` gives them."""
    J = parent.shape[0]
    T = np.empty((J + 1, 4, 4))
    V = np.zeros((J + 1, 3))
    W = np.zeros((J + 1, 3))
    T[0] = base
    M = np.empty((4, 4))
    for j in range(J):
        p = parent[j]
        _mul4(T[p], origin[j], M)
        ax = np.empty(3)   # the axis in the world
        for r in range(3):
            ax[r] = M[r, 0] * axis[j, 0] + M[r, 1] * axis[j, 1] + M[r, 2] * axis[j, 2]
        x, xd = 0.0, 0.0
        if kind[j] != 0:
            if lead[j] >= 0:
                x, xd = mul[j] * q[lead[j]] + off[j], mul[j] * qd[lead[j]]
            else:
                x, xd = q[qi[j]], qd[qi[j]]
        if kind[j] == 2:     # the child's origin slides along the axis
            for r in range(3):
                M[r, 3] += ax[r] * x
        elif kind[j] == 1:   # the child's frame turns about the axis (Rodrigues), its origin stays
            u0, u1, u2 = axis[j, 0], axis[j, 1], axis[j, 2]
            cs, sn = math.cos(x), math.sin(x)
            C = 1.0 - cs
            Rj = np.array([[cs + u0 * u0 * C, u0 * u1 * C - u2 * sn, u0 * u2 * C + u1 * sn],
                           [u1 * u0 * C + u2 * sn, cs + u1 * u1 * C, u1 * u2 * C - u0 * sn],
                           [u2 * u0 * C - u1 * sn, u2 * u1 * C + u0 * sn, cs + u2 * u2 * C]])
            Mr = M[:3, :3].copy()
            for r in range(3):
                for c in range(3):
                    M[r, c] = Mr[r, 0] * Rj[0, c] + Mr[r, 1] * Rj[1, c] + Mr[r, 2] * Rj[2, c]
        T[j + 1] = M
        # the child's origin, where the joint put it: the parent's velocity there, plus the joint's
        d0, d1, d2 = M[0, 3] - T[p, 0, 3], M[1, 3] - T[p, 1, 3], M[2, 3] - T[p, 2, 3]
        w0, w1, w2 = W[p, 0], W[p, 1], W[p, 2]
        V[j + 1, 0] = V[p, 0] + w1 * d2 - w2 * d1
        V[j + 1, 1] = V[p, 1] + w2 * d0 - w0 * d2
        V[j + 1, 2] = V[p, 2] + w0 * d1 - w1 * d0
        for r in range(3):
            W[j + 1, r] = W[p, r]
            if kind[j] == 2:
                V[j + 1, r] += ax[r] * xd
            elif kind[j] == 1:
                W[j + 1, r] += ax[r] * xd
    for b in range(body_link.shape[0]):
        L = body_link[b]
        _mul4(T[L], body_origin[b], M)
        for r in range(3):
            out[b, r] = M[r, 3]
        _quat_of(M, out[b, 3:7])
        d0, d1, d2 = M[0, 3] - T[L, 0, 3], M[1, 3] - T[L, 1, 3], M[2, 3] - T[L, 2, 3]
        w0, w1, w2 = W[L, 0], W[L, 1], W[L, 2]
        out[b, 7] = V[L, 0] + w1 * d2 - w2 * d1
        out[b, 8] = V[L, 1] + w2 * d0 - w0 * d2
        out[b, 9] = V[L, 2] + w0 * d1 - w1 * d0
        out[b, 10], out[b, 11], out[b, 12] = w0, w1, w2


@njit
def _mul4(A, B, out):
    """``out (4,4) = A @ B`` for homogeneous transforms, as scalar loops (no temporary)."""
    for r in range(4):
        for c in range(4):
            s = 0.0
            for k in range(4):
                s += A[r, k] * B[k, c]
            out[r, c] = s


@njit
def _quat_of(M, q):
    """``q (4,)`` x, y, z, w (w ≥ 0, unit) of the rotation ``M[:3, :3]``: ``matrix_to_quat``'s
    Shepperd's method for one matrix."""
    tr = M[0, 0] + M[1, 1] + M[2, 2]
    k, best = 0, tr
    for i in range(3):
        if M[i, i] > best:
            k, best = i + 1, M[i, i]
    if k == 0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q[0], q[1], q[2], q[3] = (M[2, 1] - M[1, 2]) / s, (M[0, 2] - M[2, 0]) / s, (M[1, 0] - M[0, 1]) / s, 0.25 * s
    else:
        i = k - 1
        j, m = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(1.0 + M[i, i] - M[j, j] - M[m, m])
        q[i] = 0.25 * s
        q[j] = (M[j, i] + M[i, j]) / s
        q[m] = (M[m, i] + M[i, m]) / s
        q[3] = (M[m, j] - M[j, m]) / s
    sign = -1.0 if q[3] < 0 else 1.0
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    for r in range(4):
        q[r] = sign * q[r] / n


def _joint_dict(j, prefix, where):
    t = j.type
    origin = np.eye(4) if j.origin is None else np.asarray(j.origin, float)
    axis = np.array([1.0, 0.0, 0.0]) if j.axis is None else np.asarray(j.axis, float)
    if t in MOVABLE:
        n = np.linalg.norm(axis)
        if not np.isfinite(n) or n < 1e-12:
            raise ContactSimError(f"{where}: joint {j.name!r}: axis must be non-zero, got {axis.tolist()}")
        axis = axis / n
    lo, hi = -np.inf, np.inf
    if t in ("revolute", "prismatic"):
        lim = j.limit
        lo = 0.0 if lim is None or lim.lower is None else float(lim.lower)
        hi = 0.0 if lim is None or lim.upper is None else float(lim.upper)
        if not lo <= hi:
            raise ContactSimError(f"{where}: joint {j.name!r}: lower limit {lo!r} above upper {hi!r}")
    mimic = None
    if j.mimic is not None and t in MOVABLE:
        mult = 1.0 if j.mimic.multiplier is None else float(j.mimic.multiplier)
        off = 0.0 if j.mimic.offset is None else float(j.mimic.offset)
        mimic = (prefix + j.mimic.joint, mult, off)
    if not np.all(np.isfinite(origin)):
        raise ContactSimError(f"{where}: joint {j.name!r}: origin is not finite")
    return {"name": prefix + j.name, "type": t if t in MOVABLE else "fixed", "parent": j.parent, "child": j.child,
            "origin": origin, "axis": axis, "limits": (lo, hi), "mimic": mimic}


def parse(urdf, prefix="", base_pose=None, package_paths=None, convex_meshes=False, where="add_urdf", srdf=None):
    """Parse ``urdf`` (a path, or the XML text) into ``(RobotModel without q, shapes (B,), adjacent
    body-name pairs)``. Errors name the link, joint or mesh URI."""
    import yourdfpy

    from .cylinder import Cylinder
    from .shapes import Box, Sphere

    if not isinstance(urdf, (str, os.PathLike)):
        raise ContactSimError(f"{where}: urdf must be a file path or URDF XML text, got {type(urdf).__name__}")
    if not isinstance(prefix, str):
        raise ContactSimError(f"{where}.prefix: must be a string, got {show(prefix)}")
    text = str(urdf)
    is_xml = text.lstrip().startswith("<")
    if not is_xml and not os.path.isfile(text):
        raise ContactSimError(f"{where}: no such URDF file {text!r}")
    base_dir = os.getcwd() if is_xml else os.path.dirname(os.path.abspath(text))
    # well-formed XML first: yourdfpy would otherwise "recover" a broken document into part of a robot
    import xml.etree.ElementTree as ET

    try:
        root = ET.fromstring(text) if is_xml else ET.parse(text).getroot()
    except (ET.ParseError, OSError) as exc:
        raise ContactSimError(f"{where}: not well-formed XML: {exc}") from None
    if root.tag != "robot":
        raise ContactSimError(f"{where}: not a URDF: the root element is <{root.tag}>, not <robot>")
    try:
        src = io.BytesIO(text.encode()) if is_xml else text
        model = yourdfpy.URDF.load(src, build_scene_graph=False, load_meshes=False, load_collision_meshes=False)
        robot = model.robot
    except Exception as exc:   # lxml and yourdfpy raise many types for a bad document
        raise ContactSimError(f"{where}: not a valid URDF ({type(exc).__name__}: {exc})") from None
    links = {link.name: link for link in robot.links}
    if not links:
        raise ContactSimError(f"{where}: the URDF has no links")
    children = {}
    parent_of = {}
    for j in robot.joints:
        for end in (j.parent, j.child):
            if end not in links:
                raise ContactSimError(f"{where}: joint {j.name!r} names an unknown link {end!r}")
        if j.child in parent_of:
            raise ContactSimError(f"{where}: link {j.child!r} has two parent joints")
        parent_of[j.child] = j
        children.setdefault(j.parent, []).append(j)
    roots = [n for n in links if n not in parent_of]
    if len(roots) != 1:
        raise ContactSimError(f"{where}: the links must form one tree; roots: {roots}")
    # joints parents first (depth-first from the root)
    order, stack = [], [roots[0]]
    while stack:
        for j in reversed(children.get(stack.pop(), [])):
            order.append(j)
            stack.append(j.child)
    if len(order) != len(robot.joints):
        raise ContactSimError(f"{where}: the joints contain a cycle")
    joints = [_joint_dict(j, prefix, where) for j in order]
    names = {j["name"] for j in joints}
    for j in joints:
        if j["mimic"] is not None:
            m = j["mimic"][0]
            if m not in names or j["mimic"][0] == j["name"] or \
                    next(x for x in joints if x["name"] == m)["type"] not in MOVABLE:
                raise ContactSimError(f"{where}: joint {j['name']!r} mimics {m!r}, which is not a movable joint")
    if base_pose is None:
        base = np.eye(4)
    else:
        from .validate import ORIENTATION, POSITION

        try:
            p, o = base_pose
        except (TypeError, ValueError):
            raise ContactSimError(f"{where}.base_pose: must be (position (3,), orientation (4,) x, y, z, w), "
                                  f"got {show(base_pose)}") from None
        base = pose_matrix(POSITION.check(p, f"{where}.base_pose.position"),
                           ORIENTATION.check(o, f"{where}.base_pose.orientation"))
    # collision elements → shapes (a mesh file and scale loaded once)
    shapes, bodies, body_link, origins, cache = [], [], [], [], {}
    for lname, link in links.items():
        for e, col in enumerate(link.collisions):
            what = f"{where}: link {lname!r} collision {e}"
            g = col.geometry
            if g is None:
                raise ContactSimError(f"{what}: no geometry")
            if g.box is not None:
                shape = Box(g.box.size, name=f"{what}.box")
            elif g.sphere is not None:
                shape = Sphere(g.sphere.radius, name=f"{what}.sphere")
            elif g.cylinder is not None:
                shape = Cylinder(g.cylinder.radius, g.cylinder.length, name=f"{what}.cylinder")
            elif g.mesh is not None:
                uri = g.mesh.filename
                path, looked = resolve_uri(uri, base_dir, package_paths)
                if path is None:
                    how = ""
                    if uri.startswith("package://"):
                        pkg = uri[len("package://"):].partition("/")[0]
                        how = (f"; add the folder that holds the package {pkg!r} to package_paths (add_urdf's "
                               f"package_paths, a scene robot's package_paths, the node's package_paths parameter) "
                               f"or to ${PACKAGE_PATH_ENV}")
                    raise ContactSimError(f"{what}: cannot find mesh {uri!r} (looked in: {', '.join(looked)}){how}")
                sc = np.broadcast_to(np.asarray(1.0 if g.mesh.scale is None else g.mesh.scale, float), (3,)).copy()
                if not np.all(np.isfinite(sc)) or np.any(sc == 0):
                    raise ContactSimError(f"{what}: mesh {uri!r} scale must be finite and non-zero, got {sc.tolist()}")
                key = (path, tuple(sc))
                if key not in cache:
                    cache[key] = _mesh_shape(path, sc, convex_meshes, f"{what}: mesh {uri!r}")
                shape = cache[key]
            else:
                raise ContactSimError(f"{what}: no box, sphere, cylinder or mesh")
            shapes.append(shape)
            bodies.append(prefix + lname + ("" if e == 0 else f"#{e}"))
            body_link.append(lname)
            origins.append(np.eye(4) if col.origin is None else np.asarray(col.origin, float))
    # adjacency: a joint's child against its nearest ancestor with geometry; a link's own bodies
    has_geom = {n for n in body_link}
    of_link = {}
    for b, lname in zip(bodies, body_link):
        of_link.setdefault(lname, []).append(b)
    pairs = set()
    for group in of_link.values():
        pairs |= {(a, b) for a in group for b in group if a < b}
    for lname in has_geom:
        up = parent_of.get(lname)
        while up is not None and up.parent not in has_geom:
            up = parent_of.get(up.parent)
        if up is not None:
            pairs |= {tuple(sorted((a, b))) for a in of_link[lname] for b in of_link[up.parent]}
    rm = RobotModel(prefix + robot.name, prefix, roots[0], joints, base, bodies, body_link,
                    np.array(origins).reshape(-1, 4, 4), {})
    rm.exclusions = {pair: "adjacent links" for pair in pairs}
    if srdf is not None:
        more = srdf_pairs(srdf, links, of_link, prefix, where)
        rm.exclusions.update({pair: "SRDF" for pair in more - pairs})
        pairs |= more
    return rm, shapes, pairs


def initial_positions(model, joint_positions, where):
    """Joint positions at start: 0, or the nearest limit when 0 is outside them; then the given ones."""
    q = {}
    for j in model.joints:
        if j["type"] in MOVABLE and j["mimic"] is None:
            lo, hi = j["limits"]
            q[j["name"]] = float(min(max(0.0, lo), hi))
    model.q_initial = q
    model.reset()
    if joint_positions:
        if not isinstance(joint_positions, Mapping):
            raise ContactSimError(f"{where}.joint_positions: must be a mapping of joint name → position, "
                                  f"got {show(joint_positions)}")
        names = [model.prefix + str(k) if model.prefix + str(k) in model.by_name else str(k) for k in joint_positions]
        names, pos = check_request(model.by_name, names, list(joint_positions.values()), f"{where}.joint_positions")
        q = model.update(names, pos, 0.0, f"{where}.joint_positions")[0]
    return q


def check_request(known, names, positions, call):
    """``names`` as a list of known joint names and ``positions`` as floats ``(M,)``; refuses a
    non-list, unknown or repeated name, a length mismatch, a non-number or a non-finite value."""
    if isinstance(names, (str, bytes)) or not hasattr(names, "__iter__"):
        raise ContactSimError(f"{call}.names: must be a list of joint names, got {show(names)}")
    names = list(names)
    bad = f"{call}.positions: must be {len(names)} numbers, got {show(positions)}"
    if isinstance(positions, (str, bytes)) or not hasattr(positions, "__len__"):
        raise ContactSimError(bad)
    try:
        raw = np.asarray(positions, dtype=object).reshape(-1)
        # a boolean or a string is no position, even where numpy would convert it
        if any(isinstance(x, (bool, np.bool_, str, bytes)) for x in raw):
            raise ValueError
        pos = raw.astype(float)
    except (TypeError, ValueError):
        raise ContactSimError(bad) from None
    if len(pos) != len(names):
        raise ContactSimError(f"{call}: {len(names)} joint names but {len(pos)} positions")
    for n, x in zip(names, pos):
        if n not in known:
            raise ContactSimError(f"{call}: unknown joint {n!r} (joints: {', '.join(sorted(known)) or 'none'})")
        if not np.isfinite(x):
            raise ContactSimError(f"{call}: joint {n!r} position must be finite, got {x!r}")
    if len(set(names)) != len(names):
        raise ContactSimError(f"{call}: a joint is named twice in {names!r}")
    return names, pos


def srdf_pairs(srdf, links, of_link, prefix, where):
    """Body-name pairs of an SRDF's ``<disable_collisions link1= link2=/>`` (MoveIt's allowed
    collisions; ``srdf`` a path or the XML text). Links without geometry have no bodies (no pair);
    a link the URDF does not have is refused by name."""
    import xml.etree.ElementTree as ET

    text = str(srdf)
    try:
        root = ET.fromstring(text) if text.lstrip().startswith("<") else ET.parse(text).getroot()
    except (ET.ParseError, OSError) as exc:
        raise ContactSimError(f"{where}.srdf: cannot read {text[:60]!r}: {exc}") from None
    pairs = set()
    for k, e in enumerate(root.iter("disable_collisions")):
        a, b = e.get("link1"), e.get("link2")
        for n in (a, b):
            if n not in links:
                raise ContactSimError(f"{where}.srdf: disable_collisions {k} names an unknown link {n!r}")
        pairs |= {tuple(sorted((x, y))) for x in of_link.get(a, []) for y in of_link.get(b, []) if x != y}
    return pairs


# ---------------------------------------------------------------- world operations
def add_urdf(world, urdf, prefix="", base_pose=None, joint_positions=None, package_paths=None, convex_meshes=False,
             material=None, where="add_urdf", srdf=None, disable_collisions=None, exclude_touching=True):
    """See ``World.add_urdf``; ``where`` starts error messages (a scene path)."""
    model, shapes, pairs = parse(urdf, prefix, base_pose, package_paths, convex_meshes, where, srdf)
    q = initial_positions(model, joint_positions, where)
    model.q_initial = dict(q)
    model.reset()
    taken = [b for b in model.bodies if b in world._index]
    if taken:
        raise ContactSimError(f"{where}: body {taken[0]!r} already exists (use prefix= for a second robot)")
    names = {j["name"] for r in world.robots for j in r.joints}
    clash = [j["name"] for j in model.joints if j["name"] in names]
    if clash:
        raise ContactSimError(f"{where}: joint {clash[0]!r} already belongs to another robot (use prefix=)")
    given = _given_pairs(world, model, disable_collisions, f"{where}.disable_collisions")
    pos, quat = model.body_poses(q)
    extra = {} if material is None else {"material": material}
    specs = [dict(name=b, shape=s, kind="kinematic", position=p, orientation=o, where=f"{where}: body {b!r}", **extra)
             for b, s, p, o in zip(model.bodies, shapes, pos, quat)]
    world.add_bodies(specs)   # all or nothing
    world.robots = world.robots + [model]   # a new list: a caller holding the old one can roll back
    model.exclusions.update({pair: "given" for pair in given - set(model.exclusions)})
    world.disable_collisions(sorted(pairs | given))
    if exclude_touching:
        touching = _touching_pairs(world, model) - set(model.exclusions)
        model.exclusions.update({pair: "touching at the initial configuration" for pair in touching})
        world.disable_collisions(sorted(touching))
    return list(model.bodies)


def _given_pairs(world, model, pairs, where):
    """The body-name pairs (sorted tuples) of ``pairs``: ``[[a, b], ...]``, each name a link of the robot
    (without its prefix; every body of that link) or a body of the world; refused by name."""
    out = set()
    of_link = {}
    for b, link in zip(model.bodies, model.body_link):
        of_link.setdefault(link, []).append(b)
    for k, pair in enumerate(pairs or []):
        if isinstance(pair, (str, bytes)) or not hasattr(pair, "__len__") or len(pair) != 2:
            raise ContactSimError(f"{where}[{k}]: must be a pair [link or body, link or body], got {show(pair)}")
        sides = []
        for n in pair:
            if n in of_link:
                sides.append(of_link[n])
            elif isinstance(n, str) and n in world._index:
                sides.append([n])
            else:
                raise ContactSimError(f"{where}[{k}]: {n!r} is neither a link of robot {model.name!r} with geometry "
                                      f"(links: {', '.join(sorted(of_link))}) nor a body of the world")
        out |= {tuple(sorted((a, b))) for a in sides[0] for b in sides[1] if a != b}
    return out


def _touching_pairs(world, model):
    """Body-name pairs in contact (within the contact margin) at the robot's initial configuration
    between two of its links, or one of its links and a static body: what MoveIt's Setup Assistant
    calls "Default" collisions, excluded so that a robot standing on a floor, or a zero pose with
    touching links, starts quiet. A link touching a dynamic or kinematic body stays tested."""
    from .collision import detect_world
    from .kinds import STATIC

    c, _ = detect_world(world)
    mine = np.zeros(len(world), bool)
    mine[[world.index(b) for b in model.bodies]] = True
    a, b = c.body_a, c.body_b
    keep = (mine[a] & mine[b]) | (mine[a] & (world.kind[b] == STATIC)) | (mine[b] & (world.kind[a] == STATIC))
    names = world._names
    return {tuple(sorted((names[i], names[j]))) for i, j in zip(a[keep], b[keep])}


def pose_robot(world, robot, positions, velocities):
    """See ``World.pose_robot``."""
    if not any(r is robot for r in world.robots):
        raise ContactSimError(f"pose_robot: {getattr(robot, 'name', robot)!r} is not a robot of this world")
    _commit_links(world, [_link_states(world, robot, positions, velocities, f"pose_robot({robot.name!r})")])


def _link_states(world, robot, positions, velocities, call):
    """``(indices (B,), positions, quaternions, velocities, angular velocities)`` of ``robot``'s
    links for the joint ``positions`` and ``velocities`` (mappings), checked against the world's
    bounds (``BoundsError`` naming ``call`` and the link); nothing changed yet."""
    p, q, v, w = robot.body_states(positions, velocities)
    st, names = world.settings, robot.bodies

    def row(what):
        return lambda i: f"{call}: link {names[i]!r} {what}"

    POSITIONS.check(p, call, st, count=len(p), row_path=row("position"))
    VELOCITIES.check(v, call, st, count=len(v), row_path=row("velocity"))
    ANGULAR_VELOCITIES.check(w, call, st, count=len(w), row_path=row("angular velocity"))
    return np.array([world.index(n) for n in names], np.int64), p, q, v, w


def _commit_links(world, parts):
    """Write ``_link_states``' answers into the world's state (a link's origin is its centre of
    mass unless ``com_local`` says otherwise); their pose histories start again."""
    s = world.s
    for idx, p, q, v, w in parts:
        com = world.com_local[idx]
        s.pos[idx] = p + quat_rotate(q, com) if com.any() else p
        s.quat[idx] = q
        s.vel[idx] = v
        s.omega[idx] = w
        s.posed[idx] = False


def set_joint_positions(world, names, positions, stamp=None, place=True):
    """See ``World.set_joint_positions``."""
    from .validate import STAMP

    call = "set_joint_positions"
    owner = {j["name"]: r for r in world.robots for j in r.joints if j["type"] in MOVABLE}
    names, pos = check_request(owner, names, positions, call)
    if not names:
        return
    t = world.time if stamp is None else STAMP.check(stamp, f"{call}.stamp")
    new = {}
    for n, x in zip(names, pos):
        r = owner[n]
        new.setdefault(id(r), (r, [], []))
        new[id(r)][1].append(n)
        new[id(r)][2].append(x)
    states, parts = [], []
    for r, ns, xs in new.values():
        state = r.update(ns, xs, t, call)
        states.append((r, state))
        if place:   # every robot checked before any changes
            parts.append(_link_states(world, r, state[0], state[1], call))
    _commit_links(world, parts)
    for r, (q, qd, tt, before) in states:
        r.q, r.qd, r.t, r.before = q, qd, tt, before
