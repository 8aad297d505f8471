"""The stop-signal record shared by every followbot process."""

import os
import signal

from followbot.node_runner import STOP_SIGNALS, StopSignals


def test_every_stop_signal_is_recorded_and_the_process_goes_on():
    previous_handlers = {stop_signal: signal.getsignal(stop_signal)
                         for stop_signal in STOP_SIGNALS}
    try:
        stop = StopSignals().install()
        assert not stop.is_set()
        # Several signals in a row, as when a launcher dies and a user presses Ctrl-C too.
        for stop_signal in (*STOP_SIGNALS, *STOP_SIGNALS):
            os.kill(os.getpid(), stop_signal)
        assert stop.is_set()
    finally:
        for stop_signal, handler in previous_handlers.items():
            signal.signal(stop_signal, handler)


def test_a_record_not_installed_is_never_set():
    assert not StopSignals().is_set()
