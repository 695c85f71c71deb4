"""Named unit conversions. SI inside the code; degrees only at the boundary (scenario files, display)."""

import math

DEG = math.pi / 180.0
"""One degree in radians."""

RPM = 2.0 * math.pi / 60.0
"""One revolution per minute in rad/s."""
