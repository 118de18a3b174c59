//! Classic patch forms, each converted exactly (up to f64 rounding) to a rational
//! [`BSplineSurface`] so that one evaluator and one GPU kernel family serve them all:
//! bilinear, ruled, Coons (bilinear or polynomial blends), algebraic (power basis) and
//! Hermite patches. Curves are reparametrised onto [0, 1] first; so are the patches.

use super::piecewise::{Piecewise, Value, binomial, merged_breaks};
use super::{BSplineCurve, BSplineSurface, KnotVector, bezier_surface};
use crate::error::{Error, Result};
use glam::{DVec3, DVec4};
use std::f64::consts::PI;

/// The bilinear patch with corners S(0,0) = p00, S(1,0) = p10, S(0,1) = p01, S(1,1) = p11:
/// (1−u)(1−v)p00 + u(1−v)p10 + (1−u)v·p01 + uv·p11.
pub fn bilinear(p00: DVec3, p10: DVec3, p01: DVec3, p11: DVec3) -> Result<BSplineSurface> {
    bezier_surface(1, 1, &[p00, p10, p01, p11], None)
}

/// A curve over [0, 1] split into its numerator N (x·w, y·w, z·w) and weight W, as Bezier
/// pieces; a curve with unit weights gets the constant 1 (so products do not raise degrees).
fn numerator_and_weight(curve: &BSplineCurve) -> (Piecewise<DVec3>, Piecewise<f64>) {
    let pieces = curve.bezier_form().reparametrized(0.0, 1.0);
    let weight = if pieces.coeffs.iter().all(|c| c.w == 1.0) {
        Piecewise::constant(1.0, 0.0, 1.0)
    } else {
        pieces.map(|c| c.w)
    };
    (pieces.map(DVec4::truncate), weight)
}

/// A degree and breakpoints that several piecewise polynomials are raised and refined to, so
/// that their Bernstein coefficients share one basis.
struct CommonForm {
    degree: usize,
    breaks: Vec<f64>,
}

impl CommonForm {
    /// The highest degree (at least 1) and the union of the breakpoints of `functions`, given
    /// as (degree, breakpoints).
    fn of<'a>(functions: impl IntoIterator<Item = (usize, &'a [f64])>) -> Self {
        let (degrees, breaks): (Vec<usize>, Vec<&[f64]>) = functions.into_iter().unzip();
        Self {
            degree: degrees.into_iter().max().unwrap_or(1).max(1),
            breaks: merged_breaks(breaks),
        }
    }

    /// The coefficients of each function in this form.
    fn apply<T: Value, const N: usize>(&self, functions: [Piecewise<T>; N]) -> [Vec<T>; N] {
        functions.map(|f| f.conformed(self.degree, &self.breaks).coeffs)
    }

    fn knots(&self) -> Result<KnotVector> {
        KnotVector::from_breakpoints(self.degree, &self.breaks)
    }
}

fn shape<T>(f: &Piecewise<T>) -> (usize, &[f64]) {
    (f.degree, &f.breaks)
}

fn surface(
    form_u: &CommonForm,
    form_v: &CommonForm,
    points: Vec<DVec4>,
    rational: bool,
) -> Result<BSplineSurface> {
    Ok(BSplineSurface::from_homogeneous(
        form_u.knots()?,
        form_v.knots()?,
        &points,
        rational,
    ))
}

