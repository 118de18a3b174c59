//! The classic curve and surface forms: the lecture notes' worked exercises, exactness of every
//! conversion against closed forms (≤ 1e-12 of the model size), the operations (split, knot
//! insertion, degree elevation, joins, continuity) and their errors.

mod common;

use common::{EXACT_REL, angle};
use glam::DVec3;
use knotwork::geom::curves::{self, Continuity};
use knotwork::geom::patches::{self, Blend, CoonsBoundaries, HermiteCorners};
use knotwork::geom::{bernstein, bezier_curve, bezier_surface, de_casteljau_point, shapes};
use knotwork::{BSplineCurve, BSplineSurface, Error, Interval, KnotVector};
use std::f64::consts::{FRAC_PI_2, PI};

fn p2(x: f64, y: f64) -> DVec3 {
    DVec3::new(x, y, 0.0)
}

fn close(a: DVec3, b: DVec3, size: f64) -> bool {
    (a - b).length() <= EXACT_REL * size
}

fn assert_close(a: DVec3, b: DVec3, size: f64, what: &str) {
    assert!(close(a, b, size), "{what}: {a} vs {b} (size {size})");
}

fn params(n: usize) -> impl Iterator<Item = f64> {
    (0..=n).map(move |k| k as f64 / n as f64)
}

/// The notes' worked Bezier examples at u = 1/4, 1/2, 3/4, by three independent routes:
/// the Bernstein sum, de Casteljau and the B-spline evaluator. (Example 5's printed
/// y(1/4) = 3.875 is a typo: 27/64 + 135/64 + 45/64 = 207/64.)
#[test]
fn worked_bezier_examples() {
    let examples: [(&[DVec3], [DVec3; 3]); 4] = [
        (
            &[p2(1., 1.), p2(2., 3.), p2(4., 3.), p2(6., 4.)],
            [
                p2(123. / 64., 139. / 64.),
                p2(25. / 8., 23. / 8.),
                p2(289. / 64., 217. / 64.),
            ],
        ),
        (
            &[p2(1., 1.), p2(2., 2.), p2(3., 1.)],
            [p2(1.5, 1.375), p2(2., 1.5), p2(2.5, 1.375)],
        ),
        (
            &[p2(10., 100.), p2(50., 100.), p2(70., 120.), p2(100., 150.)],
            [
                p2(2350. / 64., 6630. / 64.),
                p2(58.75, 113.75),
                p2(5050. / 64., 8290. / 64.),
            ],
        ),
        (
            &[p2(0., 1.), p2(2., 5.), p2(5., 5.), p2(8., 0.)],
            [
                p2(107. / 64., 207. / 64.),
                p2(29. / 8., 31. / 8.),
                p2(369. / 64., 181. / 64.),
            ],
        ),
    ];
    for (points, expected) in examples {
        let n = points.len() - 1;
        let curve = bezier_curve(n, points, None).unwrap();
        for (t, want) in [0.25, 0.5, 0.75].into_iter().zip(expected) {
            let sum = (0..=n).fold(DVec3::ZERO, |acc, k| acc + bernstein(n, k, t) * points[k]);
            assert_close(sum, want, 100.0, "Bernstein");
            assert_close(de_casteljau_point(points, t), want, 100.0, "de Casteljau");
            assert_close(curve.point(t), want, 100.0, "B-spline evaluator");
        }
    }
}

/// The periodic cubic B-spline: the corrected basis B₁ = (3u³ − 6u² + 4)/6 (the notes print
/// +6u²), the boundary conditions p(0) = (p0 + 4p1 + p2)/6 and p′(0) = (p2 − p0)/2, equality
/// with the uniform B-spline of the wrapped points at t = 1, and for tension t the start
/// (t·p0 + (6−2t)·p1 + t·p2)/6 with derivative t/2·(p2 − p0), C¹ but not C² at the joints.
#[test]
fn periodic_cubic_with_tension() {
    let pts = [p2(0., 0.), p2(3., 0.5), p2(4., 3.), p2(1., 4.), p2(-1., 2.)];
    let n = pts.len();
    let curve = curves::periodic_cubic(&pts, 1.0).unwrap();
    let [start, velocity, _] = curve.derivatives(0.0);
    assert_close(start, (pts[0] + 4.0 * pts[1] + pts[2]) / 6.0, 5.0, "p(0)");
    assert_close(velocity, (pts[2] - pts[0]) / 2.0, 5.0, "p'(0)");
    let basis = |u: f64| {
        [
            (1.0 - u).powi(3) / 6.0,
            (3.0 * u.powi(3) - 6.0 * u * u + 4.0) / 6.0,
            (-3.0 * u.powi(3) + 3.0 * u * u + 3.0 * u + 1.0) / 6.0,
            u.powi(3) / 6.0,
        ]
    };
    let wrapped: Vec<DVec3> = (0..n + 3).map(|k| pts[k % n]).collect();
    let uniform =
        BSplineCurve::try_new(KnotVector::uniform(3, n + 3).unwrap(), &wrapped, None).unwrap();
    for segment in 0..n {
        for u in params(8) {
            let by_basis = (0..4).fold(DVec3::ZERO, |acc, k| {
                acc + basis(u)[k] * pts[(segment + k) % n]
            });
            let at = segment as f64 + u;
            assert_close(curve.point(at), by_basis, 5.0, "corrected basis");
            assert_close(
                curve.point(at),
                uniform.point(3.0 + at),
                5.0,
                "uniform B-spline",
            );
        }
    }
    // Closed: the end is the start.
    assert_close(curve.point(n as f64), curve.point(0.0), 5.0, "closed");

    let t = 0.5;
    let tense = curves::periodic_cubic(&pts, t).unwrap();
    let [start, velocity, _] = tense.derivatives(0.0);
    assert_close(
        start,
        (t * pts[0] + (6.0 - 2.0 * t) * pts[1] + t * pts[2]) / 6.0,
        5.0,
        "p(0), t",
    );
    assert_close(velocity, t / 2.0 * (pts[2] - pts[0]), 5.0, "p'(0), t");
    let (left, right) = tense.split_at(2.0).unwrap();
    assert_eq!(curves::continuity(&left, &right, 1e-9).parametric, Some(1));
    let (left, right) = curve.split_at(2.0).unwrap();
    assert_eq!(curves::continuity(&left, &right, 1e-9).parametric, Some(2));
}

/// Hermite, Catmull–Rom and natural splines interpolate with the tangents they promise; the
/// natural spline is C² with zero end curvature.
#[test]
fn interpolating_curves() {
    let pts = [p2(0., 0.), p2(1., 2.), p2(3., 1.), p2(4., 3.), p2(6., 2.)];
    let tangents = [p2(1., 1.), p2(2., 0.), p2(0., -1.), p2(1., 3.), p2(2., 2.)];
    let hermite = curves::hermite(&pts, &tangents).unwrap();
    for k in 0..pts.len() {
        let [p, d, _] = hermite.derivatives(k as f64);
        assert_close(p, pts[k], 6.0, "Hermite point");
        assert_close(d, tangents[k], 6.0, "Hermite tangent");
    }
    let tensions = [0.0, 0.5, -1.0, 1.0, 0.0];
    let catmull = curves::catmull_rom(&pts, &tensions).unwrap();
    for k in 1..pts.len() - 1 {
        let [p, d, _] = catmull.derivatives((k - 1) as f64);
        assert_close(p, pts[k], 6.0, "Catmull-Rom point");
        let want = 0.5 * (1.0 - tensions[k]) * (pts[k + 1] - pts[k - 1]);
        assert_close(d, want, 6.0, "Catmull-Rom tangent");
    }
    let natural = curves::natural_cubic(&pts).unwrap();
    let last = (pts.len() - 1) as f64;
    assert!(natural.derivatives(0.0)[2].length() < EXACT_REL * 60.0);
    assert!(natural.derivatives(last)[2].length() < EXACT_REL * 60.0);
    for (k, &point) in pts.iter().enumerate().take(pts.len() - 1).skip(1) {
        assert_close(natural.point(k as f64), point, 6.0, "natural point");
        let (left, right) = natural.split_at(k as f64).unwrap();
        let c = curves::continuity(&left, &right, 1e-10);
        assert_eq!(c.parametric, Some(2), "joint {k}");
    }
}

