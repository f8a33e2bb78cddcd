"""The ``photogrammetry`` command line (:mod:`photogrammetry.cli.main`) and the
``ins simulate`` command (:mod:`photogrammetry.cli.simulate`, registered with ``ins``
through the ``ins.commands`` entry point).
"""
