"""Names a transport puts on the wire, checked before anything flies: ROS 2 topic namespaces."""

from __future__ import annotations

import re

# ROS 2 name tokens: letters, digits and underscores, not starting with a digit, no "__"; joined by "/"
_TOKEN = r"[A-Za-z_][A-Za-z0-9_]*"
_NAMESPACE = re.compile(rf"^/?{_TOKEN}(/{_TOKEN})*$")


def check_ros_namespace(name: str, option: str) -> str:
    """``name`` (without its leading slash) when it is a valid ROS 2 namespace; a ValueError naming
    ``option`` and the rule otherwise."""
    if not isinstance(name, str) or not _NAMESPACE.match(name) or "__" in name:
        raise ValueError(f"{option} {name!r}: not a ROS 2 namespace (tokens of letters, digits and underscores, not starting "
                         "with a digit, no '__', joined by '/')")
    return name.lstrip("/")