/// Joining Bezier curves: the notes' C¹ rule (second point of the next curve at
/// p_n + (p_n − p_(n−1))) and C² rule (third at p_(n−2) + 4(p_n − p_(n−1))); a shorter
/// tangent is G¹ but not C¹; a kinked one neither.
#[test]
fn bezier_join_conditions() {
    let p = [p2(0., 0.), p2(1., 2.), p2(3., 2.), p2(4., 0.)];
    let first = bezier_curve(3, &p, None).unwrap();
    let q1 = p[3] + (p[3] - p[2]);
    let q2 = p[1] + 4.0 * (p[3] - p[2]);
    let next = |q1: DVec3, q2: DVec3| bezier_curve(3, &[p[3], q1, q2, p2(9., 1.)], None).unwrap();
    let c = |b: &BSplineCurve| curves::continuity(&first, b, 1e-12);
    assert_eq!(
        c(&next(q1, q2)),
        Continuity {
            parametric: Some(2),
            geometric_tangent: true
        }
    );
    assert_eq!(c(&next(q1, p2(7., 0.))).parametric, Some(1));
    let shorter = p[3] + 0.5 * (p[3] - p[2]);
    assert_eq!(
        c(&next(shorter, q2)),
        Continuity {
            parametric: Some(0),
            geometric_tangent: true
        }
    );
    assert_eq!(
        c(&next(p2(5., 1.), q2)),
        Continuity {
            parametric: Some(0),
            geometric_tangent: false
        }
    );
    let apart = bezier_curve(3, &[p2(4., 1.), q1, q2, p2(9., 1.)], None).unwrap();
    assert_eq!(c(&apart).parametric, None);
    // The joined curve is both curves, one after the other.
    let second = next(q1, q2);
    let joined = curves::join(&[first.clone(), second.clone()], 1e-12).unwrap();
    for u in params(10) {
        assert_close(joined.point(u), first.point(u), 10.0, "first part");
        assert_close(joined.point(1.0 + u), second.point(u), 10.0, "second part");
    }
    let error = curves::join(&[first, apart], 1e-9).unwrap_err();
    assert!(matches!(error, Error::CurvesDoNotMeet { .. }), "{error}");
}

/// Subdivision, knot insertion and degree elevation leave a (rational) curve unchanged; the
/// midpoint split of a cubic gives the notes' A, AB, ABC, ABCD and ABCD, BCD, CD, D.
#[test]
fn curve_operations_preserve_the_curve() {
    let [a, b, c, d] = [p2(0., 0.), p2(1., 3.), p2(4., 3.), p2(5., 0.)];
    let cubic = bezier_curve(3, &[a, b, c, d], None).unwrap();
    let (left, right) = cubic.split_at(0.5).unwrap();
    let (ab, bc, cd) = ((a + b) / 2.0, (b + c) / 2.0, (c + d) / 2.0);
    let (abc, bcd) = ((ab + bc) / 2.0, (bc + cd) / 2.0);
    let abcd = (abc + bcd) / 2.0;
    let cartesian = |curve: &BSplineCurve| -> Vec<DVec3> {
        (0..curve.homogeneous_points().len())
            .map(|i| curve.control_point(i))
            .collect()
    };
    assert_eq!(cartesian(&left), vec![a, ab, abc, abcd]);
    assert_eq!(cartesian(&right), vec![abcd, bcd, cd, d]);

    let knots = KnotVector::try_new(3, vec![0., 0., 0., 0., 1., 2.5, 4., 4., 4., 4.]).unwrap();
    let pts = [
        p2(0., 0.),
        p2(1., 2.),
        p2(2., -1.),
        p2(3., 3.),
        p2(4., 0.),
        p2(5., 1.),
    ];
    let weights = [1.0, 2.0, 0.5, 1.0, 3.0, 1.0];
    let nurbs = BSplineCurve::try_new(knots, &pts, Some(&weights)).unwrap();
    let (lo, hi) = nurbs.control_box();
    assert_close(lo, p2(0., -1.), 6.0, "control box, weighted points");
    assert_close(hi, p2(5., 3.), 6.0, "control box, weighted points");
    let refined = nurbs.with_knot(1.7, 2).unwrap();
    assert_eq!(refined.homogeneous_points().len(), 8);
    let elevated = nurbs.elevated(5).unwrap();
    assert_eq!(elevated.degree(), 5);
    let (left, right) = nurbs.split_at(2.5).unwrap();
    for u in params(40).map(|t| 4.0 * t) {
        let want = nurbs.point(u);
        assert_close(refined.point(u), want, 6.0, "knot insertion");
        assert_close(elevated.point(u), want, 6.0, "degree elevation");
        let half = if u <= 2.5 { &left } else { &right };
        assert_close(half.point(u), want, 6.0, "split");
    }
    assert!(matches!(
        nurbs.split_at(4.0).unwrap_err(),
        Error::ParameterOutside { .. }
    ));
}

/// The bilinear patch and a ruled surface between two cubic Beziers are exactly the Bezier
/// surfaces of degree (1, 1) and (3, 1) with those rows (the notes' question 3b).
#[test]
fn bilinear_and_ruled_are_bezier_surfaces() {
    let corners = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 1.0)];
    let bilinear = patches::bilinear(corners[0], corners[1], corners[2], corners[3]).unwrap();
    for (u, v) in params(4).flat_map(|u| params(4).map(move |v| (u, v))) {
        let want = (1.0 - u) * (1.0 - v) * corners[0]
            + u * (1.0 - v) * corners[1]
            + (1.0 - u) * v * corners[2]
            + u * v * corners[3];
        assert_close(bilinear.point(u, v), want, 2.0, "bilinear");
    }
    let p = [
        DVec3::ZERO,
        DVec3::new(1., 2., 0.),
        DVec3::new(2., -1., 1.),
        DVec3::new(3., 0., 0.),
    ];
    let q = [
        DVec3::new(0., 0., 2.),
        DVec3::new(1., 1., 3.),
        DVec3::new(2., 1., 2.),
        DVec3::new(3., 0., 2.),
    ];
    let ruled = patches::ruled(
        &bezier_curve(3, &p, None).unwrap(),
        &bezier_curve(3, &q, None).unwrap(),
    )
    .unwrap();
    let rows: Vec<DVec3> = p.iter().chain(&q).copied().collect();
    let bezier = bezier_surface(3, 1, &rows, None).unwrap();
    assert_eq!(ruled.knots_u(), bezier.knots_u());
    assert_eq!(ruled.knots_v(), bezier.knots_v());
    assert_eq!(ruled.homogeneous_points(), bezier.homogeneous_points());
}

