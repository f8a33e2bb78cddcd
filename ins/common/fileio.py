"""Atomic output files: written to a temporary file beside the target, renamed when complete.

Output folders are built in a hidden staging sibling (``.NAME.XXXXXXXX.part``) and
swapped in whole (:func:`output_folder`).  A run stopped by Ctrl-C or SIGTERM removes its
staging folder; one killed outright (SIGKILL, a power cut) cannot, so every staging
folder holds a small owner record (:data:`OWNER_FILE`: process id, host, boot and
process start time), removed just before the swap, and the next run into the same
place removes the staging folders whose owner is gone (:func:`clear_stale_staging`);
one whose owner is alive, runs on another host, or is unknown (no record) is left
alone and named in a :class:`StagingWarning`.
"""
import contextlib
import errno
import os
import re
import shutil
import socket
import tempfile
import warnings

from ins.common import interrupts

__all__ = ["atomic_open", "check_parent_directory", "check_output_file",
           "check_output_folder", "output_folder", "make_staging", "install_staging",
           "remove_staging", "clear_stale_staging", "owner_state",
           "StagingWarning", "OWNER_FILE"]

#: The owner record inside a staging folder (and inside a replaced output moved aside
#: as ``.NAME.XXXXXXXX.old``): ``key=value`` lines ``pid``, ``host``, ``boot`` (the
#: kernel's boot id, Linux) and ``start`` (the process start time in clock ticks since
#: boot, Linux): a live process with the recorded id but another start time, or a boot
#: id that changed, is not the owner (the id was reused).
OWNER_FILE = ".insphoto-owner"


class StagingWarning(UserWarning):
    """A staging folder of an earlier run beside an output: removed (its process is
    gone) or left alone (its process is alive, on another host, or unknown)."""


def _read_text(path):
    try:
        with open(path) as fh:
            return fh.read()
    except OSError:
        return None


def _start_ticks(pid):
    """The start time of process ``pid`` in clock ticks since boot (Linux), or None."""
    text = _read_text(f"/proc/{pid}/stat")
    if not text:
        return None
    try:        # the command name (field 2) is in parentheses and may hold spaces
        return int(text[text.rindex(")") + 2:].split()[19])
    except (ValueError, IndexError):
        return None


def _boot_id():
    text = _read_text("/proc/sys/kernel/random/boot_id")
    return text.strip() if text else None


def _owner_record():
    pid = os.getpid()
    fields = {"pid": str(pid), "host": socket.gethostname(), "boot": _boot_id(),
              "start": _start_ticks(pid)}
    return "".join(f"{k}={v}\n" for k, v in fields.items() if v is not None)


def _write_owner(folder):
    with open(os.path.join(folder, OWNER_FILE), "w") as fh:
        fh.write(_owner_record())


def owner_state(folder):
    """Whether the run that made the staging folder ``folder`` is still there.

    Returns
    -------
    (state, owner) : (str, dict)
        ``state`` is ``"gone"`` (no process with the recorded id on this host, or one
        started at another time or before another boot: the id was reused),
        ``"alive"`` (``os.kill(pid, 0)`` finds it, also when it belongs to another
        user), ``"other-host"`` (recorded on another machine: cannot be checked) or
        ``"unknown"`` (no readable owner record); ``owner`` the record's fields.
    """
    text = _read_text(os.path.join(folder, OWNER_FILE))
    owner = {}
    for line in (text or "").splitlines():
        key, sep, value = line.partition("=")
        if sep:
            owner[key.strip()] = value.strip()
    try:
        pid = int(owner["pid"])
    except (KeyError, ValueError):
        return "unknown", owner
    if pid <= 0:
        return "unknown", owner
    if owner.get("host") != socket.gethostname():
        return "other-host", owner
    boot = _boot_id()
    if owner.get("boot") and boot and owner["boot"] != boot:
        return "gone", owner
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return "gone", owner
    except PermissionError:         # it exists, another user's
        return "alive", owner
    except OSError:
        return "unknown", owner
    start = _start_ticks(pid)
    if owner.get("start") and start is not None and owner["start"] != str(start):
        return "gone", owner
    return "alive", owner


def _staging_pattern(name):
    return re.compile(r"^\." + re.escape(name) + r"\.[A-Za-z0-9_]{8}\.(?P<kind>part|old)$")


