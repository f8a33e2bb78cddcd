"""Atomic output files: written to a temporary file beside the target, renamed when complete."""
import contextlib
import errno
import os
import tempfile


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_open(path, mode="wb"):
    """Open ``path`` for writing so that it appears only when complete.

    The data go to a temporary file in the same directory, which replaces ``path``
    (``os.replace``) when the ``with`` block ends without an exception; on an exception
    the temporary file is removed and ``path`` is left as it was.
    """
    if "r" in mode or "a" in mode or "+" in mode:
        raise ValueError(f"mode must be a write mode ('w' or 'wb'), got {mode!r}")
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path):
        raise IsADirectoryError(errno.EISDIR, "is a directory, not an output file", path)
    if not os.path.isdir(directory):
        raise FileNotFoundError(errno.ENOENT, "the output's directory does not exist",
                                directory)
    fd, tmp = tempfile.mkstemp(dir=directory, prefix="." + os.path.basename(path) + ".",
                               suffix=".part")
    try:
        os.chmod(tmp, 0o666 & ~_umask())   # mkstemp makes 0600; give the usual mode
        with os.fdopen(fd, mode) as f:
            yield f
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
