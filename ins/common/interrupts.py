"""Ctrl-C (SIGINT) and SIGTERM for the command-line tools: exit 130 or 143, one line,
nothing half-written.

The command-line interface installs :func:`handler` for the duration of a command, for
SIGINT (Ctrl-C) and SIGTERM (what batch schedulers, ``timeout`` and ``kill`` send) alike.
It records that the run was stopped and by which signal (:func:`interrupted`,
:func:`stop_signal`) and raises ``KeyboardInterrupt`` in the main thread, as Python's
default does for SIGINT, so that every clean-up path of a Ctrl-C (temporaries and
staging folders removed) serves SIGTERM too, except inside a
:func:`deferred` block, where the interrupt is held back until the block ends.  The
output writers of :mod:`ins.common.fileio` install a finished output (a rename) and remove
their temporaries inside such blocks, and record what they installed
(:func:`record_output`), so that an interrupt can only take effect before an output is
installed (nothing is written) or after it is complete (and the command can say so).

Why a flag as well as the exception: an interrupt that arrives inside extension code
can surface as another exception (seen with numba, which the package's kernels used
before they were all compiled ahead of time: ``SystemError: CPUDispatcher(...)
returned a result with an exception set``, an ``AttributeError`` from llvmlite) whose
``__cause__``/``__context__`` may or may not hold the ``KeyboardInterrupt``; the flag
tells the command-line interface that any exception after the interrupt is its
consequence (:func:`caused_by_interrupt`).

An interrupt that arrives inside code that cannot take an exception (the import
machinery; numba's compiler or llvmlite, should a third-party module load them: a ctypes
callback from C++ crashed the process) is not raised there: the signal is sent again
every 20 ms until the code has left it (:data:`UNSAFE_PACKAGES`, :data:`UNSAFE_FILES`).

An interrupt raised where Python cannot propagate it (a weakref callback, ``__del__``)
is "ignored" by Python: the unraisable-exception hook installed with the handler sends
the signal again instead of printing it; after an interrupt, the tracebacks of
unraisable exceptions and of background threads (its consequences) are not printed.

Library code only uses :func:`deferred` and :func:`record_output`; without the handler
installed they change nothing (Python's own handler raises ``KeyboardInterrupt`` at
once).
"""
import contextlib
import os
import signal
import sys
import threading

__all__ = ["install", "close", "handler", "interrupted", "stop_signal", "deferred",
           "record_output", "written_outputs", "caused_by_interrupt", "reset", "SIGNALS"]

#: The signals handled like Ctrl-C: SIGINT and SIGTERM.
SIGNALS = (signal.SIGINT, signal.SIGTERM)


class _State:
    def __init__(self):
        self.interrupted = False
        self.signum = None
        self.pending = False
        self.depth = 0
        self.closed = False
        self.written = []
        self.lock = threading.Lock()


_state = _State()


def reset():
    """Forget earlier interrupts and outputs (at the start of a command)."""
    with _state.lock:
        _state.interrupted = False
        _state.signum = None
        _state.pending = False
        _state.depth = 0
        _state.closed = False
        _state.written = []


def close():
    """The command is over: from now on :func:`handler` ignores SIGINT and SIGTERM."""
    _state.closed = True


#: Packages whose Python code must not be cut by an exception (the package itself loads
#: neither since its kernels are all Cython; a third-party module may): llvmlite calls
#: back into Python from C++ (its object cache), where a KeyboardInterrupt is "ignored"
#: by ctypes and the C++ side goes on with garbage (a segmentation fault was seen);
#: numba's compiler drives llvmlite.  The import machinery is unsafe too: an interrupt raised in
#: importlib's module-lock callback is "ignored" and leaves the global import lock held
#: (a hang was seen with the IMU reader thread importing).  An interrupt there is retried
#: every :data:`RETRY_S`.
UNSAFE_PACKAGES = ("llvmlite", "numba")
UNSAFE_FILES = ("<frozen importlib",)
#: Standard-library functions an exception must not cut: ``(file name, function)``.
#: tempfile's first ``gettempdir()`` probes the folder with a file it opens, writes and
#: removes; an interrupt just after the open leaves that empty file (a bare 8-letter
#: name) in the user's TMPDIR.
UNSAFE_FUNCTIONS = (("tempfile.py", "_get_default_tempdir"),)
RETRY_S = 0.02


