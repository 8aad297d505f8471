"""
Soak measurements: resident memory, open files and shared memory of running nodes over time.

``followbot --soak-period N`` samples both node processes every N wall seconds with the readers
here (Linux ``/proc`` and ``/dev/shm``), prints the table at the end and judges it with
:func:`memory_verdicts`: after a warm-up, neither node's resident memory may grow by more than
:data:`RSS_GROWTH_LIMIT_KB`. The analysis is plain arithmetic on :class:`SoakSample` rows.
"""

from dataclasses import dataclass
import os
from pathlib import Path

# The limit: resident memory flat after warm-up, within 2 MB, over 30 minutes.
RSS_GROWTH_LIMIT_KB = 2048
# Warm-up: the simulator's heap grows in 1 MiB steps during the first minutes of a run and then
# stays flat (measured on a 2-core machine: +5 MiB up to ~7 min, then +0.1 MiB over 25 min).
# It is the first 20 % of the run, and at least two and a half minutes, so that a 5-minute soak
# judges the second half of its run.
WARM_UP_FRACTION = 0.2
WARM_UP_MIN_S = 150.0
SHM_DIR = Path('/dev/shm')
KIB = 1024


@dataclass(frozen=True)
class ProcessSample:
    """One node process at one moment."""

    rss_kb: int
    open_fds: int
    shm_files: int
    shm_bytes: int


@dataclass(frozen=True)
class SoakSample:
    """Every measured quantity at one moment of a soak run."""

    elapsed_s: float
    processes: dict  # node name -> ProcessSample, or None once the process is gone
    laps: int


@dataclass(frozen=True)
class MemoryVerdict:
    """Whether one node's resident memory stayed flat after the warm-up."""

    node: str
    warm_rss_kb: int
    peak_rss_kb: int
    growth_kb: int
    limit_kb: int

    @property
    def passed(self) -> bool:
        """Tell whether the growth is within the limit."""
        return self.growth_kb <= self.limit_kb


def rss_kb(pid: int) -> int:
    """
    Read a process's resident memory.

    :param pid: the process id.
    :return: VmRSS from ``/proc/<pid>/status``, in KiB.
    :raises ProcessLookupError: when the process is gone.
    """
    try:
        status = Path(f'/proc/{pid}/status').read_text()
    except FileNotFoundError as error:
        raise ProcessLookupError(f'process {pid} is gone') from error
    for line in status.splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1])
    raise ProcessLookupError(f'process {pid} has no resident memory (a zombie)')


def open_fd_count(pid: int) -> int:
    """
    Count a process's open file descriptors.

    :param pid: the process id.
    :return: the number of entries of ``/proc/<pid>/fd``.
    :raises ProcessLookupError: when the process is gone.
    """
    try:
        return len(os.listdir(f'/proc/{pid}/fd'))
    except FileNotFoundError as error:
        raise ProcessLookupError(f'process {pid} is gone') from error


def mapped_shm_files(pid: int) -> dict:
    """
    List the shared-memory files a process has mapped (Fast DDS's segments and ports).

    :param pid: the process id.
    :return: path -> size in bytes of each ``/dev/shm`` file in ``/proc/<pid>/maps``.
    :raises ProcessLookupError: when the process is gone.
    """
    try:
        maps = Path(f'/proc/{pid}/maps').read_text()
    except FileNotFoundError as error:
        raise ProcessLookupError(f'process {pid} is gone') from error
    sizes = {}
    for line in maps.splitlines():
        fields = line.split(maxsplit=5)
        if len(fields) == 6 and fields[5].startswith(f'{SHM_DIR}/'):
            path = fields[5]
            try:
                sizes[path] = os.stat(path).st_size
            except FileNotFoundError:
                # Unlinked while still mapped: it no longer occupies a name in /dev/shm.
                continue
    return sizes


