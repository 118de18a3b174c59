#!/usr/bin/env python3
"""knotwork against Open CASCADE on the same IGES and STEP files, at the same tolerance.

For each file: Open CASCADE reads it (IGESControl_Reader with blanked entities, or
STEPControl_Reader; all roots), meshes it with
BRepMesh_IncrementalMesh at linear deflection T (angular 0.5 rad, in parallel) and gives the
exact area of its faces and volume of its solids (BRepGProp); knotwork tessellates it with
`--tolerance T --backend cpu` to OBJ. Both meshes' areas and enclosed volumes are compared
with the exact ones (volumes only where the file has solids). T is REL times the diagonal of Open CASCADE's
bounding box of the shape. Prints one Markdown table row per file: faces meshed, triangles,
mesh area against the exact one, and seconds to read and mesh (knotwork's includes writing
the OBJ file; Open CASCADE's is in-process, after Python's start): the median of RUNS runs
of each, alternating (5 unless the environment variable RUNS says otherwise), as single
runs on a shared machine vary by a tenth and more.

Open CASCADE comes from PyPI (`pip install cadquery-ocp`); it is a comparison tool only,
never a dependency of the crate.

Usage: tools/compare_occt.py KNOTWORK_BINARY REL FILE...
"""

import math
import os
import statistics
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from OCP.Bnd import Bnd_Box
from OCP.BRep import BRep_Tool
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepGProp import BRepGProp
from OCP.BRepMesh import BRepMesh_IncrementalMesh
from OCP.GProp import GProp_GProps
from OCP.IFSelect import IFSelect_RetDone
from OCP.IGESControl import IGESControl_Reader
from OCP.STEPControl import STEPControl_Reader
from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED, TopAbs_SOLID
from OCP.TopExp import TopExp_Explorer
from OCP.TopLoc import TopLoc_Location
from OCP.TopoDS import TopoDS


def occt(path, rel):
    """Faces, meshed faces, triangles, mesh area, exact area, mesh volume, exact volume
    (None without solids), seconds, tolerance."""
    start = time.perf_counter()
    step = Path(path).suffix.lower() in (".stp", ".step")
    reader = STEPControl_Reader() if step else IGESControl_Reader()
    if reader.ReadFile(str(path)) != IFSelect_RetDone:
        raise RuntimeError(f"Open CASCADE cannot read {path}")
    if not step:
        # Blanked entities too (the faces of a trimmed model are often blanked).
        reader.SetReadVisible(False)
    reader.TransferRoots()
    shape = reader.OneShape()
    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box)
    if box.IsVoid():
        return None
    low, high = box.CornerMin(), box.CornerMax()
    tolerance = rel * low.Distance(high)
    BRepMesh_IncrementalMesh(shape, tolerance, False, 0.5, True)
    seconds = time.perf_counter() - start
    faces = meshed = triangles = 0
    area = volume = 0.0
    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        face = TopoDS.Face(explorer.Current())
        faces += 1
        location = TopLoc_Location()
        mesh = BRep_Tool.Triangulation_s(face, location)
        if mesh is not None and mesh.NbTriangles() > 0:
            meshed += 1
            transform = location.Transformation()
            for k in range(1, mesh.NbTriangles() + 1):
                a, b, c = mesh.Triangle(k).Get()
                p = [mesh.Node(i).Transformed(transform) for i in (a, b, c)]
                if face.Orientation() == TopAbs_REVERSED:
                    p = [p[0], p[2], p[1]]
                volume += (
                    p[0].X() * (p[1].Y() * p[2].Z() - p[1].Z() * p[2].Y())
                    + p[0].Y() * (p[1].Z() * p[2].X() - p[1].X() * p[2].Z())
                    + p[0].Z() * (p[1].X() * p[2].Y() - p[1].Y() * p[2].X())
                ) / 6.0
                u = [p[1].X() - p[0].X(), p[1].Y() - p[0].Y(), p[1].Z() - p[0].Z()]
                v = [p[2].X() - p[0].X(), p[2].Y() - p[0].Y(), p[2].Z() - p[0].Z()]
                area += 0.5 * math.hypot(
                    u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]
                )
            triangles += mesh.NbTriangles()
        explorer.Next()
    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(shape, props)
    exact_volume = None
    if TopExp_Explorer(shape, TopAbs_SOLID).More():
        solid = GProp_GProps()
        BRepGProp.VolumeProperties_s(shape, solid)
        exact_volume = solid.Mass()
    return (faces, meshed, triangles, area, props.Mass(), volume, exact_volume, seconds,
            tolerance)


