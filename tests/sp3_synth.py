"""An SP3-c precise-orbit file synthesized from broadcast ephemerides (RTKLIB's eph2pos
through pyrtklib5): a stand-in for real precise products in the tests, written in the
SP3-c layout (22 header lines, positions km, clocks microseconds).  One ephemeris per
satellite (the one nearest the middle of the span), so the orbit is smooth across the
span; the clock is the broadcast one with its relativistic term taken out again
(RTKLIB adds -2 r.v / c^2 to a precise clock)."""
import numpy as np

C_LIGHT = 299792458.0


def _ymdhms(rtk, week, tow):
    ep = rtk.Arr1Ddouble(6)
    rtk.time2epoch(rtk.gpst2time(week, tow), ep)
    return [ep[i] for i in range(6)]


def _epoch_text(rtk, week, tow):
    y, mo, d, h, mi, s = _ymdhms(rtk, week, tow)
    return f"{int(y):4d} {int(mo):2d} {int(d):2d} {int(h):2d} {int(mi):2d} {s:11.8f}"


def satellite_states(rtk, nav_path, week, tows, mid_tow):
    """{prn: (len(tows), 4) positions m and clock s} of every GPS satellite of the file."""
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    rtk.readrnx(nav_path, 1, "", obs, nav, sta)
    mid = rtk.gpst2time(week, mid_tow)
    best = {}
    for i in range(nav.n):
        e = nav.eph[i]
        dt = abs(rtk.timediff(e.toe, mid))
        if e.svh == 0 and dt < 7200 and (e.sat not in best or dt < best[e.sat][0]):
            best[e.sat] = (dt, e)
    rs, dts, var = rtk.Arr1Ddouble(6), rtk.Arr1Ddouble(2), rtk.Arr1Ddouble(1)

    def pos_clk(t, eph):
        rtk.eph2pos(t, eph, rs, dts, var)
        return np.array([rs[0], rs[1], rs[2]]), dts[0]
    out = {}
    for sat, (_, eph) in sorted(best.items()):
        rows = []
        for tow in tows:
            t = rtk.gpst2time(week, tow)
            r, clk = pos_clk(t, eph)
            r1, _ = pos_clk(rtk.gpst2time(week, tow + 0.5), eph)
            r0, _ = pos_clk(rtk.gpst2time(week, tow - 0.5), eph)
            v = r1 - r0                                          # m/s over 1 s
            rows.append([*r, clk + 2.0 * float(r @ v) / C_LIGHT ** 2])
        out[sat] = np.array(rows)                # sat number = PRN for GPS
    return out


def write_sp3(path, rtk, states, week, tows):
    """SP3-c file of ``states`` ({prn: (n, 4) m, s}) at ``tows`` (GPS s of week)."""
    prns = sorted(states)
    ids = "".join(f"G{p:02d}" for p in prns)
    ids += "  0" * (85 - len(prns))
    step = tows[1] - tows[0]
    lines = [f"#cP{_epoch_text(rtk, week, tows[0])} {len(tows):7d} ORBIT IGS05 BRD  TST",
             f"## {week:4d} {tows[0]:15.8f} {step:14.8f} 53461 0.0000000000000"]
    for k in range(5):
        head = f"+   {len(prns):2d}   " if k == 0 else "+        "
        lines.append(head + ids[51 * k:51 * k + 51])
    for _ in range(5):
        lines.append("++       " + "  0" * 17)
    lines += ["%c G  cc GPS ccc cccc cccc cccc cccc ccccc ccccc ccccc ccccc",
              "%c cc cc ccc ccc cccc cccc cccc cccc ccccc ccccc ccccc ccccc",
              "%f  1.2500000  1.025000000  0.00000000000  0.000000000000000",
              "%f  0.0000000  0.000000000  0.00000000000  0.000000000000000",
              "%i    0    0    0    0      0      0      0      0         0",
              "%i    0    0    0    0      0      0      0      0         0"]
    lines += ["/* synthesized from broadcast ephemerides (test)"] * 4
    for j, tow in enumerate(tows):
        lines.append(f"*  {_epoch_text(rtk, week, tow)}")
        for p in prns:
            x, y, z, c = states[p][j]
            lines.append(f"PG{p:02d}{x / 1e3:14.6f}{y / 1e3:14.6f}{z / 1e3:14.6f}"
                         f"{c * 1e6:14.6f}")
    lines.append("EOF")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    return path
