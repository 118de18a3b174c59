#!/usr/bin/env python3
"""knotwork's adaptive tessellation against the coarsest uniform grid and Open CASCADE.

For each file (.bpt, or OBJ free-form B-spline surfaces) and each REL: T = REL × the
diagonal of the box of all control points (what knotwork's --tolerance-rel takes). Three
meshes of the same surfaces:

- knotwork `--tolerance T --backend cpu` to OBJ (triangles; seconds: knotwork's summary —
  read, plan, evaluate, write);
- knotwork's coarsest uniform grid n × n per patch (the same n for every patch, found by
  bisection) whose measured deviation is within T;
- Open CASCADE: every patch a Geom_BSplineSurface face, BRepMesh_IncrementalMesh at linear
  deflection T (angular 0.5 rad, in parallel; seconds: the meshing call).

The deviation of every mesh is measured by the same code: points of the true surface at
random parameters (Open CASCADE's evaluation of the same patches, uniform in each patch's
parameter range, POINTS_PER_PATCH of them), each point's exact distance to the nearest
triangle of the mesh (any patch's). Prints one Markdown table row per file and REL.

Needs numpy, scipy and cadquery-ocp (`pip install scipy cadquery-ocp`); Open CASCADE is a
comparison tool only, never a dependency of the crate.

Usage: tools/compare_adaptive.py KNOTWORK_BINARY FILE... [--rel 1e-2,1e-3,1e-4]
"""

import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
from OCP.BRepMesh import BRepMesh_IncrementalMesh
from OCP.Geom import Geom_BSplineSurface
from OCP.OCP.collections import Array1_double, Array1_int, Array2_double, Array2_gp_Pnt
from OCP.TopAbs import TopAbs_FACE
from OCP.TopExp import TopExp_Explorer
from OCP.TopLoc import TopLoc_Location
from OCP.TopoDS import TopoDS, TopoDS_Compound
from OCP.gp import gp_Pnt

POINTS_PER_PATCH = 4000
NEAREST_VERTICES = 8
SEED = 20261203


class Patch:
    """A B-spline patch: degrees, knots (full vectors), points[j][i] (u fastest), weights
    (or None) and its parameter range."""

    def __init__(self, du, dv, ku, kv, points, weights, range_u, range_v):
        self.du, self.dv, self.ku, self.kv = du, dv, ku, kv
        self.points, self.weights = points, weights
        self.range_u, self.range_v = range_u, range_v


def read_bpt(path):
    numbers = Path(path).read_text().split()
    count, at, patches = int(numbers[0]), 1, []
    for _ in range(count):
        du, dv = int(numbers[at]), int(numbers[at + 1])
        at += 2
        n = (du + 1) * (dv + 1)
        flat = [tuple(map(float, numbers[at + 3 * k: at + 3 * k + 3])) for k in range(n)]
        at += 3 * n
        # .bpt lists each u row's v points: point (i, j) at i * (dv + 1) + j.
        points = [[flat[i * (dv + 1) + j] for i in range(du + 1)] for j in range(dv + 1)]
        patches.append(Patch(du, dv, [0.0] * (du + 1) + [1.0] * (du + 1),
                             [0.0] * (dv + 1) + [1.0] * (dv + 1), points, None,
                             (0.0, 1.0), (0.0, 1.0)))
    return patches


def read_obj(path):
    lines, joined = Path(path).read_text().splitlines(), []
    for line in lines:
        if joined and joined[-1].endswith("\\"):
            joined[-1] = joined[-1][:-1] + " " + line
        else:
            joined.append(line)
    vertices, patches, state = [], [], {}
    for line in joined:
        words = line.split()
        if not words:
            continue
        if words[0] == "v":
            values = list(map(float, words[1:]))
            vertices.append((values[:3], values[3] if len(values) > 3 else 1.0))
        elif words[0] == "cstype":
            state = {"rational": words[1] == "rat"}
        elif words[0] == "deg":
            state["deg"] = (int(words[1]), int(words[2]))
        elif words[0] == "surf":
            state["range"] = tuple(map(float, words[1:5]))
            state["indices"] = [int(w.split("/")[0]) for w in words[5:]]
        elif words[0] == "parm":
            state[words[1]] = list(map(float, words[2:]))
        elif words[0] == "end":
            du, dv = state["deg"]
            ku, kv = state["u"], state["v"]
            nu, nv = len(ku) - du - 1, len(kv) - dv - 1
            indices = [k - 1 if k > 0 else len(vertices) + k for k in state["indices"]]
            cv = [vertices[k] for k in indices]
            points = [[tuple(cv[j * nu + i][0]) for i in range(nu)] for j in range(nv)]
            weights = ([[cv[j * nu + i][1] for i in range(nu)] for j in range(nv)]
                       if state["rational"] else None)
            u0, u1, v0, v1 = state["range"]
            patches.append(Patch(du, dv, ku, kv, points, weights, (u0, u1), (v0, v1)))
    return patches


