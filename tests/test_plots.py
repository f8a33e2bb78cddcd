"""The PNG plots of ``ins process`` (ins.estimation.pipeline.plots) and the shared style (ins.common.plotstyle):
titles, labels with units that fit the values, one time-axis convention, legends
outside the data, y-limits not set by the start transient, injected biases beside
the estimates.  The Figure objects are inspected, not the pixels."""
from types import SimpleNamespace

import numpy as np
import pytest

from ins.common import plotstyle
from ins.common.plotstyle import ARCSEC
from ins.estimation.pipeline import plots

T0 = 345600.0


def _result(with_errors=True):
    """A processing result shaped like ins.estimation.pipeline.process.ProcessResult: 400 s of nodes, cm
    level position sigmas, a forward filter that starts 1000 times worse (the first
    10 s), known biases."""
    rng = np.random.default_rng(3)
    t = T0 + np.arange(0.0, 400.0, 1.0)
    n = t.size
    boost = np.where(t - T0 < 10.0, 1000.0, 1.0)[:, None]
    std = np.empty((n, 21))
    std[:, 0:3] = 0.008
    std[:, 3:6] = 0.002
    std[:, 6:9] = 30 * ARCSEC
    std[:, 9:] = 1e-6
    fwd_std = std * 2 * boost
    sensors = np.zeros((n, 12))
    sensors[:, 0:3] = np.array([1.0, -0.8, 0.6]) * np.pi / 180 / 3600
    sensors[:, 3:6] = np.array([1000.0, -800.0, 600.0]) * 1e-5
    res = SimpleNamespace(node_time=t, forward_std=fwd_std, smoothed_std=std,
                          forward_sensors=sensors * boost, smoothed_sensors=sensors,
                          errors_forward=None, errors_smoothed=None)
    if with_errors:
        te = T0 + np.arange(0.0, 400.0, 0.1)
        big = np.where(te - T0 < 10.0, 500.0, 1.0)[:, None]
        def err(scale):
            return SimpleNamespace(time=te,
                                   pos_n=scale * 0.006 * rng.standard_normal((te.size, 3)),
                                   att_n=scale * 20 * ARCSEC * rng.standard_normal((te.size, 3)))
        res.errors_smoothed = err(1.0)
        res.errors_forward = err(2.0 * big)
    return res


@pytest.fixture
def figures(monkeypatch):
    """The figures the plot functions save (the PNG is still written)."""
    saved = {}
    real = plots.save_png

    def keep(fig, path, **kw):
        saved[path] = fig
        return real(fig, path, **kw)
    monkeypatch.setattr(plots, "save_png", keep)
    return saved


def _outside(fig, ax, legend):
    fig.canvas.draw()
    a, b = ax.get_window_extent(), legend.get_window_extent()
    return b.x0 >= a.x1 or b.x1 <= a.x0 or b.y0 >= a.y1 or b.y1 <= a.y0


def _png(path):
    with open(path, "rb") as f:
        return f.read(8) == b"\x89PNG\r\n\x1a\n"


def test_errors_plot_units_titles_limits(tmp_path, figures):
    res = _result()
    path = plots.plot_errors(res, str(tmp_path / "errors.png"))
    assert _png(path)
    fig = figures[path]
    axes = fig.axes
    assert "Trajectory errors" in fig._suptitle.get_text()
    assert f"{T0:.3f}" in fig._suptitle.get_text()        # the time origin, stated once
    labels = [ax.get_ylabel() for ax in axes]
    assert labels == ["north error, mm", "east error, mm", "down error, mm",
                      "tilt N error, arcsec", "tilt E error, arcsec", "heading error, arcsec"]
    assert axes[-1].get_xlabel().startswith("time since start, s")
    for ax in axes:
        lo, hi = ax.get_ylim()
        # smoothed 3 sigma = 24 mm / 90 arcsec, the smoothed errors ~ 4 sigma of 6 mm /
        # 20 arcsec; the forward transient (x 1000) must not set the limits
        assert 20 < hi < 60 if "mm" in ax.get_ylabel() else 80 < hi < 200
        assert lo == pytest.approx(-hi)
        leg = ax.get_legend()
        assert leg is not None and _outside(fig, ax, leg)
        assert "clipped" in leg.get_texts()[0].get_text()


