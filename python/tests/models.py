"""Generated inputs shared by the Ray test and bench.py."""

import numpy as np


def transformed_bpt(text, rng):
    """The .bpt patches of `text` scaled, rotated about z and moved: the same model elsewhere."""
    angle, scale = rng.uniform(0, 2 * np.pi), 2.0 ** rng.randint(-4, 6)
    c, s = np.cos(angle), np.sin(angle)
    shift = np.array([rng.uniform(-1e4, 1e4) for _ in range(3)])
    out = []
    for line in text.splitlines():
        fields = line.split()
        if len(fields) == 3:
            x, y, z = map(float, fields)
            p = scale * np.array([c * x - s * y, s * x + c * y, z]) + shift
            out.append("%.17g %.17g %.17g" % tuple(p))
        else:
            out.append(line)
    return "\n".join(out) + "\n"
