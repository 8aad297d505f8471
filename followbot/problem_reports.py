"""
Say what is wrong once per cause per period, however often it happens.

A camera that sends bad frames sends them twenty times a second, each with a slightly different
text (its size, its stamp). Logging every distinct text floods the log and remembers every text
for ever; logging each text once hides a problem that comes back. :class:`ProblemReports` keys
problems by their cause (a short fixed name such as ``'image'`` or ``'camera_info'``): the first
occurrence of a cause is reported at once, later ones within ``period_s`` are only counted, and
the first one after the period is reported with that count. Memory is one entry per cause.
"""

import dataclasses
import math

# Default time between two reports of one cause, in seconds of the caller's clock.
DEFAULT_REPORT_PERIOD_S = 10.0


@dataclasses.dataclass
class _CauseRecord:
    """When a cause was last reported, and how often it happened since."""

    reported_s: float = -math.inf
    unreported: int = 0
    active: bool = False


class ProblemReports:
    """
    Decide, per cause, which occurrences of a problem are worth a log line.

    Pure logic: the caller gives the time (a steady clock is best: it keeps running when the
    simulated clock stops) and writes the log line itself.
    """

    def __init__(self, period_s: float = DEFAULT_REPORT_PERIOD_S):
        """
        Start with no problems seen.

        :param period_s: least time between two reports of one cause, in seconds.
        :raises ValueError: if the period is not a positive finite number.
        """
        if not (math.isfinite(period_s) and period_s > 0.0):
            raise ValueError(f'period_s must be a positive finite number, got {period_s}.')
        self._period_s = period_s
        self._causes = {}

    def occurred(self, cause: str, now_s: float) -> str | None:
        """
        Record an occurrence of a problem and tell whether to report it now.

        :param cause: the problem's cause, a short name from a fixed set.
        :param now_s: the current time in seconds.
        :return: None to stay quiet; else the text to append to the report: empty for the
            first report of the cause, or how many more times it happened since the last one.
        """
        record = self._causes.setdefault(cause, _CauseRecord())
        record.active = True
        if now_s - record.reported_s < self._period_s:
            record.unreported += 1
            return None
        suffix = ''
        if record.unreported:
            suffix = (f' ({record.unreported} more time{"s" if record.unreported > 1 else ""}'
                      f' in the last {now_s - record.reported_s:.0f} s)')
        record.reported_s = now_s
        record.unreported = 0
        return suffix

    def resolved(self, cause: str) -> bool:
        """
        Record that a problem is gone (a good frame came).

        Its return is still reported at most once per period: a camera that alternates good
        and bad frames must not flood the log either.

        :param cause: the problem's cause.
        :return: whether the cause had been active, i.e. whether it is worth saying it is gone.
        """
        record = self._causes.get(cause)
        if record is None or not record.active:
            return False
        record.active = False
        return True

    def is_active(self, cause: str) -> bool:
        """
        Tell whether a problem occurred and has not been resolved since.

        :param cause: the problem's cause.
        :return: True while the cause is active.
        """
        record = self._causes.get(cause)
        return record is not None and record.active
