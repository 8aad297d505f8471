"""Run one node in its own process the same way for every followbot executable."""

import ctypes
import signal
import sys

from followbot.transport import keep_large_buffers, use_package_profile
import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args

try:
    # rclpy's executor written in C++ (Jazzy 7.1): it wakes a callback ~0.2 ms sooner than the
    # Python SingleThreadedExecutor, which rebuilds its wait set in Python on every spin.
    # Measured between the two processes: camera to cmd_vel p50 3.3 -> 2.9 ms, and the
    # simulator in lockstep with the follower 4.1x -> 5.4x real time.
    from rclpy.experimental import EventsExecutor as NodeExecutor
except ImportError:  # An rclpy without it: the standard executor works the same, slower.
    NodeExecutor = SingleThreadedExecutor

# How often the spin loop returns to Python, so that a stop request is seen even when no
# message comes.
SPIN_POLL_S = 0.1
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
# Linux prctl option: the signal the kernel sends a process when its parent dies.
PR_SET_PDEATHSIG = 1
# The errors rclpy's C extension raises when rcl refuses arguments or initialisation.
RCLInvalidROSArgsError = rclpy_implementation.RCLInvalidROSArgsError
RCLError = rclpy_implementation.RCLError
# rcl's markers around ROS arguments on a command line.
ROS_ARGS_FLAG = '--ros-args'
ROS_ARGS_END = '--'
REMAP_FLAGS = ('-r', '--remap')
# The remaps that rename a node and move it to another namespace (rcl's special names).
NODE_NAME_REMAP = '__node'
NAMESPACE_REMAP = '__ns'


class StopSignals:
    """
    Remember that SIGINT or SIGTERM came, in a handler that takes no lock.

    A handler that sets a threading.Event takes the Event's lock; a second signal arriving
    while the first handler holds it deadlocks the process in its own handler (seen: a
    simulator that never exited after its launcher was killed). Appending to a list is atomic.
    SIGINT is handled too: a shell starts background jobs with SIGINT ignored, and Python then
    keeps it ignored, so `kill -INT` (what ros2 launch sends) would not stop the process.
    """

    def __init__(self):
        """Make a record of no signals; :meth:`install` starts listening."""
        self._received = []

    def install(self):
        """
        Handle SIGINT and SIGTERM in this process from now on, by recording them.

        :return: this object.
        """
        for stop_signal in STOP_SIGNALS:
            signal.signal(stop_signal, self._record)
        return self

    def _record(self, signum, frame):
        self._received.append(signum)

    def is_set(self) -> bool:
        """Return whether a stop signal came."""
        return bool(self._received)


def die_with_parent() -> None:
    """
    Have the kernel send this process SIGTERM when its parent dies, even by SIGKILL (Linux).

    For ``subprocess.Popen(preexec_fn=...)``: a node started by a tool then never outlives it.
    """
    libc = ctypes.CDLL('libc.so.6', use_errno=True)
    libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM)


def split_ros_arguments(argv: list) -> tuple:
    """
    Separate ROS arguments from this program's own, as rcl does.

    A ROS section starts at ``--ros-args`` and runs to ``--`` or the end; there may be several.

    :param argv: arguments without the program name.
    :return: ``(own, ros)``: this program's arguments, and the ROS sections with their markers,
        each closed by ``--`` so that more arguments can follow them.
    """
    own, ros = [], []
    in_ros_section = False
    for argument in argv:
        if argument == ROS_ARGS_FLAG:
            in_ros_section = True
            ros.append(argument)
        elif in_ros_section and argument == ROS_ARGS_END:
            in_ros_section = False
            ros.append(argument)
        elif in_ros_section:
            ros.append(argument)
        else:
            own.append(argument)
    if in_ros_section:
        ros.append(ROS_ARGS_END)
    return own, ros


def refuse_ros_arguments(parser, argv, reason: str) -> None:
    """
    Stop a tool that starts nodes of its own when it is given ROS arguments, saying why.

    :param parser: the tool's ``argparse.ArgumentParser``; its ``error`` exits with code 2.
    :param argv: the tool's arguments without the program name; ``sys.argv[1:]`` when None.
    :param reason: why the tool takes none, and what to use instead.
    """
    if ROS_ARGS_FLAG in (sys.argv[1:] if argv is None else argv):
        parser.error(f'takes no {ROS_ARGS_FLAG}: {reason}')


def node_name_and_namespace(node_name: str, argv) -> tuple:
    """
    Return the name and namespace a node gets from the command line's renames.

    :param node_name: the node's own name.
    :param argv: the command line (ROS sections are read; ``sys.argv`` when None).
    :return: (name, namespace): the namespace absolute, ``'/'`` for none.
    """
    _, ros = split_ros_arguments(list(sys.argv[1:] if argv is None else argv))
    name, namespace = node_name, '/'
    for flag, remap in zip(ros, ros[1:]):
        if flag not in REMAP_FLAGS or ':=' not in remap:
            continue
        target, value = remap.split(':=', 1)
        aimed_at, _, special = target.rpartition(':')
        if aimed_at and aimed_at != node_name:
            continue
        if special == NODE_NAME_REMAP:
            name = value
        elif special == NAMESPACE_REMAP:
            namespace = '/' + value.strip('/')
    return name, namespace