/// The ruled surface S(u, v) = (1 − v)·c0(u) + v·c1(u) between any two curves (each over its
/// range, mapped onto u ∈ [0, 1]). Exact also for rational curves with different weights: the
/// surface is [(1−v)·N0·W1 + v·N1·W0] / (W0·W1), of degree p0 + p1 in u then.
pub fn ruled(c0: &BSplineCurve, c1: &BSplineCurve) -> Result<BSplineSurface> {
    let (n0, w0) = numerator_and_weight(c0);
    let (n1, w1) = numerator_and_weight(c1);
    let (a, b, weight) = (w1.times(&n0), w0.times(&n1), w0.times(&w1));
    let form = CommonForm::of([shape(&a), shape(&b), shape(&weight)]);
    let [a, b] = form.apply([a, b]);
    let [weight] = form.apply([weight]);
    // Row v = 0 is c0's numerator, row v = 1 c1's, both over the weight W0·W1.
    let points: Vec<DVec4> = a
        .iter()
        .chain(&b)
        .zip(weight.iter().cycle())
        .map(|(n, &w)| n.extend(w))
        .collect();
    let rational = c0.is_rational() || c1.is_rational();
    let linear = CommonForm {
        degree: 1,
        breaks: vec![0.0, 1.0],
    };
    surface(&form, &linear, points, rational)
}

/// A Coons blending function α on [0, 1] with α(0) = 1 and α(1) = 0; its partner is 1 − α.
#[derive(Debug, Clone)]
pub enum Blend {
    /// α(t) = 1 − t: the bilinearly blended Coons patch.
    Linear,
    /// α(t) = 1 − 3t² + 2t³ (the Hermite f₀): the patch meets the boundary ruled surfaces'
    /// cross-boundary tangents with zero blend slope.
    Cubic,
    /// α(t) = 1 − 10t³ + 15t⁴ − 6t⁵: zero blend slope and curvature at both ends.
    Quintic,
    /// α(t) = Σ cᵢ tⁱ, coefficients from the constant term up.
    Polynomial(Vec<f64>),
    /// α(t) = (1 + cos πt) / 2: smooth, zero slope at both ends. Not a polynomial, so no
    /// exact B-spline form: a [`CoonsPatch`] evaluates it directly, on both paths.
    Cosine,
    /// Any α, given as t ↦ [α(t), α′(t), α″(t)]; evaluated directly like [`Blend::Cosine`].
    Function(fn(f64) -> [f64; 3]),
}

impl Blend {
    /// Power-basis coefficients of a polynomial blend (unchecked); `None` for the others.
    fn coefficients(&self) -> Option<&[f64]> {
        match self {
            Blend::Linear => Some(&[1.0, -1.0]),
            Blend::Cubic => Some(&[1.0, 0.0, -3.0, 2.0]),
            Blend::Quintic => Some(&[1.0, 0.0, 0.0, -10.0, 15.0, -6.0]),
            Blend::Polynomial(c) => Some(c),
            Blend::Cosine | Blend::Function(_) => None,
        }
    }

    /// Power-basis coefficients of α, checked (see [`Blend::check`]); a blend that is not a
    /// polynomial is refused with [`Error::BlendNotPolynomial`].
    pub fn power_coefficients(&self) -> Result<Vec<f64>> {
        self.check()?;
        self.coefficients()
            .map(<[f64]>::to_vec)
            .ok_or(Error::BlendNotPolynomial)
    }

    /// Checks that α is finite at both ends with α(0) = 1 and α(1) = 0 (within 1e-12).
    pub fn check(&self) -> Result<()> {
        let ends = [self.derivatives(0.0), self.derivatives(1.0)];
        let (at_zero, at_one) = (ends[0][0], ends[1][0]);
        let finite = ends.iter().flatten().all(|x| x.is_finite())
            && self
                .coefficients()
                .is_none_or(|c| c.iter().all(|x| x.is_finite()));
        if !finite || (at_zero - 1.0).abs() > 1e-12 || at_one.abs() > 1e-12 {
            return Err(Error::InvalidBlend { at_zero, at_one });
        }
        Ok(())
    }

