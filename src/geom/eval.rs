//! Point evaluation of every form in f64: positions, partial derivatives up to second order,
//! unit normals with limits at degenerate points, and the one rule that decides where a
//! normal is degenerate — used by both executors, the GPU packer and conformance.

use super::basis::{MAX_ORDER, basis_ders};
use super::patches::CoonsPatch;
use super::{BSplineCurve, BSplineSurface, Interval};
use glam::{DVec3, DVec4};

/// The scale of |S_u × S_v| for a surface whose control net spans `size` (bounding-box
/// diagonal, model units) over a parameter domain `width_u` × `width_v`: size² / (width_u ·
/// width_v), in model units² per parameter unit².
pub fn cross_scale(size: f64, width_u: f64, width_v: f64) -> f64 {
    size * size / (width_u * width_v)
}

/// How many machine epsilons of [`cross_scale`] |S_u × S_v| may be and still count as zero.
pub const DEGENERATE_EPSILONS: f64 = 100.0;

/// The degeneracy rule: the squared length at or below which |S_u × S_v|² counts as zero —
/// rounding noise at a genuinely degenerate point, not a tangent plane — for a surface of
/// [`cross_scale`] `scale` evaluated in arithmetic of machine epsilon `epsilon`
/// (`f64::EPSILON` on the CPU, `f32::EPSILON` in the kernels, which receive this value from
/// the host).
pub fn degenerate_cross_sq(scale: f64, epsilon: f64) -> f64 {
    let t = DEGENERATE_EPSILONS * epsilon * scale;
    t * t
}

/// C(n, k) for n ≤ 3: the Leibniz rule's coefficients up to third derivatives.
const BINOMIAL: [[f64; 4]; 4] = [
    [1.0, 0.0, 0.0, 0.0],
    [1.0, 1.0, 0.0, 0.0],
    [1.0, 2.0, 1.0, 0.0],
    [1.0, 3.0, 3.0, 1.0],
];

/// A₁ of [`limit_normal`] for a rational surface, (a·S_uu + b·S_uv) × S_v + S_u × (a·S_uv +
/// b·S_vv), times w, with the rounding bound of its terms, from the homogeneous point and
/// derivatives `h` = [A, A_u, A_v, A_uu, A_uv, A_vv], (S_u, S_v) and S (the same frame as
/// `h`). The quotient rule's terms along S_u in S_uv (−w_v·S_u/w) and along S_v (−w_u·S_v/w)
/// drop out of the cross products they would enter exactly, instead of cancelling there in
/// rounding: with a weight ratio r in the support they are r times larger than what remains.
/// So do its terms along S_u × S_v (−2a·w_u, −b·w_v, … times S_u × S_v): A₁ is wanted only
/// where S_u × S_v is rounding noise, which those coefficients would only amplify.
fn first_order_term(
    [h, huu, huv, hvv]: [DVec4; 4],
    (su, sv): (DVec3, DVec3),
    s: DVec3,
    (a, b): (f64, f64),
) -> (DVec3, f64) {
    let terms = [
        // w·S_uu × S_v
        (a, huu.truncate().cross(sv)),
        (-a * huu.w, s.cross(sv)),
        // w·S_uv × S_v, without −w_u·S_v × S_v
        (b, huv.truncate().cross(sv)),
        (-b * huv.w, s.cross(sv)),
        // w·S_u × S_uv, without −w_v·S_u × S_u
        (a, su.cross(huv.truncate())),
        (-a * huv.w, su.cross(s)),
        // w·S_u × S_vv
        (b, su.cross(hvv.truncate())),
        (-b * hvv.w, su.cross(s)),
    ];
    let value: DVec3 = terms.iter().map(|(c, x)| *c * *x).sum();
    let bound = [
        (a.abs(), huu.truncate().length() * sv.length()),
        (b.abs(), huv.truncate().length() * sv.length()),
        (a.abs(), su.length() * huv.truncate().length()),
        (b.abs(), su.length() * hvv.truncate().length()),
        (
            (a * huu.w).abs() + (b * huv.w).abs(),
            s.length() * sv.length(),
        ),
        (
            (a * huv.w).abs() + (b * hvv.w).abs(),
            su.length() * s.length(),
        ),
    ]
    .iter()
    .map(|(c, x)| c * x)
    .sum::<f64>();
    (value / h.w, bound / h.w)
}

/// A surface point with its partial derivatives (model units per unit of parameter) and
/// unit normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceSample {
    pub position: DVec3,
    pub du: DVec3,
    pub dv: DVec3,
    pub duu: DVec3,
    pub duv: DVec3,
    pub dvv: DVec3,
    /// unit(S_u × S_v), or its limit where that cross product vanishes (see [`BSplineSurface::evaluate`]).
    pub normal: DVec3,
}