/// A ruled surface between a rational arc and a cubic: rulings are straight, in Cartesian
/// space, at every u: S(u, v) = (1 − v)·c0(u) + v·c1(u).
#[test]
fn ruled_between_rational_and_polynomial_curves() {
    let arc = curves::arc(DVec3::Z, 2.0, DVec3::X, DVec3::Y, Interval::new(0.0, 2.0)).unwrap();
    let cubic = bezier_curve(
        3,
        &[
            DVec3::X,
            DVec3::Y,
            DVec3::new(-1.0, 2.0, 0.5),
            DVec3::new(-2.0, 0.0, 0.0),
        ],
        None,
    )
    .unwrap();
    let ruled = patches::ruled(&arc, &cubic).unwrap();
    for (u, v) in params(8).flat_map(|u| params(5).map(move |v| (u, v))) {
        let want = (1.0 - v) * arc.point(u) + v * cubic.point(u);
        assert_close(ruled.point(u, v), want, 4.0, "ruled");
    }
    // Rational where either curve is (its weights are the product of theirs).
    assert!(ruled.is_rational());
    assert!(patches::ruled(&cubic, &arc).unwrap().is_rational());
    assert!(!patches::ruled(&cubic, &cubic).unwrap().is_rational());
}

/// Four boundary curves of a Coons patch, mixing a rational arc, a quadratic, a cubic and a
/// natural spline.
fn boundaries() -> [BSplineCurve; 4] {
    let v0 = curves::arc(
        DVec3::new(1.0, 0.0, 0.0),
        1.0,
        -DVec3::X,
        DVec3::Z,
        Interval::new(0.0, PI),
    )
    .unwrap();
    let v1 = bezier_curve(
        2,
        &[
            DVec3::new(0., 3., 0.),
            DVec3::new(1., 3., 1.),
            DVec3::new(2., 3., 0.),
        ],
        None,
    )
    .unwrap();
    let u0 = curves::natural_cubic(&[
        DVec3::ZERO,
        DVec3::new(-0.5, 1., 0.3),
        DVec3::new(0., 2., 0.),
        DVec3::new(0., 3., 0.),
    ])
    .unwrap();
    let u1 = bezier_curve(
        3,
        &[
            DVec3::new(2., 0., 0.),
            DVec3::new(2.5, 1., -1.),
            DVec3::new(2., 2., 1.),
            DVec3::new(2., 3., 0.),
        ],
        None,
    )
    .unwrap();
    [v0, v1, u0, u1]
}

/// The Coons formula evaluated directly from the curves (the independent reference).
fn coons_direct(curves: &[BSplineCurve; 4], alpha: &Blend, u: f64, v: f64) -> DVec3 {
    let at = |c: &BSplineCurve, t: f64| c.point(c.range().lerp(t));
    let [v0, v1, u0, u1] = curves;
    let (au, av) = (alpha.value(u).unwrap(), alpha.value(v).unwrap());
    let (c00, c10, c01, c11) = (at(v0, 0.), at(v0, 1.), at(v1, 0.), at(v1, 1.));
    au * at(u0, v) + (1.0 - au) * at(u1, v) + av * at(v0, u) + (1.0 - av) * at(v1, u)
        - (au * av * c00
            + au * (1.0 - av) * c01
            + (1.0 - au) * av * c10
            + (1.0 - au) * (1.0 - av) * c11)
}

/// Coons patches interpolate all four boundaries exactly and equal the Coons formula inside,
/// for linear, cubic (the notes' α = 1 − 3u² + 2u³), quintic and a custom polynomial blend.
#[test]
fn coons_patches_interpolate_their_boundaries() {
    let curves = boundaries();
    let [v0, v1, u0, u1] = &curves;
    let size = 4.0;
    for blend in [
        Blend::Linear,
        Blend::Cubic,
        Blend::Quintic,
        Blend::Polynomial(vec![1.0, -0.5, -0.5]),
    ] {
        let patch = patches::coons(CoonsBoundaries { v0, v1, u0, u1 }, &blend, 1e-12).unwrap();
        let at = |c: &BSplineCurve, t: f64| c.point(c.range().lerp(t));
        for t in params(24) {
            assert_close(patch.point(t, 0.0), at(v0, t), size, "S(u, 0)");
            assert_close(patch.point(t, 1.0), at(v1, t), size, "S(u, 1)");
            assert_close(patch.point(0.0, t), at(u0, t), size, "S(0, v)");
            assert_close(patch.point(1.0, t), at(u1, t), size, "S(1, v)");
        }
        for (u, v) in params(7).flat_map(|u| params(7).map(move |v| (u, v))) {
            assert_close(
                patch.point(u, v),
                coons_direct(&curves, &blend, u, v),
                size,
                "interior",
            );
        }
    }
    let bad = Blend::Polynomial(vec![1.0, -0.5]);
    assert!(matches!(
        patches::coons(CoonsBoundaries { v0, v1, u0, u1 }, &bad, 1e-12).unwrap_err(),
        Error::InvalidBlend { .. }
    ));
    let error = patches::coons(
        CoonsBoundaries {
            v0: v1,
            v1: v0,
            u0,
            u1,
        },
        &Blend::Linear,
        1e-9,
    )
    .unwrap_err();
    assert!(matches!(error, Error::CurvesDoNotMeet { .. }), "{error}");
}