    /// α, α′, α″ and 1 − α at `t` (unchecked), each to the relative precision of its own
    /// magnitude where the blend is a polynomial or [`Blend::Cosine`]: near t = 0 (α → 1),
    /// 1 − α is not formed by cancellation, and near t = 1 (α → 0) neither is α. Next to a
    /// boundary collapsed to a point, these small terms are all S_u has: formed as 1 − α, a
    /// cubic blend's 3v² at v = 1e-7 kept only a thousandth of its digits.
    pub fn sample(&self, t: f64) -> BlendSample {
        match (self, self.coefficients()) {
            (_, Some(c)) => polynomial_sample(c, t),
            (Blend::Function(f), None) => {
                let derivatives = f(t);
                BlendSample {
                    derivatives,
                    complement: 1.0 - derivatives[0],
                }
            }
            (_, None) => {
                // α = cos²(πt/2), 1 − α = sin²(πt/2), at x = t or, reflected, at x = 1 − t
                // (exact for t ≥ ½), so the small one of the two comes from a small sine.
                let reflected = t > 0.5;
                let x = if reflected { 1.0 - t } else { t };
                let (sin, cos) = (0.5 * PI * x).sin_cos();
                let (near, far) = (cos * cos, sin * sin);
                let (alpha, complement) = if reflected { (far, near) } else { (near, far) };
                BlendSample {
                    // α′ = −(π/2)·sin πt, α″ = −(π²/2)·cos πt.
                    derivatives: [
                        alpha,
                        -PI * sin * cos,
                        -0.5 * PI * PI * (alpha - complement),
                    ],
                    complement,
                }
            }
        }
    }

    /// [α(t), α′(t), α″(t)] (unchecked; see [`Blend::sample`]).
    pub fn derivatives(&self, t: f64) -> [f64; 3] {
        self.sample(t).derivatives
    }

    /// α‴(t) (unchecked), where the blend defines it: polynomial blends and
    /// [`Blend::Cosine`]; `None` for [`Blend::Function`], which gives only α..α″.
    pub fn third_derivative(&self, t: f64) -> Option<f64> {
        match (self, self.coefficients()) {
            (_, Some(c)) => {
                let mut derivatives = [0.0; 4];
                bernstein_derivatives(&bernstein_polygon(c), t, &mut derivatives);
                Some(derivatives[3])
            }
            (Blend::Function(_), None) => None,
            (_, None) => Some(0.5 * PI * PI * PI * (PI * t).sin()),
        }
    }

    /// α(t), checked.
    pub fn value(&self, t: f64) -> Result<f64> {
        self.check()?;
        Ok(self.derivatives(t)[0])
    }
}

/// A blend at one parameter t: [α, α′, α″] and 1 − α ([`Blend::sample`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlendSample {
    pub derivatives: [f64; 3],
    /// 1 − α(t), to the relative precision of its own magnitude.
    pub complement: f64,
}

/// [`Blend::sample`] of the polynomial Σ cᵢ tⁱ (at least one coefficient): α, α′, α″ from
/// [`bernstein_derivatives`] and 1 − α from the coefficients 1 − bₖ.
fn polynomial_sample(c: &[f64], t: f64) -> BlendSample {
    let alpha = bernstein_polygon(c);
    let mut derivatives = [0.0; 3];
    bernstein_derivatives(&alpha, t, &mut derivatives);
    let mut complement: Vec<f64> = alpha.iter().map(|b| 1.0 - b).collect();
    BlendSample {
        derivatives,
        complement: convex_de_casteljau(&mut complement, t),
    }
}

/// The Bernstein form on [0, 1] of the polynomial Σ cᵢ tⁱ (at least one coefficient): bₖ =
/// Σᵢ₌₀..ₖ C(k, i)·cᵢ / C(n, i) — exact for the built-in blends, whose bₖ are 0 and 1.
fn bernstein_polygon(c: &[f64]) -> Vec<f64> {
    let n = c.len() - 1;
    (0..=n)
        .map(|k| {
            (0..=k)
                .map(|i| binomial(k, i) * c[i] / binomial(n, i))
                .sum()
        })
        .collect()
}

