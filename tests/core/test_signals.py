"""fatigue_pin.core.signals: a signal inside a deferred block is raised when the block ends, never
in the middle of it; outside a deferred block it is raised at once."""

from __future__ import annotations

import os
import signal

import pytest

from fatigue_pin.core.signals import Interrupted, deferred, watch


def test_a_signal_in_a_deferred_block_is_raised_when_the_block_is_done():
    done = []
    with pytest.raises(Interrupted) as err:
        with watch():
            with deferred():
                os.kill(os.getpid(), signal.SIGINT)
                done.append("after the signal")  # the block is not cut short
            done.append("after the block")  # not reached: the block ended with the signal
    assert done == ["after the signal"] and err.value.exit_code == 130


def test_nested_deferred_blocks_raise_at_the_outermost_end():
    done = []
    with pytest.raises(Interrupted) as err:
        with watch():
            with deferred():
                with deferred():
                    os.kill(os.getpid(), signal.SIGTERM)
                done.append("inner block ended")
            done.append("outer block ended")
    assert done == ["inner block ended"] and err.value.exit_code == 143


def test_outside_a_deferred_block_the_signal_cuts_the_work_short():
    done = []
    with pytest.raises(Interrupted):
        with watch():
            os.kill(os.getpid(), signal.SIGINT)
            done.append("after the signal")
    assert done == []


def test_a_deferred_block_outside_a_watch_runs_as_it_is():
    with deferred():
        value = 1
    assert value == 1
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
