"""The ``ins`` command line (:mod:`ins.cli.main`): one module per sub-command and the
shared argument helpers (:mod:`ins.cli.util`).  Library code never prints or exits;
these modules do.

Kept light: importing this package loads nothing but the standard library, so the
Ctrl-C handler is in place before numpy loads.
"""