def test_sigma_plot_units_and_transient(tmp_path, figures):
    res = _result(with_errors=False)
    path = plots.plot_sigma(res, str(tmp_path / "sigma.png"))
    assert _png(path)
    fig = figures[path]
    pos, vel, att = fig.axes
    assert pos.get_ylabel() == "position sigma, mm"
    assert vel.get_ylabel() == "velocity sigma, mm/s"
    assert att.get_ylabel() == "attitude sigma, arcsec"
    assert "heading forward" in [t.get_text() for t in att.get_legend().get_texts()]
    assert not any(t.get_text().startswith("D ") for t in att.get_legend().get_texts())
    # forward sigma after the transient: 16 mm, 4 mm/s, 60 arcsec; the first 10 s are
    # 1000 times larger and must lie above the limits
    for ax, top in ((pos, 16), (vel, 4), (att, 60)):
        lo, hi = ax.get_ylim()
        assert top < hi < 3 * top
        assert _outside(fig, ax, ax.get_legend())
    assert "Standard deviations" in fig._suptitle.get_text()


def test_bias_plot_truth_beside_estimates(tmp_path, figures):
    flight = tmp_path / "flight"
    flight.mkdir()
    (flight / "manifest.toml").write_text(
        "[imu]\ngyro_bias_dph = [1.0, -0.8, 0.6]\naccel_bias_mgal = [1000.0, -800.0, 600.0]\n")
    inj = plots.injected_biases(str(flight))
    np.testing.assert_array_equal(inj["gyro_bias_dph"], [1.0, -0.8, 0.6])
    assert plots.injected_biases(str(tmp_path)) is None            # no manifest
    res = _result(with_errors=False)
    paths = plots.write_plots(res, str(tmp_path), flight_dir=str(flight))
    fig = figures[str(tmp_path / "biases.png")]
    gyro, accel = fig.axes
    assert gyro.get_ylabel() == "gyro bias, deg/h" and accel.get_ylabel() == "accel bias, mGal"
    for ax, truth in ((gyro, [1.0, -0.8, 0.6]), (accel, [1000.0, -800.0, 600.0])):
        lines = {ln.get_label(): ln for ln in ax.get_lines()}
        for axis, value in zip("xyz", truth):
            ln = lines[f"{axis} injected (manifest)"]
            assert np.allclose(ln.get_ydata(), value)
            # the smoothed estimate equals the truth here: on top of it
            assert np.allclose(lines[f"{axis} smoothed"].get_ydata(), value)
        lo, hi = ax.get_ylim()
        assert lo < min(truth) and hi > max(truth) and hi < 1.5 * max(np.abs(truth))
        assert _outside(fig, ax, ax.get_legend())
    assert "injected" in fig._suptitle.get_text()
    assert [p.rsplit("/", 1)[1] for p in paths] == ["sigma.png", "biases.png"]   # no truth


def test_length_unit_fits_values():
    assert plotstyle.length_unit([0.025, -0.01]) == (1000.0, "mm")
    assert plotstyle.length_unit([0.3]) == (100.0, "cm")
    assert plotstyle.length_unit([12.0]) == (1.0, "m")


def test_robust_limits_leave_out_transient():
    t = np.arange(0.0, 300.0)
    y = np.where(t < 60, 1e3, np.sin(t))
    lo, hi = plotstyle.robust_limits(t, [y], margin=0.0)
    assert -1.0 <= lo < -0.99 and 0.99 < hi <= 1.0
    lo, hi = plotstyle.robust_limits(t, [np.column_stack([y, 2 * y])], symmetric=True,
                                     margin=0.0)
    assert hi == pytest.approx(2 * np.abs(np.sin(t[60:])).max())


def test_strip_starts():
    ids = [f"S{s:02d}_{k:03d}" for s in (1, 2, 3) for k in range(1, 5)]
    assert plotstyle.strip_starts(ids) == [4, 8]
    heading = np.deg2rad([90, 91, 89, 270, 271, 90])
    assert plotstyle.strip_starts([str(i) for i in range(6)], heading_rad=heading) == [3, 5]
    assert plotstyle.strip_starts(time_s=[0, 2, 4, 6, 60, 62, 64]) == [4]


