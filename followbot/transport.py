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
# Everything by which a user configures Fast DDS: the profile file variables (2.x and 3.x
# names), the built-in transport presets (FASTDDS_BUILTIN_TRANSPORTS=DEFAULT asks for Fast
# DDS's own defaults), and the profile files Fast DDS loads from the working directory.
USER_CONFIGURATION_VARIABLES = (FASTDDS_PROFILE_VARIABLE, 'FASTDDS_DEFAULT_PROFILES_FILE',
                                'FASTDDS_BUILTIN_TRANSPORTS')
WORKING_DIRECTORY_PROFILES = ('DEFAULT_FASTRTPS_PROFILES.xml', 'DEFAULT_FASTDDS_PROFILES.xml')
RMW_VARIABLE = 'RMW_IMPLEMENTATION'
FASTDDS_RMW = 'rmw_fastrtps_cpp'
# The middleware needs no profile of ours when it is not Fast DDS.
NOT_FASTDDS = 'not Fast DDS'
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


def users_fastdds_configuration(environment: dict, working_directory='.') -> str | None:
    """
    Say which Fast DDS configuration of the user's is in force, if any.

    :param environment: the environment the ROS process runs in.
    :param working_directory: its working directory, where Fast DDS looks for profile files.
    :return: e.g. ``'FASTRTPS_DEFAULT_PROFILES_FILE=/etc/my.xml'``; ``NOT_FASTDDS`` when the
        middleware is another one; None when Fast DDS would run on its built-in defaults.
    """
    rmw = environment.get(RMW_VARIABLE)
    if rmw and rmw != FASTDDS_RMW:
        return NOT_FASTDDS
    for variable in USER_CONFIGURATION_VARIABLES:
        if environment.get(variable):
            return f'{variable}={environment[variable]}'
    for name in WORKING_DIRECTORY_PROFILES:
        path = os.path.join(working_directory, name)
        if os.path.isfile(path):
            return os.path.abspath(path)
    return None


def environment_with_profile(environment: dict) -> tuple:
    """
    Return an environment whose Fast DDS participants use the package's profile.

    A configuration of the user's (see :func:`users_fastdds_configuration`) is kept.

    :param environment: the environment to start from; it is not changed.
    :return: (the new environment, the configuration in force as a text to follow 'Fast DDS ':
        ``'profile <path>'`` for the package's, ``'configuration of yours, <what>'``).
    """
    chosen = users_fastdds_configuration(environment)
    if chosen is not None:
        return dict(environment), f'configuration of yours, {chosen}'
    path = str(fastdds_profile_path())
    return {**environment, FASTDDS_PROFILE_VARIABLE: path}, f'profile {path}'


def environment_without_profile(environment: dict) -> dict:
    """
    Return an environment whose Fast DDS participants use Fast DDS's defaults.

    :param environment: the environment to start from; it is not changed.
    :return: the environment without a profile file, asking for the default transports.
    """
    return {**{name: value for name, value in environment.items()
               if name not in USER_CONFIGURATION_VARIABLES},
            'FASTDDS_BUILTIN_TRANSPORTS': 'DEFAULT'}


def use_package_profile() -> str | None:
    """
    Give this process's Fast DDS participants the package's profile, unless the user chose.

    Call it before ``rclpy.init``. Without it a node run by ``ros2 run`` sends camera images
    over fragmented UDP and loses some of them.

    :return: one line saying which configuration is in force, for the node's log; None when
        the middleware is not Fast DDS.
    """
    chosen = users_fastdds_configuration(os.environ)
    if chosen == NOT_FASTDDS:
        return None
    try:
        path = str(fastdds_profile_path())
    except FileNotFoundError as error:
        path = None
        missing = error
    # The followbot launcher exports the package's profile for its nodes: that is not the
    # user's choice, and is said as what it is.
    if chosen is not None and chosen != f'{FASTDDS_PROFILE_VARIABLE}={path}':
        return f'Fast DDS configuration: yours ({chosen}).'
    if path is None:
        return f'Fast DDS configuration: its defaults; camera images may be lost ({missing})'
    os.environ[FASTDDS_PROFILE_VARIABLE] = path
    return (f"Fast DDS configuration: followbot's profile {path}, so images go whole through "
            f'shared memory (set {FASTDDS_PROFILE_VARIABLE} to use your own).')


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
