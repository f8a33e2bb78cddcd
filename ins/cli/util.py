"""Helpers shared by every command-line module of both packages (``ins`` and
``photogrammetry``): the argument parser, the progress bar, the option types and the
early check of an output file.

The command modules (``ins.cli.main*``, ``photogrammetry.cli.main*``, the ``ins simulate`` command
of ``photogrammetry.cli.simulate``) import these public names; the running of a command
and its exit codes are :func:`ins.cli.main.run_main` / :func:`ins.cli.main.run_command`.  Like
``ins.cli.main`` this module stays light (numpy is imported on first use) so that the tools
install their Ctrl-C handler before the heavy imports.
"""
import argparse
import re
import sys
import time as wallclock

from ins.common.fileio import check_output_file

__all__ = ["EXIT_BAD_INPUT", "NEGATIVE_VALUE", "Parser", "Progress", "check_output_file",
           "nonnegative_int", "positive_int", "triplet"]

#: Exit code of bad input (and of bad arguments, which argparse reports).
EXIT_BAD_INPUT = 2

#: One number as a user types it: -5, -.5, 5., -1.5e-3, +2E4 (no spaces).
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
#: An argument that starts with "-" but is a value, not an option: a negative number or
#: a comma-separated list of numbers that starts with one ("-33.9,151.2,50").
NEGATIVE_VALUE = re.compile(rf"^-(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?:,{_NUMBER})*$")


class Parser(argparse.ArgumentParser):
    """The parser of both command-line interfaces and all their sub-commands.

    Bad arguments exit with code 2 (as bad input does).  An argument that looks like a
    negative number or a comma-separated list starting with one (``-33.9,151.2,50``,
    ``-1.5e-3``) is a value, not an option, so ``--init-lla -33.9,151.2,50`` works as
    well as ``--init-lla=-33.9,151.2,50`` (argparse alone knows only ``-5`` and ``-.5``).
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_VALUE

    def error(self, message):
        self.print_usage(sys.stderr)
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message}\n")


def triplet(text, name="value"):
    """Option type: three comma-separated finite numbers (``"-33.9,151.2,50"``) as a
    float array of shape (3,); spaces are ignored.  The unit is the option's."""
    import numpy as np
    parts = text.replace(" ", "").split(",")
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"expected three comma-separated numbers, got {text!r}")
    try:
        values = np.array([float(p) for p in parts])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected three numbers, got {text!r}") from None
    if not np.all(np.isfinite(values)):
        raise argparse.ArgumentTypeError(f"expected finite numbers, got {text!r}")
    return values


def _int_at_least(text, minimum, expected):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
    if value < minimum:
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
    return value


def positive_int(text):
    """Option type: an integer >= 1."""
    return _int_at_least(text, 1, "a positive integer")


def nonnegative_int(text):
    """Option type: an integer >= 0 (e.g. a random seed)."""
    return _int_at_least(text, 0, "an integer >= 0")


class Progress:
    """A one-line progress bar on stderr (only on a terminal): ``progress(done, total)``
    with ``done``, ``total`` counted in ``unit`` (epochs, images, pairs ...); :meth:`note`
    shows a transient status line."""

    def __init__(self, label, enabled, unit="epochs"):
        self.label = label
        self.unit = unit
        self.enabled = enabled and sys.stderr.isatty()
        self.last = 0.0

    def note(self, text):
        """A transient status line (erased by the bar)."""
        if self.enabled:
            sys.stderr.write(f"\r{text}")
            sys.stderr.flush()

    def __call__(self, done, total):
        if not self.enabled:
            return
        now = wallclock.monotonic()
        if now - self.last < 0.1 and done < total:
            return
        self.last = now
        frac = done / max(total, 1)
        bar = "#" * int(30 * frac)
        sys.stderr.write(f"\r{self.label} [{bar:<30}] {100 * frac:5.1f}% {done}/{total} {self.unit}"
                         "      ")
        if done >= total:
            sys.stderr.write("\n")
        sys.stderr.flush()
