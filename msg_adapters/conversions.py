"""Pure conversions between contact_sim arrays and ROS 2 messages (no node, no rclpy).

Everything on a hot path is numpy: a contact set becomes a ``sensor_msgs/PointCloud2`` through
one structured array (``CONTACT_DTYPE``), and a ``geometry_msgs/PoseArray`` is read from / written
to its CDR bytes directly (``parse_posearray_cdr`` / ``posearray_cdr``), which is what the node
uses on its raw subscription and for ``body_states``. The message-object versions
(``arrays_to_posearray`` / ``posearray_to_arrays``) are for users and tests.
"""
import struct

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Pose, PoseArray, Vector3
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from contact_sim import FEATURES, BoundsError, Contacts

from .state_rows import contact_rows

# ---------------------------------------------------------------------------- contacts
#: One PointCloud2 point per contact. ``x, y, z`` (float32) is the contact point for display: RViz's
#: PointCloud2 display takes only float32 ``x y z``. ``point_x/y/z`` (float64) is the same point at
#: full precision, and every other physical quantity is float64 too (bit-exact round trip); uint32
#: for the indices. ``normal_*`` is the unit normal from B to A, ``depth`` > 0 when penetrating,
#: ``impulse_*`` the total impulse on A during the step (N·s; B got its negative) = ``normal_impulse *
#: normal + friction_impulse_*``, ``relative_normal_velocity`` n·(v_A − v_B) before the response (< 0
#: approaching), ``feature`` indexes ``contact_sim.FEATURES``, ``body_a``/``body_b`` index the body
#: names published on ``body_names``. Each field at its natural alignment: a 152-byte point.
CONTACT_FIELDS = (
    ("x", np.float32), ("y", np.float32), ("z", np.float32),
    ("point_x", np.float64), ("point_y", np.float64), ("point_z", np.float64),
    ("normal_x", np.float64), ("normal_y", np.float64), ("normal_z", np.float64),
    ("depth", np.float64),
    ("impulse_x", np.float64), ("impulse_y", np.float64), ("impulse_z", np.float64),
    ("normal_impulse", np.float64),
    ("friction_impulse_x", np.float64), ("friction_impulse_y", np.float64), ("friction_impulse_z", np.float64),
    ("relative_normal_velocity", np.float64),
    ("body_a", np.uint32), ("body_b", np.uint32), ("feature", np.uint32),
)


def _aligned_offsets(fields):
    """Offsets with every field at a multiple of its own size, and the point size (a multiple of 8)."""
    offsets, end = [], 0
    for _, t in fields:
        size = np.dtype(t).itemsize
        end = (end + size - 1) // size * size
        offsets.append(end)
        end += size
    return offsets, (end + 7) // 8 * 8


_OFFSETS, CONTACT_POINT_STEP = _aligned_offsets(CONTACT_FIELDS)
CONTACT_DTYPE = np.dtype({
    "names": [n for n, _ in CONTACT_FIELDS],
    "formats": [np.dtype(t).newbyteorder("<") for _, t in CONTACT_FIELDS],
    "offsets": _OFFSETS,
    "itemsize": CONTACT_POINT_STEP,
})

_NP_TO_POINTFIELD = {
    np.dtype(np.int8): PointField.INT8, np.dtype(np.uint8): PointField.UINT8,
    np.dtype(np.int16): PointField.INT16, np.dtype(np.uint16): PointField.UINT16,
    np.dtype(np.int32): PointField.INT32, np.dtype(np.uint32): PointField.UINT32,
    np.dtype(np.float32): PointField.FLOAT32, np.dtype(np.float64): PointField.FLOAT64,
}
_POINTFIELD_TO_NP = {v: k for k, v in _NP_TO_POINTFIELD.items()}


def point_fields(dtype):
    """``PointField`` list describing a (little-endian) structured numpy dtype."""
    if dtype == CONTACT_DTYPE:
        return [PointField(name=f.name, offset=f.offset, datatype=f.datatype, count=f.count)
                for f in _CONTACT_POINT_FIELDS]
    return _point_fields(dtype)