/// The normal at (u, v) of a sample `s` over the parameter ranges: unit(S_u × S_v), or where
/// |S_u × S_v|² ≤ `threshold` its limit toward the centre of the ranges (the contract of
/// [`BSplineSurface::evaluate`]). Along the diagonal d = (±width_u, ±width_v), S_u × S_v at
/// distance t is t·A₁ + t²·A₂ + …: the limit is the direction of A₁ (second derivatives), of
/// A₂ where A₁ vanishes too (third derivatives, from `third` = [S_uuu, S_uuv, S_uvv, S_vvv]
/// when the form has them), each taken only when it stands above the rounding of its
/// own terms; `first_derivatives` gives [S_u, S_v] at nearby points for what is left. A₁
/// comes from `first_order` (A₁ and the rounding bound of its terms, for the direction
/// (step_u, step_v)) when the form can form it more precisely than from `s`.
pub(crate) fn limit_normal(
    s: &SurfaceSample,
    (u, v): (f64, f64),
    (ru, rv): (Interval, Interval),
    threshold: f64,
    first_order: Option<&dyn Fn(f64, f64) -> (DVec3, f64)>,
    third: &dyn Fn() -> Option<[DVec3; 4]>,
    first_derivatives: impl Fn(f64, f64) -> [DVec3; 2],
) -> DVec3 {
    let n = s.du.cross(s.dv);
    if n.length_squared() > threshold {
        return n.normalize();
    }
    let step_u = if u > 0.5 * (ru.start + ru.end) {
        -ru.width()
    } else {
        ru.width()
    };
    let step_v = if v > 0.5 * (rv.start + rv.end) {
        -rv.width()
    } else {
        rv.width()
    };
    // A term counts when it exceeds the threshold and the rounding of the products it sums.
    let noise = |terms: &[(f64, DVec3, DVec3)]| {
        let bound: f64 = terms
            .iter()
            .map(|(c, a, b)| c.abs() * a.length() * b.length())
            .sum();
        (DEGENERATE_EPSILONS * f64::EPSILON * bound).max(threshold.sqrt())
    };
    let (su, sv) = (s.du, s.dv);
    // S_u and S_v along d: first and second directional derivatives.
    let su1 = step_u * s.duu + step_v * s.duv;
    let sv1 = step_u * s.duv + step_v * s.dvv;
    let (first, bound) = match first_order {
        Some(first_order) => first_order(step_u, step_v),
        None => (
            su1.cross(sv) + su.cross(sv1),
            su1.length() * sv.length() + su.length() * sv1.length(),
        ),
    };
    if first.length() > (DEGENERATE_EPSILONS * f64::EPSILON * bound).max(threshold.sqrt()) {
        return first.normalize();
    }
    if let Some([uuu, uuv, uvv, vvv]) = third() {
        let (a, b) = (step_u, step_v);
        let su2 = a * a * uuu + 2.0 * a * b * uuv + b * b * uvv;
        let sv2 = a * a * uuv + 2.0 * a * b * uvv + b * b * vvv;
        let second_order = 0.5 * su2.cross(sv) + su1.cross(sv1) + 0.5 * su.cross(sv2);
        if second_order.length() > noise(&[(0.5, su2, sv), (1.0, su1, sv1), (0.5, su, sv2)]) {
            return second_order.normalize();
        }
    }
    for fraction in [1e-6, 1e-4, 1e-2] {
        let (hu, hv) = (u + step_u * fraction, v + step_v * fraction);
        let [du, dv] = first_derivatives(hu, hv);
        let n = du.cross(dv);
        if n.length_squared() > threshold {
            return n.normalize();
        }
    }
    DVec3::Z
}