def sample_process(pid: int) -> ProcessSample | None:
    """
    Measure one process.

    :param pid: the process id.
    :return: its sample, or None when it is gone.
    """
    try:
        shm = mapped_shm_files(pid)
        return ProcessSample(rss_kb(pid), open_fd_count(pid), len(shm), sum(shm.values()))
    except (ProcessLookupError, PermissionError):
        return None


def warm_up_s(duration_s: float) -> float:
    """
    Return how long the warm-up of a soak run lasts.

    :param duration_s: the whole run, in seconds.
    :return: :data:`WARM_UP_FRACTION` of it, at least :data:`WARM_UP_MIN_S`.
    """
    return max(WARM_UP_MIN_S, WARM_UP_FRACTION * duration_s)


def memory_verdicts(samples: list, warm_up_end_s: float,
                    limit_kb: int = RSS_GROWTH_LIMIT_KB) -> list:
    """
    Judge each node's resident memory after the warm-up.

    Growth is the highest resident memory after the warm-up minus the first sample at or after
    its end: a leak shows as a rise, and a single late spike counts as growth too.

    :param samples: the run's :class:`SoakSample` rows, in time order.
    :param warm_up_end_s: elapsed seconds at which the warm-up ends.
    :param limit_kb: the growth allowed, in KiB.
    :return: one :class:`MemoryVerdict` per node, in the order the nodes first appear.
    :raises ValueError: when no sample of a node falls after the warm-up (the run was too short
        or the node died): nothing can be judged.
    """
    nodes = list(dict.fromkeys(node for sample in samples for node in sample.processes))
    verdicts = []
    for node in nodes:
        rss_after_warm_up = [
            sample.processes[node].rss_kb for sample in samples
            if sample.elapsed_s >= warm_up_end_s and sample.processes.get(node) is not None]
        if len(rss_after_warm_up) < 2:
            raise ValueError(
                f'{node}: fewer than two samples after the warm-up of {warm_up_end_s:g} s; '
                'run longer, sample more often, or see why the node stopped')
        warm_kb = rss_after_warm_up[0]
        peak_kb = max(rss_after_warm_up)
        verdicts.append(MemoryVerdict(node, warm_kb, peak_kb, peak_kb - warm_kb, limit_kb))
    return verdicts


def format_table(samples: list) -> list:
    """
    Lay the samples out as a Markdown table.

    :param samples: :class:`SoakSample` rows.
    :return: the table's lines: time, laps, then per node RSS (MiB), open fds and shm files
        and MiB; a node that is gone shows dashes.
    """
    nodes = list(dict.fromkeys(node for sample in samples for node in sample.processes))
    header = ['t (s)', 'laps']
    for node in nodes:
        header += [f'{node} RSS (MiB)', f'{node} fds', f'{node} shm files',
                   f'{node} shm (MiB)']
    lines = ['| ' + ' | '.join(header) + ' |', '|' + '---:|' * len(header)]
    for sample in samples:
        cells = [f'{sample.elapsed_s:.0f}', str(sample.laps)]
        for node in nodes:
            process = sample.processes.get(node)
            if process is None:
                cells += ['-'] * 4
            else:
                cells += [f'{process.rss_kb / KIB:.1f}', str(process.open_fds),
                          str(process.shm_files), f'{process.shm_bytes / KIB / KIB:.1f}']
        lines.append('| ' + ' | '.join(cells) + ' |')
    return lines


def format_verdict(verdict: MemoryVerdict) -> str:
    """
    Describe one node's verdict in a line.

    :param verdict: the verdict.
    :return: e.g. ``follower: RSS 95.1 MiB after warm-up, peak 95.3 MiB, growth 0.2 MiB
        (limit 2.0 MiB): flat``.
    """
    outcome = 'flat' if verdict.passed else 'GROWING'
    return (f'{verdict.node}: RSS {verdict.warm_rss_kb / KIB:.1f} MiB after warm-up, peak '
            f'{verdict.peak_rss_kb / KIB:.1f} MiB, growth {verdict.growth_kb / KIB:.1f} MiB '
            f'(limit {verdict.limit_kb / KIB:.1f} MiB): {outcome}')
