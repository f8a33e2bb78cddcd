"""PNG plots of a processing result (matplotlib, Agg backend, imported lazily)."""
import os

import numpy as np

ARCSEC = np.pi / 180.0 / 3600.0


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig, path, plt):
    from .fileio import atomic_open
    with atomic_open(path, "wb") as f:
        fig.savefig(f, format="png", dpi=110)
    plt.close(fig)
    return path


def plot_errors(result, path):
    """Position (m) and attitude (arcsec) errors against the truth, forward and smoothed,
    with the smoothed 3-sigma envelope."""
    plt = _pyplot()
    fig, axes = plt.subplots(6, 1, figsize=(10, 13), sharex=True)
    t0 = result.node_time[0]
    labels = ["north m", "east m", "down m", "tilt N arcsec", "tilt E arcsec", "heading arcsec"]
    for i, ax in enumerate(axes):
        scale = 1.0 if i < 3 else 1.0 / ARCSEC
        for name, e, style in (("forward", result.errors_forward, "C1"),
                               ("smoothed", result.errors_smoothed, "C0")):
            series = e.pos_n[:, i] if i < 3 else e.att_n[:, i - 3]
            step = max(1, len(e.time) // 20000)
            ax.plot(e.time[::step] - t0, scale * series[::step], style, lw=0.7, label=name)
        sig = 3 * result.smoothed_std[:, i if i < 3 else i + 3] * scale
        ax.plot(result.node_time - t0, sig, "k:", lw=0.7, label="smoothed 3 sigma")
        ax.plot(result.node_time - t0, -sig, "k:", lw=0.7)
        ax.set_ylabel(labels[i])
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel(f"time since {t0:.3f} s")
    return _save(fig, path, plt)


def plot_sigma(result, path):
    """Forward and smoothed 1-sigma of position (m), velocity (m/s), attitude (arcsec)."""
    plt = _pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    t = result.node_time - result.node_time[0]
    for ax, sl, scale, label in ((axes[0], slice(0, 3), 1.0, "position sigma m"),
                                 (axes[1], slice(3, 6), 1.0, "velocity sigma m/s"),
                                 (axes[2], slice(6, 9), 1 / ARCSEC, "attitude sigma arcsec")):
        for k, axis in enumerate("NED"):
            ax.semilogy(t, scale * result.forward_std[:, sl][:, k], f"C{k}--", lw=0.7,
                        label=f"{axis} forward")
            ax.semilogy(t, scale * result.smoothed_std[:, sl][:, k], f"C{k}", lw=0.9,
                        label=f"{axis} smoothed")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=7, ncol=3)
    axes[-1].set_xlabel("time since start, s")
    return _save(fig, path, plt)


def plot_biases(result, path):
    """Gyro (deg/h) and accelerometer (mGal) bias estimates, forward and smoothed."""
    plt = _pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    t = result.node_time - result.node_time[0]
    for ax, sl, scale, label in ((axes[0], slice(0, 3), 3600 * 180 / np.pi, "gyro bias deg/h"),
                                 (axes[1], slice(3, 6), 1e5, "accel bias mGal")):
        for k, axis in enumerate("xyz"):
            ax.plot(t, scale * result.forward_sensors[:, sl][:, k], f"C{k}--", lw=0.7,
                    label=f"{axis} forward")
            ax.plot(t, scale * result.smoothed_sensors[:, sl][:, k], f"C{k}", lw=0.9,
                    label=f"{axis} smoothed")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, ncol=3)
    axes[-1].set_xlabel("time since start, s")
    return _save(fig, path, plt)


def write_plots(result, out_dir):
    """Write the PNG plots into ``out_dir``; returns their paths."""
    paths = [plot_sigma(result, os.path.join(out_dir, "sigma.png")),
             plot_biases(result, os.path.join(out_dir, "biases.png"))]
    if result.errors_smoothed is not None:
        paths.append(plot_errors(result, os.path.join(out_dir, "errors.png")))
    return paths