impl BSplineSurface {
    /// Evaluates position, derivatives and normal at (u, v); parameters outside the knot
    /// domain are clamped to it.
    ///
    /// Normal contract: unit(S_u × S_v) where that cross product is not negligible. Where it
    /// vanishes (a collapsed edge, a sphere pole, a cone apex) the normal is the limit of
    /// unit(S_u × S_v) approached from inside the evaluation range along the direction
    /// (±width_u, ±width_v) — toward the centre of the range — computed from the second
    /// derivatives: S_u×S_v ≈ du(S_u×S_uv + S_uu×S_v) + dv(S_u×S_vv + S_uv×S_v). Along a
    /// collapsed edge this limit does not depend on the direction; at a corner where it does
    /// (e.g. where a collapsed edge meets a crease), it is the limit along that diagonal. If
    /// the first-order term vanishes too (to the rounding of its terms), the next order gives
    /// the limit, from third derivatives; past that the normal is taken at nearby points along
    /// the same diagonal; a surface with no tangent plane anywhere near (collapsed to a point
    /// or a line) gets +Z.
    pub fn evaluate(&self, u: f64, v: f64) -> SurfaceSample {
        // Relative to the support's reference point (see [`rebased`]): the quotient rule's
        // cancellation h_u − w_u·S then works on the distances that shape the surface there,
        // not on the model's offset or a heavy weight's pull.
        let (reference, h, [hu, hv, huu, huv, hvv]) = self.homogeneous_derivatives(u, v);
        let w = h.w;
        let position = h.truncate() / w;
        let du = (hu.truncate() - hu.w * position) / w;
        let dv = (hv.truncate() - hv.w * position) / w;
        let duu = (huu.truncate() - 2.0 * hu.w * du - huu.w * position) / w;
        let duv = (huv.truncate() - hu.w * dv - hv.w * du - huv.w * position) / w;
        let dvv = (hvv.truncate() - 2.0 * hv.w * dv - hvv.w * position) / w;
        let mut sample = SurfaceSample {
            position: self.origin() + (reference + position),
            du,
            dv,
            duu,
            duv,
            dvv,
            normal: DVec3::ZERO,
        };
        let first_order =
            |a: f64, b: f64| first_order_term([h, huu, huv, hvv], (du, dv), position, (a, b));
        sample.normal = limit_normal(
            &sample,
            (u, v),
            (self.range_u(), self.range_v()),
            degenerate_cross_sq(self.cross_scale(), f64::EPSILON),
            Some(&first_order),
            &|| Some(self.third_derivatives(u, v)),
            |u, v| self.rational_first_derivatives(u, v),
        );
        sample
    }

    /// The point at (u, v): [`evaluate`](Self::evaluate)'s position (the same sum), without
    /// the derivatives and the normal.
    pub fn point(&self, u: f64, v: f64) -> DVec3 {
        let support = Support::<1>::new(self, u, v, 0);
        let (p, q) = (self.degree_u(), self.degree_v());
        let mut h = DVec4::ZERO;
        for b in 0..=q {
            let row: DVec4 = (0..=p)
                .map(|a| support.bu[0][a] * support.point(a, b))
                .sum();
            h += support.bv[0][b] * row;
        }
        self.origin() + (support.reference + h.truncate() / h.w)
    }

    /// The point at (u, v) and S_u × S_v there (not normalised), from first derivatives only:
    /// cheaper than [`evaluate`](Self::evaluate), whose normal is the cross product's limit
    /// where it vanishes (at a pole or a collapsed edge it is zero, or rounding).
    pub(crate) fn point_and_cross(&self, u: f64, v: f64) -> (DVec3, DVec3) {
        let support = Support::<2>::new(self, u, v, 1);
        let (p, q) = (self.degree_u(), self.degree_v());
        let [mut h, mut hu, mut hv] = [DVec4::ZERO; 3];
        for b in 0..=q {
            let [c0, c1] = (support.bu)
                .map(|row| (0..=p).map(|a| row[a] * support.point(a, b)).sum::<DVec4>());
            let [n, dn] = support.bv.map(|row| row[b]);
            h += n * c0;
            hu += n * c1;
            hv += dn * c0;
        }
        let position = h.truncate() / h.w;
        let du = (hu.truncate() - hu.w * position) / h.w;
        let dv = (hv.truncate() - hv.w * position) / h.w;
        (self.origin() + (support.reference + position), du.cross(dv))
    }

    /// The points at every (u, v) of `us` × `vs` (clamped to the knot domain), u fastest:
    /// each column's and row's basis found once and every row's control points blended
    /// along v once. Summed relative to the surface's [`origin`](Self::origin) rather than
    /// each support's dominant point, so within a few ulps of the control box's size of
    /// [`point`](Self::point): for seeds and searches, not for samples.
    pub(crate) fn grid_points(&self, us: &[f64], vs: &[f64]) -> Vec<DVec3> {
        let columns: Vec<(usize, Vec<f64>)> =
            us.iter().map(|&u| self.knots_u().basis_values(u)).collect();
        let (p, q, count_u) = (self.degree_u(), self.degree_v(), self.count_u());
        let points = self.homogeneous_points();
        let mut row = vec![DVec4::ZERO; count_u];
        let mut grid = Vec::with_capacity(us.len() * vs.len());
        for &v in vs {
            let (span_v, bv) = self.knots_v().basis_values(v);
            for (i, blended) in row.iter_mut().enumerate() {
                *blended = (0..=q)
                    .map(|b| bv[b] * points[(span_v - q + b) * count_u + i])
                    .sum();
            }
            grid.extend(columns.iter().map(|(span_u, bu)| {
                let h: DVec4 = (0..=p).map(|a| bu[a] * row[span_u - p + a]).sum();
                self.origin() + h.truncate() / h.w
            }));
        }
        grid
    }