/// The directly evaluated Coons patch: with polynomial blends it equals the exact B-spline
/// conversion (positions, first and second derivatives ≤ 1e-12 of the size, normals); with the cosine blend (no
/// B-spline form) it interpolates all four boundaries, equals the Coons formula evaluated
/// from the curves, and its derivatives match central differences of its positions.
#[test]
fn direct_coons_evaluation() {
    let curves = boundaries();
    let [v0, v1, u0, u1] = &curves;
    let size = 4.0;
    let bounds = || CoonsBoundaries { v0, v1, u0, u1 };
    let grid = || params(9).flat_map(|u| params(9).map(move |v| (u, v)));
    for blend in [Blend::Linear, Blend::Cubic, Blend::Quintic] {
        let exact = patches::coons(bounds(), &blend, 1e-12).unwrap();
        let direct = patches::coons_patch(bounds(), blend, 1e-12).unwrap();
        for (u, v) in grid() {
            let (a, b) = (direct.evaluate(u, v), exact.evaluate(u, v));
            for (x, y, what) in [
                (a.position, b.position, "S"),
                (a.du, b.du, "S_u"),
                (a.dv, b.dv, "S_v"),
                (a.duu, b.duu, "S_uu"),
                (a.duv, b.duv, "S_uv"),
                (a.dvv, b.dvv, "S_vv"),
            ] {
                // Measured ≤ 1.7e-13 of the size (second derivatives; positions 3.6e-16).
                assert!(
                    (x - y).length() <= 1e-12 * size,
                    "{what} at ({u}, {v}): {x} vs {y}"
                );
            }
            assert!(
                (a.normal - b.normal).length() < 1e-9,
                "normal at ({u}, {v})"
            );
        }
    }
    // A boundary collapsed to a point (a pole along v = 0): the direct patch's limit normals
    // there (from its own second derivatives) are the exact conversion's, which are the
    // limits along the diagonal toward the centre (the conversion's normal 1e-7 along it).
    // At the corners of the cubic blend, where α′ = 0, the first-order term vanishes too
    // and the limit is the second-order term's, from the patch's third derivatives (measured
    // ≤ 3.2e-16 rad from the conversion's). A blend given as a function has no third
    // derivative: there the normal is sampled 1e-6 along the diagonal, 3.6e-6 and 3.1e-6 rad
    // from the limit at (0, 0) and (1, 0).
    let pole = bezier_curve(1, &[DVec3::ZERO, DVec3::ZERO], None).unwrap();
    let to_far_corner = bezier_curve(
        3,
        &[
            DVec3::ZERO,
            DVec3::new(1.2, 1., -0.5),
            DVec3::new(2.5, 2., 0.4),
            DVec3::new(2., 3., 0.),
        ],
        None,
    )
    .unwrap();
    let fan = || CoonsBoundaries {
        v0: &pole,
        v1,
        u0,
        u1: &to_far_corner,
    };
    let cubic_function: fn(f64) -> [f64; 3] = |t| Blend::Cubic.derivatives(t);
    // (the blend, its polynomial for the conversion, whether it has no third derivative)
    for (blend, polynomial, sampled) in [
        (Blend::Linear, Blend::Linear, false),
        (Blend::Cubic, Blend::Cubic, false),
        (Blend::Function(cubic_function), Blend::Cubic, true),
    ] {
        let exact = patches::coons(fan(), &polynomial, 1e-12).unwrap();
        let direct = patches::coons_patch(fan(), blend, 1e-12).unwrap();
        for u in [0.0, 0.2, 0.5, 0.8, 1.0] {
            let (a, b) = (direct.evaluate(u, 0.0), exact.evaluate(u, 0.0));
            assert_eq!(a.du, DVec3::ZERO, "a pole at u = {u}");
            let toward_centre = if u > 0.5 { -1e-7 } else { 1e-7 };
            let near = exact.evaluate(u + toward_centre, 1e-7).normal;
            // The normal turns by up to ~2 rad per unit here: 2.6e-7 measured over the step.
            assert!(angle(b.normal, near) < 1e-6, "u = {u}: {}", b.normal);
            let sampled_corner = sampled && (u == 0.0 || u == 1.0);
            let bar = if sampled_corner { 1e-5 } else { 1e-12 };
            assert!(
                angle(a.normal, b.normal) < bar,
                "pole normal at u = {u}: {} vs {}",
                a.normal,
                b.normal
            );
        }
    }
    // Just off the pole the cross product is tiny but not noise: its terms are the blend's
    // small values, 1 − α(v) ≈ 3v² among them. Formed as 1 − α that term kept a thousandth of
    // its digits at v = 1e-7 and the direct cubic patch's normal was 1.7e-4 rad from the
    // conversion's at (1e-7, 1e-7); from the blend's Bernstein form, ≤ 2.6e-10 measured.
    let direct = patches::coons_patch(fan(), Blend::Cubic, 1e-12).unwrap();
    let exact = patches::coons(fan(), &Blend::Cubic, 1e-12).unwrap();
    for h in [1e-4, 1e-5, 1e-6, 1e-7] {
        for (u, v) in [(h, h), (1.0 - h, h), (0.3, h)] {
            let (a, b) = (direct.evaluate(u, v).normal, exact.evaluate(u, v).normal);
            assert!(
                angle(a, b) < 1e-9,
                "near the pole at ({u}, {v}): {a} vs {b}"
            );
        }
    }
    // The cosine blend (no conversion) has α′ = 0 at its ends too: its pole corners' normals
    // are the second-order limits, against the normal 1e-7 along the diagonal, which
    // converges to them linearly (measured 1.6e-8 and 2.0e-7 rad; the sampled fallback
    // would be ~3e-6 off, 1 − α formed by cancellation 2.4e-4).
    let cosine_fan = patches::coons_patch(fan(), Blend::Cosine, 1e-12).unwrap();
    for (u, toward_centre) in [(0.0, 1e-7), (1.0, -1e-7)] {
        let limit = cosine_fan.evaluate(u, 0.0).normal;
        let near = cosine_fan.evaluate(u + toward_centre, 1e-7).normal;
        assert!(angle(limit, near) < 1e-6, "cosine pole corner u = {u}");
    }
    let cosine = patches::coons_patch(bounds(), Blend::Cosine, 1e-12).unwrap();
    let at = |c: &BSplineCurve, t: f64| c.point(c.range().lerp(t));
    for t in params(24) {
        assert_close(cosine.evaluate(t, 0.0).position, at(v0, t), size, "S(u, 0)");
        assert_close(cosine.evaluate(t, 1.0).position, at(v1, t), size, "S(u, 1)");
        assert_close(cosine.evaluate(0.0, t).position, at(u0, t), size, "S(0, v)");
        assert_close(cosine.evaluate(1.0, t).position, at(u1, t), size, "S(1, v)");
    }
    let h = 1e-5;
    for (u, v) in grid().filter(|&(u, v)| u > 0.0 && u < 1.0 && v > 0.0 && v < 1.0) {
        let s = cosine.evaluate(u, v);
        assert_close(
            s.position,
            coons_direct(&curves, &Blend::Cosine, u, v),
            size,
            "interior",
        );
        let p = |u, v| cosine.evaluate(u, v).position;
        let su = (p(u + h, v) - p(u - h, v)) / (2.0 * h);
        let sv = (p(u, v + h) - p(u, v - h)) / (2.0 * h);
        let suv =
            (p(u + h, v + h) - p(u + h, v - h) - p(u - h, v + h) + p(u - h, v - h)) / (4.0 * h * h);
        // Central differences with h = 1e-5: truncation h² and rounding ε/h (measured
        // 3.9e-10), ε/h² for the mixed one (measured 1.1e-6).
        assert!((s.du - su).length() < 2e-9 * size, "S_u at ({u}, {v})");
        assert!((s.dv - sv).length() < 2e-9 * size, "S_v at ({u}, {v})");
        assert!((s.duv - suv).length() < 1e-5 * size, "S_uv at ({u}, {v})");
    }
    // The cosine blend and its derivatives, against the closed form.
    for t in params(11) {
        let [a, a1, a2] = Blend::Cosine.derivatives(t);
        assert!((a - 0.5 * (1.0 + (PI * t).cos())).abs() < 1e-15);
        assert!((a1 + 0.5 * PI * (PI * t).sin()).abs() < 1e-14);
        assert!((a2 + 0.5 * PI * PI * (PI * t).cos()).abs() < 1e-14);
        let a3 = Blend::Cosine.third_derivative(t).unwrap();
        assert!((a3 - 0.5 * PI * PI * PI * (PI * t).sin()).abs() < 1e-13);
    }
    // Polynomial blends: the notes' cubic α = 1 − 3t² + 2t³, α′ = 6t² − 6t, α″ = 12t − 6.
    for t in params(11) {
        let [a, a1, a2] = Blend::Cubic.derivatives(t);
        assert!((a - (1.0 - 3.0 * t * t + 2.0 * t * t * t)).abs() < 1e-15);
        assert!((a1 - (6.0 * t * t - 6.0 * t)).abs() < 1e-14);
        assert!((a2 - (12.0 * t - 6.0)).abs() < 1e-14);
        assert_eq!(Blend::Cubic.third_derivative(t), Some(12.0));
        // The quintic α = 1 − 10t³ + 15t⁴ − 6t⁵: α‴ = −60 + 360t − 360t².
        let a3 = Blend::Quintic.third_derivative(t).unwrap();
        assert!((a3 - (-60.0 + 360.0 * t - 360.0 * t * t)).abs() < 1e-12);
        assert_eq!(Blend::Linear.third_derivative(t), Some(0.0));
    }
    // Near either end the small one of α and 1 − α keeps its own relative precision: at
    // distance d from the end, the cubic's is 3d² − 2d³ and the cosine's sin²(πd/2).
    for d in [1e-9, 1e-7, 1e-4, 0.1] {
        let far_end = 1.0 - d;
        let d_exact = 1.0 - far_end; // exact (Sterbenz): the distance far_end really has
        let close = |x: f64, y: f64, what: &str| {
            assert!(
                (x - y).abs() <= 1e-14 * y.abs(),
                "{what} at d = {d}: {x} vs {y}"
            );
        };
        // (blend, its small end at distance d, α′ at distance d from t = 1)
        type OfDistance = fn(f64) -> f64;
        let cases: [(Blend, OfDistance, OfDistance); 2] = [
            (
                Blend::Cubic,
                |d| 3.0 * d * d - 2.0 * d * d * d,
                |d| -6.0 * d * (1.0 - d),
            ),
            (
                Blend::Cosine,
                |d| (0.5 * PI * d).sin().powi(2),
                |d| -0.5 * PI * (PI * d).sin(),
            ),
        ];
        for (blend, small, slope) in cases {
            let at_far_end = blend.sample(far_end);
            let what = |name: &str| format!("{blend:?} {name}");
            close(blend.sample(d).complement, small(d), &what("1 − α"));
            close(at_far_end.derivatives[0], small(d_exact), &what("α"));
            close(at_far_end.derivatives[1], slope(d_exact), &what("α′"));
        }
    }
    assert!(matches!(
        patches::coons(bounds(), &Blend::Cosine, 1e-12).unwrap_err(),
        Error::BlendNotPolynomial
    ));
    // Finite coefficients whose evaluation overflows (terms of ±1e308): NaN at both ends,
    // which compares false with anything — only the finiteness check refuses it.
    let overflowing = Blend::Polynomial(vec![1.0, 1e308, -1e308, 0.0]);
    let [at_zero, at_one] = [0.0, 1.0].map(|t| overflowing.derivatives(t)[0]);
    assert!(at_zero.is_nan() && at_one.is_nan());
    assert!(matches!(
        overflowing.check().unwrap_err(),
        Error::InvalidBlend { .. }
    ));
    // Each end on its own, held to 1e-12: α(0) or α(1) off by 2e-12 is refused, by 5e-13
    // accepted.
    let ends =
        |at_zero: f64, at_one: f64| Blend::Polynomial(vec![at_zero, at_one - at_zero]).check();
    for (at_zero, at_one) in [(0.5, 0.0), (1.0, 0.5), (1.0 + 2e-12, 0.0), (1.0, 2e-12)] {
        assert!(
            matches!(ends(at_zero, at_one), Err(Error::InvalidBlend { .. })),
            "α(0) = {at_zero}, α(1) = {at_one} accepted"
        );
    }
    for (at_zero, at_one) in [(1.0 + 5e-13, 0.0), (1.0, 5e-13), (1.0 - 5e-13, -5e-13)] {
        assert!(
            ends(at_zero, at_one).is_ok(),
            "α(0) = {at_zero}, α(1) = {at_one}"
        );
    }
    let not_a_blend: fn(f64) -> [f64; 3] = |t| [t, 1.0, 0.0];
    assert!(matches!(
        patches::coons_patch(bounds(), Blend::Function(not_a_blend), 1e-12).unwrap_err(),
        Error::InvalidBlend { .. }
    ));
}

