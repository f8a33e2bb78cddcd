"""Survey-flight simulator: flight plan -> truth trajectory (with the stabilized mount)
-> IMU increments with sensor errors (and, in the modules of part B, GNSS, exposures,
terrain and tie points).

Modules
-------
plan
    :func:`~ins.simulate.plan.load_plan`: the TOML flight plan, validated, SI inside.
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

The submodules are imported on demand (``from ins.simulate.truth import build_truth``).
"""
