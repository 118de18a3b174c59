//! Shared test helpers: named tolerances, exact conic surfaces, independent evaluators.
#![allow(dead_code)]

pub mod exact;

use glam::DVec3;
use knotwork::{BSplineSurface, KnotVector};
use std::path::{Path, PathBuf};

/// A folder in the system's temporary directory for one test's files, named after the test
/// process and `name`: emptied when made, removed when the test passes, kept when it fails
/// (for a look at what was written).
pub struct ScratchDir(PathBuf);

impl ScratchDir {
    pub fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("knotwork-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        ScratchDir(dir)
    }
}

impl std::ops::Deref for ScratchDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for ScratchDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<std::ffi::OsStr> for ScratchDir {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.as_os_str()
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// f64 exactness bar for exact forms, relative to the model size.
pub const EXACT_REL: f64 = 1e-12;

pub const S: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// A sphere of radius `r` centred at the origin; v runs from the south pole to the north.
pub fn sphere(r: f64) -> BSplineSurface {
    knotwork::geom::shapes::sphere(DVec3::ZERO, r)
}

/// A torus about the z axis with major radius `big` and minor radius `small`.
pub fn torus(big: f64, small: f64) -> BSplineSurface {
    knotwork::geom::shapes::torus(DVec3::ZERO, big, small)
}

/// A quarter of the unit cylinder about z, x, y ≥ 0, height 1: degree 2 around, 1 along z.
pub fn quarter_cylinder() -> BSplineSurface {
    let arc_knots = KnotVector::try_new(2, vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0]).unwrap();
    let line_knots = KnotVector::try_new(1, vec![0.0, 0.0, 1.0, 1.0]).unwrap();
    let mut points = Vec::new();
    let mut weights = Vec::new();
    for z in [0.0, 1.0] {
        for (p, w) in [
            (DVec3::new(1.0, 0.0, z), 1.0),
            (DVec3::new(1.0, 1.0, z), S),
            (DVec3::new(0.0, 1.0, z), 1.0),
        ] {
            points.push(p);
            weights.push(w);
        }
    }
    BSplineSurface::try_new(arc_knots, line_knots, &points, Some(&weights)).unwrap()
}

/// Basis function N_(i,p)(u) by the textbook Cox–de Boor recursion (0/0 := 0), right-continuous
/// except at the domain end, which belongs to the last non-empty span. Independent of the
/// library's triangular-table code.
pub fn naive_basis(knots: &[f64], i: usize, p: usize, u: f64, domain_end: f64) -> f64 {
    if p == 0 {
        let (a, b) = (knots[i], knots[i + 1]);
        let inside = a <= u && u < b;
        let at_end = u == domain_end && b == domain_end && a < b;
        return if inside || at_end { 1.0 } else { 0.0 };
    }
    let mut value = 0.0;
    let d1 = knots[i + p] - knots[i];
    if d1 > 0.0 {
        value += (u - knots[i]) / d1 * naive_basis(knots, i, p - 1, u, domain_end);
    }
    let d2 = knots[i + p + 1] - knots[i + 1];
    if d2 > 0.0 {
        value += (knots[i + p + 1] - u) / d2 * naive_basis(knots, i + 1, p - 1, u, domain_end);
    }
    value
}

/// Surface point by the naive double sum over all control points — an independent evaluator.
pub fn naive_point(s: &BSplineSurface, u: f64, v: f64) -> DVec3 {
    let (ku, kv) = (s.knots_u(), s.knots_v());
    let (end_u, end_v) = (ku.domain().1, kv.domain().1);
    let mut sum = glam::DVec4::ZERO;
    for j in 0..s.count_v() {
        let nv = naive_basis(kv.knots(), j, kv.degree(), v, end_v);
        if nv == 0.0 {
            continue;
        }
        for i in 0..s.count_u() {
            let nu = naive_basis(ku.knots(), i, ku.degree(), u, end_u);
            let w = s.weight(i, j);
            sum += nu * nv * (s.control_point(i, j) * w).extend(w);
        }
    }
    sum.truncate() / sum.w
}

/// The diagonal of the box around all of `surfaces`' control points (what a relative
/// tolerance is taken of).
pub fn model_diagonal(surfaces: &[BSplineSurface]) -> f64 {
    let (low, high) = surfaces.iter().map(BSplineSurface::control_box).fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(low, high), (a, b)| (low.min(a), high.max(b)),
    );
    (high - low).length()
}

