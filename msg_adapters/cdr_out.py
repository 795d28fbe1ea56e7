"""The node's per-tick outputs written straight to CDR bytes (``Publisher.publish(bytes)``).

rclpy turns a message object into bytes field by field in Python-facing C: a ``MarkerArray`` of
a dozen markers with their points cost ~1.5 ms a tick and a ``PointCloud2`` ~0.2 ms, three times the
engine's step on a small scene. Written here with ``struct`` and numpy, they are the same bytes
(tests compare them with ``rclpy.serialization.serialize_message`` of the message objects that
``conversions`` builds) at a fraction of the cost, as ``conversions.posearray_cdr`` already does for
``body_states``.

The encoding is ROS 2's default: little-endian plain CDR (encapsulation ``00 01 00 00``), each
primitive aligned to its size counted from the start of the body (after those four bytes), a
string as ``uint32`` length (with its NUL) then the bytes and the NUL, a sequence as ``uint32``
count then the elements (aligned to the element's first primitive only when there is one).
"""
import functools
import struct

import numpy as np

_ENCAPSULATION = b"\x00\x01\x00\x00"


class CdrWriter:
    """Appends CDR primitives to a body, one call each: for the parts built once (the contacts'
    fields, a Marker's empty tail); the per-tick writers below pack whole runs of fields at once."""

    def __init__(self):
        self.out = bytearray()

    def align(self, n):
        pad = -len(self.out) % n
        if pad:
            self.out += b"\0" * pad

    def pack(self, align, fmt, *values):
        """Values of one alignment in a row (``fmt`` without the byte-order mark)."""
        self.align(align)
        self.out += struct.pack("<" + fmt, *values)

    def string(self, s):
        b = s.encode("utf-8") + b"\0" if isinstance(s, str) else s + b"\0"
        self.align(4)
        self.out += struct.pack("<I", len(b)) + b

    def header(self, frame_id, stamp_ns):
        """``std_msgs/Header``."""
        self.pack(4, "iI", int(stamp_ns // 1_000_000_000), int(stamp_ns % 1_000_000_000))
        self.string(frame_id)


def _header_cdr(frame_id, stamp_ns):
    """``std_msgs/Header`` at a 4-aligned offset (it holds 4-aligned items only, so its bytes do not
    depend on where it goes); it ends unaligned (the frame id's NUL)."""
    fid = frame_id.encode("utf-8") + b"\0"
    return _HEADER.pack(int(stamp_ns // 1_000_000_000), int(stamp_ns % 1_000_000_000), len(fid)) + fid


_HEADER = struct.Struct("<iII")            # stamp (sec, nanosec), frame_id's length
# PointCloud2 after its fields (which end 4-aligned): is_bigendian, point_step, row_step, len(data)
_CLOUD_MIDDLE = struct.Struct("<?3xIII")


def pointcloud2_cdr(a, fields_cdr, frame_id, stamp_ns):
    """``sensor_msgs/PointCloud2`` of the structured array ``a (N,)`` (height 1, little-endian,
    dense), ``fields_cdr`` the ``sequence<PointField>`` of its layout (``point_fields_cdr``)."""
    a = np.ascontiguousarray(a)
    out = bytearray(_header_cdr(frame_id, stamp_ns))
    out += b"\0" * (-len(out) % 4)
    out += struct.pack("<II", 1, len(a))
    out += fields_cdr   # 4-aligned, and its own alignment does not depend on where it starts
    step = a.dtype.itemsize
    out += _CLOUD_MIDDLE.pack(False, step, step * len(a), step * len(a))
    out += a.tobytes()
    out += b"\1"       # is_dense
    return _ENCAPSULATION + out


def point_fields_cdr(fields):
    """``sequence<sensor_msgs/PointField>`` of ``PointField`` messages (``conversions.point_fields``),
    to splice at a 4-aligned offset."""
    w = CdrWriter()
    w.pack(4, "I", len(fields))
    for f in fields:
        w.string(f.name)
        w.pack(4, "I", f.offset)
        w.pack(1, "B", f.datatype)
        w.pack(4, "I", f.count)
    return bytes(w.out)


# A Marker from its ``id`` (4-aligned, after header and ns) to the count of its points, in one
# struct per alignment phase (CDR aligns to the offset from the body's start). Only the doubles after
# id, type, action (12 bytes) need padding, 4 bytes when the id is 8-aligned; from there every item
# ends 8-aligned: pose (7d) and scale (3d), colour (4f), lifetime (iI), frame_locked (?) padded to the
# points' uint32 count, which ends 8-aligned, so the points follow with no padding and end 8-aligned
# too, where the (4-aligned) tail goes without padding either.
_MARKER_BODY = {phase: struct.Struct("<iii" + ("4x" if phase == 0 else "") + "10d4fiI?3xI") for phase in (0, 4)}
_IDENTITY_POSE = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)


@functools.lru_cache(maxsize=64)
def _string_cdr(s):
    """A CDR string at a 4-aligned offset: length (with its NUL), the bytes, the NUL."""
    b = s.encode("utf-8") + b"\0"
    return struct.pack("<I", len(b)) + b


def marker_array_cdr(markers, frame_id, stamp_ns):
    """``visualization_msgs/MarkerArray`` of marker specs ``(ns, id, type, action, scale (3,),
    color (4,), points (P, 3))`` (``conversions.contact_marker_specs``), each with the header
    ``frame_id``/``stamp_ns``, an identity pose, no lifetime, and every other field empty."""
    out = bytearray(struct.pack("<I", len(markers)))
    header = _header_cdr(frame_id, stamp_ns)
    header += b"\0" * (-len(header) % 4)      # the ns string is 4-aligned (header starts 4-aligned)
    heads = {}   # header + ns: 4-aligned items only, the same bytes at any 4-aligned offset
    for ns, mid, mtype, action, scale, color, points in markers:
        head = heads.get(ns)
        if head is None:
            head = heads[ns] = header + _string_cdr(ns)
        out += b"\0" * (-len(out) % 4)
        out += head
        out += b"\0" * (-len(out) % 4)
        points = np.ascontiguousarray(points, "<f8")
        out += _MARKER_BODY[len(out) % 8].pack(mid, mtype, action, *_IDENTITY_POSE, *scale, *color, 0, 0, False,
                                                len(points))
        out += points.tobytes()
        out += _MARKER_TAIL
    return _ENCAPSULATION + out


def _marker_tail():
    """A Marker's fields after ``points``, all empty: their alignments are 4 at most, so from any
    4-aligned offset they are these bytes."""
    w = CdrWriter()
    w.pack(4, "I", 0)                   # colors
    w.string("")                        # texture_resource
    w.header("", 0)                     # texture: CompressedImage (header, format, data)
    w.string("")
    w.pack(4, "I", 0)
    w.pack(4, "I", 0)                   # uv_coordinates
    w.string("")                        # text
    w.string("")                        # mesh_resource
    w.string("")                        # mesh_file: filename, data
    w.pack(4, "I", 0)
    w.pack(1, "?", False)               # mesh_use_embedded_materials
    return bytes(w.out)


_MARKER_TAIL = _marker_tail()
