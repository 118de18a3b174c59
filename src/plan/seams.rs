//! Seams: the sides two surfaces share. Where two adaptive surfaces meet along a side whose
//! boundary curves are the same — the same control points (to 1e-9 of the model's size),
//! weights and normalised knots, in the same or the opposite direction, as in .bpt and OBJ
//! files whose neighbouring patches repeat their boundary control points — both sides'
//! samples become the seam's vertices: a sample both sides have is one vertex (the first
//! surface's), and each side's grid cells along the seam take in the other side's samples
//! (see [`super::CellGrid::push_triangles`]). So the mesh is closed across the seam by shared
//! indices, not by equal floats.
//!
//! A file may also say which sides are one ([`Seam`], JSON `seams`): then the sides need not
//! have the same control points — one may have knots inserted the other lacks — but they
//! must be the same curve at the same fractions of their ranges (run either way), which the
//! plan checks at every sample of both sides ([`Error::SeamGap`]).

use super::adaptive::Side;
use crate::error::{Error, Result};
use crate::geom::{BSplineSurface, KnotVector};
use foldhash::{HashMap, HashMapExt, HashSet, HashSetExt};
use glam::DVec3;

/// Samples of two sides closer than this (as fractions of the side) are one.
const SAME_FRACTION: f64 = 1e-12;

/// Control points of two sides closer than this fraction of the model's diagonal coincide.
const SAME_POINT_REL: f64 = 1e-9;

/// A side's boundary curve, read in place from its surface: the row or column of control
/// points on it, with their weights, and the knots along it normalised to the side's range.
struct SideCurve<'a> {
    surface: &'a BSplineSurface,
    /// The knots along the side, with the start and width of the range they are normalised
    /// to.
    along: &'a KnotVector,
    start: f64,
    width: f64,
    /// Control point k of the side is (k, fixed) where it runs along u, else (fixed, k).
    along_u: bool,
    fixed: usize,
    count: usize,
}

/// The boundary curve of `surface` on `side`, if the side is where the control net's first
/// or last row (column) is the boundary: the knots clamped at that end and the evaluation
/// range reaching it, and the range along the side the whole knot domain.
fn side_curve(surface: &BSplineSurface, side: Side) -> Option<SideCurve<'_>> {
    let along_u = matches!(side, Side::Bottom | Side::Top);
    let (across, along) = if along_u {
        (surface.knots_v(), surface.knots_u())
    } else {
        (surface.knots_u(), surface.knots_v())
    };
    let (range_across, range_along) = if along_u {
        (surface.range_v(), surface.range_u())
    } else {
        (surface.range_u(), surface.range_v())
    };
    let at_start = matches!(side, Side::Bottom | Side::Left);
    let (q, k) = (across.degree(), across.knots());
    let (domain_start, domain_end) = across.domain();
    let clamped = if at_start {
        k[0] == k[q] && range_across.start == domain_start
    } else {
        k[k.len() - 1] == k[k.len() - 1 - q] && range_across.end == domain_end
    };
    if !clamped || along.domain() != (range_along.start, range_along.end) {
        return None;
    }
    let (count_u, count_v) = (surface.count_u(), surface.count_v());
    let (count, fixed) = if along_u {
        (count_u, if at_start { 0 } else { count_v - 1 })
    } else {
        (count_v, if at_start { 0 } else { count_u - 1 })
    };
    Some(SideCurve {
        surface,
        along,
        start: range_along.start,
        width: range_along.end - range_along.start,
        along_u,
        fixed,
        count,
    })
}

impl SideCurve<'_> {
    /// Control net indices (i, j) of the side's control point `k`.
    fn at(&self, k: usize) -> (usize, usize) {
        if self.along_u {
            (k, self.fixed)
        } else {
            (self.fixed, k)
        }
    }

    fn point(&self, k: usize) -> DVec3 {
        let (i, j) = self.at(k);
        self.surface.control_point(i, j)
    }

    fn weight(&self, k: usize) -> f64 {
        let (i, j) = self.at(k);
        self.surface.weight(i, j)
    }

    /// Knot `k` along the side as a fraction of the side's range.
    fn knot(&self, k: usize) -> f64 {
        (self.along.knots()[k] - self.start) / self.width
    }

    /// Whether every control point is within `tolerance` of the first.
    fn is_point(&self, tolerance: f64) -> bool {
        let first = self.point(0);
        (1..self.count).all(|k| (self.point(k) - first).length() <= tolerance)
    }

    /// Whether `other` is the same curve, run the same way (`reversed` false) or the other.
    fn same_as(&self, other: &SideCurve, reversed: bool, tolerance: f64) -> bool {
        let n = self.count;
        let m = self.along.knots().len();
        if self.along.degree() != other.along.degree()
            || n != other.count
            || m != other.along.knots().len()
        {
            return false;
        }
        let pick = |k: usize| if reversed { n - 1 - k } else { k };
        let knots_agree = (0..m).all(|k| {
            let s = if reversed {
                1.0 - other.knot(m - 1 - k)
            } else {
                other.knot(k)
            };
            (self.knot(k) - s).abs() <= SAME_FRACTION
        });
        let ratio = self.weight(0) / other.weight(pick(0));
        knots_agree
            && (0..n).all(|k| {
                (self.point(k) - other.point(pick(k))).length() <= tolerance
                    && (self.weight(k) - ratio * other.weight(pick(k))).abs()
                        <= 1e-12 * self.weight(k)
            })
    }
}