/// The four quarter arcs of the notes' two semicircles (xy- and xz-plane, unit radius) as the
/// boundaries S(u,0), S(u,1), S(0,v), S(1,v) of a Coons patch with corners (1,0,0), (0,1,0),
/// (0,0,1), (−1,0,0).
fn quarter_arcs() -> [BSplineCurve; 4] {
    let quarter = |y: DVec3, from: f64| {
        curves::arc(
            DVec3::ZERO,
            1.0,
            DVec3::X,
            y,
            Interval::new(from, from + FRAC_PI_2),
        )
        .unwrap()
    };
    [
        quarter(DVec3::Y, 0.0),
        quarter(DVec3::Z, FRAC_PI_2),
        quarter(DVec3::Z, 0.0),
        quarter(DVec3::Y, FRAC_PI_2),
    ]
}

/// The notes' question 2: the quarter sphere from revolving the xy semicircle 90° about x, and
/// the Coons patch of the four quarter arcs, at (0.5, 0.5): (0, √2/2, √2/2) and
/// (0, √2/2 − ¼, √2/2 − ¼) — not equal.
#[test]
fn two_semicircle_surfaces() {
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let semicircle =
        curves::arc(DVec3::ZERO, 1.0, DVec3::X, DVec3::Y, Interval::new(0.0, PI)).unwrap();
    let revolved = shapes::revolve(
        &semicircle,
        DVec3::ZERO,
        DVec3::X,
        Interval::new(0.0, FRAC_PI_2),
    )
    .unwrap();
    assert_close(
        revolved.point(0.5, 0.5),
        DVec3::new(0.0, h, h),
        1.0,
        "revolution",
    );
    let [v0, v1, u0, u1] = quarter_arcs();
    let coons = patches::coons(
        CoonsBoundaries {
            v0: &v0,
            v1: &v1,
            u0: &u0,
            u1: &u1,
        },
        &Blend::Linear,
        1e-12,
    )
    .unwrap();
    assert_close(
        coons.point(0.5, 0.5),
        DVec3::new(0.0, h - 0.25, h - 0.25),
        1.0,
        "Coons",
    );
    // Every point of the revolved surface is on the unit sphere.
    for (u, v) in params(9).flat_map(|u| params(9).map(move |v| (u, v))) {
        assert!((revolved.point(u, v).length() - 1.0).abs() <= EXACT_REL);
    }
}

/// The notes' question 1: the line (2,0,0)–(1,2,0) revolved 180° about y is the cone
/// x² + z² = (2 − y/2)²; its bicubic Hermite approximation from the exact corners, tangents
/// and twists is exact along v but off in the middle: (0, 1, −3π/8·1.5/… ) = (0, 1, −0.375π)
/// against the cone's (0, 1, −1.5).
#[test]
fn cone_of_revolution_against_its_bicubic_approximation() {
    let line = bezier_curve(1, &[DVec3::new(2., 0., 0.), DVec3::new(1., 2., 0.)], None).unwrap();
    let cone = shapes::revolve(&line, DVec3::ZERO, DVec3::Y, Interval::new(0.0, PI)).unwrap();
    for (u, v) in params(8).flat_map(|u| params(4).map(move |v| (u, v))) {
        let p = cone.point(u, v);
        let r = 2.0 - p.y / 2.0;
        assert!(
            ((p.x * p.x + p.z * p.z).sqrt() - r).abs() <= EXACT_REL * 4.0,
            "{p}"
        );
        assert!(p.z <= EXACT_REL, "the half turn runs through −z: {p}");
    }
    assert_close(
        cone.point(0.5, 0.5),
        DVec3::new(0.0, 1.0, -1.5),
        4.0,
        "cone",
    );
    // Exact parametrisation P(u, v) = ((2 − v) cos πu, 2v, −(2 − v) sin πu) and its derivatives.
    let s = |u: f64, v: f64| {
        DVec3::new(
            (2.0 - v) * (PI * u).cos(),
            2.0 * v,
            -(2.0 - v) * (PI * u).sin(),
        )
    };
    let su = |u: f64, v: f64| PI * (2.0 - v) * DVec3::new(-(PI * u).sin(), 0.0, -(PI * u).cos());
    let sv = |u: f64, _v: f64| DVec3::new(-(PI * u).cos(), 2.0, (PI * u).sin());
    let suv = |u: f64, _v: f64| PI * DVec3::new((PI * u).sin(), 0.0, (PI * u).cos());
    let corners = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)];
    let data = HermiteCorners {
        points: corners.map(|(u, v)| s(u, v)),
        du: corners.map(|(u, v)| su(u, v)),
        dv: corners.map(|(u, v)| sv(u, v)),
        twists: corners.map(|(u, v)| suv(u, v)),
    };
    let bicubic = patches::hermite_patch(&data).unwrap();
    assert_close(
        bicubic.point(0.5, 0.5),
        DVec3::new(0.0, 1.0, -0.375 * PI),
        4.0,
        "bicubic",
    );
}