# ---- photogrammetry refine report and the demo: strips marked, units, legends outside

@pytest.fixture
def style_figures(monkeypatch):
    """The figures saved through ins.common.plotstyle.save_png (imported at call time)."""
    saved = {}
    real = plotstyle.save_png

    def keep(fig, path, **kw):
        saved[str(path)] = fig
        return real(fig, path, **kw)
    monkeypatch.setattr(plotstyle, "save_png", keep)
    return saved


def _eo(n_strips=3, per=5, times=True):
    """Strips of ``per`` images 2 s apart, strip j starting at T0 + 100 j s (a turn of
    92 s between strips); ``times=False``: no exposure times (NaN)."""
    ids = [f"S{s:02d}_{k:03d}" for s in range(1, n_strips + 1) for k in range(1, per + 1)]
    kappa = np.repeat(np.deg2rad([0.0, 180.0, 0.0][:n_strips]), per)
    angles = np.column_stack([np.zeros_like(kappa), np.zeros_like(kappa), kappa])
    time = (T0 + 100.0 * np.repeat(np.arange(n_strips), per) + 2.0 * np.tile(np.arange(per),
                                                                            n_strips))
    return SimpleNamespace(image_id=ids, angles=angles,
                           time=time if times else np.full(len(ids), np.nan))


def _strip_lines(ax):
    return sorted(ln.get_xdata()[0] for ln in ax.get_lines()
                  if ln.get_linestyle() == "--" and np.ptp(ln.get_xdata()) == 0)


def test_refine_corrections_plot_marks_strips(tmp_path, style_figures):
    from photogrammetry.adjustment.report import _plot_corrections
    eo = _eo()
    n = len(eo.image_id)
    diff = np.tile(np.array([-100.0, 150.0, 20.0]) * ARCSEC, (n, 1))
    a = SimpleNamespace(diff=diff, used=np.ones(n, bool), names=("phi", "omega", "kappa"),
                        mean=diff.mean(axis=0))
    path = str(tmp_path / "corr.png")
    _plot_corrections(SimpleNamespace(assessment=a, eo=eo), path)
    assert _png(path)
    fig = style_figures[path]
    ax = fig.axes[0]
    assert ax.get_ylabel() == "INS - adjusted, arcsec"
    assert "Angle corrections" in ax.get_title()
    assert _strip_lines(ax) == [54.0, 154.0]      # mid-turn between S01/S02, S02/S03, s
    assert ax.get_xlabel().startswith("exposure time since start, s")
    assert f"start = GPS second of week {T0:.3f}" in ax.get_title()
    assert [t.get_text() for t in ax.texts] == ["strip 1", "strip 2", "strip 3"]
    # no line across a turn: the x data of each series hold a gap between strips
    for ln in ax.get_lines():
        x = ln.get_xdata()
        if len(x) > 2:
            assert np.isnan(x).sum() == 2
    assert _outside(fig, ax, ax.get_legend())
    means = [t.get_text() for t in ax.get_legend().get_texts() if "mean" in t.get_text()]
    assert means == ["phi mean, -100 arcsec", "omega mean, 150 arcsec", "kappa mean, 20 arcsec"]


def test_plots_over_exposures_without_times_fall_back_to_image_numbers(tmp_path,
                                                                    style_figures):
    from photogrammetry.adjustment.report import _plot_corrections
    eo = _eo(times=False)
    n = len(eo.image_id)
    diff = np.zeros((n, 3))
    a = SimpleNamespace(diff=diff, used=np.ones(n, bool), names=("phi", "omega", "kappa"),
                        mean=diff.mean(axis=0))
    path = str(tmp_path / "corr.png")
    _plot_corrections(SimpleNamespace(assessment=a, eo=eo), path)
    ax = style_figures[path].axes[0]
    assert ax.get_xlabel().startswith("image number (file order)")
    assert _strip_lines(ax) == [4.5, 9.5]


