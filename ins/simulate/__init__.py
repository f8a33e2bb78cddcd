"""Survey-flight simulator, INS part: flight plan -> truth trajectory (with the stabilized
mount) -> IMU increments with sensor errors, GNSS antenna log, mount angles, and the
flight folder with its manifest.

The image part (exposures, true EO, terrain, tie points, the camera file) needs the
camera model and lives above, in :mod:`photogrammetry.simulate`; ``ins`` never imports
``photogrammetry`` (``tests/test_layering.py``).  It joins the folder as a product
writer of :func:`ins.simulate.folder.simulate_flight`; the complete folder of
``ins simulate`` is :func:`photogrammetry.simulate.folder.simulate_flight`.

Modules
-------
plan
    :func:`~ins.simulate.plan_read.load_plan`: the TOML flight plan, validated, SI inside.
path
    The horizontal/vertical flight path in the plane: heading, ground speed, climbs.
truth
    :func:`~ins.simulate.truth.build_truth`: the smooth truth trajectory in the
    geodetic frame, evaluable at any time, with the mount angles.
imu_synth
    :func:`~ins.simulate.imu_synth.synthesize_imu`: error-free increments.
sensor_errors
    :class:`~ins.simulate.sensor_errors.ImuErrorModel`, the presets and
    :func:`~ins.simulate.sensor_errors.apply_errors`.
gnss
    :func:`~ins.simulate.gnss.simulate_gnss`: the antenna's fixes through the lever arm
    and the mount.
gnss_raw, gps_orbit, gnss_raw_plan, gnss_raw_product
    Raw GPS L1 observations (RINEX 3.04 ``rover.obs``) of the antenna from real broadcast
    orbits (own IS-GPS-200 orbit, Klobuchar, Saastamoinen, clocks, multipath, slips,
    masks) with their truth: the plan's ``[gnss_raw]`` or ``ins simulate --gnss-raw``.
gnss_multi, gnss_signals, kepler_orbit, glonass_orbit, rinex_mixed, gnss_multi_product
    The same for GPS (L1, L2, L5), GLONASS (G1, G2 FDMA; PZ-90 state vectors integrated
    by the ICD's RK4), Galileo (E1, E5a) and BeiDou (B1I, B2a, B3I; MEO, IGSO and GEO in
    BDT) from generated constellations: ``[gnss_raw] systems``, ``signals``; RINEX 3.04
    mixed observation and navigation files.
ground, gnsslogger_writer
    Ground journeys of low-cost users (a consumer car, a handheld walk) with their
    truth in closed form, and the simulated twin of an Android phone carried along one:
    a GnssLogger log (raw GPS, the inertial sensors on the phone's boot clock, the
    phone's own fixes) with the truth of every clock and measurement.
manifest
    ``manifest.toml``: the INS tables and the merge of the tables of product writers.
folder
    :func:`~ins.simulate.folder.simulate_flight`: the INS products of a flight folder and
    the product writers it is given.

Figures (``bench/bench_simulate.py``): 1 h at 200 Hz of a 4-strip block in ~2.5 s of
increments (+ ~1 s truth build, ~1.3 s sensor errors, peak RSS ~280 MB); mechanizing
the error-free increments of a 30-min flight (take-off, climb, 25-deg-bank turns with
the mount saturating) reproduces the truth within 0.8 mm horizontally and 1e-4 arcsec;
strip starts within a few mm of their planned points.

The submodules are imported on demand (``from ins.simulate.truth import build_truth``).
"""
