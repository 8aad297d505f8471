"""
Carry camera images between processes in a few milliseconds: the Fast DDS profile and malloc.

Two things slow a 640x480 image between two rclpy processes down, and neither is the copy of
its 0.9 MB (~25 us):

* Fast DDS's default shared-memory segment (512 KiB) is too small for it, so the frame goes by
  UDP in 64 KB fragments; a best-effort subscriber then loses about half of the frames. The
  package's profile, ``config/fastdds_shm.xml``, gives each participant a 16 MiB segment.
* Each frame passes through several fresh 0.9 MB buffers (the rclpy message, the serialised
  sample, the received sample). glibc serves blocks that large with mmap and returns them on
  free, so every frame faults in ~225 new pages per buffer: that doubled the transport time.
  :func:`keep_large_buffers` has glibc keep such blocks in the heap and reuse them.
"""

import ctypes
import os

from followbot.package_files import share_file

FASTDDS_PROFILE_NAME = 'fastdds_shm.xml'
# The variable Fast DDS 2.x (ROS 2 Jazzy's rmw_fastrtps_cpp) reads its default profile from.
FASTDDS_PROFILE_VARIABLE = 'FASTRTPS_DEFAULT_PROFILES_FILE'
# mallopt parameters, from glibc's malloc.h.
M_TRIM_THRESHOLD = -1
M_TOP_PAD = -2
M_MMAP_THRESHOLD = -3
# Blocks below this come from the heap: every image buffer up to 1280x1280x3 (4.9 MB) and a
# 640x480 point cloud (3.7 MB). Setting it also stops glibc from adapting it.
MMAP_THRESHOLD_BYTES = 16 * 1024 * 1024
# Free heap memory is given back to the system only above this much, so buffers freed after
# one frame are still mapped for the next.
TRIM_THRESHOLD_BYTES = 128 * 1024 * 1024
# Grow the heap in steps large enough for several frames at once.
TOP_PAD_BYTES = 16 * 1024 * 1024


def fastdds_profile_path():
    """
    Return the path of the package's Fast DDS profile for images.

    :return: the installed (or checked-out) ``config/fastdds_shm.xml``.
    :raises FileNotFoundError: if the package's config folder cannot be found.
    """
    return share_file('config', FASTDDS_PROFILE_NAME)


def environment_with_profile(environment: dict) -> tuple:
    """
    Return an environment whose Fast DDS participants use the package's profile.

    A profile the user chose already (the variable set and not empty) is kept.

    :param environment: the environment to start from; it is not changed.
    :return: (the new environment, the profile path in force).
    """
    chosen = environment.get(FASTDDS_PROFILE_VARIABLE)
    if chosen:
        return dict(environment), chosen
    path = str(fastdds_profile_path())
    return {**environment, FASTDDS_PROFILE_VARIABLE: path}, path


def environment_without_profile(environment: dict) -> dict:
    """
    Return an environment whose Fast DDS participants use Fast DDS's defaults.

    :param environment: the environment to start from; it is not changed.
    :return: the environment without a default profile file.
    """
    return {name: value for name, value in environment.items()
            if name != FASTDDS_PROFILE_VARIABLE}


def keep_large_buffers() -> bool:
    """
    Make glibc keep large freed blocks for reuse instead of unmapping them.

    Call it early in a process that sends or receives images; it affects only this process.
    Set ``MALLOC_MMAP_THRESHOLD_`` yourself to choose other values: this then leaves glibc
    alone.

    :return: whether the settings were applied (False off glibc, or when the user chose).
    """
    if 'MALLOC_MMAP_THRESHOLD_' in os.environ:
        return False
    try:
        libc = ctypes.CDLL('libc.so.6')
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False  # Not glibc (musl, macOS): nothing to tune.
    return all(mallopt(parameter, value) == 1 for parameter, value in (
        (M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES),
        (M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES),
        (M_TOP_PAD, TOP_PAD_BYTES)))