    /// [`cross_scale`] of this surface: its control box diagonal over its knot domain.
    pub fn cross_scale(&self) -> f64 {
        let (u0, u1) = self.knots_u().domain();
        let (v0, v1) = self.knots_v().domain();
        cross_scale(self.control_box_diagonal(), u1 - u0, v1 - v0)
    }

    /// [S_uuu, S_uuv, S_uvv, S_vvv] at (u, v): the quotient rule to third order on the
    /// homogeneous derivatives (Leibniz: A^(i,j) = Σ C(i,k)·C(j,l)·w^(k,l)·S^(i−k,j−l)).
    fn third_derivatives(&self, u: f64, v: f64) -> [DVec3; 4] {
        let support = Support::<4>::new(self, u, v, 3);
        let (p, q) = (self.degree_u(), self.degree_v());
        // h[i][j] = ∂ᵢᵤ∂ⱼᵥ of the homogeneous point, i + j ≤ 3.
        let mut h = [[DVec4::ZERO; 4]; 4];
        for b in 0..=q {
            for (i, hi) in h.iter_mut().enumerate() {
                let along_u: DVec4 = (0..=p)
                    .map(|a| support.bu[i][a] * support.point(a, b))
                    .sum();
                for (j, hij) in hi.iter_mut().enumerate().take(4 - i) {
                    *hij += support.bv[j][b] * along_u;
                }
            }
        }
        let mut cartesian = [[DVec3::ZERO; 4]; 4];
        for order in 0..=3 {
            for i in 0..=order {
                let j = order - i;
                let mut value = h[i][j].truncate();
                for k in 0..=i {
                    for l in 0..=j {
                        if k + l > 0 {
                            value -= BINOMIAL[i][k]
                                * BINOMIAL[j][l]
                                * h[k][l].w
                                * cartesian[i - k][j - l];
                        }
                    }
                }
                cartesian[i][j] = value / h[0][0].w;
            }
        }
        [
            cartesian[3][0],
            cartesian[2][1],
            cartesian[1][2],
            cartesian[0][3],
        ]
    }

    /// First derivatives [S_u, S_v] at (u, v).
    fn rational_first_derivatives(&self, u: f64, v: f64) -> [DVec3; 2] {
        let (_, h, [hu, hv, ..]) = self.homogeneous_derivatives(u, v);
        let position = h.truncate() / h.w;
        [
            (hu.truncate() - hu.w * position) / h.w,
            (hv.truncate() - hv.w * position) / h.w,
        ]
    }

    /// At (u, v): the support's reference point (relative to the origin), and the homogeneous
    /// point relative to it with its derivatives [∂u, ∂v, ∂uu, ∂uv, ∂vv].
    fn homogeneous_derivatives(&self, u: f64, v: f64) -> (DVec3, DVec4, [DVec4; 5]) {
        let support = Support::<3>::new(self, u, v, 2);
        let (p, q) = (self.degree_u(), self.degree_v());
        let (bu, bv) = (&support.bu, &support.bv);
        let mut out = [DVec4::ZERO; 6];
        for b in 0..=q {
            // Contract along u first: value, ∂u, ∂uu of this control row.
            let [c0, c1, c2] =
                bu.map(|row| (0..=p).map(|a| row[a] * support.point(a, b)).sum::<DVec4>());
            let [n, dn, ddn] = bv.map(|row| row[b]);
            out[0] += n * c0;
            out[1] += n * c1;
            out[2] += dn * c0;
            out[3] += n * c2;
            out[4] += dn * c1;
            out[5] += ddn * c0;
        }
        (
            support.reference,
            out[0],
            [out[1], out[2], out[3], out[4], out[5]],
        )
    }
}

