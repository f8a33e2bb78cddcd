"""Double-differenced pseudoranges of the real GEONET pair (0759 rover, 3040 base, 3.3 km,
GPS L1 C/A, an hour at 30 s) from RTKLIB's static fixed rover position, the base at its
RINEX header: prints the RMS and largest DD residual (reference: the highest satellite),
per satellite, and, for comparison, the undifferenced residuals of the rover after one
clock per epoch (broadcast orbits and clocks, Klobuchar, Saastamoinen: the errors the
DDs cancel), and the baseline length.

    .venv/bin/python bench/bench_dd_static_pair.py
"""
import tempfile
from pathlib import Path

import numpy as np
import pymap3d

from ins.estimation.coupling.double_difference import dd_operator
from ins.estimation.coupling.pseudorange import line_of_sight, sagnac_range
from ins.gnss.raw_pairs import read_pair
from ins.gnss.rtklib_engine import solve
from ins.gnss.rtklib_options import RtklibOptions
from ins.nav.earth import lla_to_ecef

PAIR = Path(__file__).resolve().parents[2] / "shared" / "real" / "rtklib_static_pair"
ROVER, BASE, NAV = (PAIR / n for n in ("07590920.05o", "30400920.05o", "07590920.05n"))


def main():
    with tempfile.TemporaryDirectory() as tmp:
        st = solve(str(ROVER), str(NAV), str(Path(tmp) / "static.pos"), base=str(BASE),
                   options=RtklibOptions(systems=("gps",), mode="static", direction="forward"))
    r_r = lla_to_ecef(*st.log.lla[-1])
    lla = np.array(pymap3d.ecef2geodetic(*r_r, deg=False))
    p = read_pair(ROVER, BASE, NAV, r_r)
    print(f"baseline {np.linalg.norm(r_r - p.base.r_e):.3f} m (RTKLIB static, Q "
          f"{st.log.quality[-1]}); {len(p)} epochs")
    dd, und, per = [], [], {}
    for k in range(len(p)):
        sb = list(p.base.sats[k])
        i = [n for n, s in enumerate(p.sats[k]) if s in sb]
        j = [sb.index(p.sats[k][n]) for n in i]
        rs = p.sat_pos_e[k][i]
        u = p.range_m[k][i] - sagnac_range(rs, r_r)
        und.append(u - np.median(u))
        sd = u - (p.base.range_m[k][j] - sagnac_range(p.base.sat_pos_e[k][j], p.base.r_e))
        el = line_of_sight(rs, lla)[1]
        ref = int(np.argmax(el))
        res = dd_operator(len(i), ref) @ sd
        dd.append(res)
        for name, r in zip([p.names[k][n] for n in i if n != i[ref]], res):
            per.setdefault(name, []).append(r)
    dd, und = np.concatenate(dd), np.concatenate(und)
    print(f"DD pseudorange residuals: {dd.size}, RMS {np.sqrt(np.mean(dd ** 2)):.3f} m, "
          f"max |.| {np.abs(dd).max():.3f} m")
    print(f"rover undifferenced (one clock per epoch): RMS {np.sqrt(np.mean(und ** 2)):.3f} m, "
          f"max |.| {np.abs(und).max():.3f} m")
    print("per satellite (DD, against the highest): " + ", ".join(
        f"{n} {np.sqrt(np.mean(np.square(v))):.2f}/{np.mean(v):+.2f}" for n, v in sorted(per.items()))
        + " (RMS/mean m)")


if __name__ == "__main__":
    main()