def clear_stale_staging(path):
    """Remove the staging folders that killed runs left beside the output folder
    ``path`` (``.NAME.XXXXXXXX.part``, and ``.NAME.XXXXXXXX.old`` of a replaced output
    once ``path`` exists again) when their process is gone; name the others.

    Returns
    -------
    list of str
        The folders removed.

    Warns
    -----
    StagingWarning
        For each folder removed (its owner's process id and host) and each one left
        alone: its owner alive, on another host, or unknown (no owner record); and for
        an ``.old`` folder of a gone owner while ``path`` is missing (the previous
        output, moved aside by a run killed in the middle of its swap: not deleted).
    """
    path = os.fspath(path)
    parent = os.path.dirname(os.path.abspath(path))
    name = os.path.basename(os.path.abspath(path))
    pattern = _staging_pattern(name)
    removed = []
    try:
        entries = sorted(os.listdir(parent))
    except OSError:
        return removed
    for entry in entries:
        m = pattern.match(entry)
        folder = os.path.join(parent, entry)
        if m is None or os.path.islink(folder) or not os.path.isdir(folder):
            continue
        shown = os.path.join(os.path.dirname(path), entry)
        state, owner = owner_state(folder)
        who = f"process {owner.get('pid', '?')} on {owner.get('host', '?')}"
        if state == "gone" and (m.group("kind") == "part" or os.path.isdir(path)):
            with interrupts.deferred():       # not half removed (the record last)
                for sub in os.listdir(folder):
                    if sub != OWNER_FILE:
                        p = os.path.join(folder, sub)
                        if os.path.isdir(p) and not os.path.islink(p):
                            shutil.rmtree(p, ignore_errors=True)
                        else:
                            with contextlib.suppress(OSError):
                                os.unlink(p)
                shutil.rmtree(folder, ignore_errors=True)
            if os.path.exists(folder):
                warnings.warn(f"{shown}: could not remove the staging folder of a run that "
                              f"was killed ({who}); remove it by hand", StagingWarning,
                              stacklevel=3)
            else:
                removed.append(folder)
                what = ("the staging folder of a run that was killed" if m.group("kind") ==
                        "part" else f"the replaced {name} that a killed run was deleting")
                warnings.warn(f"removed {shown}, {what} ({who})", StagingWarning,
                              stacklevel=3)
        elif state == "gone":
            warnings.warn(f"{shown}: the previous {name}, moved aside by a run killed in "
                          f"its swap ({who}); left alone (rename it back or remove it)",
                          StagingWarning, stacklevel=3)
        elif state == "alive":
            warnings.warn(f"{shown}: staging folder of a run still in progress ({who}); "
                          "left alone", StagingWarning, stacklevel=3)
        else:
            why = ("its owner runs on another host" if state == "other-host"
                   else "it has no owner record")
            warnings.warn(f"{shown}: staging folder of another run, left alone ({why}: "
                          f"remove it by hand if no run is writing there)",
                          StagingWarning, stacklevel=3)
    return removed


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
    and a new run.  On any exception, KeyboardInterrupt included (Ctrl-C and SIGTERM:
    :mod:`ins.common.interrupts`), the sibling is deleted and ``path`` is left as it was.

    The sibling holds an owner record (:data:`OWNER_FILE`) until just before the swap;
    staging folders of earlier runs into ``path`` whose process is gone (killed outright)
    are removed first (:func:`clear_stale_staging`, which warns about each one, removed
    or left alone).  The same two steps apart: :func:`make_staging` and
    :func:`install_staging` (a folder built by another process, a Dask worker).

    Raises
    ------
    FileNotFoundError, NotADirectoryError, FileExistsError, PermissionError
        Naming ``path``.
    """
    tmp = make_staging(path, force)
    try:
        yield tmp
        install_staging(tmp, path, force)
    except BaseException:
        remove_staging(tmp)
        raise


def make_staging(path, force=False):
    """The staging folder of the output folder ``path`` (``.<name>.*.part`` beside it,
    with this process's owner record), after the checks of :func:`check_output_folder`
    and :func:`clear_stale_staging`; install it with :func:`install_staging`, or remove
    it with :func:`remove_staging`.  Returns its path."""
    path = os.fspath(path)
    check_output_folder(path, force)
    parent = os.path.dirname(os.path.abspath(path))
    name = os.path.basename(os.path.abspath(path))
    clear_stale_staging(path)
    tmp = None
    try:
        with interrupts.deferred():   # Ctrl-C cannot fall between making and owning it
            tmp = tempfile.mkdtemp(prefix=f".{name}.", suffix=".part", dir=parent)
            _write_owner(tmp)
    except BaseException as exc:      # the held-back Ctrl-C comes at the block's end:
        if tmp is not None:           # the caller never gets tmp, so it goes here
            shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, OSError):
            raise _fs_error(exc, path) from None
        raise
    return tmp


def install_staging(tmp, path, force=False):
    """Swap the staging folder ``tmp`` (:func:`make_staging`) into place as ``path``,
    whole: an existing folder (only with ``force``, checked again now) is moved aside
    first and deleted after the swap; Ctrl-C is held back meanwhile, and ``path`` is
    recorded as written (:func:`ins.common.interrupts.record_output`)."""
    path = os.fspath(path)
    check_output_folder(path, force)
    parent = os.path.dirname(os.path.abspath(path))
    name = os.path.basename(os.path.abspath(path))
    os.chmod(tmp, 0o777 & ~_umask())
    with interrupts.deferred():       # Ctrl-C neither splits the swap nor the cleanup
        with contextlib.suppress(FileNotFoundError):
            os.unlink(os.path.join(tmp, OWNER_FILE))
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
        with contextlib.suppress(OSError):  # a kill during the removal: the next
            _write_owner(old)               # run removes the rest
        shutil.rmtree(old, ignore_errors=True)


def remove_staging(tmp):
    """Remove the staging folder ``tmp`` (Ctrl-C held back meanwhile); no error if it is
    gone already."""
    if tmp is not None:
        with interrupts.deferred():
            shutil.rmtree(tmp, ignore_errors=True)