/// A control point P (relative to an origin o) of weight w in homogeneous form rebased to
/// `reference` (relative to the same origin): ((P − reference)·w, w). Points that coincide
/// stay coincident (their terms cancel exactly), whatever their weights.
///
/// Evaluation sums these over a support whose reference is its dominant control point (the
/// largest basis value × weight there, [`dominant`]): that point's term is exactly zero, so
/// the quotient rule (A_u − w_u·S)/w cancels only the other points' terms, each as large as
/// its own weight makes it. Without it a heavy weight that pins the surface near its point
/// makes S_u small while the cancelled terms stay as large as the point's offset: the
/// derivatives lose the ratio of the weights in relative precision (1e-5 rad normals at
/// weights 1e-3..1e3 in f64, 1e-2 in f32).
pub(crate) fn rebased(point: DVec3, weight: f64, reference: DVec3) -> DVec4 {
    ((point - reference) * weight).extend(weight)
}

/// The control point with the largest `basis value × weight` among `(basis value, point,
/// weight)` triples: the reference of [`rebased`].
pub(crate) fn dominant(terms: impl Iterator<Item = (f64, DVec3, f64)>) -> DVec3 {
    let (_, point) = terms.fold(
        (f64::NEG_INFINITY, DVec3::ZERO),
        |best, (basis, point, w)| {
            let score = basis * w;
            if score > best.0 { (score, point) } else { best }
        },
    );
    point
}

/// The control points and basis functions that are non-zero at one (u, v) of a surface,
/// with the reference point they are summed relative to ([`rebased`]).
struct Support<'a, const N: usize> {
    surface: &'a BSplineSurface,
    span_u: usize,
    span_v: usize,
    /// Basis values and derivatives along u and v (see [`basis_ders`]).
    bu: [[f64; MAX_ORDER]; N],
    bv: [[f64; MAX_ORDER]; N],
    reference: DVec3,
}

impl<'a, const N: usize> Support<'a, N> {
    /// The support at (u, v), clamped to the knot domain, with derivatives up to `order`.
    fn new(surface: &'a BSplineSurface, u: f64, v: f64, order: usize) -> Self {
        let (ku, kv) = (surface.knots_u(), surface.knots_v());
        let (u, v) = (
            u.clamp(ku.domain().0, ku.domain().1),
            v.clamp(kv.domain().0, kv.domain().1),
        );
        let (span_u, span_v) = (ku.find_span(u), kv.find_span(v));
        // Filled in place: the tables are a kilobyte, too much to copy on every evaluation.
        let mut support = Self {
            surface,
            span_u,
            span_v,
            bu: [[0.0; MAX_ORDER]; N],
            bv: [[0.0; MAX_ORDER]; N],
            reference: DVec3::ZERO,
        };
        basis_ders(ku, span_u, u, order, &mut support.bu);
        basis_ders(kv, span_v, v, order, &mut support.bv);
        let (p, q) = (ku.degree(), kv.degree());
        support.reference = dominant((0..=q).flat_map(|b| {
            let support = &support;
            (0..=p).map(move |a| {
                let index = support.index(a, b);
                (
                    support.bu[0][a] * support.bv[0][b],
                    support.surface.local_points()[index],
                    support.surface.homogeneous_points()[index].w,
                )
            })
        }));
        support
    }

    /// The index of control point (a, b) of the support (a ≤ p along u, b ≤ q along v).
    fn index(&self, a: usize, b: usize) -> usize {
        let (p, q) = (self.surface.degree_u(), self.surface.degree_v());
        (self.span_v - q + b) * self.surface.count_u() + self.span_u - p + a
    }

    /// Control point (a, b) of the support, rebased to the reference.
    fn point(&self, a: usize, b: usize) -> DVec4 {
        let index = self.index(a, b);
        rebased(
            self.surface.local_points()[index],
            self.surface.homogeneous_points()[index].w,
            self.reference,
        )
    }
}

impl BSplineCurve {
    /// Position and first derivative (tangent, model units per unit of parameter) at `u`,
    /// clamped to the knot domain.
    pub fn evaluate(&self, u: f64) -> (DVec3, DVec3) {
        let [position, first, _] = self.derivatives(u);
        (position, first)
    }

    /// The point at `u`.
    pub fn point(&self, u: f64) -> DVec3 {
        self.evaluate(u).0
    }

    /// Position, first and second derivative at `u` (clamped to the knot domain).
    pub fn derivatives(&self, u: f64) -> [DVec3; 3] {
        let [local, first, second] = self.local_derivatives(u);
        [self.origin() + local, first, second]
    }

    /// As [`BSplineCurve::derivatives`] with the position relative to
    /// [`origin`](Self::origin), evaluated in that frame.
    pub(crate) fn local_derivatives(&self, u: f64) -> [DVec3; 3] {
        self.local_derivatives_to::<3>(u)
    }