/// The value and derivatives at t ∈ [0, 1] of the Bernstein polygon `b` (at least one
/// coefficient) into `out[k]`, k < `out.len()`: the k-th derivative is n!/(n − k)! times
/// the polygon of b's k-th forward differences, each evaluated by de Casteljau's convex
/// combinations, which keep a sum of terms of one sign to its own relative precision at
/// either end.
fn bernstein_derivatives(b: &[f64], t: f64, out: &mut [f64]) {
    let n = b.len() - 1;
    let mut differences = b.to_vec();
    let mut scratch = Vec::with_capacity(b.len());
    out.fill(0.0);
    for (k, derivative) in out.iter_mut().enumerate().take(n + 1) {
        if k > 0 {
            for i in 0..=n - k {
                differences[i] = differences[i + 1] - differences[i];
            }
        }
        scratch.clear();
        scratch.extend_from_slice(&differences[..=n - k]);
        let falling: f64 = (0..k).map(|i| (n - i) as f64).product();
        *derivative = falling * convex_de_casteljau(&mut scratch, t);
    }
}

/// The value at t ∈ [0, 1] of the Bernstein polygon `b` (overwritten), by (1 − t)·a + t·b.
fn convex_de_casteljau(b: &mut [f64], t: f64) -> f64 {
    let s = 1.0 - t;
    for level in 1..b.len() {
        for i in 0..b.len() - level {
            b[i] = s * b[i] + t * b[i + 1];
        }
    }
    b[0]
}

/// The four boundaries of a Coons patch: S(u, 0), S(u, 1), S(0, v), S(1, v), each over its own
/// range mapped onto [0, 1].
#[derive(Debug, Clone, Copy)]
pub struct CoonsBoundaries<'a> {
    pub v0: &'a BSplineCurve,
    pub v1: &'a BSplineCurve,
    pub u0: &'a BSplineCurve,
    pub u1: &'a BSplineCurve,
}

/// The Coons patch of four boundary curves with blend α (in both directions):
/// S = α(u)·S(0,v) + (1−α(u))·S(1,v) + α(v)·S(u,0) + (1−α(v))·S(u,1)
///     − [α(u), 1−α(u)]·[[S(0,0), S(0,1)], [S(1,0), S(1,1)]]·[α(v), 1−α(v)]ᵀ.
/// The corners must agree within `tolerance` (model units). Exact: with polynomial blends and
/// (rational) B-spline boundaries every term is a tensor product of piecewise polynomials over
/// the common denominator W(u,v) = W_v0(u)·W_v1(u)·W_u0(v)·W_u1(v), so the patch is a rational
/// B-spline of degree deg α + deg(W_v0·W_v1·N) (for non-rational curves: deg α + curve degree).
pub fn coons(curves: CoonsBoundaries<'_>, blend: &Blend, tolerance: f64) -> Result<BSplineSurface> {
    let alpha = Piecewise::from_power(&blend.power_coefficients()?);
    let one_minus_alpha = alpha.map(|c| 1.0 - c);
    let corners = check_corners(&curves, tolerance)?;
    let (nq0, wq0) = numerator_and_weight(curves.v0);
    let (nq1, wq1) = numerator_and_weight(curves.v1);
    let (np0, wp0) = numerator_and_weight(curves.u0);
    let (np1, wp1) = numerator_and_weight(curves.u1);
    // Along u: the v-boundaries' numerators and the u-blends, all over W_v0·W_v1.
    let du = wq0.times(&wq1);
    let along_u = [alpha.times(&du), one_minus_alpha.times(&du), du];
    let curves_u = [wq1.times(&nq0), wq0.times(&nq1)];
    // Along v: the same with the u-boundaries.
    let dv = wp0.times(&wp1);
    let along_v = [alpha.times(&dv), one_minus_alpha.times(&dv), dv];
    let curves_v = [wp1.times(&np0), wp0.times(&np1)];
    let form_u = CommonForm::of(along_u.iter().map(shape).chain(curves_u.iter().map(shape)));
    let form_v = CommonForm::of(along_v.iter().map(shape).chain(curves_v.iter().map(shape)));
    let [au, bu, wu] = form_u.apply(along_u);
    let [q0, q1] = form_u.apply(curves_u);
    let [av, bv, wv] = form_v.apply(along_v);
    let [p0, p1] = form_v.apply(curves_v);
    let [c00, c10, c01, c11] = corners;
    let mut points = Vec::with_capacity(au.len() * av.len());
    for j in 0..av.len() {
        for i in 0..au.len() {
            let xyz = au[i] * p0[j] + bu[i] * p1[j] + q0[i] * av[j] + q1[i] * bv[j]
                - c00 * (au[i] * av[j])
                - c01 * (au[i] * bv[j])
                - c10 * (bu[i] * av[j])
                - c11 * (bu[i] * bv[j]);
            points.push(xyz.extend(wu[i] * wv[j]));
        }
    }
    let rational = [curves.v0, curves.v1, curves.u0, curves.u1]
        .iter()
        .any(|c| c.is_rational());
    surface(&form_u, &form_v, points, rational)
}