/// Hermite patch corner values, tangents and twists are the data it was built from.
#[test]
fn hermite_patch_corner_data() {
    let data = HermiteCorners {
        points: [
            DVec3::ZERO,
            DVec3::new(2., 0., 0.),
            DVec3::new(0., 2., 0.),
            DVec3::new(2., 2., 1.),
        ],
        du: [
            DVec3::new(2., 0., 1.),
            DVec3::new(2., 0., -1.),
            DVec3::new(2., 0.5, 0.),
            DVec3::new(2., 0., 0.),
        ],
        dv: [
            DVec3::new(0., 2., 0.),
            DVec3::new(0., 2., 1.),
            DVec3::new(0.3, 2., 0.),
            DVec3::new(0., 2., 0.),
        ],
        twists: [
            DVec3::new(0., 0., 0.5),
            DVec3::ZERO,
            DVec3::new(0.2, 0., 0.),
            DVec3::new(0., 0., 1.),
        ],
    };
    let patch = patches::hermite_patch(&data).unwrap();
    for (k, (u, v)) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
        .into_iter()
        .enumerate()
    {
        let sample = patch.evaluate(u, v);
        assert_close(sample.position, data.points[k], 3.0, "corner");
        assert_close(sample.du, data.du[k], 3.0, "S_u");
        assert_close(sample.dv, data.dv[k], 3.0, "S_v");
        assert_close(sample.duv, data.twists[k], 3.0, "S_uv");
    }
}

/// The notes' bicubic example S = (0.5 + 2v + v³ − uv² − 4u³v³, 3v² + 5u²v, 1 + 2.5u − 1.5u²v³)
/// from its algebraic coefficients.
#[test]
fn algebraic_bicubic_of_the_notes() {
    let z = DVec3::ZERO;
    let a = |x: f64, y: f64, w: f64| DVec3::new(x, y, w);
    let coefficients = vec![
        vec![a(0.5, 0., 1.), a(2., 0., 0.), a(0., 3., 0.), a(1., 0., 0.)],
        vec![a(0., 0., 2.5), z, a(-1., 0., 0.), z],
        vec![z, a(0., 5., 0.), z, a(0., 0., -1.5)],
        vec![z, z, z, a(-4., 0., 0.)],
    ];
    let patch = patches::algebraic(&coefficients).unwrap();
    for (u, v) in params(6).flat_map(|u| params(6).map(move |v| (u, v))) {
        let want = DVec3::new(
            0.5 + 2.0 * v + v.powi(3) - u * v * v - 4.0 * u.powi(3) * v.powi(3),
            3.0 * v * v + 5.0 * u * u * v,
            1.0 + 2.5 * u - 1.5 * u * u * v.powi(3),
        );
        assert_close(patch.point(u, v), want, 10.0, "bicubic");
    }
}

/// Largest |implicit(p)| over a grid of the surface.
fn worst_residual(surface: &BSplineSurface, implicit: impl Fn(DVec3) -> f64) -> f64 {
    let (ru, rv) = (surface.range_u(), surface.range_v());
    params(16)
        .flat_map(|s| params(16).map(move |t| (s, t)))
        .map(|(s, t)| implicit(surface.point(ru.lerp(s), rv.lerp(t))).abs())
        .fold(0.0, f64::max)
}

/// Every quadric lies on its implicit surface: the residual of its normalised equation is
/// ≤ 1e-12 (measured ≤ 4.4e-15) over its parameter
/// ranges, and its range ends land on the requested angles and heights.
#[test]
fn quadrics_lie_on_their_implicit_surfaces() {
    let c = DVec3::new(1.0, -2.0, 3.0);
    let full = shapes::FULL_TURN;
    let r = DVec3::new(3.0, 2.0, 1.5);
    let rel = |p: DVec3| (p - c) / r;
    let ellipsoid =
        shapes::ellipsoid(c, r, Interval::new(0.3, 4.0), Interval::new(-1.0, 1.2)).unwrap();
    assert!(worst_residual(&ellipsoid, |p| rel(p).length_squared() - 1.0) <= EXACT_REL);
    let start = rel(ellipsoid.point(0.0, 0.0));
    assert!(
        (start.z - (-1.0f64).sin()).abs() <= EXACT_REL
            && (start.y.atan2(start.x) - 0.3).abs() <= EXACT_REL
    );

    let torus = shapes::torus_section(
        c,
        2.0,
        0.5,
        Interval::new(0.0, PI),
        Interval::new(-1.0, 2.0),
    )
    .unwrap();
    assert!(
        worst_residual(&torus, |p| {
            let q = p - c;
            let ring = (q.x * q.x + q.y * q.y).sqrt() - 2.0;
            ring * ring + q.z * q.z - 0.25
        }) <= EXACT_REL
    );

    let one = shapes::hyperboloid_one_sheet(c, r, full, Interval::new(-2.0, 3.0)).unwrap();
    assert!(
        worst_residual(&one, |p| {
            let q = rel(p);
            q.x * q.x + q.y * q.y - q.z * q.z - 1.0
        }) <= EXACT_REL
    );
    assert!((one.point(0.0, 0.0).z - (c.z - 2.0)).abs() <= EXACT_REL * 10.0);
    assert!((one.point(0.0, 1.0).z - (c.z + 3.0)).abs() <= EXACT_REL * 10.0);

    let [upper, lower] = shapes::hyperboloid_two_sheets(c, r, full, 4.0).unwrap();
    for sheet in [&upper, &lower] {
        assert!(
            worst_residual(sheet, |p| {
                let q = rel(p);
                q.z * q.z - q.x * q.x - q.y * q.y - 1.0
            }) <= EXACT_REL
        );
    }
    // Normals follow the gradient: +z at the upper vertex, −z at the lower.
    assert!(upper.evaluate(0.3, 1.0).normal.z > 0.999);
    assert!(lower.evaluate(0.3, 0.0).normal.z < -0.999);

    let cylinder = shapes::elliptic_cylinder(
        c,
        3.0,
        2.0,
        Interval::new(0.0, FRAC_PI_2),
        Interval::new(0.0, 2.0),
    )
    .unwrap();
    assert_eq!(
        (cylinder.degree_u(), cylinder.degree_v()),
        (2, 1),
        "one rational Bezier patch"
    );
    assert_eq!(
        cylinder.count_u(),
        3,
        "the quarter cylinder is a single segment"
    );
    assert!(
        worst_residual(&cylinder, |p| {
            let q = p - c;
            q.x * q.x / 9.0 + q.y * q.y / 4.0 - 1.0
        }) <= EXACT_REL
    );

    let paraboloid =
        shapes::elliptic_paraboloid(c, 3.0, 2.0, 0.5, full, Interval::new(0.2, 1.5)).unwrap();
    assert!(
        worst_residual(&paraboloid, |p| {
            let q = p - c;
            q.x * q.x / 9.0 + q.y * q.y / 4.0 - 0.5 * q.z
        }) <= EXACT_REL
    );

    let saddle = shapes::hyperbolic_paraboloid(
        c,
        3.0,
        2.0,
        0.5,
        Interval::new(-1.0, 2.0),
        Interval::new(-3.0, 1.0),
    )
    .unwrap();
    assert!(
        worst_residual(&saddle, |p| {
            let q = p - c;
            q.x * q.x / 9.0 - q.y * q.y / 4.0 - 0.5 * q.z
        }) <= EXACT_REL
    );

    let cone = shapes::elliptic_cone(c, 3.0, 2.0, full, Interval::new(-1.0, 2.0)).unwrap();
    assert!(
        worst_residual(&cone, |p| {
            let q = p - c;
            q.x * q.x / 9.0 + q.y * q.y / 4.0 - q.z * q.z
        }) <= EXACT_REL
    );
}

