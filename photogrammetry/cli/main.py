"""Command-line interface of the photogrammetry package.

Each command lives in a module of its own listed in ``COMMAND_MODULES``; the module has
``add_parser(sub)`` that registers one sub-command and sets ``func``.  Bad input gives
one line on stderr, exit code 2 and no output (shared with ``ins.cli.main.run_command``).
"""
import importlib
import sys

from ins.cli.main import run_main
from ins.cli.util import Parser
from photogrammetry import __version__

# Sub-commands that live in modules of their own (one line each).
COMMAND_MODULES = [
    "photogrammetry.cli.eo",
    "photogrammetry.cli.refine",
    "photogrammetry.cli.tiepoints",
    "photogrammetry.cli.sfm",
    "photogrammetry.cli.lunar",
    "photogrammetry.cli.lunar_simulate",
]


def build_parser():
    parser = Parser(
        prog="photogrammetry",
        description="Photogrammetric orientation from an INS solution: exterior orientation "
                    "per exposure, coplanarity refinement of the angles, lunar heading. "
                    "Angles in files are degrees in a named system (phi-omega-kappa or "
                    "omega-phi-kappa); lengths in m, photo coordinates in mm.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    sub.required = True
    for name in COMMAND_MODULES:
        importlib.import_module(name).add_parser(sub)
    return parser


def main(argv=None):
    """``photogrammetry`` on the command line (``argv=None``: ``sys.argv``); returns the
    exit code (bad input 2, untrustworthy result 3, Ctrl-C 130, SIGTERM 143:
    ``ins.cli.main.run_command``)."""
    return run_main(build_parser, argv, "photogrammetry")


if __name__ == "__main__":
    sys.exit(main())
