"""A smooth, seeded terrain surface ``Z(X, Y)`` in the mapping frame of a simulated block.

The mapping frame ``m`` is the local tangent plane ENU at the block origin
(``docs/interfaces.md``): ``X`` east, ``Y`` north, ``Z`` up, in m, with ``Z = 0`` at the
origin's ellipsoidal height (the plan's ``[block] origin_h_m``, the block's mean ground).
The surface is a sum of a few plane waves (cosines) with random directions, wavelengths
around ``wavelength_m`` and phases; the amplitudes add up to ``relief_m``, so
``|Z| <= relief_m`` everywhere.  It is infinitely smooth, cheap to evaluate and exactly
reproducible from its generator.
"""
from dataclasses import dataclass

import numpy as np

__all__ = ["Terrain", "make_terrain"]


@dataclass(frozen=True)
class Terrain:
    """``Z(X, Y) = sum_k a_k cos(k_k . (X, Y) + phase_k)`` in the mapping frame.

    Attributes
    ----------
    amplitudes_m : ndarray, shape (K,)
        Amplitudes, m (their sum is the relief).
    wave_vectors : ndarray, shape (K, 2)
        Wave vectors (east, north components), rad/m.
    phases : ndarray, shape (K,)
        Phases, rad.
    """

    amplitudes_m: np.ndarray
    wave_vectors: np.ndarray
    phases: np.ndarray

    @property
    def relief_m(self):
        """Bound of ``|Z|``, m."""
        return float(np.sum(np.abs(self.amplitudes_m)))

    def height(self, X, Y):
        """Terrain height ``Z`` (m, up) at mapping-frame ``X`` (east) and ``Y`` (north), m.

        ``X`` and ``Y`` broadcast against each other; the result has their shape.
        """
        X, Y = np.broadcast_arrays(np.asarray(X, float), np.asarray(Y, float))
        arg = (X[..., None] * self.wave_vectors[:, 0] + Y[..., None] * self.wave_vectors[:, 1]
               + self.phases)
        return np.cos(arg) @ self.amplitudes_m


def make_terrain(relief_m, wavelength_m, rng, n_waves=6):
    """A random smooth terrain.

    Parameters
    ----------
    relief_m : float
        Bound of ``|Z|``, m (0 gives a flat plane at ``Z = 0``).
    wavelength_m : float
        Typical horizontal wavelength of the relief, m (each wave draws its wavelength
        uniformly in ``[0.5, 1.5] * wavelength_m``).
    rng : numpy.random.Generator
        Source of the directions, wavelengths, phases and amplitude shares.
    n_waves : int
        Number of plane waves.

    Returns
    -------
    Terrain
    """
    if not relief_m >= 0 or not wavelength_m > 0:
        raise ValueError(f"relief_m must be >= 0 and wavelength_m > 0 (m), got "
                         f"{relief_m!r}, {wavelength_m!r}")
    direction = rng.uniform(0.0, 2.0 * np.pi, n_waves)
    wavelength = wavelength_m * rng.uniform(0.5, 1.5, n_waves)
    phases = rng.uniform(0.0, 2.0 * np.pi, n_waves)
    share = rng.uniform(0.5, 1.5, n_waves)
    k = 2.0 * np.pi / wavelength
    return Terrain(amplitudes_m=relief_m * share / share.sum(),
                   wave_vectors=np.column_stack([k * np.cos(direction), k * np.sin(direction)]),
                   phases=phases)
