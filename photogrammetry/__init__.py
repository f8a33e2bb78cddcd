"""Photogrammetric orientation: exterior orientation from an INS solution, coplanarity
adjustment of exposure angles, lunar heading.  (Grows in later issues.)"""

__version__ = "0.1.0"