def _point_fields(dtype):
    out = []
    for name in dtype.names:
        ftype, offset = dtype.fields[name][:2]
        base = ftype.base.newbyteorder("=")
        count = int(np.prod(ftype.shape)) if ftype.shape else 1
        out.append(PointField(name=name, offset=int(offset), datatype=_NP_TO_POINTFIELD[base], count=count))
    return out


_CONTACT_POINT_FIELDS = _point_fields(CONTACT_DTYPE)


def dtype_from_fields(fields, point_step, big_endian=False):
    """The structured numpy dtype of a PointCloud2's ``fields`` (offsets and padding kept)."""
    order = ">" if big_endian else "<"
    names, formats, offsets = [], [], []
    for f in fields:
        if f.datatype not in _POINTFIELD_TO_NP:
            raise ValueError(f"PointCloud2 field {f.name!r}: unknown datatype {f.datatype}")
        base = _POINTFIELD_TO_NP[f.datatype].newbyteorder(order)
        names.append(f.name)
        formats.append(base if f.count <= 1 else (base, (f.count,)))
        offsets.append(f.offset)
    return np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": point_step})


# CONTACT_DTYPE as three runs of one type each, to fill a contact array in a few strided copies rather
# than one per field: x y z (float32), the 15 float64 fields from point_x on, the 3 uint32 indices
_F8_NAMES = [n for n, t in CONTACT_FIELDS if t is np.float64]
_U4_NAMES = [n for n, t in CONTACT_FIELDS if t is np.uint32]
_CONTACT_RUNS = np.dtype({
    "names": ["xyz", "f8", "u4"],
    "formats": [("<f4", 3), ("<f8", len(_F8_NAMES)), ("<u4", len(_U4_NAMES))],
    "offsets": [CONTACT_DTYPE.fields[n][1] for n in ("x", _F8_NAMES[0], _U4_NAMES[0])],
    "itemsize": CONTACT_POINT_STEP,
})
assert all(CONTACT_DTYPE.fields[n][1] == _CONTACT_RUNS.fields["f8"][1] + 8 * i for i, n in enumerate(_F8_NAMES))
assert all(CONTACT_DTYPE.fields[n][1] == _CONTACT_RUNS.fields["u4"][1] + 4 * i for i, n in enumerate(_U4_NAMES))
assert [n for n, _ in CONTACT_FIELDS][:3] == ["x", "y", "z"]
# the float64 columns as contacts_to_array fills them
assert _F8_NAMES == [f"{v}_{ax}" for v in ("point", "normal") for ax in "xyz"] + ["depth"] + \
    [f"impulse_{ax}" for ax in "xyz"] + ["normal_impulse"] + [f"friction_impulse_{ax}" for ax in "xyz"] + \
    ["relative_normal_velocity"]
assert _U4_NAMES == ["body_a", "body_b", "feature"]


def contacts_to_array(contacts):
    """``contact_sim.Contacts`` → structured array of ``CONTACT_DTYPE`` (vectorised)."""
    k = len(contacts)
    a = np.zeros(k, CONTACT_DTYPE)
    if k == 0:
        return a
    runs = a.view(_CONTACT_RUNS)
    c = contacts
    with np.errstate(over="ignore"):        # beyond float32's range: inf for display, exact in point_*
        contact_rows(c.point, c.normal, c.depth, c.impulse, c.normal_impulse, c.friction_impulse,
                     c.relative_normal_velocity, c.body_a, c.body_b, c.feature, runs["xyz"], runs["f8"], runs["u4"])
    return a


def array_to_contacts(a):
    """Structured array with the ``CONTACT_DTYPE`` field names → ``contact_sim.Contacts`` (the
    point from the float64 ``point_*`` fields; from ``x y z`` in a cloud without them)."""
    def vec(prefix):
        return np.stack([a[prefix + ax] for ax in "xyz"], axis=1).astype(np.float64, copy=False).reshape(-1, 3)

    return Contacts(
        body_a=a["body_a"].astype(np.int64), body_b=a["body_b"].astype(np.int64),
        point=vec("point_" if "point_x" in a.dtype.names else ""), normal=vec("normal_"), depth=a["depth"].astype(np.float64),
        impulse=vec("impulse_"), normal_impulse=a["normal_impulse"].astype(np.float64),
        friction_impulse=vec("friction_impulse_"),
        relative_normal_velocity=a["relative_normal_velocity"].astype(np.float64),
        feature=a["feature"].astype(np.int64),
        feature_id=np.zeros(len(a), np.int64),   # not carried by the contacts cloud (no such field): zeros
    )