    /// The position relative to [`origin`](Self::origin) and the first N − 1 derivatives at
    /// `u` (clamped to the knot domain; N ≤ 4): the quotient rule on the homogeneous
    /// derivatives, C⁽ᵏ⁾ = (A⁽ᵏ⁾ − Σₘ₌₁..ₖ C(k, m)·w⁽ᵐ⁾·C⁽ᵏ⁻ᵐ⁾) / w.
    pub(crate) fn local_derivatives_to<const N: usize>(&self, u: f64) -> [DVec3; N] {
        let knots = self.knots();
        let p = knots.degree();
        let span = knots.find_span(u);
        let mut basis = [[0.0; MAX_ORDER]; N];
        let (a, b) = knots.domain();
        basis_ders(knots, span, u.clamp(a, b), N - 1, &mut basis);
        let points = &self.local_points()[span - p..=span];
        let weights = self.homogeneous_points()[span - p..=span]
            .iter()
            .map(|h| h.w);
        let reference = dominant(
            (basis[0].iter().copied().zip(points.iter().copied()))
                .zip(weights.clone())
                .map(|((n, pt), w)| (n, pt, w)),
        );
        let mut h = [DVec4::ZERO; N];
        for (r, (&pt, w)) in points.iter().zip(weights).enumerate() {
            let pt = rebased(pt, w, reference);
            for (k, hk) in h.iter_mut().enumerate() {
                *hk += basis[k][r] * pt;
            }
        }
        let mut cartesian = [DVec3::ZERO; N];
        for k in 0..N {
            let mut value = h[k].truncate();
            for m in 1..=k {
                value -= BINOMIAL[k][m] * h[m].w * cartesian[k - m];
            }
            cartesian[k] = value / h[0].w;
        }
        cartesian[0] += reference;
        cartesian
    }
}

/// What one parameter value contributes: the two opposite boundaries there (positions
/// relative to the patch's origin) with their first N − 1 derivatives, and α..α⁽ᴺ⁻¹⁾ of the
/// blend — to second order for sampling, third for limit normals. A grid column (u) holds
/// S(u,0) and S(u,1); a grid row (v) holds S(0,v) and S(1,v).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Rail<const N: usize = 3> {
    pub near: [DVec3; N],
    pub far: [DVec3; N],
    pub blend: [f64; N],
    /// 1 − α ([`crate::geom::patches::BlendSample::complement`]).
    pub complement: f64,
}

impl<const N: usize> Rail<N> {
    /// [F₀⁽ᵏ⁾, F₁⁽ᵏ⁾] with F₀ = α and F₁ = 1 − α.
    fn blend_pair(&self, k: usize) -> (f64, f64) {
        if k == 0 {
            (self.blend[0], self.complement)
        } else {
            (self.blend[k], -self.blend[k])
        }
    }
}

impl CoonsPatch {
    /// The column rail at u (`across` = false: S(u,0), S(u,1)) or the row rail at v (true).
    pub(crate) fn rail(&self, t: f64, across: bool) -> Rail {
        let blend = self.blend().sample(t);
        self.rail_with_blend(t, across, blend.derivatives, blend.complement)
    }

    /// As [`CoonsPatch::rail`], with the blend's α..α⁽ᴺ⁻¹⁾ and 1 − α at `t` given (from a
    /// plan).
    pub(crate) fn rail_with_blend<const N: usize>(
        &self,
        t: f64,
        across: bool,
        blend: [f64; N],
        complement: f64,
    ) -> Rail<N> {
        let [v0, v1, u0, u1] = self.boundaries();
        let (near, far) = if across { (u0, u1) } else { (v0, v1) };
        let local = |curve: &BSplineCurve| {
            let mut derivatives = curve.local_derivatives_to::<N>(t);
            derivatives[0] += curve.origin() - self.origin();
            derivatives
        };
        Rail {
            near: local(near),
            far: local(far),
            blend,
            complement,
        }
    }

    /// ∂ᵢᵤ∂ⱼᵥ S from the rails at u and v: every term of the Coons formula is a product of a
    /// function of u and one of v, so each order differentiates its own factors.
    fn derivative<const N: usize>(
        &self,
        column: &Rail<N>,
        row: &Rail<N>,
        i: usize,
        j: usize,
    ) -> DVec3 {
        let [c00, c10, c01, c11] = self.local_corners();
        let (fu, gu) = column.blend_pair(i);
        let (fv, gv) = row.blend_pair(j);
        fv * column.near[i] + gv * column.far[i] + fu * row.near[j] + gu * row.far[j]
            - (fu * fv * c00 + gu * fv * c10 + fu * gv * c01 + gu * gv * c11)
    }