/// Samples along a side: (fraction of the side's range, vertex index), increasing.
pub(crate) type SideSamples = Vec<(f64, u32)>;

/// Which sides of `surface` (in the order Bottom, Right, Top, Left) collapse to a point —
/// poles, whose samples are one vertex — with control points within `tolerance`.
pub(crate) fn pole_sides(surface: &BSplineSurface, tolerance: f64) -> [bool; 4] {
    [Side::Bottom, Side::Right, Side::Top, Side::Left]
        .map(|side| side_curve(surface, side).is_some_and(|c| c.is_point(tolerance)))
}

/// How close control points must be to coincide: [`SAME_POINT_REL`] of `diagonal`, that of
/// the box around all the surfaces' control points ([`super::model_diagonal`]).
pub(crate) fn point_tolerance(diagonal: f64) -> f64 {
    SAME_POINT_REL * diagonal
}

/// A side of one surface of a plan: the surface's index in the list planned, and which side
/// of its evaluation range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SurfaceSide {
    pub surface: usize,
    pub side: Side,
}

/// Two sides of different surfaces that are one edge of the model, as a file's connectivity
/// says: both are sampled alike and share their vertices. The sides must be the same curve
/// at the same fractions of their ranges, in the same or the opposite direction (which one
/// is found from their ends). Seams join surfaces sampled to a tolerance; a seam with a
/// surface sampled on a grid is left alone.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Seam {
    pub sides: [SurfaceSide; 2],
}

/// Two surfaces' sides that a plan joins.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Joined {
    pub first: (usize, Side),
    pub second: (usize, Side),
    /// The second side runs the other way.
    pub reversed: bool,
    /// The index of the [`Seam`] that asked for it; `None` where found from the control
    /// points.
    pub asked: Option<usize>,
}

/// The point of `surface` at `fraction` ∈ [0, 1] of its evaluation range along `side`.
fn side_point(surface: &BSplineSurface, side: Side, fraction: f64) -> DVec3 {
    let (range_u, range_v) = (surface.range_u(), surface.range_v());
    let (u, v) = match side {
        Side::Bottom => (range_u.lerp(fraction), range_v.start),
        Side::Top => (range_u.lerp(fraction), range_v.end),
        Side::Left => (range_u.start, range_v.lerp(fraction)),
        Side::Right => (range_u.end, range_v.lerp(fraction)),
    };
    surface.point(u, v)
}

/// The seams a file asked for among the surfaces sampled to a tolerance (`adaptive[k]`),
/// each run the way its sides' ends say. Refuses a seam naming a surface out of range, a
/// side twice, or two sides of one surface.
pub(crate) fn asked_seams(
    surfaces: &[BSplineSurface],
    adaptive: &[bool],
    seams: &[Seam],
) -> Result<Vec<Joined>> {
    let mut used = HashSet::new();
    let mut joined = Vec::with_capacity(seams.len().min(4 * surfaces.len()));
    for (index, seam) in seams.iter().enumerate() {
        let refuse = |reason: String| Error::InvalidSeam {
            seam: index,
            reason,
        };
        for side in seam.sides {
            if side.surface >= surfaces.len() {
                return Err(refuse(format!(
                    "names surface {} of {}",
                    side.surface,
                    surfaces.len()
                )));
            }
            if !used.insert((side.surface, side.side as usize)) {
                return Err(refuse(format!(
                    "names side {} of surface {}, which an earlier seam joins already",
                    side.side.label(),
                    side.surface
                )));
            }
        }
        let [a, b] = seam.sides;
        if a.surface == b.surface {
            return Err(refuse(format!(
                "joins two sides of surface {} (a surface closed on itself needs no seam)",
                a.surface
            )));
        }
        if !(adaptive[a.surface] && adaptive[b.surface]) {
            continue;
        }
        let ends = |s: SurfaceSide| {
            let surface = &surfaces[s.surface];
            (
                side_point(surface, s.side, 0.0),
                side_point(surface, s.side, 1.0),
            )
        };
        let ((a0, a1), (b0, b1)) = (ends(a), ends(b));
        let reversed =
            (a0 - b1).length() + (a1 - b0).length() < (a0 - b0).length() + (a1 - b1).length();
        joined.push(Joined {
            first: (a.surface, a.side),
            second: (b.surface, b.side),
            reversed,
            asked: Some(index),
        });
    }
    Ok(joined)
}

