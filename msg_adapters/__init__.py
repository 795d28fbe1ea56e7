"""msg_adapters: the only code of contact_sim that knows ROS 2.

``msg_adapters.conversions`` holds pure message <-> numpy conversions (no node needed);
``msg_adapters.node`` is the thin ``contact_sim`` node (console script ``contact_sim_node``,
or ``python -m msg_adapters``). Importing the conversions needs the ROS 2 Jazzy message packages.

The conversions' names are importable from here too, loaded on first use: importing the package
itself stays cheap, so the node's entry point (``msg_adapters.launch``) catches signals before
rclpy and numpy are loaded.
"""
_EXPORTS = (
    "CONTACT_DTYPE", "CONTACT_FIELDS", "CdrError", "PoseError", "array_to_contacts", "array_to_pointcloud2",
    "arrays_to_posearray", "contact_markers", "contacts_to_array", "contacts_to_pointcloud2", "diagnostic_array",
    "diagnostics_to_dict", "make_header", "parse_posearray_cdr", "pointcloud2_to_array", "pointcloud2_to_contacts",
    "posearray_cdr", "posearray_to_arrays", "validate_poses",
)
__all__ = list(_EXPORTS)


def __getattr__(name):
    if name in _EXPORTS:
        from . import conversions
        return getattr(conversions, name)
    raise AttributeError(f"module 'msg_adapters' has no attribute {name!r}")