/// A Coons patch evaluated directly from its four boundary curves and its blend, on (u, v) ∈
/// [0, 1]² — the form of blends with no exact B-spline conversion ([`Blend::Cosine`],
/// [`Blend::Function`]); polynomial blends work too (and convert exactly with [`coons`]).
/// Tessellated by [`crate::Tessellator::tessellate_coons_into`] on either path.
#[derive(Debug, Clone)]
pub struct CoonsPatch {
    boundaries: [BSplineCurve; 4],
    corners: [DVec3; 4],
    blend: Blend,
    /// The centre of the control box: evaluation is relative to it.
    origin: DVec3,
    /// The corners relative to `origin`, from the v-boundaries evaluated in their own frames
    /// (consistent with the rails to rounding of the model's size, not of its offset).
    local_corners: [DVec3; 4],
}

/// The directly evaluated Coons patch of `curves` (corners within `tolerance`, model units)
/// with any checked `blend`; the formula is that of [`coons`].
pub fn coons_patch(
    curves: CoonsBoundaries<'_>,
    blend: Blend,
    tolerance: f64,
) -> Result<CoonsPatch> {
    blend.check()?;
    let corners = check_corners(&curves, tolerance)?;
    let unit = |c: &BSplineCurve| c.unit_parametrized();
    let boundaries = [
        unit(curves.v0)?,
        unit(curves.v1)?,
        unit(curves.u0)?,
        unit(curves.u1)?,
    ];
    let (lo, hi) = boxes_union(boundaries.iter().map(BSplineCurve::control_box));
    let origin = 0.5 * (lo + hi);
    let local_end =
        |curve: &BSplineCurve, t: f64| curve.local_derivatives(t)[0] + (curve.origin() - origin);
    let [v0, v1, ..] = &boundaries;
    let local_corners = [
        local_end(v0, 0.0),
        local_end(v0, 1.0),
        local_end(v1, 0.0),
        local_end(v1, 1.0),
    ];
    Ok(CoonsPatch {
        boundaries,
        corners,
        blend,
        origin,
        local_corners,
    })
}

impl CoonsPatch {
    /// S(u, 0), S(u, 1), S(0, v), S(1, v), each reparametrized to the range [0, 1].
    pub fn boundaries(&self) -> &[BSplineCurve; 4] {
        &self.boundaries
    }
    /// S(0,0), S(1,0), S(0,1), S(1,1).
    pub fn corners(&self) -> [DVec3; 4] {
        self.corners
    }
    pub fn blend(&self) -> &Blend {
        &self.blend
    }
    /// Bounding box (min, max) of the boundaries' control points.
    pub fn control_box(&self) -> (DVec3, DVec3) {
        boxes_union(self.boundaries.iter().map(BSplineCurve::control_box))
    }
    /// The local origin evaluation is relative to: the centre of the control box.
    pub fn origin(&self) -> DVec3 {
        self.origin
    }
    /// [`CoonsPatch::corners`] relative to [`CoonsPatch::origin`].
    pub(crate) fn local_corners(&self) -> [DVec3; 4] {
        self.local_corners
    }
    /// Diagonal of [`CoonsPatch::control_box`]: the size relative tolerances refer to.
    pub fn size(&self) -> f64 {
        let (lo, hi) = self.control_box();
        (hi - lo).length()
    }
}

