"""Flight plan of a photogrammetric survey flight (TOML), validated, SI units inside.

The file has the sections ``[block] [flight] [wind] [turbulence] [mount] [imu] [gnss]
[camera] [terrain] [tie_points]``; key names carry their unit (``_deg``, ``_m``,
``_mps``, ``_hz``, ``_s``, ``_percent``).  ``data/flights/demo.toml`` is the documented
example.  Every key has a default except the block origin; unknown keys and sections are
errors (:mod:`ins.tomlschema`: the message lists the known keys of the section, with
"did you mean" for a near miss; :data:`PLAN_KEYS` holds them).  :func:`load_plan` and
:func:`parse_plan` raise :class:`~ins.errors.InputError` as
``"plan.toml: [section] key: message (expected unit)"``.

Geometry of the photo block
---------------------------
The strips are straight lines of azimuth ``strip_azimuth_deg`` (clockwise from north)
and length ``strip_length_m``; strip 0 starts at the block origin, the next strips lie to
the right of the first (looking along the azimuth), ``strip_spacing`` apart, flown
alternately back and forth.  With the nominal camera axes (``[camera] axes``, rows of
``C_bc``) the body x axis (forward, along track) is the image axis whose row of ``axes``
has the larger entry: for the default nadir axes ``[[1,0,0],[0,-1,0],[0,0,-1]]`` the
camera x axis (image columns, ``width_px``) is along track and the image rows
(``height_px``) across track.  Then::

    footprint_along  = height_agl * n_px_along  * pixel_size / focal_length
    footprint_across = height_agl * n_px_across * pixel_size / focal_length
    exposure_interval = (1 - forward_overlap) * footprint_along / ground_speed
    strip_spacing     = (1 - side_overlap) * footprint_across

Feasibility
-----------
The turns are coordinated turns at ``turn_rate_deg_s`` or ``bank_deg`` (typically 15-25
deg bank), up to ``[flight] max_bank_deg`` (default 30).  In the turns the stabilized
mount runs into its level limit and saturates smoothly (normal in a survey); on the
strips it must follow: the crab of the wind plus the yaw turbulence, and the roll and
pitch turbulence, must stay below :data:`MOUNT_KNEE` (80 %) of the azimuth and level
limits ("the mount cannot follow" otherwise), and ``run_in_m`` must give the servos 3
lags to recover from the turn.

Modules: :mod:`~ins.simulate.plan_model` (the dataclasses of the sections and the derived
quantities), :mod:`~ins.simulate.plan_read` (the keys, the section readers,
:func:`parse_plan`, :func:`load_plan`), :mod:`~ins.simulate.plan_checks` (feasibility,
crab angle).  This module gathers them under one name.
"""
from .plan_checks import check_feasible, crab_angle, max_crab_angle
from .plan_model import (G_TURN, MOUNT_KNEE, NADIR_AXES, Block, CameraSettings, Flight,
                         FlightPlan, GnssSettings, ImuSettings, Mount, Terrain, TiePoints,
                         Turbulence, Wind)
from .plan_read import PLAN_KEYS, load_plan, parse_plan

__all__ = ["PLAN_KEYS", "FlightPlan", "Block", "Flight", "Wind", "Turbulence", "Mount",
           "ImuSettings", "GnssSettings", "CameraSettings", "Terrain", "TiePoints",
           "load_plan", "parse_plan", "check_feasible", "crab_angle", "max_crab_angle",
           "G_TURN", "MOUNT_KNEE", "NADIR_AXES"]