_CONTACT_FIELDS_MSG = None   # the contact layout's PointFields, built once (a tuple: published, never edited)


def array_to_pointcloud2(a, header):
    """Any structured array → unorganised ``PointCloud2`` (height 1, little-endian, dense)."""
    global _CONTACT_FIELDS_MSG
    a = np.ascontiguousarray(a)
    msg = PointCloud2()
    msg.header = header
    msg.height = 1
    msg.width = int(a.shape[0])
    if a.dtype == CONTACT_DTYPE:
        if _CONTACT_FIELDS_MSG is None:
            _CONTACT_FIELDS_MSG = tuple(point_fields(CONTACT_DTYPE))
        msg.fields = _CONTACT_FIELDS_MSG
    else:
        msg.fields = point_fields(a.dtype)
    msg.is_bigendian = False
    msg.point_step = a.dtype.itemsize
    msg.row_step = msg.point_step * msg.width
    msg.is_dense = True
    msg.data = a.tobytes()  # bytes, not memoryview: the setter is ~80x faster
    return msg


def contacts_to_pointcloud2(contacts, header):
    """``contact_sim.Contacts`` → ``sensor_msgs/PointCloud2`` with the ``CONTACT_DTYPE`` layout."""
    return array_to_pointcloud2(contacts_to_array(contacts), header)


def pointcloud2_to_array(msg):
    """``PointCloud2`` → structured array (a zero-copy view on ``msg.data``, read-only)."""
    dtype = dtype_from_fields(msg.fields, msg.point_step, msg.is_bigendian)
    n = int(msg.width) * int(msg.height)
    if msg.row_step != msg.point_step * msg.width:
        raise ValueError(f"PointCloud2 with row padding (row_step {msg.row_step}, point_step {msg.point_step}, "
                         f"width {msg.width}) is not supported")
    if len(msg.data) < n * msg.point_step:
        raise ValueError(f"PointCloud2 data has {len(msg.data)} bytes, needs {n * msg.point_step}")
    return np.frombuffer(msg.data, dtype, count=n)


def pointcloud2_to_contacts(msg):
    """``PointCloud2`` published on ``contacts`` → ``contact_sim.Contacts``."""
    return array_to_contacts(pointcloud2_to_array(msg))


# ---------------------------------------------------------------------------- stamps and headers
def stamp_to_ns(stamp):
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def ns_to_stamp(ns):
    return Time(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))


def make_header(frame_id, stamp_ns):
    return Header(frame_id=frame_id, stamp=ns_to_stamp(stamp_ns))


# ---------------------------------------------------------------------------- poses
def arrays_to_posearray(positions, orientations, header):
    """``(N, 3)`` positions and ``(N, 4)`` x,y,z,w orientations → ``geometry_msgs/PoseArray``."""
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    q = np.asarray(orientations, np.float64).reshape(-1, 4)
    if len(p) != len(q):
        raise ValueError(f"{len(p)} positions but {len(q)} orientations")
    msg = PoseArray(header=header)
    poses = []
    for (px, py, pz), (qx, qy, qz, qw) in zip(p.tolist(), q.tolist()):
        pose = Pose()
        pose.position.x, pose.position.y, pose.position.z = px, py, pz
        pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = qx, qy, qz, qw
        poses.append(pose)
    msg.poses = poses
    return msg


def posearray_to_arrays(msg):
    """``geometry_msgs/PoseArray`` → ``(positions (N, 3), orientations (N, 4) x,y,z,w)`` float64."""
    flat = np.array([(p.position.x, p.position.y, p.position.z,
                      p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w) for p in msg.poses],
                    dtype=np.float64).reshape(-1, 7)
    return flat[:, :3].copy(), flat[:, 3:].copy()