/// Angle between two directions, in radians (robust near 0).
pub fn angle(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// The uv on `surface` of a triangle's vertex at `uv` (of its own surface) and `position`,
/// where that uv may not be this triangle's: a vertex another part's surface owns (a seam
/// vertex: on a side of this surface's range at the same fraction along it, or the opposite
/// one), or a pole's one vertex (any point of the collapsed side, taken nearest the
/// triangle's other corners `others`). Of the candidates whose point is `position` (to
/// rounding), the one nearest the other corners in uv.
fn corner_uv(
    surface: &BSplineSurface,
    uv: glam::DVec2,
    position: DVec3,
    others: &[glam::DVec2],
) -> glam::DVec2 {
    let (ru, rv) = (surface.range_u(), surface.range_v());
    let mut candidates = vec![uv];
    for f in [uv.x, uv.y] {
        for g in [f, 1.0 - f] {
            candidates.extend([(g, 0.0), (g, 1.0), (0.0, g), (1.0, g)].map(glam::DVec2::from));
        }
    }
    for o in others {
        candidates.extend([(o.x, 0.0), (o.x, 1.0), (0.0, o.y), (1.0, o.y)].map(glam::DVec2::from));
    }
    let off = |c: glam::DVec2| (surface.point(ru.lerp(c.x), rv.lerp(c.y)) - position).length();
    let scored: Vec<(f64, glam::DVec2)> = candidates.into_iter().map(|c| (off(c), c)).collect();
    let least = scored.iter().map(|c| c.0).fold(f64::INFINITY, f64::min);
    let rounding = 1e-9 * surface.control_box_diagonal();
    let near = others.iter().copied().sum::<glam::DVec2>() / others.len().max(1) as f64;
    scored
        .into_iter()
        .filter(|c| c.0 <= least + rounding)
        .map(|c| c.1)
        .min_by(|a, b| (*a - near).length().total_cmp(&(*b - near).length()))
        .expect("candidates")
}

/// Which sides of `surface`'s range are collapsed to one point (a pole): v = 0, v = 1,
/// u = 0, u = 1.
fn collapsed_sides(surface: &BSplineSurface) -> [bool; 4] {
    let (ru, rv) = (surface.range_u(), surface.range_v());
    let at = |u: f64, v: f64| surface.point(ru.lerp(u), rv.lerp(v));
    let rounding = 1e-9 * surface.control_box_diagonal();
    let collapsed =
        |points: [DVec3; 3]| points.iter().all(|q| (*q - points[0]).length() <= rounding);
    let along = [0.0, 0.5, 1.0];
    [
        collapsed(along.map(|u| at(u, 0.0))),
        collapsed(along.map(|u| at(u, 1.0))),
        collapsed(along.map(|v| at(0.0, v))),
        collapsed(along.map(|v| at(1.0, v))),
    ]
}

/// Whether `uv` lies on a side in `collapsed` (see [`collapsed_sides`]), and if so whether
/// that side runs along u (v fixed) — or along v.
fn pole_side(collapsed: [bool; 4], uv: glam::DVec2) -> Option<bool> {
    if (uv.y == 0.0 && collapsed[0]) || (uv.y == 1.0 && collapsed[1]) {
        Some(true)
    } else if (uv.x == 0.0 && collapsed[2]) || (uv.x == 1.0 && collapsed[3]) {
        Some(false)
    } else {
        None
    }
}

/// The largest distance, over every triangle of `mesh` (part k from `surfaces[k]`), between a
/// point of the triangle and the surface at the same parameter — at its centroid and its edge
/// midpoints, the parameter interpolated from the vertices' uv like the position (a vertex
/// of another part, on a seam, at its uv on this part's surface; a pole's one vertex at the
/// u (or v) of the others, weighted as they are: each edge from a pole runs along the
/// other end's meridian). What an adaptive plan's tolerance bounds (distance to the
/// surface itself is never larger).
pub fn worst_deviation(surfaces: &[BSplineSurface], mesh: &knotwork::Mesh) -> f64 {
    const AT: [[f64; 3]; 4] = [
        [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
        [0.5, 0.5, 0.0],
        [0.0, 0.5, 0.5],
        [0.5, 0.0, 0.5],
    ];
    let mut worst = 0.0f64;
    for part in &mesh.parts {
        let surface = &surfaces[part.item as usize];
        let (ru, rv) = (surface.range_u(), surface.range_v());
        let poles = collapsed_sides(surface);
        let first = part.first_index as usize;
        for t in mesh.indices[first..first + part.index_count as usize].chunks(3) {
            for l in AT {
                let (mut p, mut uv) = (DVec3::ZERO, glam::DVec2::ZERO);
                let own =
                    |v: u32| v >= part.first_vertex && v < part.first_vertex + part.vertex_count;
                // A corner's uv where it may not be this triangle's: a seam vertex of another
                // part, or a vertex on the range's boundary (a pole's one vertex).
                let corners: Vec<glam::DVec2> = (0..3)
                    .map(|k| {
                        let v = t[k];
                        let vertex_uv = mesh.uvs[v as usize];
                        let on_side = [vertex_uv.x, vertex_uv.y]
                            .iter()
                            .any(|&c| c == 0.0 || c == 1.0);
                        if own(v) && !on_side {
                            return vertex_uv;
                        }
                        // The other corners that say where the triangle is (not a pole,
                        // whose one uv is any point of its side).
                        let others: Vec<glam::DVec2> = (0..3)
                            .filter(|&j| j != k && own(t[j]))
                            .map(|j| mesh.uvs[t[j] as usize])
                            .filter(|&uv| pole_side(poles, uv).is_none())
                            .collect();
                        corner_uv(surface, vertex_uv, mesh.positions[v as usize], &others)
                    })
                    .collect();
                for (k, &weight) in l.iter().enumerate() {
                    let position = mesh.positions[t[k] as usize];
                    // A pole's fan triangle maps each edge from the pole to a curve of the
                    // other end's u (or v): the pole's free coordinate follows the others'.
                    let vertex_uv = match pole_side(poles, corners[k]) {
                        Some(along_u) => {
                            let rest: f64 = (0..3).filter(|&j| j != k).map(|j| l[j]).sum();
                            let follow = |c: fn(glam::DVec2) -> f64| {
                                (0..3)
                                    .filter(|&j| j != k)
                                    .map(|j| l[j] * c(corners[j]))
                                    .sum::<f64>()
                                    / rest
                            };
                            match (rest > 0.0, along_u) {
                                (false, _) => corners[k],
                                (true, true) => glam::DVec2::new(follow(|c| c.x), corners[k].y),
                                (true, false) => glam::DVec2::new(corners[k].x, follow(|c| c.y)),
                            }
                        }
                        None => corners[k],
                    };
                    p += weight * position;
                    uv += weight * vertex_uv;
                }
                let on_surface = surface.point(ru.lerp(uv.x), rv.lerp(uv.y));
                worst = worst.max((on_surface - p).length());
            }
        }
    }
    worst
}

/// The edges (vertex pairs, lower index first) used by exactly one triangle of `mesh`.
pub fn open_edges(mesh: &knotwork::Mesh) -> Vec<(u32, u32)> {
    let mut uses = std::collections::HashMap::new();
    for t in mesh.indices.chunks(3) {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *uses.entry((a.min(b), a.max(b))).or_insert(0u32) += 1;
        }
    }
    uses.into_iter()
        .filter(|&(_, n)| n == 1)
        .map(|(edge, _)| edge)
        .collect()
}

/// Edges used by exactly one triangle, and the number of pieces connected through shared
/// edges (a single shared vertex — the handle's lower end touches the body at one point —
/// does not join two pieces of surface).
pub fn open_edges_and_pieces(mesh: &knotwork::Mesh) -> (usize, usize) {
    use std::collections::HashMap;
    fn find(parent: &mut [usize], x: usize) -> usize {
        let mut root = x;
        while parent[root] != root {
            root = parent[root];
        }
        parent[x] = root;
        root
    }
    let triangles: Vec<&[u32]> = mesh.indices.chunks_exact(3).collect();
    let mut parent: Vec<usize> = (0..triangles.len()).collect();
    let mut edges: HashMap<(u32, u32), (usize, usize)> = HashMap::new();
    for (t, tri) in triangles.iter().enumerate() {
        for (a, b) in [(tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])] {
            let entry = edges.entry((a.min(b), a.max(b))).or_insert((t, 0));
            entry.1 += 1;
            let (ra, rb) = (find(&mut parent, entry.0), find(&mut parent, t));
            parent[ra] = rb;
        }
    }
    let roots: std::collections::HashSet<usize> =
        (0..triangles.len()).map(|t| find(&mut parent, t)).collect();
    (edges.values().filter(|e| e.1 == 1).count(), roots.len())
}

/// The JSON (its padding trimmed) and binary chunk of a .glb file.
pub fn glb_chunks(bytes: &[u8]) -> (String, Vec<u8>) {
    let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    assert_eq!(&bytes[..4], b"glTF");
    assert_eq!(word(8), bytes.len(), "the header's length is the file's");
    let json_length = word(12);
    let json = std::str::from_utf8(&bytes[20..20 + json_length]).unwrap();
    let bin_at = 20 + json_length;
    assert_eq!(&bytes[bin_at + 4..bin_at + 8], b"BIN\0");
    let bin = bytes[bin_at + 8..bin_at + 8 + word(bin_at)].to_vec();
    (json.trim_end().to_string(), bin)
}
