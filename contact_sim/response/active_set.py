"""Compiled exact contact solve: the active-set method of ``direct`` per island, in one kernel.

Contacts that share no movable body never push on each other, so the Delassus matrix ``A = J M⁻¹ Jᵀ``
is block diagonal over *islands* (connected components of the contact graph through movable
bodies; Box2D's islands). Each island is solved on its own. In the contacts' rows (``_island``)
it is dense: a resting box's four contacts are a 12 × 12 system, a 10-box stack's 40 contacts
120 × 120; an island of more than ``DIRECT_BAND_MIN`` contacts is kept to each contact's
coupling range (from the first to the last contact of the island that shares a movable body
with it): its matrix, products and Cholesky factor visit no block outside it (a stack's matrix
is banded in detection order), so the cost follows the island's coupling, not its size squared
or cubed; a smaller island is taken whole.

The method per island is ``direct.solve_direct``'s: the rows of the active contacts (normal, and
both tangents of a contact with friction, sticking) are solved for the least-norm impulses that
meet them (exact to rounding for full rank; for redundant contacts, four points on a face, the
least-norm split); contacts with a negative normal impulse leave the set, satisfied-but-violated
ones join, until neither happens. A sticking impulse outside the static cone (sliding), an
inconsistent set or too many rounds leaves the island unfinished, with the start of lowest contact
objective for Gauss–Seidel to finish from.

Where the active rows fix every freedom of the island's bodies (a box's four contacts with
friction: 12 rows on 6 freedoms; a 10-box stack: 120 rows on 60) the solve is in the bodies'
freedoms (``_island_body``): the least-norm impulses ``A⁺r = J G⁻¹ M G⁻¹ Jᵀ r`` from the factor
of ``G = JᵀJ`` (``6B × 6B`` for ``B`` bodies, banded along a stack) and the bodies' mass matrix
``M``, the Delassus matrix never formed, refined while a row misses by more than its round-off. Every
update is ``J`` times something, so the impulses stay in the range of ``J``: the least-norm
split to rounding (the rows' regularised solve below, ``(A_SS + εI) x = r`` with two steps of
refinement, leaves ε's trace in it: 1e-5 of the impulses in the stack). Elsewhere (fewer active
rows than freedoms, a freedom no active row fixes, compliant rows, an inconsistent set) the rows'
method (``_island``) solves it.

The island kernels (``_single``, ``_island_body``, ``_island``) allocate nothing (their workspace
is ``solve_islands``', shared by all islands) and are compiled without reference counts
(``jit``: ``_nrt=False``).

Shapes: ``K`` contacts, ``N`` bodies; rows as in ``rows.Rows``.
"""
import math

import numpy as np

from ..jit import njit
from ..constants import (DIRECT_BAND_MIN, DIRECT_FREEDOM_FLOOR, DIRECT_PIVOT_FRACTION, DIRECT_REFINEMENTS,
                         DIRECT_ROUNDOFF)
from .pgs import _apply, _row_velocity

_TINY = 1e-300

#: island status (``status (K,)`` per contact)
SOLVED, UNFINISHED, TOO_LARGE = 0, 1, 2


@njit
def _find(parent, x):
    while parent[x] != x:
        parent[x] = parent[parent[x]]
        x = parent[x]
    return x


@njit
def islands(a, b, movable, n_bodies):
    """Contacts grouped by island: ``(order (K,) int64, start (I+1,) int64)``, island ``i`` being
    the contacts ``order[start[i]:start[i+1]]`` in their original order, islands in the order of
    their first contact (deterministic). A contact between two immovable bodies is its own island."""
    k = a.shape[0]
    trees = np.empty((2, n_bodies), np.int64)   # union-find parents; each root's island number
    parent, number = trees[0], trees[1]
    for i in range(n_bodies):
        parent[i] = i
        number[i] = -1
    for c in range(k):
        if movable[a[c]] and movable[b[c]]:
            ra = _find(parent, a[c])
            rb = _find(parent, b[c])
            if ra != rb:
                parent[max(ra, rb)] = min(ra, rb)
    # one block: each contact's island number (by first appearance), the islands' sizes then their
    # starts (a running sum in place), the fill pointers, the order
    ints = np.empty((4, k + 1), np.int64)
    label, sizes, fill, order = ints[0, :k], ints[1], ints[2], ints[3, :k]
    count = 0
    sizes[:] = 0
    for c in range(k):
        if movable[a[c]]:
            r = _find(parent, a[c])
        elif movable[b[c]]:
            r = _find(parent, b[c])
        else:
            r = -1
        if r < 0:
            label[c] = count
            count += 1
        else:
            if number[r] < 0:
                number[r] = count
                count += 1
            label[c] = number[r]
        sizes[label[c] + 1] += 1
    start = sizes[:count + 1]
    for i in range(count):
        start[i + 1] += start[i]
        fill[i] = start[i]
    for c in range(k):
        order[fill[label[c]]] = c
        fill[label[c]] += 1
    return order, start


@njit
def _delassus(ids, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, compliance, A, band):
    """The Delassus matrix of the island's contacts ``ids (m,)`` into ``A (3m,3m)``: block ``(p,q)``
    sums, over each body the two contacts share, ``s_p s_q (m⁻¹ d_p d_qᵀ + (r_p×d_p)·I⁻¹(r_q×d_q)ᵀ)``
    (``s`` = +1 on A, −1 on B; an immovable body's inverse mass and inertia are zero); the normal
    rows' diagonal gets ``compliance``. Only the blocks within each contact's coupling range
    (``band[0], band[1]``: ``_island``) are written, and only they are read."""
    m = ids.shape[0]
    for p in range(m):
        cp = ids[p]
        A[3 * p:3 * p + 3, 3 * band[0, p]:3 * band[1, p] + 3] = 0.0
        for q in range(band[0, p], band[1, p] + 1):
            cq = ids[q]
            for side_p in range(2):
                body_p = a[cp] if side_p == 0 else b[cp]
                for side_q in range(2):
                    body_q = a[cq] if side_q == 0 else b[cq]
                    if body_p != body_q:
                        continue
                    s = 1.0 if side_p == side_q else -1.0
                    im = ima[cq] if side_q == 0 else imb[cq]
                    if im == 0.0:
                        continue   # immovable (its inverse inertia is zero too)
                    for d in range(3):
                        for e in range(3):
                            lin = 0.0
                            ang = 0.0
                            for x in range(3):
                                lin += dirs[cp, d, x] * dirs[cq, e, x]
                                if side_p == 0:
                                    jp = ang_a[cp, d, x]
                                else:
                                    jp = ang_b[cp, d, x]
                                if side_q == 0:
                                    wq = iang_a[cq, e, x]
                                else:
                                    wq = iang_b[cq, e, x]
                                ang += jp * wq
                            A[3 * p + d, 3 * q + e] += s * (im * lin + ang)
        A[3 * p, 3 * p] += compliance[cp]


