"""Files of the filter's optional states and measurements, written by ``ins process`` beside
the solution: ``innovations.txt`` (every tested measurement, per axis:
:func:`ins.estimation.core.measurements.write_innovations`) and ``states.txt`` (the smoothed estimates
and sigmas of the optional state groups, in edge units: arcsec, m, ms)."""
from types import SimpleNamespace

import numpy as np

from ins.common.textformat import format_table
from ins.estimation.core.error_model import OPTIONAL_GROUPS
from ins.estimation.core.measurements import write_innovations

__all__ = ["write_innovations", "write_optional_states", "GROUP_UNITS"]

ARCSEC = np.pi / 180.0 / 3600.0
#: Edge unit of each optional group: (suffix, SI per unit).
GROUP_UNITS = {"gyro_misalignment": ("arcsec", ARCSEC), "accel_misalignment": ("arcsec", ARCSEC),
               "lever_arm": ("m", 1.0), "time_offset": ("ms", 1e-3),
               # the receiver clock (tight coupling): bias c*dt in m, drift in m/s
               "clock": (("m", 1.0), ("mps", 1.0)),
               # inter-system biases (tight coupling, several constellations), m
               "isb": ("m", 1.0)}


def _state_units(group):
    """(suffix, SI per unit) of each state of an optional group."""
    u = GROUP_UNITS[group]
    return list(u) if isinstance(u[0], tuple) else [u] * OPTIONAL_GROUPS[group]


def optional_columns(layout):
    """Column names of ``states.txt`` for a layout (estimates, then sigmas)."""
    names = [n for n in layout.names[21:layout.groups_stop]]
    unit = {}
    for g in layout.groups:
        for k, (suffix, _) in enumerate(_state_units(g)):
            unit[layout.names[getattr(layout, g).start + k]] = suffix
    return ([f"{n}_{unit[n]}" for n in names] + [f"std_{n}_{unit[n]}" for n in names])


def write_optional_states(path, result):
    """Write ``states.txt``: time_s, the smoothed estimates of the optional groups of
    ``result.fwd.layout`` and their smoothed sigmas (edge units), one row per filter
    node; returns ``path`` or ``None`` when the layout has no optional group."""
    from ins.common.fileio import atomic_open
    layout = result.fwd.layout
    if not layout.groups:
        return None
    scale = np.array([si for g in layout.groups for _, si in _state_units(g)])
    chunks = (result.node_chunks() if hasattr(result, "node_chunks") else
              [SimpleNamespace(time=result.node_time, smoothed_sensors=result.smoothed_sensors,
                               smoothed_std=result.smoothed_std)])
    with atomic_open(path, "w") as f:
        f.write("# time_s " + " ".join(optional_columns(layout))
                + "  (smoothed, at the filter nodes; lever arm: correction added to the "
                  "configured arm, b frame; time offset: a GNSS record stamped t is at IMU "
                  "time t + offset; clock: the estimated receiver clock bias c dt, m, "
                  "and drift, m/s)\n")
        for c in chunks:                     # block by block over the nodes
            est = c.smoothed_sensors[:, 12:layout.groups_stop - 9] / scale
            std = c.smoothed_std[:, 21:layout.groups_stop] / scale
            table = np.column_stack([c.time, est, std])
            try:                             # compiled, digit for digit as '%.6f'
                f.write(format_table(table, 6).tobytes().decode("ascii"))
            except ValueError:               # a non-finite value: Python's nan / inf
                f.write("".join(" ".join(f"{v:.6f}" for v in row) + "\n"
                                for row in table.tolist()))
    return path