/// Subdividing a patch at u and at v: the halves are the surface.
#[test]
fn surface_split_preserves_the_surface() {
    let torus = shapes::torus(DVec3::ZERO, 2.0, 0.5);
    let (a, b) = torus.split_u(0.3).unwrap();
    let (c, d) = torus.split_v(0.55).unwrap();
    for (u, v) in params(12).flat_map(|u| params(12).map(move |v| (u, v))) {
        let want = torus.point(u, v);
        let by_u = if u <= 0.3 { &a } else { &b };
        let by_v = if v <= 0.55 { &c } else { &d };
        assert_close(by_u.point(u, v), want, 5.0, "split u");
        assert_close(by_v.point(u, v), want, 5.0, "split v");
    }
    assert!(matches!(
        torus.split_u(1.0).unwrap_err(),
        Error::ParameterOutside { .. }
    ));
}

/// The control box of a surface made from another's control points (split, transposed,
/// reseamed) is the box of its own control points, also far from the origin where the points
/// are kept relative to the parent's origin.
#[test]
fn derived_surfaces_keep_their_control_boxes() {
    let far = DVec3::new(1.0e5, -2.0e5, 3.0e5);
    let torus = shapes::torus(far, 2.0, 0.5);
    let (a, b) = torus.split_u(0.3).unwrap();
    let (c, d) = torus.split_v(0.55).unwrap();
    let reseamed = torus.reseamed_v(0.4).expect("a torus closes along v");
    let derived = [&a, &b, &c, &d, &torus.transposed(), &reseamed];
    for (k, surface) in derived.into_iter().enumerate() {
        let points = (0..surface.count_v())
            .flat_map(|j| (0..surface.count_u()).map(move |i| surface.control_point(i, j)));
        let want = points.fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        });
        let (lo, hi) = surface.control_box();
        // The points are rounded once when made absolute: a few ulps of the offset.
        let ulps = 4.0 * f64::EPSILON * far.abs().max_element();
        assert!(
            lo.abs_diff_eq(want.0, ulps) && hi.abs_diff_eq(want.1, ulps),
            "surface {k}: box {lo} .. {hi}, control points span {} .. {}",
            want.0,
            want.1
        );
    }
}

/// `surface` with the knots `knots_v` along v and each control point and weight replaced by
/// `edit(i, j, point, weight)`.
fn rebuilt(
    surface: &BSplineSurface,
    knots_v: &KnotVector,
    edit: impl Fn(usize, usize, DVec3, f64) -> (DVec3, f64),
) -> BSplineSurface {
    let (mut points, mut weights) = (Vec::new(), Vec::new());
    for j in 0..surface.count_v() {
        for i in 0..surface.count_u() {
            let (p, w) = edit(i, j, surface.control_point(i, j), surface.weight(i, j));
            points.push(p);
            weights.push(w);
        }
    }
    BSplineSurface::try_new(
        surface.knots_u().clone(),
        knots_v.clone(),
        &points,
        Some(&weights),
    )
    .unwrap()
}

/// `surface`'s knots along v mapped linearly onto the domain [v0, v1].
fn knots_v_on(surface: &BSplineSurface, (v0, v1): (f64, f64)) -> KnotVector {
    let (a, b) = surface.knots_v().domain();
    let knots: Vec<f64> = (surface.knots_v().knots().iter())
        .map(|k| v0 + (k - a) / (b - a) * (v1 - v0))
        .collect();
    KnotVector::try_new(surface.degree_v(), knots).unwrap()
}

/// Splitting exactly at a range end is refused: the halves would be empty.
#[test]
fn splits_at_the_range_ends_are_refused() {
    let torus = shapes::torus(DVec3::ZERO, 2.0, 0.5);
    for t in [0.0, 1.0] {
        for result in [torus.split_u(t), torus.split_v(t)] {
            assert!(
                matches!(result.unwrap_err(), Error::ParameterOutside { .. }),
                "t = {t}"
            );
        }
    }
}

/// Moving the seam of a closed surface whose domain does not start at 0 (v in [2, 5]):
/// the range becomes [c, c + 3] and the surface is the same point set, shifted by the
/// period past the old seam. Surfaces that do not close — an open section, a last row off
/// by 1e-9 of the size, weights that differ by 1e-3, a range short of the domain, unclamped
/// knots — are refused; rows and weights that agree to half the 1e-12 tolerance (at a size
/// and weights of ~1e3, so the relative bound matters) are accepted.
#[test]
fn reseaming_moves_the_seam_of_closed_surfaces_only() {
    let torus = shapes::torus(DVec3::ZERO, 2.0, 0.5);
    let on_2_5 = knots_v_on(&torus, (2.0, 5.0));
    let closed = rebuilt(&torus, &on_2_5, |_, _, p, w| (p, w));
    let c = 3.2;
    let moved = closed.reseamed_v(c).expect("a full torus closes along v");
    assert_eq!(moved.range_v(), Interval::new(c, c + 3.0));
    assert_eq!(moved.range_u(), closed.range_u());
    for u in params(8) {
        for v in params(12).map(|t| 2.0 + 3.0 * t) {
            let shifted = if v < c { v + 3.0 } else { v };
            assert_close(
                moved.point(u, shifted),
                closed.point(u, v),
                5.0,
                "reseamed v",
            );
        }
    }
    let transposed = closed.transposed().reseamed_u(c).expect("closes along u");
    assert_close(
        transposed.point(4.0, 0.3),
        closed.point(0.3, 4.0),
        5.0,
        "reseamed u",
    );

    let last = closed.count_v() - 1;
    let size = closed.control_box_diagonal();
    let nudged = rebuilt(&torus, &on_2_5, |_, j, p, w| {
        (
            if j == last {
                p + DVec3::X * 1e-9 * size
            } else {
                p
            },
            w,
        )
    });
    let reweighted = rebuilt(&torus, &on_2_5, |_, j, p, w| {
        (p, if j == last { w * 1.001 } else { w })
    });
    let section = shapes::torus_section(
        DVec3::ZERO,
        2.0,
        0.5,
        Interval::new(0.0, 2.0 * PI),
        Interval::new(0.0, 1.5 * PI),
    )
    .unwrap();
    let shortened = closed
        .clone()
        .with_range(closed.range_u(), Interval::new(2.0, 4.5))
        .unwrap();
    let unclamped_knots = KnotVector::uniform(2, closed.count_v()).unwrap();
    let unclamped = rebuilt(&closed, &unclamped_knots, |_, _, p, w| (p, w));
    for (what, surface) in [
        ("nudged last row", &nudged),
        ("last row's weights differ", &reweighted),
        ("open section", &section),
        ("range short of the domain", &shortened),
        ("unclamped", &unclamped),
    ] {
        let c = surface.range_v().lerp(0.4);
        assert!(surface.reseamed_v(c).is_none(), "{what} was reseamed");
    }

    // Size ~2.6e3 and weights ~1e3: agreement to half of 1e-12 relative is closed.
    let scaled = |edit_last: bool| {
        rebuilt(&torus, &on_2_5, move |_, j, p, w| {
            let (p, w) = (p * 512.0, w * 1024.0);
            if edit_last && j == last {
                (p + DVec3::X * 0.5e-12 * (512.0 * size), w * (1.0 + 0.5e-12))
            } else {
                (p, w)
            }
        })
    };
    assert!(scaled(false).control_box_diagonal() >= 512.0 * size * (1.0 - 1e-15));
    let big = scaled(true);
    assert!(
        big.reseamed_v(c).is_some(),
        "rows within the tolerance refused"
    );
}

