"""Stopping a command cleanly: Ctrl-C and SIGTERM become exceptions, held back while a record is written.

SIGTERM (what `dvc queue kill`, CI and schedulers send) raises `Stopped`, a
`KeyboardInterrupt`, so one `except KeyboardInterrupt` handles both signals.
Either signal arriving while MLflow opens or closes a run would break off its
database writes half way and leave the run FAILED or RUNNING instead of
KILLED; inside `held()` the signal is noted and raised once the block is done.
Python runs signal handlers in the main thread only, so the flag is all the
state needed, whichever thread the operating system delivered the signal to.

Python drops an exception raised inside a ctypes callback (Numba's compiler
calls one as it writes its cache) or a destructor, printing "Exception
ignored": a stop that lands there would be lost, and the command would run
on and write its outputs. So the signals raised are also noted until the
command says it stopped (`acknowledge`), and `check`, which every atomic
write calls before it replaces anything and every job of `runtime.jobs`
before it starts, raises a noted one again; Python's report of the dropped
exception (a traceback on stderr) is left out, since the stop is not lost.
A stop that lands inside a constructor (Ctrl-C in Numba's compiler, inside
llvmlite) leaves an object half built, whose destructor fails when the
stop's traceback is freed: from the moment a stop is raised, and after the
command said it stopped (`stopped`) until another command installs the
handlers, what Python drops is the stop's debris and goes unreported too.
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_held = 0  # depth of nested `held()` blocks
_pending: list[int] = []  # signals that arrived while held, first first
_raised: list[int] = []  # signals raised by the handler that the command has not said it stopped for
_ended = False  # the command said it stopped: destructors failing from here on are the stop's debris


class Stopped(KeyboardInterrupt):
    """SIGTERM, handled as Ctrl-C is."""


def _raise(signum: int) -> None:
    if signum == signal.SIGTERM:
        raise Stopped(signal.Signals(signum).name)
    raise KeyboardInterrupt


def _handler(signum: int, frame: object) -> None:
    if _held:
        _pending.append(signum)
        return
    _raised.append(signum)
    _raise(signum)


def check() -> None:
    """Raise again a stopping signal whose exception was dropped where it landed (see above); nothing when every
    signal raised was acknowledged, or when this module's handler is not the one installed."""
    if _raised and signal.getsignal(signal.SIGINT) is _handler:
        _raise(_raised[0])


def _unraisable(unraisable: sys.UnraisableHookArgs) -> None:
    """Python's hook for an exception it drops: silent from the moment a stop is raised (`check` raises a dropped
    one again; anything else dropped from then on is the stop's debris), the usual report otherwise."""
    if _raised or _ended:
        return
    sys.__unraisablehook__(unraisable)


def acknowledge() -> None:
    """The command has stopped for the signals raised so far: `check` forgets them."""
    _raised.clear()


def stopped() -> None:
    """The command has stopped and said so: `check` forgets the signals, and its teardown goes unreported."""
    global _ended
    acknowledge()
    _ended = True


def install() -> None:
    """Handle SIGTERM and SIGINT in this process (main thread only, where Python allows handlers).

    SIGINT is installed even where it started ignored: a shell's background
    jobs start that way, and such a stage would otherwise ignore Ctrl-C sent
    with `kill -INT`.
    """
    global _ended
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _handler)
        signal.signal(signal.SIGINT, _handler)
        sys.unraisablehook = _unraisable
    _ended = False
    acknowledge()


@contextmanager
def held() -> Iterator[None]:
    """Run the block whole: a stopping signal that arrives inside it is raised when it ends."""
    global _held
    _held += 1
    try:
        yield
    finally:
        _held -= 1
        if not _held and _pending:
            signum = _pending[0]
            _pending.clear()
            _raised.append(signum)  # noted as the handler notes a signal it raises at once
            _raise(signum)