class CdrError(ValueError):
    """Bytes that are not a well-formed serialized message of the expected type."""


def _align(offset, n):
    return (offset + n - 1) // n * n


def parse_posearray_cdr(data):
    """Serialized (CDR) ``geometry_msgs/PoseArray`` → ``(stamp_ns, frame_id, positions (N, 3),
    orientations (N, 4))`` with numpy, no message objects. Raises ``CdrError`` on malformed bytes."""
    buf = memoryview(data).cast("B") if not isinstance(data, (bytes, bytearray)) else data
    if len(buf) < 4:
        raise CdrError(f"PoseArray: {len(buf)} bytes, too short for a CDR header")
    kind = buf[1]
    if buf[0] != 0 or kind not in (0, 1):
        raise CdrError(f"PoseArray: unsupported CDR encapsulation {bytes(buf[:2]).hex()}")
    e = "<" if kind == 1 else ">"
    body = memoryview(buf)[4:]
    n_body = len(body)
    try:
        sec, nsec, slen = struct.unpack_from(e + "iII", body, 0)
        off = 12
        if slen == 0 or off + slen > n_body:
            raise CdrError(f"PoseArray: frame_id length {slen} does not fit in {n_body} bytes")
        frame_id = bytes(body[off:off + slen - 1]).decode("utf-8", "replace")
        off = _align(off + slen, 4)
        (n,) = struct.unpack_from(e + "I", body, off)
        off = _align(off + 4, 8) if n else off + 4
        if off + 56 * n > n_body:
            raise CdrError(f"PoseArray: {n} poses need {off + 56 * n} bytes, got {n_body}")
    except struct.error as exc:
        raise CdrError(f"PoseArray: truncated ({exc})") from None
    flat = np.frombuffer(body, np.dtype(e + "f8"), count=7 * n, offset=off).reshape(n, 7)
    if e == ">":
        flat = flat.astype("<f8")
    return int(sec) * 1_000_000_000 + int(nsec), frame_id, flat[:, :3], flat[:, 3:]


def posearray_cdr(positions, orientations, frame_id, stamp_ns):
    """``(N, 3)`` + ``(N, 4)`` → serialized little-endian CDR bytes of a ``geometry_msgs/PoseArray``
    (publishable as is with ``Publisher.publish(bytes)``); vectorised, no message objects."""
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    q = np.asarray(orientations, np.float64).reshape(-1, 4)
    if len(p) != len(q):
        raise ValueError(f"{len(p)} positions but {len(q)} orientations")
    flat = np.empty((len(p), 7), "<f8")
    flat[:, :3] = p
    flat[:, 3:] = q
    return posearray_rows_cdr(flat, frame_id, stamp_ns)


def posearray_rows_cdr(rows, frame_id, stamp_ns):
    """``posearray_cdr`` of the poses already laid out as rows: little-endian float64, C-ordered,
    ``(N, 7)`` (x y z qx qy qz qw) or flat ``(7 N,)``."""
    n = rows.size // 7
    head = _header_cdr(frame_id, stamp_ns)
    head += b"\0" * (_align(len(head), 4) - len(head))
    head += struct.pack("<I", n)
    if n:
        head += b"\0" * (_align(len(head), 8) - len(head))
    return b"\x00\x01\x00\x00" + head + rows.tobytes()


def names_cdr(names):
    """CDR of a ``sequence<string>`` (count, then each string with its NUL), to splice into a
    message at a 4-aligned offset: its inner alignment does not depend on where it goes."""
    out = bytearray(struct.pack("<I", len(names)))
    for n in names:
        b = n.encode("utf-8") + b"\0"
        out += b"\0" * (_align(len(out), 4) - len(out))
        out += struct.pack("<I", len(b)) + b
    return bytes(out)