/// The smallest box (min, max) holding every box of `boxes`.
fn boxes_union(boxes: impl Iterator<Item = (DVec3, DVec3)>) -> (DVec3, DVec3) {
    boxes.fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), (a, b)| (lo.min(a), hi.max(b)),
    )
}

/// The corners S(0,0), S(1,0), S(0,1), S(1,1) from the v-boundaries, checked against the
/// u-boundaries' ends.
fn check_corners(curves: &CoonsBoundaries<'_>, tolerance: f64) -> Result<[DVec3; 4]> {
    let start = |c: &BSplineCurve| c.point(c.range().start);
    let end = |c: &BSplineCurve| c.point(c.range().end);
    let corners = [
        start(curves.v0),
        end(curves.v0),
        start(curves.v1),
        end(curves.v1),
    ];
    let others = [
        (start(curves.u0), "S(0,0): start of u0 and v0"),
        (start(curves.u1), "S(1,0): start of u1 and end of v0"),
        (end(curves.u0), "S(0,1): end of u0 and start of v1"),
        (end(curves.u1), "S(1,1): end of u1 and v1"),
    ];
    for (corner, (other, at)) in corners.iter().zip(others) {
        let gap = (*corner - other).length();
        if gap.is_nan() || gap > tolerance {
            return Err(Error::CurvesDoNotMeet {
                at: format!("corner {at}"),
                gap,
            });
        }
    }
    Ok(corners)
}

/// The polynomial patch S(u, v) = Σᵢ Σⱼ a_ij uⁱ vʲ on [0, 1]², with `coefficients[i][j]` =
/// a_ij (rows: powers of u; every row the same length), converted to Bernstein form — e.g.
/// the bicubic patch [1 u u² u³]·A·[1 v v² v³]ᵀ.
pub fn algebraic(coefficients: &[Vec<DVec3>]) -> Result<BSplineSurface> {
    if coefficients.is_empty() {
        return Err(Error::ControlPointCount {
            expected: 1,
            found: 0,
            what: "at least one row of coefficients",
        });
    }
    let degree_u = coefficients.len() - 1;
    let degree_v = coefficients
        .first()
        .map_or(0, |row| row.len().saturating_sub(1));
    for row in coefficients {
        if row.len() != degree_v + 1 {
            return Err(Error::ControlPointCount {
                expected: degree_v + 1,
                found: row.len(),
                what: "the same number of v powers in every row of coefficients",
            });
        }
    }
    // Convert along v for each power of u, then along u for each Bernstein index in v.
    let along_v: Vec<Vec<DVec3>> = coefficients
        .iter()
        .map(|row| Piecewise::from_power(row).coeffs)
        .collect();
    let mut points = vec![DVec3::ZERO; (degree_u + 1) * (degree_v + 1)];
    for l in 0..=degree_v {
        let column: Vec<DVec3> = along_v.iter().map(|row| row[l]).collect();
        for (k, b) in Piecewise::from_power(&column)
            .coeffs
            .into_iter()
            .enumerate()
        {
            points[l * (degree_u + 1) + k] = b;
        }
    }
    bezier_surface(degree_u, degree_v, &points, None)
}

/// The boundary data of a bicubic Hermite patch, each array ordered by corner (u, v) =
/// (0,0), (1,0), (0,1), (1,1): positions, ∂S/∂u, ∂S/∂v and twists ∂²S/∂u∂v.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HermiteCorners {
    pub points: [DVec3; 4],
    pub du: [DVec3; 4],
    pub dv: [DVec3; 4],
    pub twists: [DVec3; 4],
}

