"""
Soak measurements: the growth verdict on made-up samples, the /proc readers on real processes.

The 5-minute soak of both nodes is marked ``soak``: the suite runs it once, and the nested copy
of the suite that ``colcon test`` runs (test_colcon_workspace.py) deselects it.
"""

import os
import subprocess
import sys

from conftest import child_environment, run_domain_id
from followbot_sim import launcher, soak
import pytest

MIB_KB = 1024
SOAK_DURATION_S = 300.0
SOAK_PERIOD_S = 15.0
SOAK_TIMEOUT_S = SOAK_DURATION_S * 3


def run_of(rss_mib_by_time: dict, laps: int = 0) -> list:
    """Build samples of two nodes, ``{elapsed_s: (sim RSS MiB, follower RSS MiB)}``."""
    samples = []
    for elapsed_s, rss_mib in rss_mib_by_time.items():
        processes = {
            node: None if mib is None else soak.ProcessSample(int(mib * MIB_KB), 30, 2, 1 << 20)
            for node, mib in zip(('sim', 'follower'), rss_mib)}
        samples.append(soak.SoakSample(elapsed_s, processes, laps))
    return samples


def test_memory_that_grows_only_during_warm_up_is_flat():
    samples = run_of({0: (50, 40), 60: (200, 90), 120: (210, 95), 300: (211, 95.5)})
    verdicts = soak.memory_verdicts(samples, warm_up_end_s=120)
    assert [(v.node, v.passed) for v in verdicts] == [('sim', True), ('follower', True)]
    assert verdicts[0].growth_kb == 1 * MIB_KB


def test_memory_growing_after_warm_up_fails_for_that_node_only():
    samples = run_of({120: (210, 95), 200: (212, 95), 300: (215, 95.2)})
    sim, follower = soak.memory_verdicts(samples, warm_up_end_s=120)
    assert not sim.passed and sim.growth_kb == 5 * MIB_KB
    assert follower.passed


def test_a_late_spike_counts_as_growth_even_when_memory_falls_again():
    samples = run_of({120: (100, 90), 200: (103, 90), 300: (100, 90)})
    assert not soak.memory_verdicts(samples, warm_up_end_s=120)[0].passed


def test_growth_of_exactly_the_limit_passes():
    samples = run_of({120: (100, 90), 300: (102, 90)})
    assert soak.memory_verdicts(samples, warm_up_end_s=120)[0].passed


def test_a_node_gone_after_warm_up_cannot_be_judged():
    samples = run_of({120: (100, 90), 200: (100, None), 300: (100, None)})
    with pytest.raises(ValueError, match='follower: fewer than two samples after the warm-up'):
        soak.memory_verdicts(samples, warm_up_end_s=120)


@pytest.mark.parametrize('duration_s, expected_s', [(60, 150), (300, 150), (1800, 360)])
def test_warm_up_is_a_fifth_of_the_run_and_at_least_two_and_a_half_minutes(duration_s, expected_s):
    assert soak.warm_up_s(duration_s) == expected_s


def test_table_shows_every_node_and_dashes_for_a_gone_one():
    lines = soak.format_table(run_of({0: (100, 90.25), 60: (100, None)}, laps=1))
    assert lines[0] == ('| t (s) | laps | sim RSS (MiB) | sim fds | sim shm files | sim shm (MiB)'
                        ' | follower RSS (MiB) | follower fds | follower shm files'
                        ' | follower shm (MiB) |')
    assert lines[2] == '| 0 | 1 | 100.0 | 30 | 2 | 1.0 | 90.2 | 30 | 2 | 1.0 |'
    assert lines[3] == '| 60 | 1 | 100.0 | 30 | 2 | 1.0 | - | - | - | - |'


def test_verdict_line_names_the_node_and_the_outcome():
    verdict = soak.MemoryVerdict('sim', 100 * MIB_KB, 103 * MIB_KB, 3 * MIB_KB, 2 * MIB_KB)
    assert soak.format_verdict(verdict) == (
        'sim: RSS 100.0 MiB after warm-up, peak 103.0 MiB, growth 3.0 MiB (limit 2.0 MiB): '
        'GROWING')


def test_readers_measure_a_real_process_and_its_shared_memory(tmp_path):
    shm_path = soak.SHM_DIR / f'followbot_test_soak_{os.getpid()}'
    holder = subprocess.Popen(
        [sys.executable, '-c',
         'import mmap, sys, time\n'
         f'f = open({str(shm_path)!r}, "w+b"); f.truncate(1 << 20)\n'
         'm = mmap.mmap(f.fileno(), 1 << 20)\n'
         'print("ready", flush=True); time.sleep(60)\n'],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == 'ready'
        sample = soak.sample_process(holder.pid)
        assert sample.rss_kb > 1000
        assert sample.open_fds >= 3
        assert soak.mapped_shm_files(holder.pid) == {str(shm_path): 1 << 20}
        assert (sample.shm_files, sample.shm_bytes) == (1, 1 << 20)
    finally:
        holder.kill()
        holder.wait()
        shm_path.unlink(missing_ok=True)
    assert soak.sample_process(holder.pid) is None


@pytest.mark.soak
def test_five_minute_soak_of_both_nodes_keeps_memory_flat():
    launcher = subprocess.run(
        [sys.executable, '-m', 'followbot_sim.launcher', '--domain-id', str(run_domain_id()),
         '--duration', f'{SOAK_DURATION_S:g}', '--soak-period', f'{SOAK_PERIOD_S:g}',
         '--report-period', '60'],
        env=child_environment(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        timeout=SOAK_TIMEOUT_S)
    output = launcher.stdout
    assert launcher.returncode == 0, output[-5000:]
    assert '[soak] PASSED' in output
    verdicts = [line for line in output.splitlines()
                if line.startswith(('[soak] sim: RSS', '[soak] follower: RSS'))]
    assert len(verdicts) == 2 and all('): flat' in line for line in verdicts), output[-5000:]
    rows = [line for line in output.splitlines() if line.startswith('| ') and
            line[2].isdigit()]
    assert len(rows) >= SOAK_DURATION_S / SOAK_PERIOD_S - 2
    # The robot lapped the course meanwhile (a lap of book_loop takes ~32 s at 0.7 m/s).
    assert int(rows[-1].split('|')[2]) >= 1


def test_help_describes_the_soak_option(capsys):
    with pytest.raises(SystemExit) as exit_info:
        launcher.parse_arguments(['--help'])
    assert exit_info.value.code == 0
    assert 'first 20 % of the run, at least 150 s' in ' '.join(capsys.readouterr().out.split())


@pytest.mark.parametrize('arguments, message', [
    (['--soak-period', '0'], "argument --soak-period: must be a number > 0, got '0'"),
    (['--soak-period', '10', '--duration', '0'], '--soak-period needs a --duration'),
])
def test_soak_needs_a_positive_period_and_a_duration(arguments, message, capsys):
    with pytest.raises(SystemExit):
        launcher.parse_arguments(arguments)
    assert message in capsys.readouterr().err