@njit
def _cholesky(M, n, nz, band):
    """In-place lower Cholesky factor of ``M[:n,:n]`` (right-looking, the update of each column
    restricted to its non-zeros ``nz``: a banded island costs its band, not ``n³``), row ``i``
    zero left of column ``band[3, i]`` (its envelope, which the factor keeps; never decreasing
    with ``i``, so the rows below the diagonal of column ``j`` that reach it are ``j+1 …
    band[5, j]``, the last one): nothing outside it is read or written. False when a pivot is not
    positive (the caller falls back)."""
    for j in range(n):
        d = M[j, j]
        if not (d > 0.0):
            return False
        d = math.sqrt(d)
        M[j, j] = d
        cnt = 0
        for i in range(j + 1, band[5, j] + 1):
            if M[i, j] != 0.0:
                M[i, j] /= d
                nz[cnt] = i
                cnt += 1
        for p in range(cnt):
            i = nz[p]
            lij = M[i, j]
            for q in range(p + 1):
                r = nz[q]
                M[i, r] -= lij * M[r, j]
    return True


@njit
def _cho_solve(L, n, band, x):
    """Solve ``L Lᵀ y = x`` in place (``x (n,)``; the envelope in ``band``, as ``_cholesky``'s)."""
    for i in range(n):
        s = x[i]
        for j in range(band[3, i], i):
            s -= L[i, j] * x[j]
        x[i] = s / L[i, i]
    for i in range(n - 1, -1, -1):
        s = x[i]
        for j in range(i + 1, band[5, i] + 1):
            s -= L[j, i] * x[j]
        x[i] = s / L[i, i]