def _header_cdr(frame_id, stamp_ns):
    fid = frame_id.encode("utf-8") + b"\0"
    return struct.pack("<iII", int(stamp_ns // 1_000_000_000), int(stamp_ns % 1_000_000_000), len(fid)) + fid


def _doubles_seq(out, left, right):
    """Append a ``sequence`` of structs of doubles, ``left (N, a)`` then ``right (N, b)`` in each
    (a transform: translation, rotation), to the CDR body ``out``."""
    left, right = np.asarray(left), np.asarray(right)
    a = left.shape[1]
    rows = np.empty((len(left), a + right.shape[1]), "<f8")   # np.hstack's copies without its overhead
    rows[:, :a], rows[:, a:] = left, right                     # (a ValueError if their lengths differ, as hstack)
    _rows_seq(out, len(rows), rows)


def _rows_seq(out, n, rows):
    """Append a ``sequence`` of ``n`` structs of doubles laid out as ``rows`` (little-endian float64,
    C-ordered) to the CDR body ``out``."""
    out += b"\0" * (_align(len(out), 4) - len(out))
    out += struct.pack("<I", n)
    if n:
        out += b"\0" * (_align(len(out), 8) - len(out))
        out += rows.tobytes()


def multidof_cdr(names_blob, positions, orientations, linear, angular, force, torque, frame_id, stamp_ns):
    """Serialized little-endian CDR of a ``sensor_msgs/MultiDOFJointState``, vectorised: ``names_blob``
    from ``names_cdr`` (built once per body set), transforms from ``positions (N, 3)`` and
    ``orientations (N, 4)``, twists from ``linear``/``angular (N, 3)``, wrenches from
    ``force``/``torque (N, 3)``. Publishable as is with ``Publisher.publish(bytes)``."""
    out = _multidof_head(names_blob, frame_id, stamp_ns)
    _doubles_seq(out, positions, orientations)
    _doubles_seq(out, linear, angular)
    _doubles_seq(out, force, torque)
    return b"\x00\x01\x00\x00" + out


def multidof_rows_cdr(names_blob, transforms, twists, wrenches, frame_id, stamp_ns):
    """``multidof_cdr`` of rows already laid out (little-endian float64, C-ordered): ``transforms``
    ``(N, 7)``, ``twists`` and ``wrenches`` ``(N, 6)`` (``state_rows.blocks``)."""
    n = len(transforms)
    out = _multidof_head(names_blob, frame_id, stamp_ns)
    _rows_seq(out, n, transforms)
    _rows_seq(out, n, twists)
    _rows_seq(out, n, wrenches)
    return b"\x00\x01\x00\x00" + out


def _multidof_head(names_blob, frame_id, stamp_ns):
    out = bytearray(_header_cdr(frame_id, stamp_ns))
    out += b"\0" * (_align(len(out), 4) - len(out))
    out += names_blob
    return out


def multidof_to_arrays(msg, what="set_body_states"):
    """``sensor_msgs/MultiDOFJointState`` → ``(names, positions (N, 3) | None, orientations (N, 4) |
    None, linear (N, 3) | None, angular (N, 3) | None)``: an empty ``transforms`` or ``twist`` list is
    None (that part unchanged). ``PoseError`` (``length``) when a non-empty list does not match the names."""
    names = list(msg.joint_names)
    n = len(names)
    for label, items in (("transforms", msg.transforms), ("twist", msg.twist)):
        if len(items) not in (0, n):
            raise PoseError("length", f"{what}: {len(items)} {label} for {n} joint_names (give one per name, or none)")
    p = q = v = w = None
    if len(msg.transforms):
        t = np.array([(x.translation.x, x.translation.y, x.translation.z, x.rotation.x, x.rotation.y, x.rotation.z,
                       x.rotation.w) for x in msg.transforms], np.float64).reshape(n, 7)
        p, q = t[:, :3], t[:, 3:]
    if len(msg.twist):
        t = np.array([(x.linear.x, x.linear.y, x.linear.z, x.angular.x, x.angular.y, x.angular.z)
                      for x in msg.twist], np.float64).reshape(n, 6)
        v, w = t[:, :3], t[:, 3:]
    return names, p, q, v, w


def contact_wrenches(contacts, origins, duration):
    """Net contact force and torque ``(N, 3)`` on every body over ``duration`` seconds: the sum of
    the impulses on it (``+impulse`` on A, ``-impulse`` on B) divided by ``duration``; the torque is
    about the body's origin ``origins (N, 3)``, world frame."""
    n = len(origins)
    k = len(contacts)
    if not k:
        return np.zeros((n, 3)), np.zeros((n, 3))
    j = contacts.impulse / duration
    ab = np.concatenate((contacts.body_a, contacts.body_b)).reshape(2, k)
    # per contact, (j, r × j) with r from A's origin, then from B's: the wrench on A, and minus that on B
    w = np.empty((2, k, 6))
    w[:, :, :3] = j
    r = contacts.point - origins[ab]                                    # (2, k, 3)
    r0, r1, r2, j0, j1, j2 = r[..., 0], r[..., 1], r[..., 2], j[:, 0], j[:, 1], j[:, 2]
    w[..., 3], w[..., 4], w[..., 5] = r1 * j2 - r2 * j1, r2 * j0 - r0 * j2, r0 * j1 - r1 * j0
    # summed per body and column in one bincount per side (np.add.at is ~10x slower), A's sum minus
    # B's: the same additions in the same order as one bincount per column, so the same bits
    bins = (ab * 6)[..., None] + _SIX                                   # (2, k, 6): body * 6 + column
    wrench = np.bincount(bins[0].ravel(), w[0].ravel(), 6 * n) - np.bincount(bins[1].ravel(), w[1].ravel(), 6 * n)
    wrench = wrench.reshape(n, 6)
    return wrench[:, :3], wrench[:, 3:]


_SIX = np.arange(6)


class PoseError(ValueError):
    """Refused pose input; ``reason`` is a short key (``length``, ``nonfinite``, ``zero_quaternion``,
    ``non_unit_quaternion``) used for the diagnostics counters."""

    def __init__(self, reason, message):
        self.reason = reason
        super().__init__(message)


def validate_poses(positions, orientations, expected=None, tolerance=1e-3, what="poses"):
    """Check poses before they touch a world; returns ``(positions, unit orientations)`` copies.

    Refuses (``PoseError``) a count different from ``expected``, NaN/inf anywhere, a zero
    quaternion, and a quaternion whose norm differs from 1 by more than ``tolerance``.
    """
    p = np.asarray(positions, np.float64)
    q = np.asarray(orientations, np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or q.ndim != 2 or q.shape[1] != 4 or len(p) != len(q):
        raise PoseError("length", f"{what}: need (N, 3) positions and (N, 4) orientations, "
                                  f"got {p.shape} and {q.shape}")
    if expected is not None and len(p) != expected:
        raise PoseError("length", f"{what}: {len(p)} poses for {expected} tracked bodies")
    bad = ~(np.isfinite(p).all(axis=1) & np.isfinite(q).all(axis=1))
    if bad.any():
        raise PoseError("nonfinite", f"{what}: pose {int(np.flatnonzero(bad)[0])} has NaN or infinite values")
    norm = np.linalg.norm(q, axis=1)
    zero = norm < 1e-12
    if zero.any():
        raise PoseError("zero_quaternion", f"{what}: pose {int(np.flatnonzero(zero)[0])} has a zero quaternion")
    off = np.abs(norm - 1.0) > tolerance
    if off.any():
        i = int(np.flatnonzero(off)[0])
        raise PoseError("non_unit_quaternion",
                        f"{what}: pose {i} quaternion has norm {norm[i]:.6g} (must be 1 ± {tolerance:g})")
    return p.copy(), q / norm[:, None]


def engine_reject_reason(exc):
    """The rejection counter of poses the engine refused (``World.set_poses``): ``out_of_bounds``
    for a pose beyond a world bound (``settings.max_position``, or a speed implied by successive
    poses beyond ``max_speed`` / ``max_angular_speed``), ``engine`` for any other refusal."""
    return "out_of_bounds" if isinstance(exc, BoundsError) else "engine"


# ---------------------------------------------------------------------------- RViz markers
_FLOAT_MAX = np.finfo(np.float64).max


def contact_marker_specs(contacts, impulse_scale=1.0, max_arrows=10, ns="contacts", point_size=0.02):
    """The markers of ``contact_markers`` as specs ``(ns, id, type, action, scale (3,), color (4,),
    points (P, 3))`` (what ``cdr_out.marker_array_cdr`` writes; every marker has the identity pose)."""
    none = np.zeros((0, 3))
    specs = [(ns, 0, Marker.ARROW, Marker.DELETEALL, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), none),
             (ns + "/points", 0, Marker.SPHERE_LIST, Marker.ADD, (point_size,) * 3, (1.0, 0.2, 0.1, 1.0),
              np.asarray(contacts.point, float).reshape(-1, 3))]
    k = len(contacts)
    if k and max_arrows > 0:
        with np.errstate(over="ignore", invalid="ignore"):     # one context: each costs ~4 us
            mag = np.linalg.norm(contacts.impulse, axis=1)
            # the impulses drawn (not zero, not NaN), largest first, ties in contact order: a stable
            # sort of those alone orders them as one of all the contacts would; an infinite magnitude
            # ranks as the largest float (its tie with one that large in contact order, as
            # nan_to_num made it)
            drawn = np.flatnonzero(mag > 0)
            order = drawn[np.argsort(-np.minimum(mag[drawn], _FLOAT_MAX), kind="stable")]
            start = contacts.point[order]
            end = start + impulse_scale * contacts.impulse[order]
        seg = np.empty((len(order), 2, 3), np.result_type(start, end))   # start, end, start, ... (np.stack's
        seg[:, 0], seg[:, 1] = start, end                                 # overhead doubled this)
        seg = seg.reshape(-1, 3)
        blue = (0.1, 0.6, 1.0, 1.0)
        specs.append((ns + "/impulse_lines", 0, Marker.LINE_LIST, Marker.ADD, (point_size * 0.25, 0.0, 0.0), blue, seg))
        arrow, add, scale = Marker.ARROW, Marker.ADD, (point_size * 0.5, point_size, point_size)
        specs += [(ns + "/impulses", j, arrow, add, scale, blue, seg[2 * j:2 * j + 2])
                  for j in range(min(len(order), max_arrows))]
    return specs


def contact_markers(contacts, header, impulse_scale=1.0, max_arrows=10, ns="contacts", point_size=0.02):
    """``MarkerArray`` for RViz: a DELETEALL, one SPHERE_LIST of all contact points, one LINE_LIST
    drawing every non-zero impulse on A as a segment from its point (length = ``impulse_scale`` m
    per N·s), and an ARROW for each of the ``max_arrows`` largest impulses.

    Segments in one LINE_LIST keep a tick with 100 contacts cheap, where 100 ARROW markers took
    ~4 ms. The node publishes the same markers as bytes (``cdr_out.marker_array_cdr`` of
    ``contact_marker_specs``), which costs a fraction of building these objects."""
    out = MarkerArray()
    for ns_, mid, mtype, action, scale, color, points in contact_marker_specs(contacts, impulse_scale, max_arrows, ns,
                                                                               point_size):
        m = Marker(header=header, ns=ns_, id=mid, type=mtype, action=action)
        m.scale = Vector3(x=scale[0], y=scale[1], z=scale[2])
        m.color = ColorRGBA(r=color[0], g=color[1], b=color[2], a=color[3])
        m.points = [Point(x=x, y=y, z=z) for x, y, z in np.asarray(points, float).tolist()]
        out.markers.append(m)
    return out


# ---------------------------------------------------------------------------- diagnostics
def _fmt(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def diagnostic_array(header, name, hardware_id, values, level=DiagnosticStatus.OK, message="ok"):
    """``DiagnosticArray`` with one status ``name`` whose key/values are ``values`` (a dict, in order)."""
    status = DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id,
                              values=[KeyValue(key=str(k), value=_fmt(v)) for k, v in values.items()])
    return DiagnosticArray(header=header, status=[status])


def diagnostics_to_dict(msg, name=None):
    """Key/values of the first status (named ``name`` if given) of a ``DiagnosticArray``."""
    for s in msg.status:
        if name is None or s.name == name:
            return {kv.key: kv.value for kv in s.values}
    return None


def feature_name(index):
    return FEATURES[index] if 0 <= index < len(FEATURES) else f"unknown({index})"
