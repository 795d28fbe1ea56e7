"""msg_adapters: the only code of contact_sim that knows ROS 2.

``msg_adapters.conversions`` holds pure message <-> numpy conversions (no node needed);
``msg_adapters.node`` is the thin ``contact_sim`` node (console script ``contact_sim_node``,
or ``python -m msg_adapters``). Importing this package needs the ROS 2 Jazzy message packages.
"""
from .conversions import (  # noqa: F401
    CONTACT_DTYPE, CONTACT_FIELDS, CdrError, PoseError, array_to_contacts, array_to_pointcloud2,
    arrays_to_posearray, contact_markers, contacts_to_array, contacts_to_pointcloud2, diagnostic_array,
    diagnostics_to_dict, make_header, parse_posearray_cdr, pointcloud2_to_array, pointcloud2_to_contacts,
    posearray_cdr, posearray_to_arrays, validate_poses,
)