def test_refine_residual_plot_title_and_units(tmp_path, style_figures):
    from photogrammetry.adjustment.report import _plot_residuals
    rng = np.random.default_rng(1)
    xy = rng.uniform(-30, 30, (50, 2))
    rejected = np.zeros((1, 50), bool)
    rejected[0, :3] = True
    blk = SimpleNamespace(residuals=rng.standard_normal((1, 50)), rejected=rejected,
                          mask=~rejected, sigma0=1.2)
    res = SimpleNamespace(block=blk, pair_points=[(xy, xy)],
                          settings={"sigma_mm": 0.002, "pixel_size_mm": 0.004})
    path = str(tmp_path / "res.png")
    _plot_residuals(res, path)
    assert _png(path)
    ax = style_figures[path].axes[0]
    assert ax.get_xlabel().startswith("image x, mm") and ax.get_ylabel() == "image y, mm"
    title = ax.get_title()
    assert "47 conditions used, 3 rejected" in title and "(0.6 px)" in title


def test_demo_angle_plot_marks_strips(tmp_path, style_figures):
    import importlib.util
    from pathlib import Path
    spec = importlib.util.spec_from_file_location(
        "demo_tool", Path(__file__).resolve().parents[1] / "tools" / "demo.py")
    demo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(demo)
    eo = _eo(n_strips=2, per=4)
    d = np.full((8, 3), 30 * ARCSEC)
    demo.plot_angles(tmp_path, eo, d, d / 10, ["phi", "omega", "kappa"])
    fig = style_figures[str(tmp_path / "angles.png")]
    assert _png(tmp_path / "angles.png")
    assert [ax.get_ylabel() for ax in fig.axes] == ["phi error, arcsec", "omega error, arcsec",
                                                    "kappa error, arcsec"]
    assert "truth" in fig._suptitle.get_text()
    assert fig.axes[-1].get_xlabel().startswith("exposure time since start, s")
    for ax in fig.axes:
        assert _strip_lines(ax) == [53.0]
        assert _outside(fig, ax, ax.get_legend())
        texts = [t.get_text() for t in ax.get_legend().get_texts()]
        assert "RMS 30 arcsec" in texts[0] and "RMS 3 arcsec" in texts[1]


def test_allan_plot_units_and_legends(tmp_path, style_figures):
    from ins.cli.allan import plot_allan
    tau = np.logspace(-2, 2, 20)
    gyro = np.column_stack([1e-5 / np.sqrt(tau)] * 3)            # rad/s
    accel = np.column_stack([1e-3 / np.sqrt(tau)] * 3)           # m/s^2
    path = str(tmp_path / "allan.png")
    plot_allan(path, tau, gyro, accel, "imu.txt: 600 s static")
    assert _png(path)
    fig = style_figures[path]
    a1, a2 = fig.axes
    assert (a1.get_ylabel(), a2.get_ylabel()) == ("Allan deviation, deg/h",
                                                  "Allan deviation, mGal")
    assert a1.get_xlabel() == "averaging time tau, s"
    # 1e-5 rad/s = 2.063 deg/h at tau 1 s; 1e-3 m/s^2 = 100 mGal
    y1 = a1.get_lines()[0].get_ydata()
    assert y1[np.argmin(np.abs(tau - 1))] == pytest.approx(
        1e-5 / np.sqrt(tau[np.argmin(np.abs(tau - 1))]) * 180 / np.pi * 3600)
    assert a2.get_lines()[0].get_ydata()[0] == pytest.approx(1e-3 / np.sqrt(tau[0]) / 1e-5)
    assert "600 s static" in fig._suptitle.get_text()
    assert all(_outside(fig, a, a.get_legend()) for a in (a1, a2))


def test_lunar_convergence_plot(tmp_path, style_figures):
    from photogrammetry.cli.lunar import _plot
    counts = np.arange(2, 12)
    sig = np.deg2rad(40 / 3600) / np.sqrt(counts - 1)
    final = np.deg2rad(-30.0)
    hdg = final + np.deg2rad(2 / 3600) + 2 * np.pi           # wraps to +2 arcsec
    path = str(tmp_path / "conv.png")
    _plot(path, counts, np.full(counts.size, hdg), sig, final)
    assert _png(path)
    ax = style_figures[path].axes[0]
    assert ax.get_ylabel() == "heading difference, arcsec"
    assert "heading 330.000000 deg" in ax.get_title()
    assert np.allclose(ax.get_lines()[0].get_ydata(), 2.0)
    assert _outside(ax.figure, ax, ax.get_legend())
