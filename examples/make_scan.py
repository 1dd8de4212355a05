"""Write examples/scan/upper_arm.stl: a SYNTHETIC 3D scan of an upper arm (fixed parameters).

The limb is an elliptic cylinder that tapers toward the elbow, with a slight biceps bulge,
260 mm long, closed at both ends, as a binary STL in millimetres in a scanner's frame: the arm
hangs down (the scanner's -Z) tilted forward and outward, its shoulder end around
(250, -120, 1100) mm. The cuff frame on it (docs/scans.md) is

    geometry:
      scan:
        file: ../examples/scan/upper_arm.stl     # relative to the config file
        unit: mm
        origin: [262.687, -94.627, 973.133]      # on the axis, 130 mm from the shoulder end
        axis: [0.1, 0.2, -1.0]
        y_axis: [1.0, 0.0, 0.0]

(the script prints it too). On the paper's layout (rows at -25, 0, 25 mm, 25 mm wide; seven
locations from 75 degrees, 35 apart) the elements' normals carry the 4-degree taper.
Only numpy is needed. Run from the repository root:

    python examples/make_scan.py
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent

LENGTH = 0.260            # m, shoulder end to elbow end
A0, B0 = 0.050, 0.042     # m, semi-axes at the cuff's middle (x = 0)
TAPER_DEG = 4.0           # both semi-axes shrink by tan(4 deg) per metre toward the elbow (+x)
ROTATION_DEG = 15.0       # the ellipse's a-axis, turned from +y toward +z
BULGE = 0.004             # m, the biceps: a bump on the +y side around x = 0.01 m
AROUND, RINGS = 144, 53   # facets around, rings along (5 mm apart)
#: the scanner's frame: the cuff's +x (toward the elbow) and a direction for +y, and where the
#: cuff's origin is [mm]
AXIS = np.array([0.1, 0.2, -1.0])
Y_HINT = np.array([1.0, 0.0, 0.0])
SHOULDER_END_MM = np.array([250.0, -120.0, 1100.0])


def cuff_frame():
    """Rows: the cuff's unit +x, +y, +z in the scanner's frame."""
    ex = AXIS / np.linalg.norm(AXIS)
    ey = Y_HINT - (Y_HINT @ ex) * ex
    ey /= np.linalg.norm(ey)
    return np.vstack([ex, ey, np.cross(ex, ey)])


def origin_mm() -> np.ndarray:
    """The cuff frame's origin in the scanner's frame [mm]: on the axis, mid-length."""
    return SHOULDER_END_MM + 1000 * LENGTH / 2 * cuff_frame()[0]


def limb_mesh():
    """Vertices [m] in the cuff frame and triangles of the closed limb surface."""
    xs = np.linspace(-LENGTH / 2, LENGTH / 2, RINGS)
    u = 2 * np.pi * np.arange(AROUND) / AROUND
    shrink = xs * np.tan(np.radians(TAPER_DEG))
    a, b = A0 - shrink, B0 - shrink
    along = np.exp(-((xs - 0.01) / 0.05) ** 2)
    bump = BULGE * along[:, None] * np.maximum(np.cos(u), 0)[None, :] ** 2
    yp = (a[:, None] + bump) * np.cos(u)[None, :]
    zp = b[:, None] * np.sin(u)[None, :]
    phi = np.radians(ROTATION_DEG)
    y = np.cos(phi) * yp - np.sin(phi) * zp
    z = np.sin(phi) * yp + np.cos(phi) * zp
    ring = np.stack([np.broadcast_to(xs[:, None], y.shape), y, z], axis=-1).reshape(-1, 3)
    centres = np.array([[xs[0], 0.0, 0.0], [xs[-1], 0.0, 0.0]])
    vertices = np.vstack([ring, centres])
    i = np.arange(AROUND)
    j = (i + 1) % AROUND
    faces = []
    for r in range(RINGS - 1):
        p, q = r * AROUND + i, r * AROUND + j
        faces += [np.column_stack([p, q, q + AROUND]), np.column_stack([p, q + AROUND, p + AROUND])]
    first, last = len(ring), len(ring) + 1
    faces.append(np.column_stack([np.full(AROUND, first), j, i]))           # shoulder cap
    top = (RINGS - 1) * AROUND
    faces.append(np.column_stack([np.full(AROUND, last), top + i, top + j]))  # elbow cap
    return vertices, np.vstack(faces)


def write_binary_stl(path: Path, vertices: np.ndarray, faces: np.ndarray, header: str) -> None:
    tri = vertices[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    rec = np.zeros(len(faces), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["n"], rec["v"] = normal, tri
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as fh:
        fh.write(header.encode("ascii").ljust(80, b" ")[:80] + struct.pack("<I", len(faces)))
        fh.write(rec.tobytes())


def write_scan(path: Path) -> None:
    """The synthetic scan, in mm in the scanner's frame, as a binary STL at ``path``."""
    vertices, faces = limb_mesh()
    scanner = 1000 * vertices @ cuff_frame() + origin_mm()
    write_binary_stl(path, scanner, faces, "SYNTHETIC upper arm, examples/make_scan.py, mm")


def main() -> None:
    out = HERE / "scan" / "upper_arm.stl"
    write_scan(out)
    print(f"wrote {out} ({out.stat().st_size / 1e3:.0f} kB); geometry.scan: unit: mm, "
          f"origin: {np.round(origin_mm(), 3).tolist()}, axis: {AXIS.tolist()}, "
          f"y_axis: {Y_HINT.tolist()}")


if __name__ == "__main__":
    main()
