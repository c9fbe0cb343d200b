"""Seal friction measured on a cylinder: which friction law the data need.

``read_friction_test`` reads one friction file (the TU Delft 2021 format:
time, piston position, chamber gauge pressure, rod force); the laws in
``laws`` (the nominal Stribeck law with one level per direction, and the
pressure-dependent law of the effect ``pressure_dependent_friction``) are
fitted and compared on pressures the fit never saw by ``FrictionStudy``.
"""

from .data import FrictionTest, read_friction_test
from .laws import NOMINAL_LAW, PRESSURE_LAW, FrictionLaw
from .study import FrictionStudy

__all__ = ["FrictionTest", "read_friction_test", "FrictionLaw", "NOMINAL_LAW", "PRESSURE_LAW", "FrictionStudy"]