/// Degrees of the exact Coons conversion: polynomial boundaries keep deg α + p; rational arcs
/// multiply weights (cubic blend over arcs: 3 + 2 + 2 = 7).
#[test]
fn coons_degrees() {
    let [v0, v1, u0, u1] = quarter_arcs();
    let arcs = CoonsBoundaries {
        v0: &v0,
        v1: &v1,
        u0: &u0,
        u1: &u1,
    };
    let patch = patches::coons(arcs, &Blend::Cubic, 1e-12).unwrap();
    assert_eq!((patch.degree_u(), patch.degree_v()), (7, 7));
    let line = |a: DVec3, b: DVec3| bezier_curve(1, &[a, b], None).unwrap();
    let (a, b, c, d) = (DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 0.5));
    let lines = [line(a, b), line(c, d), line(a, c), line(b, d)];
    let flat = patches::coons(
        CoonsBoundaries {
            v0: &lines[0],
            v1: &lines[1],
            u0: &lines[2],
            u1: &lines[3],
        },
        &Blend::Linear,
        1e-12,
    )
    .unwrap();
    assert_eq!(
        (flat.degree_u(), flat.degree_v()),
        (1, 1),
        "the Coons patch of four lines is bilinear"
    );
    assert!(!flat.is_rational());
}

/// Errors of the forms name what is wrong.
#[test]
fn form_errors() {
    let two = [DVec3::ZERO, DVec3::X];
    assert!(matches!(
        curves::catmull_rom(&two, &[0.0]).unwrap_err(),
        Error::TooFewPoints {
            found: 2,
            min: 4,
            ..
        }
    ));
    assert!(matches!(
        curves::hermite(&two, &[DVec3::X]).unwrap_err(),
        Error::ControlPointCount { .. }
    ));
    assert!(matches!(
        shapes::ellipsoid(
            DVec3::ZERO,
            DVec3::ONE,
            shapes::FULL_TURN,
            Interval::new(-2.0, 1.0)
        )
        .unwrap_err(),
        Error::ParameterOutside {
            name: "latitude",
            ..
        }
    ));
    assert!(matches!(
        shapes::hyperboloid_two_sheets(DVec3::ZERO, DVec3::ONE, shapes::FULL_TURN, 0.5)
            .unwrap_err(),
        Error::ParameterOutside { name: "height", .. }
    ));
    assert!(matches!(
        shapes::elliptic_paraboloid(
            DVec3::ZERO,
            1.0,
            1.0,
            0.0,
            shapes::FULL_TURN,
            Interval::new(0.0, 1.0)
        )
        .unwrap_err(),
        Error::InvalidParameter { name: "c", .. }
    ));
    assert!(matches!(
        shapes::unit_arc(Interval::new(0.0, 7.0)).unwrap_err(),
        Error::ParameterOutside { .. }
    ));
}

/// Two bicubic Bezier patches joined along u: sharing the boundary column gives C⁰; mirroring
/// the last inner column through it (P₀ʲ of the second = 2P₃ʲ − P₂ʲ of the first) gives C¹;
/// a shorter mirror keeps G¹ only; a bent one loses G¹.
#[test]
fn patch_join_continuity() {
    let first: Vec<DVec3> = (0..16)
        .map(|k| {
            DVec3::new(
                (k % 4) as f64,
                (k / 4) as f64,
                (((k % 4) * (k / 4)) as f64 * 0.3).sin(),
            )
        })
        .collect();
    let second = |scale: f64, bend: f64| {
        let mut points = Vec::with_capacity(16);
        for j in 0..4 {
            let (p2, p3) = (first[j * 4 + 2], first[j * 4 + 3]);
            let q1 = p3 + scale * (p3 - p2) + DVec3::new(0.0, 0.0, bend * j as f64);
            points.extend([
                p3,
                q1,
                q1 + DVec3::new(1.0, 0.1, 0.2),
                q1 + DVec3::new(2.0, 0.0, -0.3),
            ]);
        }
        bezier_surface(3, 3, &points, None).unwrap()
    };
    let a = bezier_surface(3, 3, &first, None).unwrap();
    let measure =
        |b: &BSplineSurface| patches::continuity(&a, b, patches::JoinDirection::U, 9, 1e-9);
    assert_eq!(measure(&second(1.0, 0.0)).parametric, Some(1));
    assert!(measure(&second(1.0, 0.0)).geometric_tangent);
    assert_eq!(
        measure(&second(0.5, 0.0)),
        Continuity {
            parametric: Some(0),
            geometric_tangent: true
        }
    );
    assert_eq!(
        measure(&second(1.0, 0.4)),
        Continuity {
            parametric: Some(0),
            geometric_tangent: false
        }
    );
    // Along v, the transposed patches join the same way.
    let c1 = patches::continuity(
        &a.transposed(),
        &second(1.0, 0.0).transposed(),
        patches::JoinDirection::V,
        9,
        1e-9,
    );
    assert_eq!(c1.parametric, Some(1));
}

/// Degenerate tori (tube wider than its distance from the axis): the apple keeps the tube's
/// arc outside the axis, every point at the tube radius from the near side of the major
/// circle; the lemon the arc beyond it, at the tube radius from the far side; both meet the
/// axis at their poles z = ±√(r² − R²) and their normals point away from the tube centre
/// they belong to. A tube no wider than R is the ordinary torus; a negative major radius is
/// refused.
#[test]
fn degenerate_tori_keep_their_apple_or_lemon() {
    let (centre, major, minor): (DVec3, f64, f64) = (DVec3::new(1.0, -2.0, 0.5), 1.5, 2.5);
    let pole = (minor * minor - major * major).sqrt();
    for outer in [true, false] {
        let surface =
            shapes::degenerate_torus_section(centre, major, minor, outer, shapes::FULL_TURN)
                .unwrap();
        let (ru, rv) = (surface.range_u(), surface.range_v());
        for (end, z) in [(rv.start, -pole), (rv.end, pole)] {
            for s in params(6) {
                let p = surface.point(ru.lerp(s), end) - centre;
                assert!(
                    p.truncate().length() < 1e-12 && (p.z - z).abs() < 1e-12,
                    "{outer}: pole {p}"
                );
            }
        }
        for s in params(12) {
            for t in params(12).filter(|&t| t > 0.0 && t < 1.0) {
                let sample = surface.evaluate(ru.lerp(s), rv.lerp(t));
                let p = sample.position - centre;
                let rho = p.truncate().length();
                // The tube centre this point belongs to: the near or the far side of the major circle.
                let side = if outer { major } else { -major };
                let tube_centre = (p.truncate() / rho * side).extend(0.0);
                let off = ((p - tube_centre).length() - minor).abs();
                assert!(off < 1e-12 * minor, "{outer}: {p} is {off:e} off its tube");
                assert!(
                    sample.normal.dot((p - tube_centre).normalize()) > 1.0 - 1e-9,
                    "{outer}: normal {} at {p}",
                    sample.normal
                );
            }
        }
    }
    // A negative or non-finite major radius is no torus.
    for major in [-0.5, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            shapes::degenerate_torus_section(centre, major, minor, true, shapes::FULL_TURN),
            Err(Error::InvalidParameter {
                name: "major radius",
                ..
            })
        ));
    }
    let ordinary = shapes::degenerate_torus_section(centre, 2.5, 1.5, true, shapes::FULL_TURN);
    assert_eq!(
        ordinary.unwrap(),
        shapes::torus_section(centre, 2.5, 1.5, shapes::FULL_TURN, shapes::FULL_TURN).unwrap()
    );
}
