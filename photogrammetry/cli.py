"""Command-line interface of the photogrammetry package.

Its commands (``eo``, ``refine``, ``lunar-heading``) arrive with the issues that build
them; until then the command only explains itself.
"""
import argparse
import sys

from . import __version__


def build_parser():
    parser = argparse.ArgumentParser(
        prog="photogrammetry",
        description="Photogrammetric orientation from an INS solution. No command is "
                    "available in this version yet: exterior orientation (eo), coplanarity "
                    "refinement (refine) and lunar heading (lunar-heading) are planned.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    return parser


def main(argv=None):
    build_parser().parse_args(argv)
    print("photogrammetry: no command is available in this version yet (see --help)",
          file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
