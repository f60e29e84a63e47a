#!/usr/bin/python3
"""Writes the six-arm gripper of assets/scenes/mpm_gripper.yaml as closed ASCII STL prisms (mm): a hexagonal
centre plate and six arms, one file each so each part carries its own magnetisation (after Xu et al.'s gripper in
thesis 3.6.5, thickened to 0.5 mm and scaled to a 14 mm span).

    tools/make_gripper_meshes.py assets/meshes
"""
import math
import pathlib
import sys

THICKNESS = 0.5   # mm
CENTRE_R = 2.0    # circumradius of the hexagon, mm
ARM_LENGTH = 5.0  # beyond the hexagon's edge, mm
ARM_WIDTH = 1.2   # mm


def prism(polygon, z0, z1):
    """Triangles of a closed prism over a convex polygon (counter-clockwise seen from +z)."""
    n = len(polygon)
    tris = []
    for i in range(1, n - 1):  # bottom (outward -z: clockwise) and top
        tris.append(((*polygon[0], z0), (*polygon[i + 1], z0), (*polygon[i], z0)))
        tris.append(((*polygon[0], z1), (*polygon[i], z1), (*polygon[i + 1], z1)))
    for i in range(n):
        a, b = polygon[i], polygon[(i + 1) % n]
        tris.append(((*a, z0), (*b, z0), (*b, z1)))
        tris.append(((*a, z0), (*b, z1), (*a, z1)))
    return tris


def write_stl(path, name, tris):
    with open(path, "w") as f:
        f.write(f"solid {name}\n")
        for t in tris:
            u = [t[1][k] - t[0][k] for k in range(3)]
            v = [t[2][k] - t[0][k] for k in range(3)]
            n = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
            length = math.sqrt(sum(c * c for c in n)) or 1.0
            f.write(f"  facet normal {n[0]/length:.6f} {n[1]/length:.6f} {n[2]/length:.6f}\n    outer loop\n")
            for p in t:
                f.write(f"      vertex {p[0]:.6f} {p[1]:.6f} {p[2]:.6f}\n")
            f.write("    endloop\n  endfacet\n")
        f.write(f"endsolid {name}\n")


def main():
    out = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "assets/meshes")
    out.mkdir(parents=True, exist_ok=True)
    hexagon = [(CENTRE_R * math.cos(math.radians(60 * k)), CENTRE_R * math.sin(math.radians(60 * k))) for k in range(6)]
    write_stl(out / "gripper_centre.stl", "centre", prism(hexagon, 0.0, THICKNESS))
    apothem = CENTRE_R * math.cos(math.radians(30))
    for k in range(6):  # arm k points along the normal of the hexagon's edge k (angle 30 + 60k degrees)
        a = math.radians(30 + 60 * k)
        r, t = (math.cos(a), math.sin(a)), (-math.sin(a), math.cos(a))
        w = ARM_WIDTH / 2
        pts = [(apothem * r[0] + s * w * t[0] + d * r[0], apothem * r[1] + s * w * t[1] + d * r[1])
               for s, d in ((-1, 0.0), (-1, ARM_LENGTH), (1, ARM_LENGTH), (1, 0.0))]
        # counter-clockwise order: start at (-w, 0), go out, across, back
        write_stl(out / f"gripper_arm{k + 1}.stl", f"arm{k + 1}", prism(pts, 0.0, THICKNESS))


if __name__ == "__main__":
    main()