/// How far apart the two sides of a seam a file asked for may be, as a fraction of the
/// finer of their surfaces' tolerances: the seam's vertices are one surface's, so the other
/// surface's triangles may be this much further from it than its tolerance.
const SEAM_GAP_FRACTION: f64 = 0.01;

/// Where neither surface of a seam has a tolerance (edge lengths or angles only), the
/// sides' gap allowed as a fraction of the model's diagonal.
const SEAM_GAP_REL: f64 = 1e-6;

/// The gap allowed between the sides of a seam whose surfaces were planned to `tolerances`
/// (model units, infinite: none), in a model of this `diagonal`.
pub(crate) fn allowed_gap(tolerances: [f64; 2], diagonal: f64) -> f64 {
    let finer = tolerances[0].min(tolerances[1]);
    if finer.is_finite() {
        SEAM_GAP_FRACTION * finer
    } else {
        SEAM_GAP_REL * diagonal
    }
}

/// Checks that the two sides of `seam` (asked for by a file) are one curve at the samples
/// `first` and `second` of each (fractions along its side): the largest distance between
/// the sides at the same fraction at most `allowed` (model units), else [`Error::SeamGap`].
pub(crate) fn check_gap(
    surfaces: &[BSplineSurface],
    seam: &Joined,
    first: &[(f64, u32)],
    second: &[(f64, u32)],
    allowed: f64,
) -> Result<()> {
    let Some(index) = seam.asked else {
        return Ok(());
    };
    let flip = |f: f64| if seam.reversed { 1.0 - f } else { f };
    let gap_at = |f: f64| {
        let on_first = side_point(&surfaces[seam.first.0], seam.first.1, f);
        let on_second = side_point(&surfaces[seam.second.0], seam.second.1, flip(f));
        (on_first - on_second).length()
    };
    let fractions = first
        .iter()
        .map(|&(f, _)| f)
        .chain(second.iter().map(|&(f, _)| flip(f)));
    let gap = fractions.map(gap_at).fold(0.0, f64::max);
    if gap > allowed {
        return Err(Error::SeamGap {
            seam: index,
            gap,
            allowed,
        });
    }
    Ok(())
}

/// The seams among the sides of the surfaces sampled to a tolerance (`adaptive[k]`) that
/// their control points show, leaving out the sides in `taken` (seams asked for): each
/// side in one seam at most (the first match, in surface and side order). Control points
/// within `tolerance` ([`point_tolerance`]) coincide.
pub(crate) fn find_seams(
    surfaces: &[BSplineSurface],
    adaptive: &[bool],
    taken: &[Joined],
    tolerance: f64,
) -> Vec<Joined> {
    let asked: HashSet<(usize, usize)> = taken
        .iter()
        .flat_map(|j| {
            [
                (j.first.0, j.first.1 as usize),
                (j.second.0, j.second.1 as usize),
            ]
        })
        .collect();
    let asked = &asked;
    let sides = [Side::Bottom, Side::Right, Side::Top, Side::Left];
    let curves: Vec<((usize, Side), SideCurve)> = surfaces
        .iter()
        .enumerate()
        .filter(|&(k, _)| adaptive[k])
        .flat_map(|(k, surface)| {
            sides
                .iter()
                .filter(move |&&side| !asked.contains(&(k, side as usize)))
                .filter_map(move |&side| side_curve(surface, side).map(|c| ((k, side), c)))
        })
        // A side collapsed to a point (a pole) is no seam: every pole of that point would
        // match it, and its samples are one point anyway.
        .filter(|(_, curve)| !curve.is_point(tolerance))
        .collect();
    // Candidates by the cell of their first and last points on a grid of the tolerance's
    // size (both orders), so that matching is not quadratic in the sides.
    let key = |p: DVec3| (p / (tolerance * 16.0)).floor().as_i64vec3().to_array();
    let ends = |c: &SideCurve| (key(c.point(0)), key(c.point(c.count - 1)));
    let mut by_ends: HashMap<_, Vec<usize>> = HashMap::new();
    for (index, (_, curve)) in curves.iter().enumerate() {
        by_ends.entry(ends(curve)).or_default().push(index);
    }
    let mut taken = vec![false; curves.len()];
    let mut seams = Vec::new();
    for (index, ((surface, side), curve)) in curves.iter().enumerate() {
        if taken[index] {
            continue;
        }
        let (start, end) = ends(curve);
        let candidates = [(start, end, false), (end, start, true)];
        let found = candidates.iter().find_map(|&(a, b, reversed)| {
            by_ends
                .get(&(a, b))?
                .iter()
                .copied()
                .find(|&other| {
                    other != index
                        && !taken[other]
                        && curves[other].0.0 != *surface
                        && curve.same_as(&curves[other].1, reversed, tolerance)
                })
                .map(|other| (other, reversed))
        });
        if let Some((other, reversed)) = found {
            taken[index] = true;
            taken[other] = true;
            seams.push(Joined {
                first: (*surface, *side),
                second: curves[other].0,
                reversed,
                asked: None,
            });
        }
    }
    seams
}