@njit
def _objective(A, rhs, x, n, band):
    """Contact objective ``½ x·Ax − x·rhs`` (what Gauss–Seidel descends) over ``n`` rows (each
    row's non-zero range from ``band``)."""
    f = 0.0
    for i in range(n):
        if x[i] == 0.0:
            continue
        s = 0.0
        for j in range(3 * band[0, i // 3], 3 * band[1, i // 3] + 3):
            s += A[i, j] * x[j]
        f += x[i] * (0.5 * s - rhs[i])
    return f


@njit(inline="always")
def _start(ids, v0, target, warm, use_warm, rhs, act):
    """An island's right-hand side ``rhs (3m,)`` (each row's velocity change to its target: ``−v0``,
    plus the normal row's target) and its first active set ``act (m,)``: every contact that is not
    separating (a resting stack starts with all its layers active: only the approaching ones would
    add one layer per round), or that pushed in the warm start. Returns the largest ``|rhs|``."""
    m = ids.shape[0]
    for p in range(m):
        c = ids[p]
        for d in range(3):
            rhs[3 * p + d] = -v0[c, d]
        rhs[3 * p] += target[c]
        act[p] = v0[c, 0] <= target[c] or (use_warm and warm[c, 0] > 0.0)
    rmax = 0.0
    for i in range(3 * m):
        rmax = max(rmax, abs(rhs[i]))
    return rmax


@njit(inline="always")
def _active_rows(ids, act, friction, mu_s, S):
    """The rows of the active contacts into ``S``: the normal row, and both tangents of a contact
    with friction (sticking). Returns how many."""
    ns = 0
    for p in range(ids.shape[0]):
        if act[p]:
            S[ns] = 3 * p
            ns += 1
            if friction and mu_s[ids[p]] > 0.0:
                S[ns] = 3 * p + 1
                S[ns + 1] = 3 * p + 2
                ns += 2
    return ns


@njit(inline="always")
def _next_set(ids, act, x, ax, v0, target, tol):
    """The active set's change after a round (``x`` its impulses, ``ax`` their velocity change): a
    contact pulling (negative normal impulse) leaves, one left out that its pushing neighbours
    drive into its target (by more than ``tol``) joins. Returns whether any changed."""
    change = False
    for p in range(ids.shape[0]):
        if act[p] and x[3 * p] < 0.0:
            act[p] = False
            change = True
        elif not act[p] and v0[ids[p], 0] + ax[3 * p] < target[ids[p]] - tol:
            act[p] = True
            change = True
    return change


@njit(inline="always")
def _into_cone(ids, x, friction, mu_s, mu_d):
    """The island's answer ``x (3m,)`` made admissible: no pulling normal impulse, a sticking
    impulse outside the static cone scaled onto the kinetic one (sliding: the set is then not the
    answer), no tangential impulse without friction. Returns whether every contact was inside."""
    inside = True
    for p in range(ids.shape[0]):
        c = ids[p]
        x[3 * p] = max(x[3 * p], 0.0)
        if friction:
            mag = math.sqrt(x[3 * p + 1] ** 2 + x[3 * p + 2] ** 2)
            if mag > mu_s[c] * x[3 * p] * (1 + 1e-12) + 1e-300:
                inside = False
                scale = mu_d[c] * x[3 * p] / max(mag, _TINY)
                x[3 * p + 1] *= scale
                x[3 * p + 2] *= scale
        else:
            x[3 * p + 1] = 0.0
            x[3 * p + 2] = 0.0
    return inside


@njit(inline="always")
def _solved(ids, x, ax, rhs, friction, lam):
    """A solved island's impulses ``x`` into ``lam``'s rows of ``ids``. Returns its residual (m/s:
    how far a row's velocity, ``ax − rhs`` from the last round's products, misses its target; a
    normal row that does not push only where it approaches, a tangent only with friction)."""
    residual = 0.0
    for i in range(3 * ids.shape[0]):
        s = ax[i] - rhs[i]
        d = i % 3
        if d == 0 and not (x[i] > 0.0):
            s = min(s, 0.0)
        if d != 0 and not friction:
            s = 0.0
        residual = max(residual, abs(s))
        lam[ids[i // 3], d] = x[i]
    return residual


@njit(inline="always")
def _warm_candidate(ids, warm, y):
    """The warm start of the island's contacts as a candidate ``y (3m,)`` (a non-finite value 0)."""
    for p in range(ids.shape[0]):
        for d in range(3):
            y[3 * p + d] = warm[ids[p], d] if math.isfinite(warm[ids[p], d]) else 0.0


@njit(inline="always")
def _lowest_start(ids, x, fx, y, fy, use_warm, lam):
    """Gauss–Seidel's start for an unfinished island into ``lam``'s rows of ``ids``: of zero, the
    set's answer ``x`` (contact objective ``fx``) and the warm start ``y`` (``fy``, when
    ``use_warm``), the one of lowest objective (an unfinished answer can be far worse than no
    impulse, and the start decides where Gauss–Seidel ends)."""
    best = 0.0   # zero's objective
    chosen = 0
    if fx < best:
        best = fx
        chosen = 1
    if use_warm and fy < best:
        chosen = 2
    for p in range(ids.shape[0]):
        for d in range(3):
            lam[ids[p], d] = x[3 * p + d] if chosen == 1 else (y[3 * p + d] if chosen == 2 else 0.0)

#: ``_island_body``'s answer when the island is the row-space method's (``_island`` goes on)
_ROWS = -1


@njit
def _number_bodies(ids, a, b, ima, imb, act, every_contact, local, listed, nb_old, first):
    """The movable bodies of the island's contacts ``ids`` that are active (``act (m,)``, or every
    contact with ``every_contact``) numbered in order of first appearance: ``local[body]`` (−1 for
    the others; the ``nb_old`` bodies numbered before are cleared first), ``listed`` the bodies by
    number, and ``first[i]`` the lowest number of a body sharing such a contact with body ``i``,
    made never decreasing (each body's block row of the body-space matrices starts there).
    Returns the number of bodies."""
    for i in range(nb_old):
        local[listed[i]] = -1
    nb = 0
    for p in range(ids.shape[0]):
        if not (every_contact or act[p]):
            continue
        c = ids[p]
        if ima[c] != 0.0 and local[a[c]] < 0:
            local[a[c]] = nb
            listed[nb] = a[c]
            first[nb] = nb
            nb += 1
        if imb[c] != 0.0 and local[b[c]] < 0:
            local[b[c]] = nb
            listed[nb] = b[c]
            first[nb] = nb
            nb += 1
    for p in range(ids.shape[0]):
        c = ids[p]
        if (every_contact or act[p]) and ima[c] != 0.0 and imb[c] != 0.0:
            i = local[a[c]]
            j = local[b[c]]
            lo = min(i, j)
            first[i] = min(first[i], lo)
            first[j] = min(first[j], lo)
    for i in range(nb - 2, -1, -1):
        first[i] = min(first[i], first[i + 1])
    return nb


@njit(inline="always")
def _row_vector(c, d, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, jv, bv):
    """Row ``d`` of contact ``c`` in its bodies' freedoms (A's six, linear then angular, then B's):
    the Jacobian ``jv (12,)`` (the row's velocity is ``jv · v``) and ``bv = M⁻¹ jv`` (the
    velocity change of a unit impulse on the row)."""
    for x in range(3):
        jv[x], jv[3 + x], jv[6 + x], jv[9 + x] = dirs[c, d, x], ang_a[c, d, x], -dirs[c, d, x], -ang_b[c, d, x]
        bv[x], bv[3 + x] = ima[c] * dirs[c, d, x], iang_a[c, d, x]
        bv[6 + x], bv[9 + x] = -(imb[c] * dirs[c, d, x]), -iang_b[c, d, x]


@njit(inline="always")
def _body_sum(ids, rows, nr, w, a, b, dirs, rot_a, rot_b, ima, imb, by_mass, local, n, out):
    """``out (n,)``: the impulses ``w`` on the rows ``rows[:nr]`` (row ``3p + d``: contact
    ``ids[p]``, direction ``d``) summed into the bodies' freedoms (6 per movable body, numbered by
    ``local``; immovable bodies, ``ima``/``imb`` 0, take none). With ``by_mass`` and ``rot_*`` the
    rows' images under the inverse inertia (``iang_*``) the bodies' velocity change ``M⁻¹Jᵀw``
    (``pgs._apply``'s arithmetic); without, and ``rot_*`` the rows themselves (``ang_*``), their
    impulse ``Jᵀw`` (force, then moment about the centre)."""
    for i in range(n):
        out[i] = 0.0
    for s in range(nr):
        ws = w[s]
        if ws == 0.0:
            continue
        p = rows[s] // 3
        d = rows[s] - 3 * p
        c = ids[p]
        if ima[c] != 0.0:
            base = 6 * local[a[c]]
            m = ima[c] if by_mass else 1.0
            for x in range(3):
                out[base + x] += m * (dirs[c, d, x] * ws)
                out[base + 3 + x] += rot_a[c, d, x] * ws
        if imb[c] != 0.0:
            base = 6 * local[b[c]]
            m = imb[c] if by_mass else 1.0
            for x in range(3):
                out[base + x] -= m * (dirs[c, d, x] * ws)
                out[base + 3 + x] -= rot_b[c, d, x] * ws


@njit(inline="always")
def _body_rows(ids, rows, nr, a, b, dirs, ang_a, ang_b, ima, imb, local, dv, out):
    """``out[s]``: the velocity of row ``rows[s]`` (as ``_body_sum``'s) for the freedoms'
    velocities ``dv`` (``pgs._row_velocity``'s arithmetic; a body not numbered, immovable or
    touched by no impulse, does not move)."""
    for s in range(nr):
        p = rows[s] // 3
        d = rows[s] - 3 * p
        c = ids[p]
        t = 0.0
        if ima[c] != 0.0 and local[a[c]] >= 0:
            base = 6 * local[a[c]]
            for x in range(3):
                t += dirs[c, d, x] * dv[base + x] + ang_a[c, d, x] * dv[base + 3 + x]
        if imb[c] != 0.0 and local[b[c]] >= 0:
            base = 6 * local[b[c]]
            for x in range(3):
                t -= dirs[c, d, x] * dv[base + x] + ang_b[c, d, x] * dv[base + 3 + x]
        out[s] = t


@njit(inline="always")
def _body_matrices(ids, S, ns, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, local, n, band, G, jv, bv):
    """The lower envelope (``band[3]``) of ``G = JᵀJ`` (``n × n``, the bodies' freedoms) over the
    active rows ``S[:ns]``: each row adds its outer product on its bodies' blocks. Returns the
    largest diagonal of ``A = J M⁻¹ Jᵀ`` on them (a row's ``jv · bv``)."""
    for i in range(n):
        for j in range(band[3, i], i + 1):
            G[i, j] = 0.0
    dmax = 0.0
    for s in range(ns):
        p = S[s] // 3
        d = S[s] - 3 * p
        c = ids[p]
        _row_vector(c, d, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, jv, bv)
        ba = 6 * local[a[c]] if ima[c] != 0.0 else -1
        bb = 6 * local[b[c]] if imb[c] != 0.0 else -1
        diag = 0.0
        for u in range(12):
            if (u < 6 and ba >= 0) or (u >= 6 and bb >= 0):
                diag += jv[u] * bv[u]
        dmax = max(dmax, diag)
        for side in range(2):
            base, off = (ba, 0) if side == 0 else (bb, 6)
            if base < 0:
                continue
            for u in range(6):
                for w in range(u + 1):
                    G[base + u, base + w] += jv[off + u] * jv[off + w]
        if ba >= 0 and bb >= 0:   # the block between the two bodies, below the diagonal
            hi, lo, oh, ol = (ba, bb, 0, 6) if ba > bb else (bb, ba, 6, 0)
            for u in range(6):
                for w in range(6):
                    G[hi + u, lo + w] += jv[oh + u] * jv[ol + w]
    return dmax


@njit
def _body_mass(listed, nb, inv_mass, inv_inertia, mb):
    """``mb (nb, 10)``: the mass matrix ``M`` of the bodies ``listed[:nb]`` (their mass, then their
    world inertia, row by row: the inverse of ``inv_inertia``, the matrix the rows were built with).
    Returns False when one cannot be inverted (a body that does not rotate: the rows' method), or
    when the bodies are not given (``inv_mass`` empty: rows made without them)."""
    if inv_mass.shape[0] == 0:
        return False
    for i in range(nb):
        body = listed[i]
        q = inv_inertia[body]
        c00 = q[1, 1] * q[2, 2] - q[1, 2] * q[2, 1]
        c01 = q[1, 2] * q[2, 0] - q[1, 0] * q[2, 2]
        c02 = q[1, 0] * q[2, 1] - q[1, 1] * q[2, 0]
        det = q[0, 0] * c00 + q[0, 1] * c01 + q[0, 2] * c02
        scale = abs(q[0, 0]) + abs(q[1, 1]) + abs(q[2, 2])
        if not (inv_mass[body] > 0.0 and det > DIRECT_PIVOT_FRACTION * scale * scale * scale):
            return False
        mb[i, 0] = 1.0 / inv_mass[body]
        mb[i, 1], mb[i, 4], mb[i, 7] = c00 / det, c01 / det, c02 / det
        mb[i, 2] = (q[0, 2] * q[2, 1] - q[0, 1] * q[2, 2]) / det
        mb[i, 5] = (q[0, 0] * q[2, 2] - q[0, 2] * q[2, 0]) / det
        mb[i, 8] = (q[0, 1] * q[2, 0] - q[0, 0] * q[2, 1]) / det
        mb[i, 3] = (q[0, 1] * q[1, 2] - q[0, 2] * q[1, 1]) / det
        mb[i, 6] = (q[0, 2] * q[1, 0] - q[0, 0] * q[1, 2]) / det
        mb[i, 9] = (q[0, 0] * q[1, 1] - q[0, 1] * q[1, 0]) / det
    return True


@njit(inline="always")
def _least_norm(ids, S, ns, r, a, b, dirs, ang_a, ang_b, ima, imb, local, n, nb, G, band, mb, t, out):
    """``out[:ns]``: the least-norm impulses on the active rows ``S`` whose velocity change is
    ``r[:ns]``: ``A⁺ r = J G⁻¹ M G⁻¹ Jᵀ r`` with ``A = J M⁻¹ Jᵀ``, ``G = JᵀJ`` (its factor:
    ``_body_matrices``) and the bodies' mass matrix ``M`` (``mb``: ``_body_mass``). With ``J`` of
    full column rank this is the pseudo-inverse (``A·A⁺·A = A``, ``A⁺·A·A⁺ = A⁺``, both products
    symmetric), and every answer is ``J`` times something: in the range of ``J``, the least-norm split."""
    _body_sum(ids, S, ns, r, a, b, dirs, ang_a, ang_b, ima, imb, False, local, n, t)
    _cho_solve(G, n, band, t)
    for i in range(nb):
        base = 6 * i
        for x in range(3):
            t[base + x] *= mb[i, 0]
        w0, w1, w2 = t[base + 3], t[base + 4], t[base + 5]
        t[base + 3] = mb[i, 1] * w0 + mb[i, 2] * w1 + mb[i, 3] * w2
        t[base + 4] = mb[i, 4] * w0 + mb[i, 5] * w1 + mb[i, 6] * w2
        t[base + 5] = mb[i, 7] * w0 + mb[i, 8] * w1 + mb[i, 9] * w2
    _cho_solve(G, n, band, t)
    _body_rows(ids, S, ns, a, b, dirs, ang_a, ang_b, ima, imb, local, t, out)


@njit(_nrt=False)
def _island_body(ids, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, v0, compliance, mu_s, mu_d, friction, warm,
                 use_warm, consistency, max_rounds, lam, ws, target, inv_mass, inv_inertia):
    """``_island``'s active set solved in the bodies' freedoms instead of the rows: where the active
    rows fix every freedom of the island's ``nb`` bodies (a box's four contacts with friction, 12
    rows on 6 freedoms; a 10-box stack's 120 rows on 60), the least-norm impulses ``A⁺ r`` come
    from one ``6nb × 6nb`` factor and the bodies' mass matrix (``_least_norm``; ``inv_mass (N,)``,
    ``inv_inertia (N,3,3)`` the bodies' inverse mass and world inverse inertia the rows were built
    with, ``mb`` its workspace) instead of the ``3m × 3m`` Delassus matrix, which is never formed
    (every product goes through the bodies: ``_body_sum``, ``_body_rows``). ``ws`` is
    ``solve_islands``' workspace as one tuple ``(G, vecs, dofs, S, nz, act, band, local, listed,
    first, jv, bv, rhs_s, every, mb)``.
    The same rounds and tests as ``_island`` (its answer to round-off, and the least-norm split
    exactly where ``_island``'s regularisation leaves a trace); returns ``(_ROWS, 0)`` when the
    island is the row-space method's: compliant rows, fewer active rows than freedoms, a freedom no active
    row fixes (a factor's pivot below ``DIRECT_PIVOT_FRACTION`` of its diagonal, or of
    ``DIRECT_FREEDOM_FLOOR`` × the island's largest diagonal), a body that does not
    rotate (its inverse inertia not invertible: ``_body_mass``), or active rows that cannot all hold
    (``_island`` then decides)."""
    G, vecs, dofs, S, nz, act, band, local, listed, first, jv, bv, rhs_s, every, mb = ws
    m = ids.shape[0]
    n3 = 3 * m
    for p in range(m):
        if compliance[ids[p]] != 0.0:
            return _ROWS, 0.0
    rhs, y, r, x, ax = vecs[0], vecs[1], vecs[2], vecs[3], vecs[4]
    t, dv, diag = dofs[0], dofs[1], dofs[2]
    rmax = _start(ids, v0, target, warm, use_warm, rhs, act)
    tol = 1e-12 + 1e-9 * rmax
    converged = False
    status = UNFINISHED
    nb = 0
    n = 0
    for _ in range(max_rounds + m // 4):
        ns = _active_rows(ids, act, friction, mu_s, S)
        x[:n3] = 0.0
        # the freedoms: the bodies the active contacts touch (a body touched by none gets no impulse)
        nb = _number_bodies(ids, a, b, ima, imb, act, False, local, listed, nb, first)
        n = 6 * nb
        if ns:
            if ns < n:   # fewer rows than freedoms: some freedom is free
                status = _ROWS
                break
            # the envelope (band[3]: a row's first column; band[5]: the last row reaching a column)
            for i in range(n):
                band[3, i] = 6 * first[i // 6]
                band[5, i] = i
            for i in range(n):
                band[5, band[3, i]] = max(band[5, band[3, i]], i)
            for j in range(1, n):
                band[5, j] = max(band[5, j], band[5, j - 1])
            if not _body_mass(listed, nb, inv_mass, inv_inertia, mb):
                status = _ROWS
                break
            dmax = _body_matrices(ids, S, ns, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, local, n, band, G,
                                  jv, bv)
            gmax = 0.0
            for i in range(n):
                diag[i] = G[i, i]
                gmax = max(gmax, diag[i])
            ok = _cholesky(G, n, nz, band)
            # a freedom only a negligible lever reaches (a sphere on two nearly parallel normals: its
            # spin about them) is not fixed: its pivot, tiny but positive, divided a solve to overflow
            floor = DIRECT_FREEDOM_FLOOR * gmax
            for i in range(n):
                ok = ok and G[i, i] * G[i, i] >= DIRECT_PIVOT_FRACTION * max(diag[i], floor)
            if not ok:
                status = _ROWS
                break
            for s in range(ns):
                rhs_s[s] = rhs[S[s]]
            _least_norm(ids, S, ns, rhs_s, a, b, dirs, ang_a, ang_b, ima, imb, local, n, nb, G, band, mb, t, y)
            # a row's velocity sums terms of up to its diagonal times the largest impulse: its round-off
            scale = rmax
            for s in range(ns):
                scale = max(scale, dmax * abs(y[s]))
            for refine in range(DIRECT_REFINEMENTS + 1):
                # the rows' velocities (all rows: the set's tests read them too); while an active row
                # misses by more than round-off, the miss is solved again (iterative refinement)
                _body_sum(ids, S, ns, y, a, b, dirs, iang_a, iang_b, ima, imb, True, local, n, dv)
                _body_rows(ids, every, n3, a, b, dirs, ang_a, ang_b, ima, imb, local, dv, ax)
                worst = 0.0
                for s in range(ns):
                    r[s] = rhs_s[s] - ax[S[s]]
                    worst = max(worst, abs(r[s]))
                if worst <= DIRECT_ROUNDOFF * scale or refine == DIRECT_REFINEMENTS:
                    break
                _least_norm(ids, S, ns, r, a, b, dirs, ang_a, ang_b, ima, imb, local, n, nb, G, band, mb, t, r)
                for s in range(ns):
                    y[s] += r[s]
            for s in range(ns):
                x[S[s]] = y[s]
        else:
            for i in range(n3):
                ax[i] = 0.0
        if ns:
            worst = 0.0
            for i in range(ns):
                worst = max(worst, abs(ax[S[i]] - rhs[S[i]]))
            if worst > consistency * (rmax + _TINY):
                status = _ROWS   # inconsistent (or a factor too poor to tell): the rows' method decides
                break
        if not _next_set(ids, act, x, ax, v0, target, tol):
            converged = True
            status = SOLVED
            break
    if status == _ROWS:
        for i in range(nb):
            local[listed[i]] = -1
        return _ROWS, 0.0
    converged = _into_cone(ids, x, friction, mu_s, mu_d) and converged
    if not converged:
        # as _island: Gauss–Seidel starts from the candidate of lowest objective ½ x·Ax − x·rhs
        fx = 0.0
        fy = 0.0
        for k in range(2 if use_warm else 1):
            z = x if k == 0 else y
            if k == 1:   # the warm start may push on any contact: every body numbered
                _warm_candidate(ids, warm, y)
                nb = _number_bodies(ids, a, b, ima, imb, act, True, local, listed, nb, first)
                n = 6 * nb
            _body_sum(ids, every, n3, z, a, b, dirs, iang_a, iang_b, ima, imb, True, local, n, dv)
            _body_rows(ids, every, n3, a, b, dirs, ang_a, ang_b, ima, imb, local, dv, ax)
            f = 0.0
            for i in range(n3):
                f += z[i] * (0.5 * ax[i] - rhs[i])
            if k == 0:
                fx = f
            else:
                fy = f
        _lowest_start(ids, x, fx, y, fy, use_warm, lam)
        for i in range(nb):
            local[listed[i]] = -1
        return UNFINISHED, math.inf
    residual = _solved(ids, x, ax, rhs, friction, lam)
    for i in range(nb):
        local[listed[i]] = -1
    return SOLVED, residual


@njit(_nrt=False)
def _island(ids, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, v0, target, compliance, mu_s, mu_d,
            friction, warm, use_warm, regularisation, consistency, max_rounds, lam, A, sub, L, vecs, S, nz, act,
            band):
    """The active set on one island (contacts ``ids (m,)``); writes ``lam`` rows of ``ids``.
    ``A, sub, L (≥3m, ≥3m)``, ``vecs (5, ≥3m)``, ``S, nz (≥3m,) int64``, ``act (≥m,) bool``,
    ``band (6, ≥3m+1) int64`` are workspace (allocated once for all islands). Every product and
    the factorisation keep to the non-zero range of each row (``band``), every sum in the order
    of the dense form (only exact zeros skipped). Returns ``(status, residual)``."""
    m = ids.shape[0]
    n = 3 * m
    # each contact's coupling range: the first and last contact of the island sharing a movable
    # body with it (band[0], band[1]); the Delassus blocks outside it are zero, and no product
    # below visits them, so a 10-box stack (each contact coupled to those of its two boxes, in
    # detection's order) costs its band, not its size squared
    full = m <= DIRECT_BAND_MIN   # a small island is taken whole: its bookkeeping would cost more than it skips
    for p in range(m):
        cp = ids[p]
        band[0, p] = 0 if full else p
        band[1, p] = m - 1 if full else p
        for q in range(0 if full else m):
            cq = ids[q]
            if (ima[cq] != 0.0 and (a[cq] == a[cp] or a[cq] == b[cp])) \
                    or (imb[cq] != 0.0 and (b[cq] == a[cp] or b[cq] == b[cp])):
                band[0, p] = min(band[0, p], q)
                band[1, p] = max(band[1, p], q)
    # the first contact coupled made never decreasing along the island (a range only widens, over
    # zeros): every row's envelope then starts at or before the next row's, so each column of the
    # factor below its diagonal is one run of rows (``_cholesky``, ``_cho_solve`` rely on it)
    for p in range(m - 2, -1, -1):
        band[0, p] = min(band[0, p], band[0, p + 1])
    _delassus(ids, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, compliance, A, band)
    rhs, y, r, x, ax = vecs[0], vecs[1], vecs[2], vecs[3], vecs[4]
    rmax = _start(ids, v0, target, warm, use_warm, rhs, act)
    dmax = 0.0
    for i in range(n):
        dmax = max(dmax, A[i, i])
    eps = regularisation * max(dmax, _TINY)
    tol = 1e-12 + 1e-9 * rmax
    converged = False
    for _ in range(max_rounds + m // 4):
        ns = _active_rows(ids, act, friction, mu_s, S)
        x[:n] = 0.0
        if ns:
            # the active rows' range in S (band[2]: the place in S of the first active row at or
            # after each row; band[3], band[4]: a row's first and last column; band[5]: the last
            # row whose range reaches a column)
            if full:
                for i in range(ns):
                    band[3, i], band[4, i], band[5, i] = 0, ns - 1, ns - 1
            else:
                k = 0
                for col in range(n + 1):
                    while k < ns and S[k] < col:
                        k += 1
                    band[2, col] = k
                for i in range(ns):
                    p = S[i] // 3
                    band[3, i] = band[2, 3 * band[0, p]]
                    band[4, i] = band[2, 3 * band[1, p] + 3] - 1
                    band[5, i] = i
                for i in range(ns):
                    band[5, band[3, i]] = max(band[5, band[3, i]], i)
                for j in range(1, ns):
                    band[5, j] = max(band[5, j], band[5, j - 1])
            for i in range(ns):
                for j in range(band[3, i], band[4, i] + 1):
                    sub[i, j] = A[S[i], S[j]]
                for j in range(band[3, i], i + 1):
                    L[i, j] = sub[i, j]
                L[i, i] += eps
            if not _cholesky(L, ns, nz, band):
                return TOO_LARGE, 0.0
            for i in range(ns):
                y[i] = rhs[S[i]]
            _cho_solve(L, ns, band, y)
            for _refine in range(2):   # proximal point: removes ε's bias where the rows are independent
                i = 0
                while i < ns:
                    if i + 2 < ns and S[i + 2] == S[i] + 2:   # a contact's three rows, one range: three sums at once
                        s0 = rhs[S[i]]
                        s1 = rhs[S[i + 1]]
                        s2 = rhs[S[i + 2]]
                        for j in range(band[3, i], band[4, i] + 1):
                            yj = y[j]
                            s0 -= sub[i, j] * yj
                            s1 -= sub[i + 1, j] * yj
                            s2 -= sub[i + 2, j] * yj
                        r[i], r[i + 1], r[i + 2] = s0, s1, s2
                        i += 3
                    else:
                        s = rhs[S[i]]
                        for j in range(band[3, i], band[4, i] + 1):
                            s -= sub[i, j] * y[j]
                        r[i] = s
                        i += 1
                _cho_solve(L, ns, band, r)
                for i in range(ns):
                    y[i] += r[i]
            for i in range(ns):
                x[S[i]] = y[i]
        for p in range(m):   # a contact's three rows share their range: three sums at once, each in order
            i = 3 * p
            s0 = 0.0
            s1 = 0.0
            s2 = 0.0
            for j in range(3 * band[0, p], 3 * band[1, p] + 3):
                xj = x[j]
                s0 += A[i, j] * xj
                s1 += A[i + 1, j] * xj
                s2 += A[i + 2, j] * xj
            ax[i], ax[i + 1], ax[i + 2] = s0, s1, s2
        if ns:
            worst = 0.0
            for i in range(ns):
                worst = max(worst, abs(ax[S[i]] - rhs[S[i]]))
            if worst > consistency * (rmax + _TINY):
                # the active rows cannot all hold (more sticking points than freedoms, pulling
                # different ways): no set containing them is right; Gauss–Seidel takes over
                break
        if not _next_set(ids, act, x, ax, v0, target, tol):
            converged = True
            break
    converged = _into_cone(ids, x, friction, mu_s, mu_d) and converged
    if not converged:
        fw = 0.0
        if use_warm:
            _warm_candidate(ids, warm, y)
            fw = _objective(A, rhs, y, n, band)
        _lowest_start(ids, x, _objective(A, rhs, x, n, band), y, fw, use_warm, lam)
        return UNFINISHED, math.inf
    # the residual of the solved island: the last round's products (x has not changed since, but
    # for the sign of a zero)
    return SOLVED, _solved(ids, x, ax, rhs, friction, lam)


@njit(_nrt=False)
def _single(c, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, v0, target, compliance, mu_s, mu_d, friction, warm,
            use_warm, regularisation, consistency, max_rounds, lam, A, L, vecs, S):
    """``_island`` for an island of the one contact ``c`` (a body touching only the ground or other
    immovable bodies: most islands of a scene at rest), the same arithmetic in the same order on its
    3 × 3 block, written out with no call and no array view (a call and its arrays' reference
    counts were most of a one-contact solve). ``A, L (≥3, ≥3)``, ``vecs (5, ≥3)``, ``S (≥3,)
    int64`` are workspace. Returns ``(status, residual)``."""
    # the block (_delassus for p = q = c: A's side, then B's; a contact never has a = b)
    for d in range(3):
        for e in range(3):
            A[d, e] = 0.0
            for side in range(2):
                im = ima[c] if side == 0 else imb[c]
                if im == 0.0:
                    continue
                lin = 0.0
                ang = 0.0
                for x in range(3):
                    lin += dirs[c, d, x] * dirs[c, e, x]
                    if side == 0:
                        ang += ang_a[c, d, x] * iang_a[c, e, x]
                    else:
                        ang += ang_b[c, d, x] * iang_b[c, e, x]
                A[d, e] += 1.0 * (im * lin + ang)
    A[0, 0] += compliance[c]
    # vecs rows: rhs, y, r, x, ax (as _island's)
    rmax = 0.0
    dmax = 0.0
    for d in range(3):
        vecs[0, d] = -v0[c, d]
        dmax = max(dmax, A[d, d])
    vecs[0, 0] += target[c]
    act = v0[c, 0] <= target[c] or (use_warm and warm[c, 0] > 0.0)
    for i in range(3):
        rmax = max(rmax, abs(vecs[0, i]))
    eps = regularisation * max(dmax, _TINY)
    tol = 1e-12 + 1e-9 * rmax
    converged = False
    for _ in range(max_rounds):
        ns = 0
        if act:
            S[0] = 0
            ns = 1
            if friction and mu_s[c] > 0.0:
                S[1] = 1
                S[2] = 2
                ns = 3
        for i in range(3):
            vecs[3, i] = 0.0
        if ns:
            for i in range(ns):
                for j in range(i + 1):
                    L[i, j] = A[S[i], S[j]]
                L[i, i] += eps
            # _cholesky: a column's updates over its non-zeros only (at most two below the diagonal)
            for j in range(ns):
                dj = L[j, j]
                if not (dj > 0.0):
                    return TOO_LARGE, 0.0
                dj = math.sqrt(dj)
                L[j, j] = dj
                z0 = -1
                z1 = -1
                for i in range(j + 1, ns):
                    if L[i, j] != 0.0:
                        L[i, j] /= dj
                        if z0 < 0:
                            z0 = i
                        else:
                            z1 = i
                if z0 >= 0:
                    L[z0, z0] -= L[z0, j] * L[z0, j]
                if z1 >= 0:
                    L[z1, z0] -= L[z1, j] * L[z0, j]
                    L[z1, z1] -= L[z1, j] * L[z1, j]
            for i in range(ns):
                vecs[1, i] = vecs[0, S[i]]
            for solve in range(3):   # the solve, then two refinements (proximal point, as _island)
                row = 1 if solve == 0 else 2
                if solve > 0:
                    for i in range(ns):
                        s = vecs[0, S[i]]
                        for j in range(ns):
                            s -= A[S[i], S[j]] * vecs[1, j]
                        vecs[2, i] = s
                for i in range(ns):   # _cho_solve
                    s = vecs[row, i]
                    for j in range(i):
                        s -= L[i, j] * vecs[row, j]
                    vecs[row, i] = s / L[i, i]
                for i in range(ns - 1, -1, -1):
                    s = vecs[row, i]
                    for j in range(i + 1, ns):
                        s -= L[j, i] * vecs[row, j]
                    vecs[row, i] = s / L[i, i]
                if solve > 0:
                    for i in range(ns):
                        vecs[1, i] += vecs[2, i]
            for i in range(ns):
                vecs[3, S[i]] = vecs[1, i]
        for i in range(3):
            s = 0.0
            for j in range(3):
                s += A[i, j] * vecs[3, j]
            vecs[4, i] = s
        if ns:
            worst = 0.0
            for i in range(ns):
                worst = max(worst, abs(vecs[4, S[i]] - vecs[0, S[i]]))
            if worst > consistency * (rmax + _TINY):
                break
        change = False
        if act and vecs[3, 0] < 0.0:
            act = False
            change = True
        elif not act and v0[c, 0] + vecs[4, 0] < target[c] - tol:
            act = True
            change = True
        if not change:
            converged = True
            break
    vecs[3, 0] = max(vecs[3, 0], 0.0)
    if friction:
        mag = math.sqrt(vecs[3, 1] ** 2 + vecs[3, 2] ** 2)
        if mag > mu_s[c] * vecs[3, 0] * (1 + 1e-12) + 1e-300:
            converged = False
            scale = mu_d[c] * vecs[3, 0] / max(mag, _TINY)
            vecs[3, 1] *= scale
            vecs[3, 2] *= scale
    else:
        vecs[3, 1] = 0.0
        vecs[3, 2] = 0.0
    if not converged:
        # _island's choice of Gauss–Seidel's start: the candidate of lowest objective
        best = 0.0
        for k in range(2):
            if k == 1:
                if not use_warm:
                    break
                for d in range(3):
                    vecs[3, d] = warm[c, d] if math.isfinite(warm[c, d]) else 0.0
            f = 0.0
            for i in range(3):
                if vecs[3, i] == 0.0:
                    continue
                s = 0.0
                for j in range(3):
                    s += A[i, j] * vecs[3, j]
                f += vecs[3, i] * (0.5 * s - vecs[0, i])
            if f < best:
                best = f
                for d in range(3):
                    lam[c, d] = vecs[3, d]
            elif k == 0:
                for d in range(3):
                    lam[c, d] = 0.0
        return UNFINISHED, math.inf
    residual = 0.0
    for i in range(3):
        s = -vecs[0, i]
        for j in range(3):
            s += A[i, j] * vecs[3, j]
        if i == 0 and not (vecs[3, i] > 0.0):
            s = min(s, 0.0)
        if i != 0 and not friction:
            s = 0.0
        residual = max(residual, abs(s))
        lam[c, i] = vecs[3, i]
    return SOLVED, residual


@njit
def solve_islands(a, b, order, start, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, target, compliance, mu_s, mu_d,
                  friction, warm, use_warm, max_island, regularisation, consistency, max_rounds, vel, omega, apply,
                  lam, status, inv_mass, inv_inertia):
    """The exact active set on every island of at most ``max_island`` contacts.

    ``a, b (K,) int64``; ``order, start`` the contacts by island (``islands``); ``dirs, ang_a, ang_b,
    iang_a, iang_b (K,3,3)``;
    ``ima, imb (K,)``; ``target, compliance, mu_s, mu_d (K,)``; ``warm (K,3)`` (read when
    ``use_warm``); ``vel, omega (N,3)`` the velocities before; ``inv_mass (N,)``, ``inv_inertia
    (N,3,3)`` the bodies' inverse mass and world inverse inertia the rows were built with (the
    body-space method's mass matrix; empty: rows made without them, the rows' method). Writes
    ``lam (K,3)`` (the impulses of a solved island, the Gauss–Seidel start of an unfinished one)
    and ``status (K,)`` (``SOLVED``,
    ``UNFINISHED``, ``TOO_LARGE``: larger than ``max_island`` or a failed factorisation, left to
    the caller). With ``apply`` the solved islands' impulses are applied to ``vel, omega`` (islands
    share no movable body, so each sees the velocities before). Returns the largest
    residual of the solved islands (m/s: how far a row's velocity misses its target)."""
    k = a.shape[0]
    v0 = np.empty((k, 3))
    for c in range(k):
        v0[c, 0], v0[c, 1], v0[c, 2] = _row_velocity(c, a[c], b[c], dirs, ang_a, ang_b, vel, omega)
    m_max = 0
    for i in range(start.shape[0] - 1):
        size = start[i + 1] - start[i]
        if size <= max_island:
            m_max = max(m_max, size)
    n_max = 3 * m_max   # workspace for the largest island solved here, shared by all
    mats = np.empty((3, n_max, n_max))   # A, sub, L: one block
    A, sub, L = mats[0], mats[1], mats[2]
    vecs = np.empty((5, n_max))
    rows = np.empty((2, n_max), np.int64)
    S, nz, act = rows[0], rows[1], np.empty(m_max, np.bool_)
    band = np.empty((6, n_max + 1), np.int64)
    # the body-space method's (_island_body), in two blocks and the numbering (empty where every
    # island is a single contact): freedoms' vectors (6 for each of up to two bodies a contact), the
    # active rows' right-hand side, a row's Jacobian and velocity change; every row's index, the
    # bodies' numbering
    nf = n_max if m_max > 1 else 0
    nb_max = 2 * m_max + 1 if m_max > 1 else 0
    floats = np.empty(13 * nf + 24)
    ints = np.empty(nf + 2 * nb_max, np.int64)
    dofs = floats[:12 * nf].reshape((3, 4 * nf))
    rhs_s, jv, bv = floats[12 * nf:13 * nf], floats[13 * nf:13 * nf + 12], floats[13 * nf + 12:]
    every, listed, first = ints[:nf], ints[nf:nf + nb_max], ints[nf + nb_max:]
    for j in range(nf):
        every[j] = j
    local = np.full(vel.shape[0] if m_max > 1 else 0, -1, np.int64)
    mb = np.empty((nb_max, 10))
    ws = (A, vecs, dofs, S, nz, act, band, local, listed, first, jv, bv, rhs_s, every, mb)
    residual = 0.0
    for i in range(start.shape[0] - 1):
        ids = order[start[i]:start[i + 1]]
        if ids.shape[0] > max_island:
            st = TOO_LARGE
        elif ids.shape[0] == 1:
            st, res = _single(ids[0], a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, v0, target, compliance, mu_s,
                              mu_d, friction, warm, use_warm, regularisation, consistency, max_rounds, lam, A, L, vecs, S)
        else:
            st, res = _island_body(ids, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, v0, compliance, mu_s, mu_d,
                                   friction, warm, use_warm, consistency, max_rounds, lam, ws, target, inv_mass,
                                   inv_inertia)
            if st == _ROWS:
                st, res = _island(ids, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, v0, target, compliance,
                                  mu_s, mu_d, friction, warm, use_warm, regularisation, consistency, max_rounds, lam,
                                  A, sub, L, vecs, S, nz, act, band)
        if st == SOLVED:
            residual = max(residual, res)
            if apply:
                for c in ids:
                    _apply(c, a[c], b[c], lam[c, 0], lam[c, 1], lam[c, 2], dirs, iang_a, iang_b, ima, imb, vel, omega)
        for c in ids:
            status[c] = st
    return residual
