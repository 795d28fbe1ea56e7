"""Signed distances and contacts for the pairs response and time of impact need in closed form.

These kernels are vectorised over pairs of one shape-type pair and follow the detection
conventions (normal from B to A, ``depth = -signed distance``, pairs reported when separated by at
most ``margin``). They serve two purposes: the closed-form time of impact (sphere–plane,
sphere–sphere), and a stand-in narrow phase for plane/sphere/box scenes while the full detection
package (``contact_sim.collision``, issue 3) is not importable. When it is, ``detect`` uses it.
"""
import numpy as np

from .. import quat
from ..contacts import FEATURES, Contacts
from ..shapes import Box, Plane, Polyhedron, Sphere

SPHERE = FEATURES.index("sphere")
PLANE = FEATURES.index("plane")
VERTEX_FACE = FEATURES.index("vertex_face")


def _dot(x, y):
    return np.einsum("ij,ij->i", x, y)


def plane_world(shape, pos, q):
    """World normal ``(3,)`` and offset of a plane shape posed at centre ``pos``, orientation ``q``."""
    n = quat.rotate(q, shape.normal)
    return n, shape.offset + float(n @ pos)


def _make(a, b, point, normal, depth, feature):
    k = len(depth)
    return Contacts(body_a=np.asarray(a, np.int64), body_b=np.asarray(b, np.int64), point=point,
                    normal=normal, depth=depth, impulse=np.zeros((k, 3)), normal_impulse=np.zeros(k),
                    friction_impulse=np.zeros((k, 3)), relative_normal_velocity=np.zeros(k),
                    feature=np.full(k, feature, np.int64))


def _pairs_allowed(world, i, j):
    g, m = world.group, world.mask
    return ((g[i] & m[j]) != 0) & ((g[j] & m[i]) != 0) & ~((world.kind[i] != 2) & (world.kind[j] != 2))


def fallback_detect(world, margin):
    """Contacts ``Contacts`` of the current state for plane–sphere, plane–polyhedron,
    sphere–sphere and sphere–box pairs (other pairs need ``contact_sim.collision``)."""
    s = world.s
    shapes = world.shapes
    types = np.array([sh.type for sh in shapes])
    planes = np.flatnonzero(types == "plane")
    spheres = np.flatnonzero(types == "sphere")
    polys = np.array([i for i, sh in enumerate(shapes) if isinstance(sh, Polyhedron)], dtype=np.int64)
    boxes = np.array([i for i, sh in enumerate(shapes) if isinstance(sh, Box)], dtype=np.int64)
    parts = []
    radius = np.array([shapes[i].radius for i in spheres]) if spheres.size else np.zeros(0)
    for p in planes:
        n, off = plane_world(shapes[p], s.pos[p], s.quat[p])
        if spheres.size:
            ok = _pairs_allowed(world, spheres, np.full(spheres.size, p))
            sp, r = spheres[ok], radius[ok]
            dist = s.pos[sp] @ n - off - r
            hit = dist <= margin
            sp, r, dist = sp[hit], r[hit], dist[hit]
            nn = np.broadcast_to(n, (sp.size, 3)).copy()
            point = s.pos[sp] - (r + 0.5 * dist)[:, None] * n
            parts.append(_make(sp, np.full(sp.size, p), point, nn, -dist, PLANE))
        for i in polys:
            if not _pairs_allowed(world, np.array([i]), np.array([p]))[0]:
                continue
            v = s.pos[i] + quat.rotate(s.quat[i], shapes[i].vertices)
            dist = v @ n - off
            hit = dist <= margin
            v, dist = v[hit], dist[hit]
            nn = np.broadcast_to(n, (v.shape[0], 3)).copy()
            parts.append(_make(np.full(len(dist), i), np.full(len(dist), p), v - 0.5 * dist[:, None] * n, nn,
                               -dist, VERTEX_FACE))
    if spheres.size > 1:
        parts.append(_sphere_sphere(world, spheres, radius, margin))
    if spheres.size and boxes.size:
        parts.append(_sphere_box(world, spheres, radius, boxes, margin))
    return Contacts.concat(parts)


def _sphere_sphere(world, spheres, radius, margin):
    s = world.s
    c = s.pos[spheres]
    from scipy.spatial import cKDTree

    pairs = cKDTree(c).query_pairs(2 * radius.max() + margin, output_type="ndarray")
    if len(pairs) == 0:
        return Contacts.empty()
    i, j = pairs[:, 0], pairs[:, 1]
    # A is the dynamic one when only one is
    swap = (world.kind[spheres[i]] != 2) & (world.kind[spheres[j]] == 2)
    i, j = np.where(swap, j, i), np.where(swap, i, j)
    ok = _pairs_allowed(world, spheres[i], spheres[j])
    i, j = i[ok], j[ok]
    d = c[i] - c[j]
    dist_c = np.linalg.norm(d, axis=1)
    sep = dist_c - radius[i] - radius[j]
    hit = sep <= margin
    i, j, d, dist_c, sep = i[hit], j[hit], d[hit], dist_c[hit], sep[hit]
    n = d / np.maximum(dist_c, 1e-300)[:, None]
    n[dist_c == 0] = [0.0, 0.0, 1.0]
    point = c[j] + (radius[j] + 0.5 * sep)[:, None] * n
    return _make(spheres[i], spheres[j], point, n, -sep, SPHERE)


def _sphere_box(world, spheres, radius, boxes, margin):
    s = world.s
    si = np.repeat(spheres, boxes.size)
    ri = np.repeat(radius, boxes.size)
    bi = np.tile(boxes, spheres.size)
    ok = _pairs_allowed(world, si, bi)
    si, ri, bi = si[ok], ri[ok], bi[ok]
    if si.size == 0:
        return Contacts.empty()
    half = np.array([world.shapes[b].half for b in bi])
    qb = s.quat[bi]
    local = quat.rotate(quat.conj(qb), s.pos[si] - s.pos[bi])
    closest = np.clip(local, -half, half)
    diff = local - closest
    dist_out = np.linalg.norm(diff, axis=1)
    inside = dist_out == 0
    # inside: push out through the nearest face
    face_gap = half - np.abs(local)
    ax = np.argmin(face_gap, axis=1)
    rows = np.arange(si.size)
    n_in = np.zeros_like(local)
    n_in[rows, ax] = np.where(local[rows, ax] >= 0, 1.0, -1.0)
    n_local = np.where(inside[:, None], n_in, diff / np.where(inside, 1.0, dist_out)[:, None])
    sep = np.where(inside, -face_gap[rows, ax], dist_out) - ri
    hit = sep <= margin
    n = quat.rotate(qb, n_local)
    point = s.pos[si] - (ri + 0.5 * sep)[:, None] * n
    return _make(si[hit], bi[hit], point[hit], n[hit], -sep[hit], SPHERE)


def detect(world, margin):
    """Contacts of the current state with ``margin``: ``contact_sim.collision.detect_world`` when
    that package is importable, else ``fallback_detect``."""
    try:
        from ..collision import detect_world
    except ImportError:
        detect_world = None
    if detect_world is not None:
        contacts, stats = detect_world(world, margin=margin)
        world.last_detection = stats
        return contacts
    return fallback_detect(world, margin)