def occt_surface(patch):
    def knots(full):
        values, counts = [], []
        for k in full:
            if values and abs(k - values[-1]) <= 1e-12 * max(1.0, abs(k)):
                counts[-1] += 1
            else:
                values.append(k)
                counts.append(1)
        a, m = Array1_double(1, len(values)), Array1_int(1, len(values))
        for k, (value, count) in enumerate(zip(values, counts)):
            a.SetValue(k + 1, value)
            m.SetValue(k + 1, count)
        return a, m

    nv, nu = len(patch.points), len(patch.points[0])
    poles = Array2_gp_Pnt(1, nu, 1, nv)
    weights = Array2_double(1, nu, 1, nv)
    for j in range(nv):
        for i in range(nu):
            poles.SetValue(i + 1, j + 1, gp_Pnt(*patch.points[j][i]))
            weights.SetValue(i + 1, j + 1, patch.weights[j][i] if patch.weights else 1.0)
    (ku, mu), (kv, mv) = knots(patch.ku), knots(patch.kv)
    if patch.weights:
        return Geom_BSplineSurface(poles, weights, ku, kv, mu, mv, patch.du, patch.dv)
    return Geom_BSplineSurface(poles, ku, kv, mu, mv, patch.du, patch.dv)


def true_points(surfaces, patches):
    rng = np.random.default_rng(SEED)
    out = []
    for surface, patch in zip(surfaces, patches):
        us = rng.uniform(*patch.range_u, POINTS_PER_PATCH)
        vs = rng.uniform(*patch.range_v, POINTS_PER_PATCH)
        for u, v in zip(us, vs):
            p = surface.Value(float(u), float(v))
            out.append((p.X(), p.Y(), p.Z()))
    return np.array(out)


def closest_on_triangles(p, a, b, c):
    """Distances from points p (n, 3) to triangles (a, b, c) (n, m, 3 each): (n, m)."""
    p = p[:, None, :]
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    bp = p - b
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    cp = p - c
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v = np.where(denom != 0, vb / denom, 0.0)
        w = np.where(denom != 0, vc / denom, 0.0)
        q = a + ab * v[..., None] + ac * w[..., None]
        # Regions outside the face (Ericson, Real-Time Collision Detection 5.1.5).
        t_ab = np.clip(d1 / (d1 - d3), 0, 1)
        t_ac = np.clip(d2 / (d2 - d6), 0, 1)
        t_bc = np.clip((d4 - d3) / ((d4 - d3) + (d5 - d6)), 0, 1)
    on_ab = a + ab * np.nan_to_num(t_ab)[..., None]
    on_ac = a + ac * np.nan_to_num(t_ac)[..., None]
    on_bc = b + (c - b) * np.nan_to_num(t_bc)[..., None]
    q = np.where(((vc <= 0) & (d1 >= 0) & (d3 <= 0))[..., None], on_ab, q)
    q = np.where(((vb <= 0) & (d2 >= 0) & (d6 <= 0))[..., None], on_ac, q)
    q = np.where(((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0))[..., None], on_bc, q)
    q = np.where(((d1 <= 0) & (d2 <= 0))[..., None], a, q)
    q = np.where(((d3 >= 0) & (d4 <= d3))[..., None], b, q)
    q = np.where(((d6 >= 0) & (d5 <= d6))[..., None], c, q)
    return np.linalg.norm(p - q, axis=-1)


def deviation(points, positions, triangles):
    """The largest distance from `points` to the mesh, exactly: first an upper bound for
    every point (the triangles around its nearest vertices), then, from the largest bound
    down, the exact distance over every triangle whose centroid is near enough to matter,
    until no bound left exceeds the largest exact distance found."""
    tree = cKDTree(positions)
    around = [[] for _ in range(len(positions))]
    for t, tri in enumerate(triangles):
        for v in tri:
            around[v].append(t)
    corners = positions[triangles]
    centroids = corners.mean(axis=1)
    reach = float(np.linalg.norm(corners - centroids[:, None, :], axis=-1).max())
    centroid_tree = cKDTree(centroids)
    bounds = np.empty(len(points))
    for start in range(0, len(points), 20000):
        chunk = points[start:start + 20000]
        _, nearest = tree.query(chunk, NEAREST_VERTICES)
        candidates = [sorted({t for v in row for t in around[v]}) for row in nearest]
        width = max(len(c) for c in candidates)
        index = np.array([c + [c[0]] * (width - len(c)) for c in candidates])
        tri = corners[index]
        d = closest_on_triangles(chunk, tri[..., 0, :], tri[..., 1, :], tri[..., 2, :])
        bounds[start:start + len(chunk)] = d.min(axis=1)
    worst = 0.0
    for k in np.argsort(-bounds):
        if bounds[k] <= worst:
            break
        near = np.array(centroid_tree.query_ball_point(points[k], bounds[k] + reach))
        tri = corners[near][None]
        exact = closest_on_triangles(points[k][None], tri[..., 0, :], tri[..., 1, :],
                                     tri[..., 2, :]).min()
        worst = max(worst, float(exact))
    return worst