/// The bicubic Hermite patch S(u, v) = F(u)·G·F(v)ᵀ with F = [f₀ f₁ f₂ f₃], f₀ = 1 − 3t² + 2t³,
/// f₁ = 3t² − 2t³, f₂ = t − 2t² + t³, f₃ = t³ − t², and G the 4×4 geometry matrix of corner
/// points, tangents and twists. Exact change of basis to a bicubic Bezier patch: along each
/// direction, (P₀, P₁, T₀, T₁) ↦ (P₀, P₀ + T₀/3, P₁ − T₁/3, P₁).
pub fn hermite_patch(corners: &HermiteCorners) -> Result<BSplineSurface> {
    let HermiteCorners {
        points: s,
        du,
        dv,
        twists,
    } = corners;
    // G[i][j]: i over (S(0,·), S(1,·), S_u(0,·), S_u(1,·)), j over (·(0), ·(1), ∂v(0), ∂v(1)).
    let g = [
        [s[0], s[2], dv[0], dv[2]],
        [s[1], s[3], dv[1], dv[3]],
        [du[0], du[2], twists[0], twists[2]],
        [du[1], du[3], twists[1], twists[3]],
    ];
    let h = [
        [1.0, 0.0, 0.0, 0.0],
        [1.0, 0.0, 1.0 / 3.0, 0.0],
        [0.0, 1.0, 0.0, -1.0 / 3.0],
        [0.0, 1.0, 0.0, 0.0],
    ];
    let mut points = Vec::with_capacity(16);
    for hl in &h {
        for hk in &h {
            let mut b = DVec3::ZERO;
            for (i, gi) in g.iter().enumerate() {
                for (j, gij) in gi.iter().enumerate() {
                    b += hk[i] * hl[j] * *gij;
                }
            }
            points.push(b);
        }
    }
    bezier_surface(3, 3, &points, None)
}

/// Which edge two patches share: `U` — the u = end edge of the first and the u = start edge of
/// the second (they follow each other along u); `V` — likewise along v.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JoinDirection {
    U,
    V,
}

/// Measures the continuity across the edge two patches share, at `samples` (≥ 2) points
/// along it matched by their fraction of each edge's range: positions (C⁰), cross-edge
/// derivatives of orders 1 and 2 (C¹, C²) and normals (G¹), each equal within `relative`
/// × its size (positions: × the larger control box diagonal).
pub fn continuity(
    a: &BSplineSurface,
    b: &BSplineSurface,
    direction: JoinDirection,
    samples: usize,
    relative: f64,
) -> super::curves::Continuity {
    let size = a.control_box_diagonal().max(b.control_box_diagonal());
    let close = |x: DVec3, y: DVec3, scale: f64| (x - y).length() <= relative * scale;
    let mut parametric = Some(2u8);
    let mut geometric_tangent = true;
    for k in 0..samples.max(2) {
        let t = k as f64 / (samples.max(2) - 1) as f64;
        let (sa, sb, cross) = match direction {
            JoinDirection::U => {
                let (ea, eb) = (
                    a.evaluate(a.range_u().end, a.range_v().lerp(t)),
                    b.evaluate(b.range_u().start, b.range_v().lerp(t)),
                );
                (ea, eb, [(ea.du, eb.du), (ea.duu, eb.duu)])
            }
            JoinDirection::V => {
                let (ea, eb) = (
                    a.evaluate(a.range_u().lerp(t), a.range_v().end),
                    b.evaluate(b.range_u().lerp(t), b.range_v().start),
                );
                (ea, eb, [(ea.dv, eb.dv), (ea.dvv, eb.dvv)])
            }
        };
        let mut order = if close(sa.position, sb.position, size) {
            Some(0u8)
        } else {
            None
        };
        if order.is_some() {
            for (k, (da, db)) in cross.iter().enumerate() {
                if close(
                    *da,
                    *db,
                    da.length().max(db.length()).max(f64::MIN_POSITIVE),
                ) {
                    order = Some(k as u8 + 1);
                } else {
                    break;
                }
            }
        }
        parametric = parametric.min(order);
        let parallel =
            sa.normal.cross(sb.normal).length() <= relative && sa.normal.dot(sb.normal) > 0.0;
        geometric_tangent &= order.is_some() && parallel;
    }
    super::curves::Continuity {
        parametric,
        geometric_tangent,
    }
}
