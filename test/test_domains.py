"""Test runs, scorecards and benchmarks on one machine keep their DDS traffic apart."""

import os
import subprocess
import sys

from conftest import DOMAINS_PER_RUN, run_domain_id
from followbot_sim import benchmark, domains, scorecard
from followbot_sim.domains import DomainsTaken, reserve_domains
import pytest

TEST_DIR = os.path.dirname(os.path.abspath(__file__))


@pytest.fixture
def locks_dir(tmp_path, monkeypatch):
    """Keep this test's reservations apart from real runs': lock files in a folder of its own."""
    monkeypatch.setattr(domains, 'LOCKS_DIR', tmp_path)
    return tmp_path


def domain_of_another_run(pid: int) -> int:
    """Return the domain a second test process gets while this one holds its own."""
    # The process id picks where the search for a free domain starts: the second run is made
    # to start where this one did, as two runs whose ids differ by the domain count would.
    program = f'import os; os.getpid = lambda: {pid}; import conftest; ' \
              'print(conftest.run_domain_id())'
    result = subprocess.run([sys.executable, '-c', program], cwd=TEST_DIR,
                            capture_output=True, text=True, timeout=120, check=True)
    return int(result.stdout.split()[-1])


def test_a_second_run_gets_a_block_of_domains_apart_from_this_runs():
    mine = run_domain_id()
    assert run_domain_id() == mine, 'a run keeps its domain'
    other = domain_of_another_run(os.getpid())
    assert abs(other - mine) >= DOMAINS_PER_RUN


def test_a_block_is_never_shared_and_is_free_again_once_released(locks_dir):
    first = reserve_domains(3, 10, 3)
    assert first.first == 10
    # Whichever block the process id points the search at, the only free one is 13-14.
    second = reserve_domains(2, 10, 5)
    assert second.first == 13
    with pytest.raises(DomainsTaken, match='10-14'):
        reserve_domains(1, 10, 5)
    second.release()
    with reserve_domains(2, 10, 5) as again:
        assert again.first == 13
    first.release()


@pytest.mark.parametrize('pid', range(6))
def test_the_search_goes_round_the_range_from_where_the_process_id_points(pid, locks_dir,
                                                                          monkeypatch):
    taken = reserve_domains(1, 12, 1)
    monkeypatch.setattr(domains.os, 'getpid', lambda: pid)
    with reserve_domains(2, 10, 5) as block:
        assert 12 not in (block.first, block.first + 1)
    taken.release()


@pytest.mark.parametrize('count, first, span', [(0, 10, 5), (3, 10, 2), (1, -1, 5), (2, 230, 5)])
def test_a_range_outside_the_ros_domains_is_refused(count, first, span, locks_dir):
    with pytest.raises(ValueError, match='domains go from 0 to 232'):
        reserve_domains(count, first, span)


def test_a_scorecard_takes_the_free_domains_others_left_and_holds_them(locks_dir):
    last = scorecard.FIRST_DOMAIN_ID + scorecard.DOMAIN_ID_SPREAD - 1
    others = [reserve_domains(1, domain, 1)
              for domain in range(scorecard.FIRST_DOMAIN_ID, last - 1)]

    options = scorecard.parse_arguments(['--jobs', '2', '--configs', 'followbot,book'])

    assert options.domain_id == last - 1
    with pytest.raises(DomainsTaken):
        reserve_domains(1, last - 1, 2)
    for reservation in others:
        reservation.release()


def test_a_scorecard_with_every_domain_taken_asks_for_one(locks_dir, capsys):
    taken = reserve_domains(scorecard.DOMAIN_ID_SPREAD, scorecard.FIRST_DOMAIN_ID,
                            scorecard.DOMAIN_ID_SPREAD)
    with pytest.raises(SystemExit) as exit_info:
        scorecard.parse_arguments(['--jobs', '1'])
    assert exit_info.value.code == 2
    assert 'Give one with --domain-id' in capsys.readouterr().err
    assert scorecard.parse_arguments(['--jobs', '1', '--domain-id', '7']).domain_id == 7
    taken.release()


def test_a_benchmark_holds_its_domain_apart_from_the_next_benchmarks(locks_dir):
    options = benchmark.parse_arguments([])
    assert benchmark.FIRST_DOMAIN_ID <= options.domain_id < (benchmark.FIRST_DOMAIN_ID
                                                             + benchmark.DOMAIN_ID_SPREAD)
    assert benchmark.parse_arguments([]).domain_id != options.domain_id