    /// Position, derivatives and normal at (u, v) from the rails there; the normal follows
    /// the contract of [`crate::BSplineSurface::evaluate`] over [0, 1]².
    pub(crate) fn sample_from(&self, column: &Rail, row: &Rail, u: f64, v: f64) -> SurfaceSample {
        let d = |i, j| self.derivative(column, row, i, j);
        let mut sample = SurfaceSample {
            position: self.origin() + d(0, 0),
            du: d(1, 0),
            dv: d(0, 1),
            duu: d(2, 0),
            duv: d(1, 1),
            dvv: d(0, 2),
            normal: DVec3::ZERO,
        };
        let unit = Interval::new(0.0, 1.0);
        sample.normal = limit_normal(
            &sample,
            (u, v),
            (unit, unit),
            degenerate_cross_sq(self.cross_scale(), f64::EPSILON),
            None,
            &|| self.third_derivatives(u, v),
            |u, v| {
                let (column, row) = (self.rail(u, false), self.rail(v, true));
                [
                    self.derivative(&column, &row, 1, 0),
                    self.derivative(&column, &row, 0, 1),
                ]
            },
        );
        sample
    }

    /// [S_uuu, S_uuv, S_uvv, S_vvv] at (u, v), where the blend has a third derivative.
    fn third_derivatives(&self, u: f64, v: f64) -> Option<[DVec3; 4]> {
        let rail = |t: f64, across: bool| {
            let blend = self.blend().sample(t);
            let [a, a1, a2] = blend.derivatives;
            let a3 = self.blend().third_derivative(t)?;
            Some(self.rail_with_blend(t, across, [a, a1, a2, a3], blend.complement))
        };
        let (column, row) = (rail(u, false)?, rail(v, true)?);
        let d = |i, j| self.derivative(&column, &row, i, j);
        Some([d(3, 0), d(2, 1), d(1, 2), d(0, 3)])
    }

    /// Evaluates position, derivatives and normal at (u, v) ∈ [0, 1]².
    pub fn evaluate(&self, u: f64, v: f64) -> SurfaceSample {
        self.sample_from(&self.rail(u, false), &self.rail(v, true), u, v)
    }