def logger_name(node_name: str, argv) -> str:
    """
    Return the name a node will log under, with the command line's renames applied.

    rcl names a node's logger after its namespace and name (``robot1.follower`` for
    ``/robot1/follower``). A node that fails to start must say so under that name too.

    :param node_name: the node's own name.
    :param argv: the command line (ROS sections are read; ``sys.argv`` when None).
    :return: the logger name.
    """
    name, namespace = node_name_and_namespace(node_name, argv)
    return '.'.join(part for part in (*namespace.strip('/').split('/'), name) if part)


class RosStartError(ValueError):
    """rcl refused to start: a ROS argument it cannot parse, or a bad ROS environment variable."""


def _rcl_reason(error: Exception, prefix: str) -> str:
    # rcl's messages: '<prefix><what>. Error: <detail>, at <file:line>[, at <file:line>]'.
    return str(error).removeprefix(prefix).split(', at ')[0]


def init_rclpy(args=None, **init_options) -> None:
    """
    Initialise rclpy, saying in one sentence what rcl refused, if anything.

    :param args: the command line, ``sys.argv`` when None; rcl reads its ROS sections.
    :param init_options: further keywords for :func:`rclpy.init`.
    :raises RosStartError: for a remap, parameter or parameters file rcl cannot parse
        ('Invalid ROS arguments: ...'), or another reason rcl gives for not starting, such as a
        ROS_DOMAIN_ID that is not a number ('ROS could not start: ...').
    """
    try:
        # rcl's own argument parser first, so that a bad argument is named as one.
        remove_ros_args(args)
    except RCLInvalidROSArgsError as error:
        reason = _rcl_reason(error, 'Failed to parse ROS arguments: ')
        raise RosStartError(f'Invalid ROS arguments: {reason}') from None
    try:
        rclpy.init(args=args, **init_options)
    except RCLError as error:
        reason = _rcl_reason(error, 'failed to initialize rcl: ')
        raise RosStartError(f'ROS could not start: {reason}') from None


def run_node(node_class, args=None, startup_errors=()) -> None:
    """
    Spin a node until Ctrl-C, SIGTERM or its own ``finished`` flag, then clean it up.

    rclpy's own SIGINT handler shuts the context down before a node's cleanup runs, so a
    node could not publish its last words (the follower's zero Twist). Here rclpy installs no
    handler; SIGINT and SIGTERM only set a flag that the spin loop checks between callbacks,
    so no callback is cut short and ``destroy_node`` runs while the context is still valid.

    :param node_class: a Node subclass taking ``**kwargs``; an optional ``finished`` property
        ends the spin when it becomes true.
    :param args: command-line arguments for ``rclpy.init`` (``--ros-args`` and friends).
    :param startup_errors: further exception types that mean "cannot start here" and are
        reported as one line, like invalid parameters.
    """
    # Before rclpy allocates anything: image buffers are then reused, not re-mapped per frame.
    keep_large_buffers()
    # Before rclpy creates the participant, which reads the Fast DDS configuration.
    transport_line = use_package_profile()
    startup_logger = rclpy.logging.get_logger(
        logger_name(getattr(node_class, 'NODE_NAME', node_class.__name__), args))
    try:
        init_rclpy(args, signal_handler_options=SignalHandlerOptions.NO)
    except RosStartError as error:
        startup_logger.fatal(f'Cannot start: {error}')
        raise SystemExit(2)
    stop_signals = StopSignals().install()
    node = None
    # An executor of our own, not rclpy.spin_once's global one: shutting it down drops its
    # half-consumed wait generator, which may hold the node's handles in use (it yields ready
    # waitables, such as a subscription's matched event, from inside the wait set's context).
    # Left alive, that generator makes Node.destroy_node wait forever for the handles.
    executor = NodeExecutor()
    try:
        try:
            node = node_class()
        except (ValueError, ParameterException, *startup_errors) as error:
            # A parameter of the wrong type, out of its range, or naming nothing known, or a
            # machine that lacks something: say which, not a traceback.
            startup_logger.fatal(f'Cannot start: {error}')
            raise SystemExit(2)
        if transport_line is not None:
            node.get_logger().info(transport_line)
        executor.add_node(node)
        while (rclpy.ok() and not stop_signals.is_set()
               and not getattr(node, 'finished', False)):
            executor.spin_once(timeout_sec=SPIN_POLL_S)
    except ExternalShutdownException:
        pass
    finally:
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
