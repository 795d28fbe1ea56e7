"""3-vector helpers for compiled kernels: plain arithmetic (numba's ``@`` on 3-vectors calls BLAS,
whose call costs more than the product)."""
import numpy as np

from ..jit import njit


@njit
def dot(a, b):
    """``a · b`` of 3-vectors."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit
def dotr(X, i, Y, j):
    """``X[i] · Y[j]`` of rows of ``(n, 3)`` arrays, without making row views (each view costs a
    reference-count round trip in compiled code, more than the product)."""
    return X[i, 0] * Y[j, 0] + X[i, 1] * Y[j, 1] + X[i, 2] * Y[j, 2]


@njit
def cross(a, b):
    """``a × b`` of 3-vectors, a new ``(3,)`` array."""
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@njit
def mv(R, v):
    """``R v`` for ``R (3, 3)``, ``v (3,)``."""
    out = np.empty(3)
    for i in range(3):
        out[i] = R[i, 0] * v[0] + R[i, 1] * v[1] + R[i, 2] * v[2]
    return out


@njit
def mtv(R, v):
    """``Rᵀ v``."""
    out = np.empty(3)
    for i in range(3):
        out[i] = R[0, i] * v[0] + R[1, i] * v[1] + R[2, i] * v[2]
    return out


@njit
def norm(a):
    return np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


# the smallest square the plain ``sqrt(x² + y² + z²)`` keeps to full precision: below the
# normal doubles (2.2e-308) a square loses bits, and below 4.9e-324 it is 0
_NORMAL_SQUARE = 1e-290


@njit
def unit3(x, y, z):
    """``(x, y, z) / |(x, y, z)|`` and the length, of unit length for every non-zero vector:
    components below ~1e-154 square to less than the normal doubles (1.79e-162 squares to 0, or
    to a denormal), so such a vector is first divided by its largest component. The zero vector
    gives ``(0, 0, 0, 0)``; a caller picks its own direction then. Above that range this is
    the plain formula, to the bit."""
    d2 = x * x + y * y + z * z
    if d2 >= _NORMAL_SQUARE:
        length = np.sqrt(d2)
        return x / length, y / length, z / length, length
    m = max(abs(x), abs(y), abs(z))
    if m == 0.0:
        return 0.0, 0.0, 0.0, 0.0
    x, y, z = x / m, y / m, z / m
    length = np.sqrt(x * x + y * y + z * z)
    return x / length, y / length, z / length, m * length


@njit
def closest_on_triangle(px, py, pz, V, ia, ib, ic):
    """Closest point ``(x, y, z)`` on the triangle of rows ``ia, ib, ic`` of ``V (n, 3)`` to ``p``
    (Ericson, Real-Time Collision Detection 5.1.5: vertex, edge and face regions in turn), no
    temporaries."""
    a0, a1, a2 = V[ia, 0], V[ia, 1], V[ia, 2]
    b0, b1, b2 = V[ib, 0], V[ib, 1], V[ib, 2]
    c0, c1, c2 = V[ic, 0], V[ic, 1], V[ic, 2]
    abx, aby, abz = b0 - a0, b1 - a1, b2 - a2
    acx, acy, acz = c0 - a0, c1 - a1, c2 - a2
    apx, apy, apz = px - a0, py - a1, pz - a2
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0 and d2 <= 0:
        return a0, a1, a2
    bpx, bpy, bpz = px - b0, py - b1, pz - b2
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0 and d4 <= d3:
        return b0, b1, b2
    vc = d1 * d4 - d3 * d2
    if vc <= 0 and d1 >= 0 and d3 <= 0:
        den = d1 - d3
        v = d1 / den if den != 0 else d1
        return a0 + abx * v, a1 + aby * v, a2 + abz * v
    cpx, cpy, cpz = px - c0, py - c1, pz - c2
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0 and d5 <= d6:
        return c0, c1, c2
    vb = d5 * d2 - d1 * d6
    if vb <= 0 and d2 >= 0 and d6 <= 0:
        den = d2 - d6
        w = d2 / den if den != 0 else d2
        return a0 + acx * w, a1 + acy * w, a2 + acz * w
    va = d3 * d6 - d5 * d4
    if va <= 0 and d4 - d3 >= 0 and d5 - d6 >= 0:
        den = (d4 - d3) + (d5 - d6)
        w = (d4 - d3) / den if den != 0 else d4 - d3
        return b0 + (c0 - b0) * w, b1 + (c1 - b1) * w, b2 + (c2 - b2) * w
    den = va + vb + vc
    if den == 0:
        den = 1.0
    v, w = vb / den, vc / den
    return a0 + abx * v + acx * w, a1 + aby * v + acy * w, a2 + abz * v + acz * w


@njit
def transform_rows(src, p, R, out, n):
    """``out[:n] = R src[:n] + p`` row by row, no temporaries."""
    for v in range(n):
        x, y, z = src[v, 0], src[v, 1], src[v, 2]
        for i in range(3):
            out[v, i] = R[i, 0] * x + R[i, 1] * y + R[i, 2] * z + p[i]


@njit(_nrt=False)
def rotations(quat, R):
    """``R (N, 3, 3)`` of unit quaternions ``quat (N, 4)`` x, y, z, w (one pass, no temporaries)."""
    for k in range(quat.shape[0]):
        x, y, z, w = quat[k, 0], quat[k, 1], quat[k, 2], quat[k, 3]
        R[k, 0, 0], R[k, 0, 1], R[k, 0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
        R[k, 1, 0], R[k, 1, 1], R[k, 1, 2] = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
        R[k, 2, 0], R[k, 2, 1], R[k, 2, 2] = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)


@njit
def unit_rotations(quat, R):
    """Normalise the quaternion rows of ``quat (N, 4)`` in place (any non-zero length) and write
    their rotation matrices into ``R (N, 3, 3)`` (``rotations``)."""
    for k in range(quat.shape[0]):
        norm = np.sqrt(quat[k, 0] * quat[k, 0] + quat[k, 1] * quat[k, 1] + quat[k, 2] * quat[k, 2]
                       + quat[k, 3] * quat[k, 3])
        for x in range(4):
            quat[k, x] = quat[k, x] / norm
    rotations(quat, R)


@njit
def col_max(si, col, shape_of, a, b):
    """Largest ``si[s, col]`` over the shapes of the pairs ``a, b`` (at least 1): sizes a kernel's
    scratch arrays (over the pairs, not the whole table: a batch of a few pairs in a big world)."""
    m = 1
    for i in range(a.shape[0]):
        m = max(m, si[shape_of[a[i]], col], si[shape_of[b[i]], col])
    return m


@njit
def counting_order(key, nkeys, order):
    """``order`` = the stable ascending order of ``key (n,)`` with values in ``[0, nkeys)``."""
    count = np.zeros(nkeys + 1, np.int64)
    for i in range(key.shape[0]):
        count[key[i] + 1] += 1
    for k in range(nkeys):
        count[k + 1] += count[k]
    for i in range(key.shape[0]):
        order[count[key[i]]] = i
        count[key[i]] += 1


@njit
def set_row(dst, i, src):
    """``dst[i, :3] = src[:3]`` component by component (a row assignment from an array compiles the
    general broadcasting code, seconds of compile time for three numbers)."""
    dst[i, 0], dst[i, 1], dst[i, 2] = src[0], src[1], src[2]


@njit
def inside_loop(N, p, V, loops, l0, m, x, y, z, eps):
    """Point ``(x, y, z)`` on the plane of face ``p`` (normal ``N[p]``) inside its polygon
    ``loops[l0:l0 + m]`` of ``V`` rows: on the inner side of every edge (within ``eps``)."""
    nx, ny, nz = N[p, 0], N[p, 1], N[p, 2]
    for q in range(m):
        i0, i1 = loops[l0 + q], loops[l0 + (q + 1) % m]
        ex, ey, ez = V[i1, 0] - V[i0, 0], V[i1, 1] - V[i0, 1], V[i1, 2] - V[i0, 2]
        sx, sy, sz = ey * nz - ez * ny, ez * nx - ex * nz, ex * ny - ey * nx     # (edge × n): outward
        if sx * (x - V[i0, 0]) + sy * (y - V[i0, 1]) + sz * (z - V[i0, 2]) > eps:
            return False
    return True


@njit(inline="always")   # called per edge-face pair in the kernels' inner loops
def edge_through_face(VX, i0, i1, NY, dY, p, VY, loops, l0, m, eps):
    """Does the edge ``VX[i0]–VX[i1]`` cross the plane of face ``p`` of Y (normal ``NY[p]``,
    offset ``dY[p]``) inside its polygon ``loops[l0:l0 + m]`` of ``VY`` rows (within ``eps``)?
    ``(crossed, s0, s1, x, y, z)``: the endpoints' signed distances to the plane and the crossing."""
    s0 = dotr(NY, p, VX, i0) - dY[p]
    s1 = dotr(NY, p, VX, i1) - dY[p]
    if not s0 * s1 < 0:
        return False, s0, s1, 0.0, 0.0, 0.0
    t = s0 / (s0 - s1)
    x = VX[i0, 0] + t * (VX[i1, 0] - VX[i0, 0])
    y = VX[i0, 1] + t * (VX[i1, 1] - VX[i0, 1])
    z = VX[i0, 2] + t * (VX[i1, 2] - VX[i0, 2])
    return inside_loop(NY, p, VY, loops, l0, m, x, y, z, eps), s0, s1, x, y, z