def _in_unsafe_code(frame):
    while frame is not None:
        name = frame.f_code.co_filename
        if any(f"{os.sep}{p}{os.sep}" in name for p in UNSAFE_PACKAGES) or \
                name.startswith(UNSAFE_FILES) or \
                any(os.path.basename(name) == f and frame.f_code.co_name == fn
                    for f, fn in UNSAFE_FUNCTIONS):
            return True
        frame = frame.f_back
    return False


def _retry_later(signum):
    timer = threading.Timer(RETRY_S, os.kill, (os.getpid(), signum))
    timer.daemon = True
    timer.start()


def handler(signum, frame):
    """SIGINT and SIGTERM handler: record the interrupt (the first signal's number);
    raise ``KeyboardInterrupt`` unless deferred (or the command is over, :func:`close`);
    inside numba's compiler or llvmlite the signal is sent again a moment later, until
    the code has left them."""
    if _state.closed:
        return
    _state.interrupted = True
    if _state.signum is None:
        _state.signum = signum
    if _state.depth > 0:
        _state.pending = True
        return
    if _in_unsafe_code(frame):
        _retry_later(signum)
        return
    raise KeyboardInterrupt


def install():
    """Install :func:`handler` for SIGINT and SIGTERM (main thread only).

    Returns
    -------
    callable
        ``restore()`` puts the previous handlers back (a no-op outside the main thread).
    """
    if threading.current_thread() is not threading.main_thread():
        return lambda: None
    previous = {s: signal.signal(s, handler) for s in SIGNALS}
    previous_unraisable, previous_thread_hook = sys.unraisablehook, threading.excepthook

    def unraisable(info):
        # a KeyboardInterrupt raised where Python cannot propagate it (a weakref
        # callback, __del__, a ctypes callback) is lost: send the signal again
        if isinstance(info.exc_value, KeyboardInterrupt):
            if not _state.closed:
                _retry_later(_state.signum or signal.SIGINT)
            return
        if not _state.interrupted:          # after an interrupt: its consequences
            previous_unraisable(info)

    def thread_hook(info):
        if not _state.interrupted:
            previous_thread_hook(info)

    sys.unraisablehook, threading.excepthook = unraisable, thread_hook

    def restore():
        for s, old in previous.items():
            signal.signal(s, old if old is not None else signal.SIG_DFL)
        sys.unraisablehook, threading.excepthook = previous_unraisable, previous_thread_hook
    return restore


def interrupted():
    """Whether SIGINT or SIGTERM arrived since :func:`reset` (while :func:`handler` was
    installed)."""
    return _state.interrupted


def stop_signal():
    """The number of the first signal that stopped the run since :func:`reset`
    (``signal.SIGINT`` or ``signal.SIGTERM``), or None."""
    return _state.signum


@contextlib.contextmanager
def deferred():
    """Hold Ctrl-C (and SIGTERM) back inside the block; raise it when the (outermost)
    block ends.

    For short steps that must not be cut in the middle: installing a finished output
    (and recording it), removing temporaries.  Only the main thread is concerned
    (Python runs signal handlers there); elsewhere this is a no-op.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _state.depth += 1
    try:
        yield
    finally:
        _state.depth -= 1
        if _state.depth == 0 and _state.pending:
            _state.pending = False
            raise KeyboardInterrupt


def _is_staging(path):
    """Whether ``path`` lies inside a hidden staging folder (``.name.XXXX.part``)."""
    parent = os.path.dirname(os.path.abspath(path))
    while True:
        base = os.path.basename(parent)
        if base.startswith(".") and base.endswith(".part"):
            return True
        up = os.path.dirname(parent)
        if up == parent:
            return False
        parent = up


def record_output(path):
    """Note that the user's output ``path`` is complete and in place (a file renamed
    into place, a folder swapped in); files inside a folder still being built aside
    are not recorded."""
    path = os.fspath(path)
    if _is_staging(path):
        return
    with _state.lock:
        _state.written.append(path)


def written_outputs():
    """Outputs recorded since :func:`reset`, in order."""
    with _state.lock:
        return list(_state.written)


def caused_by_interrupt(exc):
    """Whether ``exc`` is, wraps, or follows a Ctrl-C (or SIGTERM).

    True for ``KeyboardInterrupt`` itself, for an exception whose ``__cause__`` or
    ``__context__`` chain holds one, and for any exception once :func:`handler` has
    recorded an interrupt.
    """
    if _state.interrupted:
        return True
    todo, seen = [exc], set()
    while todo:
        e = todo.pop()
        if e is None or id(e) in seen:
            continue
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        todo += [e.__cause__, e.__context__]
    return False
