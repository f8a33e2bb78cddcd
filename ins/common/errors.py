"""Exceptions and warnings about input data.

:class:`InputError` is raised for bad input data (a malformed or implausible file, a
value out of range).  Its message is one line and names the file and, when known, the
1-based line (``"imu.txt:17: text in a number field 3: '1.2.3'"``); the command-line
interface prints it and exits with code 2.  :class:`InputWarning` flags data that are
usable but suspicious (gaps, a log that looks like increments where rates were
announced); library code issues it through :mod:`warnings`, never by printing.
:class:`QualityWarning` (an :class:`InputWarning`) flags a result that should not be
trusted as it stands (an adjustment that did not converge, a variance that is not
estimable).  :class:`QualityError` is raised when a result must not be used at all
(a filter that rejected most of its measurements or diverged, a covariance that lost
positive definiteness); the command-line interface prints it and exits with code 3.
"""

__all__ = ["InputError", "InputWarning", "QualityError", "QualityWarning"]


class InputError(ValueError):
    """Bad input data.

    Parameters
    ----------
    message : str
        What is wrong, without the location prefix.  Newlines are replaced by spaces so
        that the message stays on one line.
    path : str or os.PathLike, optional
        The file the data came from.
    line : int, optional
        1-based line number in that file (header and comment lines counted as they are
        in the file).
    record : int, optional
        1-based record number, for binary files that have no lines.

    Attributes
    ----------
    path : str or None
    line : int or None
    record : int or None
    reason : str
        The message without the location prefix.

    Notes
    -----
    ``str(exc)`` is ``"{path}:{line}: {message}"`` when both path and line are known,
    ``"{path}: record {record}: {message}"`` for a binary record,
    ``"{path}: {message}"`` with only the path, ``"line {line}: {message}"`` with only
    the line, and the bare message otherwise.
    """

    def __init__(self, message, path=None, line=None, record=None):
        self.path = None if path is None else str(path)
        self.line = None if line is None else int(line)
        self.record = None if record is None else int(record)
        self.reason = " ".join(str(message).splitlines()).strip()
        super().__init__(self._format())

    def _format(self):
        if self.path is not None and self.line is not None:
            prefix = f"{self.path}:{self.line}: "
        elif self.path is not None and self.record is not None:
            prefix = f"{self.path}: record {self.record}: "
        elif self.path is not None:
            prefix = f"{self.path}: "
        elif self.line is not None:
            prefix = f"line {self.line}: "
        elif self.record is not None:
            prefix = f"record {self.record}: "
        else:
            prefix = ""
        return prefix + self.reason

    def __reduce__(self):   # keep the attributes through pickling (multiprocessing)
        return (type(self), (self.reason, self.path, self.line, self.record))


class InputWarning(UserWarning):
    """Input data that are usable but suspicious (gaps, an unusual magnitude)."""


class QualityWarning(InputWarning):
    """A result that is computed but should not be trusted as it stands (not converged,
    a variance factor or component that cannot be estimated)."""


class QualityError(RuntimeError):
    """A result that is not to be trusted (exit code 3 in the command-line interface).

    The message is one line and names the likely cause (start state, noise settings,
    lever arm, time base) or the time and state of a numerical failure.
    """

    def __init__(self, message):
        super().__init__(" ".join(str(message).splitlines()).strip())
