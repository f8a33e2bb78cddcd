"""The image part of the survey-flight simulator, and the ``ins simulate`` command.

``ins`` sits below ``photogrammetry`` and never imports it (``tests/test_layering.py``),
so the parts of the simulator that need the camera model live here, beside the INS part
they extend (:mod:`ins.simulate`: plan, truth, IMU synthesis, sensor errors, GNSS,
mount, manifest).

Modules
-------
exposures
    :func:`~photogrammetry.simulate.exposures.event_times` and
    :func:`~photogrammetry.simulate.exposures.true_exposures`: exposure times on the
    strips and the true exterior orientation.
terrain
    :func:`~photogrammetry.simulate.terrain.make_terrain`: a seeded smooth surface in the
    mapping frame.
tiepoints
    :func:`~photogrammetry.simulate.tiepoints.simulate_tiepoints`: ground points seen in
    two or more images, projected with the true EO and the camera's distortion.
images
    :func:`~photogrammetry.simulate.images.write_images`: the product writer of the
    camera file, events, true EO, tie points and ground points.
folder
    :func:`~photogrammetry.simulate.folder.simulate_flight`: the complete flight folder
    (INS products + image products).
cli
    ``ins simulate PLAN -o FLIGHT_DIR``, added to the ``ins`` tool through the
    entry-point group ``ins.commands`` (``pyproject.toml``; see :mod:`ins.cli.main`).

The submodules are imported on demand (``from photogrammetry.simulate.folder import
simulate_flight``).
"""
