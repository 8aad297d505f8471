"""Every command of the package explains itself with --help."""

from followbot import benchmark, latency_probe, launcher, scorecard
import pytest


@pytest.mark.parametrize('command', [launcher, scorecard, benchmark, latency_probe],
                         ids=lambda module: module.__name__)
def test_help_prints_the_usage_and_exits_cleanly(command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        command.parse_arguments(['--help'])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out.startswith('usage: ')