/// Merges the samples of two sides of one seam, each (fraction along its side, vertex
/// index) in increasing fraction: returns the pairs of vertices that are one sample, and
/// the samples each side lacks from the other (in that side's fractions, increasing).
pub(crate) fn merge_samples(
    first: &[(f64, u32)],
    second: &[(f64, u32)],
    reversed: bool,
) -> (Vec<(u32, u32)>, [SideSamples; 2]) {
    let flip = |f: f64| if reversed { 1.0 - f } else { f };
    let mut second_in_first: Vec<(f64, u32)> = second.iter().map(|&(f, v)| (flip(f), v)).collect();
    second_in_first.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (mut same, mut first_lacks, mut second_lacks) = (
        Vec::with_capacity(first.len().min(second.len())),
        Vec::with_capacity(second.len()),
        Vec::with_capacity(first.len()),
    );
    let (mut i, mut j) = (0, 0);
    while i < first.len() || j < second_in_first.len() {
        match (first.get(i), second_in_first.get(j)) {
            (Some(&(fa, va)), Some(&(fb, vb))) if (fa - fb).abs() <= SAME_FRACTION => {
                same.push((va, vb));
                i += 1;
                j += 1;
            }
            (Some(&(fa, va)), Some(&(fb, _))) if fa < fb => {
                second_lacks.push((flip(fa), va));
                i += 1;
            }
            (Some(&(fa, va)), None) => {
                second_lacks.push((flip(fa), va));
                i += 1;
            }
            (_, Some(&(fb, vb))) => {
                first_lacks.push((fb, vb));
                j += 1;
            }
            (None, None) => unreachable!("the loop runs while either has samples"),
        }
    }
    second_lacks.sort_by(|a, b| a.0.total_cmp(&b.0));
    (same, [first_lacks, second_lacks])
}

/// The representative of every vertex after merging `pairs` (the smallest index of each
/// group): union–find over the vertices `0..count` that pairs name.
pub(crate) fn representatives(count: usize, pairs: &[(u32, u32)]) -> Vec<u32> {
    let mut parent: Vec<u32> = (0..count as u32).collect();
    fn find(parent: &mut [u32], mut v: u32) -> u32 {
        while parent[v as usize] != v {
            let up = parent[parent[v as usize] as usize];
            parent[v as usize] = up;
            v = up;
        }
        v
    }
    for &(a, b) in pairs {
        let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
        let (low, high) = (ra.min(rb), ra.max(rb));
        parent[high as usize] = low;
    }
    (0..count as u32).map(|v| find(&mut parent, v)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Shared samples pair up; the rest go to the side that lacks them, in its own
    /// direction and order.
    #[test]
    fn samples_merge_both_ways() {
        let first = [(0.0, 0), (0.5, 1), (1.0, 2)];
        let second = [(0.0, 10), (0.25, 11), (0.5, 12), (1.0, 13)];
        let (same, [first_lacks, second_lacks]) = merge_samples(&first, &second, true);
        assert_eq!(same, [(0, 13), (1, 12), (2, 10)]);
        assert_eq!(first_lacks, [(0.75, 11)]);
        assert!(second_lacks.is_empty());
        let groups = representatives(14, &same);
        assert_eq!(
            (groups[13], groups[12], groups[10], groups[11]),
            (0, 1, 2, 11)
        );
    }
}
