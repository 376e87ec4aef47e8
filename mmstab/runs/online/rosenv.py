"""ROS 2 from the package registry's wheels: the environment ``rclpy`` needs, set by mmstab.

The ``ros`` extra (``make ros``) installs ROS 2 Jazzy's ``rclpy`` and message wheels into
the virtualenv, and ``ros/setup.sh`` generates the message packages no wheel carries
(``grid_map_msgs``, ``tf2_msgs``) into it. The wheels' shared libraries (site-packages'
``ros_*.libs`` and the virtualenv's ``lib``) must be on ``LD_LIBRARY_PATH`` when the process
starts (the dynamic loader reads it once), and the middleware is Fast DDS
(``RMW_IMPLEMENTATION=rmw_fastrtps_cpp``): :func:`ensure_ros_env` re-executes the
command once with both set, so a user types ``mmstab node PROBLEM`` and nothing else.
"""

from __future__ import annotations

import os
import sys
import sysconfig
from pathlib import Path
from typing import Any, NamedTuple

#: The middleware of the wheels.
RMW = "rmw_fastrtps_cpp"
#: Set in the re-executed process (no second re-exec).
GUARD = "MMSTAB_ROS_ENV"


def library_dirs() -> list[str]:
    """The wheels' shared-library folders of this interpreter's virtualenv."""
    site = Path(sysconfig.get_paths()["purelib"])
    dirs = sorted(str(p) for p in site.glob("ros_*.libs") if p.is_dir())
    return [*dirs, str(Path(sys.prefix) / "lib")]


def ros_env(env: dict[str, str] | None = None) -> dict[str, str]:
    """``env`` (default the process's) with the wheels' libraries and Fast DDS set."""
    out = dict(os.environ if env is None else env)
    have = [p for p in out.get("LD_LIBRARY_PATH", "").split(os.pathsep) if p]
    out["LD_LIBRARY_PATH"] = os.pathsep.join([*[d for d in library_dirs() if d not in have], *have])
    out.setdefault("RMW_IMPLEMENTATION", RMW)
    out.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    out[GUARD] = "1"
    return out


def ros_available() -> str | None:
    """None when the ros extra is installed, else why not (one line)."""
    import importlib.util

    for name in ("rclpy", "grid_map_msgs", "tf2_msgs", "nav_msgs", "visualization_msgs"):
        if importlib.util.find_spec(name) is None:
            return f"no {name} in this Python: install the ros extra (make ros)"
    return None


def ensure_ros_env() -> None:
    """Re-execute this command with :func:`ros_env` unless it has it already."""
    if os.environ.get(GUARD) == "1":
        return
    os.execve(sys.executable, [sys.executable, *sys.orig_argv[1:]], ros_env())


class NodeTopics(NamedTuple):
    """The node's topics (ROS parameters of the same names)."""

    map_topic: str
    odom_topic: str
    joints_topic: str
    arm_target_topic: str = "/mmstab/arm_target"
    command_topic: str = "/mmstab/joint_velocity"
    diagnostics_topic: str = "/diagnostics"
    markers_topic: str = "/mmstab/markers"

    @classmethod
    def of(cls, online: dict[str, Any]) -> NodeTopics:
        """The topics of a problem's ``online`` section (the outputs' defaults)."""
        return cls(online["map_topic"], online["odom_topic"], online["joints_topic"] or "")


def stamp_of(msg: Any) -> float:
    """A message's header stamp [s] (ROS 2's ``sec`` / ``nanosec``)."""
    st = msg.header.stamp
    return float(st.sec) + 1e-9 * float(st.nanosec)


def time_msg(t: float) -> Any:
    """``builtin_interfaces/Time`` of ``t`` [s] (rclpy's)."""
    from builtin_interfaces.msg import Time

    sec = int(t // 1)
    return Time(sec=sec, nanosec=min(int(round((t - sec) * 1e9)), 999_999_999))