def obj_area(path):
    """Triangles, area and enclosed volume of an OBJ mesh."""
    points, area, volume, triangles = [], 0.0, 0.0, 0
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                points.append(tuple(map(float, line.split()[1:4])))
            elif line.startswith("f "):
                a, b, c = (points[int(t.split("/")[0]) - 1] for t in line.split()[1:4])
                u = [b[k] - a[k] for k in range(3)]
                v = [c[k] - a[k] for k in range(3)]
                area += 0.5 * math.hypot(
                    u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]
                )
                volume += (
                    a[0] * (b[1] * c[2] - b[2] * c[1])
                    + a[1] * (b[2] * c[0] - b[0] * c[2])
                    + a[2] * (b[0] * c[1] - b[1] * c[0])
                ) / 6.0
                triangles += 1
    return triangles, area, volume


def knotwork(binary, path, tolerance):
    """Items, faces left out, triangles, area, volume, seconds (knotwork's own figure)."""
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "mesh.obj"
        run = subprocess.run(
            [binary, "tessellate", str(path), "-o", str(out), "--backend", "cpu",
             "--tolerance", repr(tolerance)],
            capture_output=True, text=True,
        )
        # "N surfaces", "N solids", "N open shells", or a list of them ("1 solid, 2 open
        # shells (9 faces)").
        summary = re.search(
            r": ((?:\d+ (?:surfaces?|solids?|open shells?)(?:, )?)+).* in ([0-9.]+) s",
            run.stdout,
        )
        if summary is None:
            raise RuntimeError(f"knotwork failed on {path}: {run.stderr}")
        items = sum(int(n) for n in re.findall(r"\d+", summary.group(1)))
        triangles, area, volume = obj_area(out)
        dropped = [l for l in run.stderr.splitlines() if l.startswith("error:")]
        return (items, len(dropped), triangles, area, volume, float(summary.group(2)))


def main():
    binary, rel, files = sys.argv[1], float(sys.argv[2]), sys.argv[3:]
    print(f"At tolerance {rel:g} of the diagonal (Open CASCADE {__import__('OCP').__version__}"
          " via cadquery-ocp; deflection = tolerance, angular 0.5 rad):\n")
    print("| file | faces meshed (knotwork / OCCT) | triangles knotwork | triangles OCCT | "
          "area error knotwork | area error OCCT | volume error knotwork | volume error OCCT | "
          "seconds knotwork | seconds OCCT |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    runs = int(os.environ.get("RUNS", "5"))
    for path in files:
        measured = occt(path, rel)
        if measured is None:
            print(f"| {Path(path).name} | Open CASCADE transfers no shape | | | | | | |")
            continue
        (faces, meshed, occ_triangles, occ_area, exact, occ_volume, exact_volume, occ_seconds,
         tolerance) = measured
        items, dropped, triangles, area, volume, seconds = knotwork(binary, path, tolerance)
        occ_times, times = [occ_seconds], [seconds]
        for _ in range(runs - 1):
            occ_times.append(occt(path, rel)[7])
            times.append(knotwork(binary, path, tolerance)[5])
        occ_seconds, seconds = statistics.median(occ_times), statistics.median(times)
        # A STEP item is a shell: count faces, of which `dropped` were left out.
        step = Path(path).suffix.lower() in (".stp", ".step")
        total = faces if step else items
        def error(value, exact_value):
            return "" if exact_value is None else f"{(value - exact_value) / exact_value:+.2e}"
        print(
            f"| {Path(path).name} | {total - dropped}/{total} / {meshed}/{faces} | {triangles} | "
            f"{occ_triangles} | {error(area, exact)} | {error(occ_area, exact)} | "
            f"{error(volume, exact_volume)} | {error(occ_volume, exact_volume)} | "
            f"{seconds:.3f} | {occ_seconds:.3f} |"
        )


if __name__ == "__main__":
    main()
