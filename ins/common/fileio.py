"""Atomic output files: written to a temporary file beside the target, renamed when complete."""
import contextlib
import errno
import os
import shutil
import tempfile

from ins.common import interrupts


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
        probe = directory
        while probe and not os.path.exists(probe):
            probe = os.path.dirname(probe)
        if probe and not os.path.isdir(probe):          # -o FILE/sub/out.nav
            raise NotADirectoryError(errno.ENOTDIR, f"{probe} is a file, not a directory",
                                     path)
        raise FileNotFoundError(errno.ENOENT, "the output's directory does not exist",
                                directory)
    tmp = None
    try:
        with interrupts.deferred():       # Ctrl-C cannot fall between making and owning it
            try:
                fd, tmp = tempfile.mkstemp(dir=directory, suffix=".part",
                                           prefix="." + os.path.basename(path) + ".")
            except OSError as exc:       # name the user's path, not the hidden temporary
                raise _fs_error(exc, path) from None
        os.chmod(tmp, 0o666 & ~_umask())   # mkstemp makes 0600; give the usual mode
        with os.fdopen(fd, mode) as f:
            yield f
        with interrupts.deferred():       # Ctrl-C: before the rename or after the record
            try:
                os.replace(tmp, path)
            except OSError as exc:
                raise _fs_error(exc, path) from None
            interrupts.record_output(path)
    except BaseException:
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        raise


def _fs_error(exc, user_path):
    """The same OSError naming ``user_path`` instead of a hidden temporary name."""
    return type(exc)(exc.errno, exc.strerror, os.fspath(user_path))


def check_parent_directory(path, missing="the output's directory does not exist"):
    """Raise unless the directory that would hold ``path`` exists.

    A regular file in the way (``-o FILE/sub/out.csv``) gives NotADirectoryError naming
    that file; a missing directory gives FileNotFoundError with the text ``missing``.
    Both name ``path`` (the user's spelling).
    """
    path = os.fspath(path)
    parent = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(parent):
        return
    probe = parent
    while probe and not os.path.exists(probe):
        probe = os.path.dirname(probe)
    if probe and not os.path.isdir(probe):
        raise NotADirectoryError(errno.ENOTDIR, f"{probe} is a file, not a directory", path)
    raise FileNotFoundError(errno.ENOENT, missing, path)


def check_output_file(path):
    """Raise before the work the OSError that writing the output file ``path`` would
    raise at its end (:func:`atomic_open`): ``path`` a directory, its directory missing
    or a regular file in the way (``-o FILE/sub/out.csv``), naming ``path``."""
    path = os.fspath(path)
    if os.path.isdir(path):
        raise IsADirectoryError(errno.EISDIR, "is a directory, not an output file", path)
    check_parent_directory(path)


def check_output_folder(path, force=False):
    """Raise if ``path`` cannot become a new output folder.

    The parent must be an existing directory (every component a directory), ``path`` must
    not be a regular file, and an existing non-empty folder is refused unless ``force``.

    Raises
    ------
    FileNotFoundError, NotADirectoryError, FileExistsError
        Naming ``path`` (the user's spelling).
    """
    path = os.fspath(path)
    check_parent_directory(path, "the output's parent directory does not exist")
    if os.path.exists(path) and not os.path.isdir(path):
        raise NotADirectoryError(errno.ENOTDIR, "exists and is not a directory", path)
    if os.path.isdir(path) and os.listdir(path) and not force:
        raise FileExistsError(errno.EEXIST, "the output folder is not empty (--force "
                              "replaces it whole)", path)


@contextlib.contextmanager
def output_folder(path, force=False):
    """Build an output folder aside and swap it into place whole.

    Yields a temporary sibling directory (``.<name>.*.part``) to write into.  When the
    ``with`` block ends without an exception the sibling is renamed to ``path``; an
    existing folder (allowed only with ``force``, checked before and after the work) is
    moved aside first and deleted after the swap, so ``path`` is never a mix of an old
    and a new run.  On any exception, KeyboardInterrupt included, the sibling is deleted
    and ``path`` is left as it was.

    Raises
    ------
    FileNotFoundError, NotADirectoryError, FileExistsError, PermissionError
        Naming ``path``.
    """
    path = os.fspath(path)
    check_output_folder(path, force)
    parent = os.path.dirname(os.path.abspath(path))
    name = os.path.basename(os.path.abspath(path))
    tmp = None
    try:
        with interrupts.deferred():       # Ctrl-C cannot fall between making and owning it
            try:
                tmp = tempfile.mkdtemp(prefix=f".{name}.", suffix=".part", dir=parent)
            except OSError as exc:
                raise _fs_error(exc, path) from None
        yield tmp
        check_output_folder(path, force)
        os.chmod(tmp, 0o777 & ~_umask())
        with interrupts.deferred():       # Ctrl-C neither splits the swap nor the cleanup
            if not os.path.exists(path):
                os.rename(tmp, path)
                interrupts.record_output(path)
                return
            old = tempfile.mkdtemp(prefix=f".{name}.", suffix=".old", dir=parent)
            os.rename(path, old)                # replaces the empty placeholder
            try:
                os.rename(tmp, path)
            except BaseException:
                os.rename(old, path)
                raise
            interrupts.record_output(path)
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        if tmp is not None:
            with interrupts.deferred():
                shutil.rmtree(tmp, ignore_errors=True)
        raise
