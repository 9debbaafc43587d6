"""wavetomo/layout.py: the slope and command orderings (docs/formats.md, "Layout"), the same object from the
library (System.layout) and from any output file's "layout" group (Result.layout)."""
import dataclasses
import math
from typing import List, Tuple

import numpy as np

__all__ = ["ARCSEC", "Sensor", "DM", "Layout"]

_Slice = slice  # the built-in, by a name the properties called slice do not hide

ARCSEC = math.pi / (180.0 * 3600.0)  # radians per arcsecond (the library's WT_ARCSEC)


@dataclasses.dataclass
class Sensor:
    """A wavefront sensor and its block of a slope vector s[offset : offset + 2 nsub] =
    [s_x of every valid subaperture..., s_y...] [rad]."""
    name: str            # "LGS1", ..., "NGS1", ...
    kind: str            # "LGS" or "NGS"
    nsub: int            # valid subapertures
    offset: int          # index of its first slope
    theta_x: float       # direction on the sky [rad]
    theta_y: float
    altitude: float      # source altitude [m]; 0: at infinity (NGS)
    subapertures: np.ndarray  # (nsub, 2) centres (x, y) in the pupil [m], in slope order

    @property
    def nslopes(self) -> int:
        return 2 * self.nsub

    @property
    def slice(self) -> _Slice:
        """The sensor's slopes in a slope vector: s[sensor.slice]."""
        return slice(self.offset, self.offset + 2 * self.nsub)

    def split(self, slopes: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """(s_x, s_y) of this sensor from a slope vector (or frames x slopes): views, nsub values each."""
        s = np.asarray(slopes)[..., self.slice]
        return s[..., :self.nsub], s[..., self.nsub:]


@dataclasses.dataclass
class DM:
    """A deformable mirror and its block of a command vector a[offset : offset + nactive] [m]."""
    altitude: float      # conjugation altitude [m]
    pitch: float         # actuator spacing [m]
    nactive: int         # active actuators (its commands)
    offset: int          # index of its first command
    nx: int              # its actuator grid
    ny: int
    x0: float            # position of grid point (0, 0) [m]
    y0: float

    @property
    def slice(self) -> _Slice:
        return slice(self.offset, self.offset + self.nactive)


@dataclasses.dataclass
class Layout:
    """The orderings of a system's slope and command vectors."""
    sensors: List[Sensor]         # in slope order (the LGS first)
    actuator_index: np.ndarray    # (nact, 3) int32: DM (0-based), column ix, row iy of each command
    actuator_position: np.ndarray  # (nact, 2) float64 [m]: (x, y) in its DM's conjugate plane

    @property
    def nslopes(self) -> int:
        return sum(s.nslopes for s in self.sensors)

    @property
    def nactuators(self) -> int:
        return len(self.actuator_index)

    def sensor(self, name: str) -> Sensor:
        for s in self.sensors:
            if s.name == name:
                return s
        raise KeyError("no sensor %r (the sensors are %s)" % (name, ", ".join(s.name for s in self.sensors)))
