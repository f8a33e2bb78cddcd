"""The complete flight folder of ``ins simulate``: the INS products of
:mod:`ins.simulate` with the image products of :mod:`photogrammetry.simulate.images`.

The simulator is split along the layering of the packages: ``ins.simulate`` (plan,
truth, IMU synthesis, sensor errors, GNSS, mount, manifest) knows nothing of cameras;
the parts that need the camera model (exposures, true EO, terrain, tie points, the
camera file) live here, in the package that may depend on both.  This module composes
them: :func:`simulate_flight` is :func:`ins.simulate.folder.simulate_flight` with the
product writer :func:`photogrammetry.simulate.images.write_images`, and writes the folder
of ``docs/interfaces.md`` (byte for byte what the simulator wrote before the split).
"""
from ins.simulate import folder as ins_folder
from photogrammetry.simulate import images

__all__ = ["FILES", "simulate_flight"]

#: Manifest ``[files]`` key -> file name of every product (``mount`` only with the mount
#: enabled).
FILES = {**ins_folder.FILES, **images.FILES}


def simulate_flight(plan, out_dir, seed, grade=None, force=False, progress=None,
                    gnss_raw_nav=None):
    """Simulate a survey flight and write its folder (``docs/interfaces.md``): truth, IMU
    with sensor errors, GNSS antenna log, mount angles, exposures, true EO, terrain and
    tie points, and ``manifest.toml``.

    The parameters, return value and errors are those of
    :func:`ins.simulate.folder.simulate_flight` (without ``products``; ``gnss_raw_nav``
    adds the raw GPS observations of :mod:`ins.simulate.gnss_raw_product`): the folder is
    built aside and swapped into place whole; the same plan and seed give the same bytes.
    """
    return ins_folder.simulate_flight(plan, out_dir, seed, grade=grade, force=force,
                                      progress=progress, products=(images.write_images,),
                                      gnss_raw_nav=gnss_raw_nav)
