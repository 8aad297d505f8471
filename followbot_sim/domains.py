"""
ROS domains reserved on this machine: tools and test runs started side by side never share one.

A process that picks a domain for its own DDS traffic (a test run, a scorecard's workers, a
benchmark) locks one file per domain in a folder every such process uses, and holds the locks
until it ends or releases them. Another process then skips those domains, whichever range it
searches. ``flock`` locks go away with the process that holds them, so a killed run leaves no
stale reservation behind.
"""

import fcntl
import os
from pathlib import Path
import tempfile

from followbot.number_options import number_in

LOCKS_DIR = Path(tempfile.gettempdir()) / 'followbot-domains'
# Largest ROS_DOMAIN_ID whose DDS ports fit in the port range on Linux.
MAX_DOMAIN_ID = 232
# The argparse type of a command's --domain-id.
domain_id_option = number_in(0, MAX_DOMAIN_ID, whole=True)


class DomainsTaken(RuntimeError):
    """Every block of domains in the range searched is held by another process."""


class DomainReservation:
    """Consecutive ROS domains locked for this process until ``release`` or its end."""

    def __init__(self, first: int, locks: list):
        """
        Keep the locks of a block of domains.

        :param first: the block's first domain.
        :param locks: the open, locked files, one per domain of the block.
        """
        self.first = first
        self._locks = locks

    def release(self) -> None:
        """Let other processes use these domains."""
        for lock in self._locks:
            lock.close()
        self._locks = []

    def __enter__(self):
        """Return the reservation itself."""
        return self

    def __exit__(self, *exception) -> None:
        """Release the domains."""
        self.release()


def _lock(domain: int):
    """Return the domain's lock file locked for this process, or None if another holds it."""
    lock = open(LOCKS_DIR / f'{domain}.lock', 'a')
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        lock.close()
        return None
    return lock


def reserve_domains(count: int, first: int, span: int) -> DomainReservation:
    """
    Lock the first free block of ``count`` consecutive domains in ``first``..``first + span - 1``.

    The search starts at a block the process id picks, so that processes started together
    rarely compete for the same files, and goes round the range from there.

    :param count: how many consecutive domains are needed.
    :param first: the range's first domain.
    :param span: how many domains the range holds.
    :return: the reservation, which holds the domains until released or until the process ends.
    :raises ValueError: when the range does not fit in 0..MAX_DOMAIN_ID or is shorter than
        ``count``.
    :raises DomainsTaken: when every block of the range holds a domain another process locked.
    """
    if count < 1 or span < count or first < 0 or first + span - 1 > MAX_DOMAIN_ID:
        raise ValueError(f'cannot reserve {count} domain(s) in {first}-{first + span - 1}: '
                         f'domains go from 0 to {MAX_DOMAIN_ID}')
    LOCKS_DIR.mkdir(exist_ok=True)
    starts = span - count + 1
    for step in range(starts):
        start = first + (os.getpid() + step) % starts
        locks = []
        for domain in range(start, start + count):
            lock = _lock(domain)
            if lock is None:
                break
            locks.append(lock)
        if len(locks) == count:
            return DomainReservation(start, locks)
        for lock in locks:
            lock.close()
    raise DomainsTaken(f'Every block of {count} domain(s) in {first}-{first + span - 1} holds '
                       f'one that another process uses (lock files in {LOCKS_DIR}).')


def reserve_default_domains(parser, count: int, first: int, span: int) -> DomainReservation:
    """
    Reserve the domains of a command given no --domain-id, or end it with a usage error.

    :param parser: the command's argparse.ArgumentParser, whose error() ends it.
    :param count: how many consecutive domains the command needs.
    :param first: the range's first domain.
    :param span: how many domains the range holds.
    :return: the reservation; keep it for as long as the command runs.
    """
    try:
        return reserve_domains(count, first, span)
    except (DomainsTaken, ValueError) as error:
        parser.error(f'{error} Give one with --domain-id.')
