"""An exit at a deadline that needs no Python thread: :func:`arm_exit`.

A middleware call can hang while it holds the GIL (Fast DDS deleting a participant, seen once in
CI after a peer was killed); then no Python thread runs, and a ``threading.Timer`` watchdog never
fires. ``faulthandler`` still can, from C, but it always exits with code 1, which would turn a
clean end (0) or a lost line (3) into a different failure. :func:`arm_exit` asks the C library
for a POSIX timer (``timer_create`` with ``SIGEV_THREAD``) whose expiry calls ``_exit(code)`` in
a thread of the library's own: it runs whatever the interpreter is doing.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys
from collections.abc import Callable

__all__ = ['arm_exit']

_CLOCK_MONOTONIC = 1
_SIGEV_THREAD = 2


class _Sigval(ctypes.Union):
    _fields_ = (('sival_int', ctypes.c_int), ('sival_ptr', ctypes.c_void_p))


class _SigevThread(ctypes.Structure):
    _fields_ = (('function', ctypes.c_void_p), ('attribute', ctypes.c_void_p))


class _SigevUnion(ctypes.Union):
    _fields_ = (('pad', ctypes.c_int * 12), ('thread', _SigevThread))


class _Sigevent(ctypes.Structure):
    """Linux's ``struct sigevent`` (64 bytes)."""

    _fields_ = (
        ('value', _Sigval),
        ('signo', ctypes.c_int),
        ('notify', ctypes.c_int),
        ('un', _SigevUnion),
    )


class _Timespec(ctypes.Structure):
    _fields_ = (('sec', ctypes.c_long), ('nsec', ctypes.c_long))


class _Itimerspec(ctypes.Structure):
    _fields_ = (('interval', _Timespec), ('value', _Timespec))


def arm_exit(seconds: float, code: int) -> Callable[[], None] | None:
    """End the process with ``code`` after ``seconds`` s unless cancelled, GIL or not.

    Parameters
    ----------
    seconds : float
        Wall seconds (monotonic clock) until the exit; > 0.
    code : int
        Exit code, 0 to 255.

    Returns
    -------
    callable or None
        ``cancel()``, which disarms the timer (call it once); None where the C library offers no
        such timer (not Linux), and the caller keeps its own fallback.
    """
    if not sys.platform.startswith('linux') or ctypes.sizeof(_Sigevent) != 64:
        return None
    libc = ctypes.CDLL(ctypes.util.find_library('c'), use_errno=True)
    event = _Sigevent()
    event.notify = _SIGEV_THREAD
    event.value.sival_int = code
    # _exit(int) as the notify function void (*)(union sigval): the union is passed as its int
    event.un.thread.function = ctypes.cast(libc['_exit'], ctypes.c_void_p).value
    timer = ctypes.c_void_p()
    if libc.timer_create(_CLOCK_MONOTONIC, ctypes.byref(event), ctypes.byref(timer)) != 0:
        return None
    whole = int(seconds)
    when = _Itimerspec(value=_Timespec(whole, max(1, int((seconds - whole) * 1e9))))
    if libc.timer_settime(timer, 0, ctypes.byref(when), None) != 0:
        libc.timer_delete(timer)
        return None

    def cancel() -> None:
        libc.timer_delete(timer)

    return cancel
