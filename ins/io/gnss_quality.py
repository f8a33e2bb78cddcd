"""Solution quality flags of a GNSS log (RTKLIB's Q: 1 fix, 2 float, 3 SBAS, 4 DGPS,
5 single, 6 PPP): which qualities a run keeps and a factor on the sigmas of each."""
from dataclasses import replace

import numpy as np

from ins.common.errors import InputError

__all__ = ["QUALITY", "QUALITY_NAME", "apply_quality", "parse_quality", "parse_quality_scale"]

#: RTKLIB's Q values by name.
QUALITY = {"fix": 1, "float": 2, "sbas": 3, "dgps": 4, "single": 5, "ppp": 6}
#: RTKLIB's Q names by value.
QUALITY_NAME = {v: k for k, v in QUALITY.items()}


def parse_quality(text, where="--gnss-quality"):
    """Q values kept, from ``"fix,float"`` or a list of names / numbers (set of int)."""
    items = text.split(",") if isinstance(text, str) else list(text)
    out = set()
    for item in items:
        key = str(item).strip().lower()
        if key in QUALITY:
            out.add(QUALITY[key])
        elif key.isdigit() and int(key) in QUALITY_NAME:
            out.add(int(key))
        else:
            raise InputError(f"{where}: unknown quality {item!r}; expected names of "
                             f"{', '.join(QUALITY)} (or Q numbers 1..6), comma-separated")
    if not out:
        raise InputError(f"{where}: no quality given")
    return out


def parse_quality_scale(value, where="--gnss-quality-scale"):
    """Sigma factors per Q from ``"float=3,single=10"`` or a dict (Q -> factor)."""
    if isinstance(value, str):
        pairs = []
        for item in value.split(","):
            if "=" not in item:
                raise InputError(f"{where}: expected name=factor pairs like float=3,single=10, "
                                 f"got {item!r}")
            k, v = item.split("=", 1)
            pairs.append((k, v))
    else:
        pairs = list(dict(value).items())
    out = {}
    for k, v in pairs:
        q = parse_quality([k], where).pop()
        try:
            f = float(v)
        except (TypeError, ValueError):
            raise InputError(f"{where}: factor {v!r} of {k!r} is not a number") from None
        if not np.isfinite(f) or f <= 0:
            raise InputError(f"{where}: factor {v!r} of {k!r} must be > 0")
        out[q] = f
    return out


def apply_quality(log, quality=None, quality_scale=None):
    """The records of ``log`` whose Q is in ``quality`` (names or numbers; ``None``: all),
    with the standard deviations of each Q multiplied by ``quality_scale[Q]``.

    Raises
    ------
    InputError
        When no record is left (naming the file and the Q values found).
    """
    if quality is None and not quality_scale:
        return log
    if log.quality is None:
        raise InputError("a GNSS quality policy needs quality flags (RTKLIB Q)", path=log.path)
    if quality is not None:
        keep_q = quality if isinstance(quality, set) else parse_quality(quality)
        keep = np.isin(log.quality, sorted(keep_q))
        if not keep.any():
            found = sorted({QUALITY_NAME[int(q)] for q in np.unique(log.quality)})
            raise InputError(f"no epoch left with quality {', '.join(QUALITY_NAME[q] for q in sorted(keep_q))} "
                             f"(the file has {', '.join(found)})", path=log.path)
        log = log.select(keep)
    if quality_scale:
        scale = quality_scale if all(isinstance(k, int) for k in quality_scale) \
            else parse_quality_scale(quality_scale)
        f = np.ones(len(log))
        for q, factor in scale.items():
            f[log.quality == q] = factor
        cov = None if log.cov_ned_m2 is None else log.cov_ned_m2 * (f ** 2)[:, None, None]
        log = replace(log, sigma_ned_m=log.sigma_ned_m * f[:, None], cov_ned_m2=cov)
    return log