    /// [`cross_scale`] of this patch: its control box diagonal over [0, 1]².
    pub fn cross_scale(&self) -> f64 {
        cross_scale(self.size(), 1.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::patches::{Blend, CoonsBoundaries, coons, coons_patch};
    use crate::geom::{Interval, KnotVector, bezier_curve, curves};
    use std::f64::consts::PI;

    /// `point_and_cross` is `evaluate`'s point and S_u × S_v, by its own sums (first
    /// derivatives only): on a rational bicubic × quadratic surface with weights 0.25..4 on
    /// non-uniform knots, 1e3 from the origin, within 1e-13 of the size and of |S_u × S_v|.
    #[test]
    fn point_and_cross_matches_evaluate() {
        let (nu, nv) = (5, 4);
        let points: Vec<DVec3> = (0..nu * nv)
            .map(|k| {
                let (i, j) = ((k % nu) as f64, (k / nu) as f64);
                DVec3::new(1e3 + i, -2e3 + j + 0.3 * i, (0.7 * i + 1.3 * j).sin())
            })
            .collect();
        let weights: Vec<f64> = (0..nu * nv)
            .map(|k| [0.25, 1.0, 4.0, 0.5, 2.0][k % 5])
            .collect();
        let knots_u = KnotVector::try_new(3, vec![0., 0., 0., 0., 0.3, 1., 1., 1., 1.]).unwrap();
        let knots_v = KnotVector::try_new(2, vec![0., 0., 0., 0.6, 1., 1., 1.]).unwrap();
        let surface = BSplineSurface::try_new(knots_u, knots_v, &points, Some(&weights)).unwrap();
        let size = surface.control_box_diagonal();
        for (u, v) in [(0.0, 0.0), (0.1, 0.7), (0.3, 0.6), (0.55, 0.2), (1.0, 0.9)] {
            let sample = surface.evaluate(u, v);
            let (point, cross) = surface.point_and_cross(u, v);
            let expected = sample.du.cross(sample.dv);
            assert!(
                (point - sample.position).length() <= 1e-13 * size,
                "point at ({u}, {v})"
            );
            assert!(
                (cross - expected).length() <= 1e-13 * expected.length(),
                "cross at ({u}, {v}): {cross} vs {expected}"
            );
        }
    }

    /// A directly evaluated Coons patch's third derivatives — the rails' (a rational arc's
    /// included) and the blend's, combined term by term — equal those of its exact B-spline
    /// conversion, which come from the surface's own Leibniz rule on homogeneous derivatives.
    #[test]
    fn coons_third_derivatives_match_the_exact_conversion() {
        let arc = curves::arc(DVec3::X, 1.0, -DVec3::X, DVec3::Z, Interval::new(0.0, PI));
        let cubic = |points: [DVec3; 4], weights: Option<&[f64]>| {
            bezier_curve(3, &points, weights).unwrap()
        };
        let v0 = arc.unwrap();
        let v1 = cubic(
            [
                DVec3::new(0., 3., 0.),
                DVec3::new(0.7, 3.2, 1.),
                DVec3::new(1.4, 2.9, -0.4),
                DVec3::new(2., 3., 0.),
            ],
            Some(&[1.0, 4.0, 0.5, 2.0]),
        );
        let u0 = cubic(
            [
                DVec3::ZERO,
                DVec3::new(-0.5, 1., 0.3),
                DVec3::new(0.2, 2., -0.2),
                DVec3::new(0., 3., 0.),
            ],
            None,
        );
        let u1 = cubic(
            [
                DVec3::new(2., 0., 0.),
                DVec3::new(2.5, 1., -1.),
                DVec3::new(1.6, 2.2, 0.8),
                DVec3::new(2., 3., 0.),
            ],
            None,
        );
        let bounds = || CoonsBoundaries {
            v0: &v0,
            v1: &v1,
            u0: &u0,
            u1: &u1,
        };
        // Off the arc's break at 1/2, where its third derivative jumps.
        let params = [0.0, 0.07, 0.3, 0.45, 0.62, 0.9, 1.0];
        for blend in [Blend::Linear, Blend::Cubic, Blend::Quintic] {
            let exact = coons(bounds(), &blend, 1e-12).unwrap();
            let direct = coons_patch(bounds(), blend.clone(), 1e-12).unwrap();
            let pairs: Vec<_> = params
                .iter()
                .flat_map(|&u| params.iter().map(move |&v| (u, v)))
                .map(|(u, v)| {
                    let ours = direct.third_derivatives(u, v).unwrap();
                    ((u, v), ours, exact.third_derivatives(u, v))
                })
                .collect();
            // The conversion's rounding grows with its degree (the quintic blend over the
            // cubic rails: degree 8): measured ≤ 6.7e-15 of the largest third derivative.
            let largest = pairs
                .iter()
                .flat_map(|(_, ours, _)| ours.map(DVec3::length))
                .fold(0.0, f64::max);
            for ((u, v), ours, theirs) in pairs {
                for (k, (a, b)) in ours.iter().zip(theirs).enumerate() {
                    assert!(
                        (*a - b).length() <= 1e-13 * largest,
                        "{blend:?}: third derivative {k} at ({u}, {v}): {a} vs {b}"
                    );
                }
            }
        }
        let no_third: fn(f64) -> [f64; 3] = |t| [1.0 - t, -1.0, 0.0];
        let function = coons_patch(bounds(), Blend::Function(no_third), 1e-12).unwrap();
        assert_eq!(function.third_derivatives(0.5, 0.5), None);
    }

    /// The degeneracy scale follows |S_u × S_v| under any reparametrisation: a flat bilinear
    /// square (|S_u × S_v| = side² / (w_u·w_v), diagonal² = 2·side²) stands at half its
    /// `cross_scale` over every domain, square or not, wide or narrow — so the degeneracy
    /// rule decides alike for the same surface with rescaled knots.
    #[test]
    fn cross_scale_follows_the_cross_product_under_reparametrisation() {
        let side = 3.0;
        let corners = [
            DVec3::ZERO,
            DVec3::new(side, 0.0, 0.0),
            DVec3::new(0.0, side, 0.0),
            DVec3::new(side, side, 0.0),
        ];
        for (w_u, w_v) in [(1.0, 1.0), (2.0, 0.5), (0.001, 1000.0), (7.0, 1e-4)] {
            let knots = |w: f64| KnotVector::try_new(1, vec![0.0, 0.0, w, w]).unwrap();
            let surface = BSplineSurface::try_new(knots(w_u), knots(w_v), &corners, None).unwrap();
            let sample = surface.evaluate(0.5 * w_u, 0.5 * w_v);
            let ratio = sample.du.cross(sample.dv).length() / surface.cross_scale();
            assert!(
                (ratio - 0.5).abs() < 1e-14,
                "domain {w_u} × {w_v}: |S_u × S_v| / cross_scale = {ratio}, not 1/2"
            );
        }
    }
}