def read_mesh_obj(path):
    positions, faces = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                positions.append(tuple(map(float, line.split()[1:4])))
            elif line.startswith("f "):
                faces.append([int(t.split("/")[0]) - 1 for t in line.split()[1:4]])
    return np.array(positions), np.array(faces, dtype=np.int64)


def knotwork(binary, path, args):
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "mesh.obj"
        run = subprocess.run([binary, "tessellate", str(path), "-o", str(out), "--backend",
                              "cpu", *args], capture_output=True, text=True)
        summary = re.search(r" in ([0-9.]+) s", run.stdout)
        if run.returncode != 0 or summary is None:
            raise RuntimeError(f"knotwork failed on {path}: {run.stderr}")
        positions, triangles = read_mesh_obj(out)
        return positions, triangles, float(summary.group(1))


def occt(surfaces, tolerance):
    builder, compound = BRep_Builder(), TopoDS_Compound()
    builder.MakeCompound(compound)
    for surface in surfaces:
        u0, u1, v0, v1 = surface.Bounds()
        builder.Add(compound, BRepBuilderAPI_MakeFace(surface, u0, u1, v0, v1, 1e-9).Face())
    start = time.perf_counter()
    BRepMesh_IncrementalMesh(compound, tolerance, False, 0.5, True)
    seconds = time.perf_counter() - start
    positions, triangles = [], []
    explorer = TopExp_Explorer(compound, TopAbs_FACE)
    while explorer.More():
        face = TopoDS.Face(explorer.Current())
        location = TopLoc_Location()
        mesh = BRep_Tool.Triangulation_s(face, location)
        if mesh is not None:
            transform, base = location.Transformation(), len(positions)
            for k in range(1, mesh.NbNodes() + 1):
                p = mesh.Node(k).Transformed(transform)
                positions.append((p.X(), p.Y(), p.Z()))
            for k in range(1, mesh.NbTriangles() + 1):
                triangles.append([base + i - 1 for i in mesh.Triangle(k).Get()])
        explorer.Next()
    return np.array(positions), np.array(triangles, dtype=np.int64), seconds


def coarsest_grid(binary, path, points, tolerance):
    """The least n whose n × n grid per patch holds `tolerance` (measured), with its mesh."""
    def measure(n):
        positions, triangles, _ = knotwork(binary, path, ["--grid", f"{n}x{n}"])
        return deviation(points, positions, triangles), len(triangles)
    low, high = 2, 4
    while measure(high)[0] > tolerance:
        low, high = high, 2 * high
    while high - low > 1:
        middle = (low + high) // 2
        if measure(middle)[0] > tolerance:
            low = middle
        else:
            high = middle
    return high, measure(high)


def main():
    args, rels = sys.argv[1:], [1e-2, 1e-3, 1e-4]
    if "--rel" in args:
        at = args.index("--rel")
        rels = [float(r) for r in args[at + 1].split(",")]
        del args[at:at + 2]
    binary, files = args[0], args[1:]
    print(f"Open CASCADE {__import__('OCP').__version__} (cadquery-ocp): deflection = "
          "tolerance, angular 0.5 rad, parallel. Deviation: largest distance from "
          f"{POINTS_PER_PATCH} random true-surface points per patch to the mesh.\n")
    print("| file | REL | tolerance | knotwork triangles (deviation) | seconds | uniform grid "
          "| triangles (deviation) | OCCT triangles (deviation) | seconds | knotwork / OCCT |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for path in files:
        patches = read_bpt(path) if path.endswith(".bpt") else read_obj(path)
        corners = np.array([p for patch in patches for row in patch.points for p in row])
        diagonal = float(np.linalg.norm(corners.max(0) - corners.min(0)))
        surfaces = [occt_surface(p) for p in patches]
        points = true_points(surfaces, patches)
        for rel in rels:
            tolerance = rel * diagonal
            positions, triangles, seconds = knotwork(binary, path,
                                                     ["--tolerance", repr(tolerance)])
            ours = deviation(points, positions, triangles)
            n, (grid_deviation, grid_triangles) = coarsest_grid(binary, path, points, tolerance)
            occ_positions, occ_triangles, occ_seconds = occt(surfaces, tolerance)
            theirs = deviation(points, occ_positions, occ_triangles)
            print(f"| {Path(path).name} | {rel:g} | {tolerance:.3g} | {len(triangles)} "
                  f"({ours / tolerance:.2f}) | {seconds:.3f} | {n}×{n} | {grid_triangles} "
                  f"({grid_deviation / tolerance:.2f}) | {len(occ_triangles)} "
                  f"({theirs / tolerance:.2f}) | {occ_seconds:.3f} | "
                  f"{len(triangles) / len(occ_triangles):.2f} |", flush=True)


if __name__ == "__main__":
    main()
