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
           "check_initial", "finite_float", "nonnegative_int", "number", "positive_int", "triplet"]

#: Exit code of bad input (and of bad arguments, which argparse reports).
EXIT_BAD_INPUT = 2

#: One number as a user types it: -5, -.5, 5., -1.5e-3, +2E4 (no spaces).
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
#: An argument that starts with "-" but is a value, not an option: a negative number or
#: a comma-separated list of numbers that starts with one ("-33.9,151.2,50").
NEGATIVE_VALUE = re.compile(rf"^-(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?:,{_NUMBER})*$")


class Parser(argparse.ArgumentParser):
    """The parser of both command-line interfaces and all their sub-commands.

    Bad arguments exit with code 2 (as bad input does) and ONE line on stderr that names
    the option and what it expects (``ins process: error: --week: expected an integer
    >= 0, got '-5'``); the usage is shown only by ``--help``.  ``type=float`` options
    refuse ``nan`` and ``inf`` (:func:`finite_float` is registered for ``float``).  An
    argument that looks like a negative number or a comma-separated list starting with
    one (``-33.9,151.2,50``, ``-1.5e-3``) is a value, not an option, so ``--init-lla
    -33.9,151.2,50`` works as well as ``--init-lla=-33.9,151.2,50`` (argparse alone knows
    only ``-5`` and ``-.5``).
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_VALUE
        self.register("type", float, finite_float)

    def parse_known_args(self, args=None, namespace=None):
        namespace, extras = super().parse_known_args(args, namespace)
        if extras and self._subparsers is None:
            # a sub-command (a parser without sub-commands of its own): what it does not
            # know is an error here, under its own name (not the top-level tool's)
            self.error(_unrecognized(extras))
        return namespace, extras

    def error(self, message):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {_one_line(message)}\n")


def _unrecognized(extras):
    first = extras[0]
    if first.startswith("-") and not NEGATIVE_VALUE.match(first):
        return f"{first.split('=', 1)[0]}: unknown option (see --help)"
    return f"unexpected argument {' '.join(extras)!r} (see --help)"


_ARGUMENT = re.compile(r"^argument (?P<name>\S+?): (?P<rest>.*)$", re.S)
_INVALID = re.compile(r"^invalid (?P<type>\w+) value: (?P<value>.*)$", re.S)
_CHOICE = re.compile(r"^invalid choice: (?P<value>.*?) \(choose from (?P<choices>.*)\)$", re.S)
_TYPE_WORDS = {"float": "a number", "int": "an integer", "finite_float": "a finite number"}


def _one_line(message):
    """argparse's message as ``OPTION: expected ..., got ...`` on one line."""
    m = _ARGUMENT.match(message)
    if m is None:
        return " ".join(message.split())
    name = max(m["name"].split("/"), key=len)            # -o/--output -> --output
    rest = m["rest"]
    if (t := _INVALID.match(rest)) is not None:
        rest = f"expected {_TYPE_WORDS.get(t['type'], t['type'])}, got {t['value']}"
    elif (c := _CHOICE.match(rest)) is not None:
        choices = c["choices"].replace("'", "")
        rest = f"invalid choice {c['value']}: expected one of {choices}"
    elif rest == "expected one argument":
        rest = "expected a value after it"
    return " ".join(f"{name}: {rest}".split())


def finite_float(text):
    """Option type: one finite number (``nan``, ``inf`` and ``1e999`` are refused)."""
    return number()(text)


def number(lo=None, hi=None, lo_open=False, hi_open=False, unit=""):
    """Option type factory: a finite number within ``[lo, hi]`` (``lo_open``/``hi_open``
    exclude the bound), the unit named in the message (``"deg"``, ``"m/s"``).

    ``number(0, lo_open=True, unit="s")`` accepts 0.5 and refuses ``0``, ``-1``, ``nan``
    with ``expected a finite number > 0 (s), got '0'``.
    """
    parts = []
    if lo is not None:
        parts.append(f"{'>' if lo_open else '>='} {lo:g}")
    if hi is not None:
        parts.append(f"{'<' if hi_open else '<='} {hi:g}")
    if lo is not None and hi is not None:
        lb, hb = "(" if lo_open else "[", ")" if hi_open else "]"
        expected = f"a finite number in {lb}{lo:g}, {hi:g}{hb}"
    else:
        expected = " ".join(["a finite number", *parts])
    if unit:
        expected += f" ({unit})"

    def convert(text):
        import math
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
        if not math.isfinite(value) or (
                lo is not None and (value <= lo if lo_open else value < lo)) or (
                hi is not None and (value >= hi if hi_open else value > hi)):
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
        return value
    convert.__name__ = "number"
    return convert


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


def check_initial(lla, lla_option, vel=None, vel_option=None):
    """An initial position (deg, deg, m) and velocity (m/s) typed on the command line
    within the bounds of :mod:`ins.common.limits`; :class:`InputError` naming the option
    otherwise."""
    from ins.common import limits
    from ins.common.errors import InputError
    msg = limits.check_position(lla[0], lla[1], lla[2], lla_option)
    if msg is None and vel is not None:
        msg = limits.check_vector(vel, limits.MAX_SPEED_MPS, vel_option, "m/s")
    if msg is not None:
        raise InputError(msg)


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
