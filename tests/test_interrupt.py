"""Ctrl-C within ``interruptible()``: raised at once, and again at the next check if swallowed."""

from __future__ import annotations

import signal
import sys
import weakref

import pytest

from edeflare._interrupt import check_interrupt, interruptible, sigint_blocked

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")


class Thing:
    """Something to drop, whose weak reference's callback runs as it dies."""


def test_a_ctrl_c_swallowed_by_a_finaliser_is_raised_at_the_next_check(monkeypatch):
    reported: list[object] = []
    monkeypatch.setattr(sys, "unraisablehook", reported.append)
    callback_ended = went_on = False

    def callback(_ref: object) -> None:  # as WeakValueDictionary's, numba's caches'
        nonlocal callback_ended
        signal.raise_signal(signal.SIGINT)  # Ctrl-C while the callback runs
        for _ in range(1000):  # the handler runs here: its exception ends the callback
            pass
        callback_ended = True

    with pytest.raises(KeyboardInterrupt), interruptible():
        thing = Thing()
        ref = weakref.ref(thing, callback)
        del thing  # the callback runs; Python ignores the exception it raised
        went_on = True  # so the run goes on...
        check_interrupt()  # ...to its next safe point, which stops it
        went_on = False
    assert ref() is None and went_on and not callback_ended
    assert reported == []  # not reported: it was not lost
    check_interrupt()  # cleared with the run: nothing pending afterwards
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_ctrl_c_outside_finalisers_is_raised_at_once():
    reached = False
    with pytest.raises(KeyboardInterrupt), interruptible():
        signal.raise_signal(signal.SIGINT)
        for _ in range(1000):
            pass
        reached = True
    assert not reached
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_an_applications_own_handler_is_kept():
    seen: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: seen.append(signum))
    try:
        with interruptible():
            signal.raise_signal(signal.SIGINT)
            check_interrupt()  # the application handled it: nothing pending here
        assert seen == [signal.SIGINT]
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_ctrl_c_held_back_is_delivered_afterwards():
    reached = False
    with pytest.raises(KeyboardInterrupt), interruptible():
        with sigint_blocked():
            signal.raise_signal(signal.SIGINT)
            for _ in range(1000):
                pass
            reached = True  # held back meanwhile...
        for _ in range(1000):  # ...and raised once released
            pass
        reached = False
    assert reached


def test_an_interrupt_wrapped_in_another_error_comes_out_as_an_interrupt():
    with pytest.raises(KeyboardInterrupt) as info, interruptible():
        try:
            signal.raise_signal(signal.SIGINT)
            for _ in range(1000):
                pass
        except KeyboardInterrupt as exc:  # as numba's compiled code reports it
            raise SystemError("returned a result with an exception set") from exc
    assert isinstance(info.value.__cause__, SystemError)
    with pytest.raises(ValueError, match="a plain error"), interruptible():
        raise ValueError("a plain error")  # no Ctrl-C: errors pass unchanged
