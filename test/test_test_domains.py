"""Concurrent test runs on one machine keep their DDS traffic on domains of their own."""

import os
import subprocess
import sys

from conftest import DOMAINS_PER_RUN, run_domain_id

TEST_DIR = os.path.dirname(os.path.abspath(__file__))


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
