"""
Give every camera frame a time that moves forward, even from a camera that does not stamp.

The controller measures acceleration and line memory between frames by their times. Camera
drivers exist that leave ``header.stamp`` at zero, or stamp several frames alike; taken as they
are, such stamps freeze the controller's time, and its acceleration limit then holds the robot
at a standstill for ever while it reports that it is tracking the line. :class:`FrameClock`
uses the stamp when it is set and later than the last one, and otherwise the last frame's time
advanced by the wall time since that frame arrived.
"""

# A stamp this much earlier than the last usable one starts a new time line (a restarted
# simulation, a looped recording); nearer ones are repeats or reordered frames.
RESTART_JUMP_S = 1.0


class FrameClock:
    """Time camera frames by their stamps, or by their arrival where the stamps cannot."""

    def __init__(self):
        """Start with no frame seen."""
        self._last_time_s = None
        self._last_stamp_s = None
        self._last_arrival_s = None

    def reset(self) -> None:
        """Forget the frames seen (a new camera, a restarted simulation)."""
        self.__init__()

    def frame_time(self, stamp_s: float, arrival_s: float) -> tuple[float, bool]:
        """
        Return the time to use for a frame.

        :param stamp_s: the frame's ``header.stamp`` in seconds (0 when unset).
        :param arrival_s: when the frame arrived, on a steady clock, in seconds.
        :return: (time in seconds, whether the stamp was usable). A stamp is usable when it is
            above zero and later than the last frame's time; a stamp more than
            ``RESTART_JUMP_S`` earlier than the last usable stamp is taken as a restart (a new
            simulation, a looped recording) and used too, so the controller sees time go back.
        """
        last_time_s, last_arrival_s = self._last_time_s, self._last_arrival_s
        self._last_arrival_s = arrival_s
        stamped = stamp_s > 0.0
        restarted = (stamped and self._last_stamp_s is not None
                     and stamp_s < self._last_stamp_s - RESTART_JUMP_S)
        if stamped and (last_time_s is None or stamp_s > last_time_s or restarted):
            self._last_time_s = self._last_stamp_s = stamp_s
            return stamp_s, True
        if last_time_s is None:
            self._last_time_s = 0.0
            return 0.0, False
        self._last_time_s = last_time_s + max(arrival_s - last_arrival_s, 0.0)
        return self._last_time_s, False
