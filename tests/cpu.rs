//! The f64 reference path: knot vectors, basis functions, evaluation, normals, Bezier
//! extraction and grid tessellation, against closed forms, an independent evaluator and
//! properties.

mod common;

use common::*;
use glam::{DMat3, DVec3};
use knotwork::geom::{bezier_curve, bezier_surface, piecewise_bezier_surface};
use knotwork::{
    BSplineCurve, BSplineSurface, CpuTessellator, Error, Interval, KnotVector, Mesh, TessOptions,
    Tessellator, Tolerance,
};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

/// Central finite differences of a smooth surface: O(h²) truncation plus rounding/h.
const FD_REL: f64 = 1e-6;

// ---------------------------------------------------------------- exact values

#[test]
fn cubic_bezier_at_quarter_is_exact() {
    let points = [
        DVec3::new(1.0, 1.0, 0.0),
        DVec3::new(2.0, 3.0, 0.0),
        DVec3::new(4.0, 3.0, 0.0),
        DVec3::new(6.0, 4.0, 0.0),
    ];
    let curve = bezier_curve(3, &points, None).unwrap();
    let p = curve.point(0.25);
    assert!(
        (p - DVec3::new(123.0 / 64.0, 139.0 / 64.0, 0.0)).length() < 1e-15,
        "{p}"
    );
}

#[test]
fn quadratic_basis_on_bezier_knots_is_bernstein() {
    let knots = KnotVector::try_new(2, vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0]).unwrap();
    for k in 0..=16 {
        let u = k as f64 / 16.0;
        let (span, values) = knots.basis_values(u);
        assert_eq!(span, 2);
        let bernstein = [(1.0 - u) * (1.0 - u), 2.0 * u * (1.0 - u), u * u];
        for (a, b) in values.iter().zip(bernstein) {
            assert!((a - b).abs() < 1e-15, "u={u}: {values:?} vs {bernstein:?}");
        }
    }
}

#[test]
fn standard_knot_vector_for_8_points_order_4() {
    let knots = KnotVector::clamped_uniform(3, 8).unwrap();
    assert_eq!(
        knots.knots(),
        &[0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 5.0, 5.0, 5.0]
    );
    assert!(knots.is_clamped());
    let uniform = KnotVector::uniform(3, 8).unwrap();
    assert_eq!(
        uniform.knots(),
        &(0..12).map(f64::from).collect::<Vec<_>>()[..]
    );
    assert_eq!(uniform.domain(), (3.0, 8.0));
    assert!(!uniform.is_clamped());
    // Clamped means degree + 1 equal knots at both ends: one end, or degree at an end, is not.
    let clamped = |knots: &[f64]| KnotVector::try_new(3, knots.to_vec()).unwrap().is_clamped();
    assert!(!clamped(&[0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0]));
    assert!(!clamped(&[0.0, 1.0, 2.0, 3.0, 4.0, 4.0, 4.0, 4.0]));
    assert!(!clamped(&[0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 2.0, 2.0]));
    assert!(!clamped(&[0.0, 0.0, 0.0, 1.0, 2.0, 2.0, 2.0, 2.0]));
    assert!(clamped(&[0.0, 0.0, 0.0, 0.0, 2.0, 2.0, 2.0, 2.0]));
    // Too few control points for the degree is said as such, not as too few knots.
    for made in [KnotVector::clamped_uniform(3, 3), KnotVector::uniform(3, 3)] {
        assert!(matches!(
            made,
            Err(knotwork::Error::ControlPointCount {
                expected: 4,
                found: 3,
                ..
            })
        ));
    }
    assert_eq!(
        KnotVector::clamped_uniform(3, 4).unwrap().control_count(),
        4
    );
    assert_eq!(KnotVector::uniform(3, 4).unwrap().control_count(), 4);
}

#[test]
fn find_span_handles_ends_and_repeated_knots() {
    let knots = KnotVector::try_new(2, vec![0.0, 0.0, 0.0, 1.0, 1.0, 2.0, 3.0, 3.0, 3.0]).unwrap();
    assert_eq!(knots.find_span(0.0), 2);
    assert_eq!(knots.find_span(0.999), 2);
    assert_eq!(knots.find_span(1.0), 4);
    assert_eq!(knots.find_span(2.5), 5);
    assert_eq!(knots.find_span(3.0), 5);
    // Unclamped ends whose domain knots repeat inwards: the spans next to them.
    let inner = KnotVector::try_new(2, vec![0.0, 0.0, 1.0, 1.0, 2.0, 3.0, 3.0, 4.0, 5.0]).unwrap();
    assert_eq!(inner.domain(), (1.0, 3.0));
    assert_eq!(inner.find_span(0.0), 3);
    assert_eq!(inner.find_span(1.0), 3);
    assert_eq!(inner.find_span(2.5), 4);
    assert_eq!(inner.find_span(3.0), 4);
    assert_eq!(inner.find_span(9.0), 4);
}

// ---------------------------------------------------------------- exact conics

fn check_on_surface(
    surface: &BSplineSurface,
    samples: usize,
    distance: impl Fn(DVec3) -> f64,
    normal: impl Fn(DVec3) -> DVec3,
) {
    let size = surface.control_box_diagonal();
    let (ru, rv) = (surface.range_u(), surface.range_v());
    let (mut worst_distance, mut worst_angle) = (0.0f64, 0.0f64);
    for j in 0..=samples {
        for i in 0..=samples {
            let (u, v) = (
                ru.lerp(i as f64 / samples as f64),
                rv.lerp(j as f64 / samples as f64),
            );
            let s = surface.evaluate(u, v);
            worst_distance = worst_distance.max(distance(s.position).abs());
            worst_angle = worst_angle.max(angle(s.normal, normal(s.position)));
        }
    }
    assert!(
        worst_distance <= EXACT_REL * size,
        "off the surface by {worst_distance:e} (size {size})"
    );
    assert!(worst_angle <= 1e-7, "normal off by {worst_angle:e} rad");
}

#[test]
fn nurbs_sphere_is_exact_with_analytic_normals_at_the_poles() {
    let r = 2.5;
    let sphere = sphere(r);
    check_on_surface(&sphere, 40, |p| p.length() - r, |p| p.normalize());
    for k in 0..=8 {
        let u = k as f64 / 8.0;
        let south = sphere.evaluate(u, 0.0);
        let north = sphere.evaluate(u, 1.0);
        assert!((south.position - DVec3::new(0.0, 0.0, -r)).length() < 1e-15);
        assert!(south.du.length() < 1e-12, "the pole is a collapsed edge");
        assert!(
            angle(south.normal, -DVec3::Z) < 1e-12,
            "south pole normal {}",
            south.normal
        );
        assert!(
            angle(north.normal, DVec3::Z) < 1e-12,
            "north pole normal {}",
            north.normal
        );
    }
}

#[test]
fn nurbs_torus_is_exact_with_analytic_normals() {
    let (big, small) = (3.0, 1.25);
    let torus = torus(big, small);
    let tube_centre = |p: DVec3| DVec3::new(p.x, p.y, 0.0).normalize() * big;
    check_on_surface(
        &torus,
        40,
        |p| (p - tube_centre(p)).length() - small,
        |p| (p - tube_centre(p)).normalize(),
    );
}

#[test]
fn rational_quarter_cylinder_is_exact() {
    let cylinder = quarter_cylinder();
    check_on_surface(
        &cylinder,
        24,
        |p| p.truncate().length() - 1.0,
        |p| DVec3::new(p.x, p.y, 0.0),
    );
    // verb's published value: (0, 0.6, 0.8) at (0.5, 0.5) of its patch is the same arc at
    // mid-parameter; here the arc's midpoint sits on the diagonal.
    let mid = cylinder.point(0.5, 0.5);
    assert!((mid - DVec3::new(S, S, 0.5)).length() < 1e-15, "{mid}");
}

// ---------------------------------------------------------------- random surfaces

/// Knots for `count` points of `degree`: clamped or unclamped, with repeated interior knots.
fn knots_strategy(degree: usize, count: usize) -> impl Strategy<Value = KnotVector> {
    let len = count + degree + 1;
    (
        prop::collection::vec(0.0f64..1.0, len),
        any::<bool>(),
        -5.0f64..5.0,
        0.1f64..10.0,
    )
        .prop_map(move |(r, clamped, offset, scale)| {
            let mut knots = Vec::with_capacity(len);
            let mut value = 0.0;
            let mut run = 1;
            for (index, &x) in r.iter().enumerate() {
                let clamp_run = clamped && (index <= degree || index >= len - degree);
                let repeat = index > 0
                    && (clamp_run
                        || (x < 0.25
                            && run < degree
                            && index > degree
                            && index < len - degree - 1));
                if index > 0 && !repeat {
                    value += 0.05 + x;
                    run = 1;
                } else if index > 0 {
                    run += 1;
                }
                knots.push(offset + scale * value);
            }
            KnotVector::try_new(degree, knots).expect("generated knots are valid")
        })
}

fn surface_strategy(max_degree: usize) -> impl Strategy<Value = BSplineSurface> {
    (
        1..=max_degree,
        1..=max_degree,
        0usize..5,
        0usize..5,
        any::<bool>(),
    )
        .prop_flat_map(|(p, q, extra_u, extra_v, rational)| {
            let (nu, nv) = (p + 1 + extra_u, q + 1 + extra_v);
            (
                knots_strategy(p, nu),
                knots_strategy(q, nv),
                prop::collection::vec((-10.0f64..10.0, -10.0f64..10.0, -10.0f64..10.0), nu * nv),
                prop::collection::vec(0.2f64..5.0, nu * nv),
                Just(rational),
            )
        })
        .prop_map(|(ku, kv, points, weights, rational)| {
            let points: Vec<DVec3> = points
                .into_iter()
                .map(|(x, y, z)| DVec3::new(x, y, z))
                .collect();
            BSplineSurface::try_new(ku, kv, &points, rational.then_some(&weights[..])).unwrap()
        })
}

fn params(surface: &BSplineSurface, a: f64, b: f64) -> (f64, f64) {
    (surface.range_u().lerp(a), surface.range_v().lerp(b))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn basis_matches_naive_recursion_and_sums_to_one(knots in (1usize..=6, 0usize..6).prop_flat_map(|(p, extra)| knots_strategy(p, p + 1 + extra)), t in 0.0f64..=1.0) {
        let (start, end) = knots.domain();
        let u = start + (end - start) * t;
        let (span, values) = knots.basis_values(u);
        let p = knots.degree();
        prop_assert!((values.iter().sum::<f64>() - 1.0).abs() < 1e-13, "partition of unity: {values:?}");
        prop_assert!(values.iter().all(|&b| b >= -1e-15));
        for (r, &value) in values.iter().enumerate() {
            let naive = naive_basis(knots.knots(), span - p + r, p, u, end);
            prop_assert!((value - naive).abs() < 1e-12, "N_{} = {value} vs {naive}", span - p + r);
        }
    }

    #[test]
    fn evaluation_matches_naive_double_sum(surface in surface_strategy(5), a in 0.0f64..=1.0, b in 0.0f64..=1.0) {
        let (u, v) = params(&surface, a, b);
        let size = surface.control_box_diagonal();
        let d = (surface.point(u, v) - naive_point(&surface, u, v)).length();
        prop_assert!(d <= 1e-12 * size, "differs by {d:e}");
    }

    #[test]
    fn affine_invariance(surface in surface_strategy(4), a in 0.0f64..=1.0, b in 0.0f64..=1.0, m in prop::array::uniform9(-2.0f64..2.0), t in prop::array::uniform3(-50.0f64..50.0)) {
        let matrix = DMat3::from_cols_array(&m);
        let shift = DVec3::from_array(t);
        let map = |p: DVec3| matrix * p + shift;
        let points: Vec<DVec3> = (0..surface.count_v()).flat_map(|j| (0..surface.count_u()).map(move |i| (i, j))).map(|(i, j)| map(surface.control_point(i, j))).collect();
        let weights: Vec<f64> = (0..surface.count_v()).flat_map(|j| (0..surface.count_u()).map(move |i| (i, j))).map(|(i, j)| surface.weight(i, j)).collect();
        let moved = BSplineSurface::try_new(surface.knots_u().clone(), surface.knots_v().clone(), &points, Some(&weights)).unwrap();
        let (u, v) = params(&surface, a, b);
        let expected = map(surface.point(u, v));
        let scale = 1.0 + expected.length() + moved.control_box_diagonal();
        prop_assert!((moved.point(u, v) - expected).length() <= 1e-12 * scale);
    }

    #[test]
    fn points_lie_in_the_control_box(surface in surface_strategy(5), a in 0.0f64..=1.0, b in 0.0f64..=1.0) {
        let (u, v) = params(&surface, a, b);
        let p = surface.point(u, v);
        let (lo, hi) = (0..surface.count_v()).flat_map(|j| (0..surface.count_u()).map(move |i| (i, j)))
            .map(|(i, j)| surface.control_point(i, j))
            .fold((DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |(lo, hi), c| (lo.min(c), hi.max(c)));
        let slack = 1e-12 * surface.control_box_diagonal();
        prop_assert!(p.cmpge(lo - slack).all() && p.cmple(hi + slack).all(), "{p} outside [{lo}, {hi}]");
    }

    #[test]
    fn derivatives_match_central_differences(surface in surface_strategy(4), a in 0.05f64..0.95, b in 0.05f64..0.95) {
        let (u, v) = params(&surface, a, b);
        let (ru, rv) = (surface.range_u(), surface.range_v());
        // Stay inside one polynomial piece: finite differences do not see across knots.
        let ku = surface.knots_u().knots();
        let kv = surface.knots_v().knots();
        let (hu, hv) = (1e-5 * ru.width(), 1e-5 * rv.width());
        prop_assume!(ku.iter().all(|&k| (k - u).abs() > 2.0 * hu) && kv.iter().all(|&k| (k - v).abs() > 2.0 * hv));
        let s = surface.evaluate(u, v);
        let p = |du: f64, dv: f64| surface.evaluate(u + du, v + dv);
        let su = (p(hu, 0.0).position - p(-hu, 0.0).position) / (2.0 * hu);
        let sv = (p(0.0, hv).position - p(0.0, -hv).position) / (2.0 * hv);
        let suu = (p(hu, 0.0).du - p(-hu, 0.0).du) / (2.0 * hu);
        let suv = (p(0.0, hv).du - p(0.0, -hv).du) / (2.0 * hv);
        let svv = (p(0.0, hv).dv - p(0.0, -hv).dv) / (2.0 * hv);
        let close = |a: DVec3, b: DVec3| (a - b).length() <= FD_REL * (1.0 + a.length().max(b.length()));
        prop_assert!(close(s.du, su), "S_u {} vs {}", s.du, su);
        prop_assert!(close(s.dv, sv), "S_v {} vs {}", s.dv, sv);
        prop_assert!(close(s.duu, suu), "S_uu {} vs {}", s.duu, suu);
        prop_assert!(close(s.duv, suv), "S_uv {} vs {}", s.duv, suv);
        prop_assert!(close(s.dvv, svv), "S_vv {} vs {}", s.dvv, svv);
    }

    #[test]
    fn bezier_extraction_reproduces_the_surface(surface in surface_strategy(5), a in 0.0f64..=1.0, b in 0.0f64..=1.0) {
        let patches = surface.bezier_patches();
        let (u, v) = params(&surface, a, b);
        let patch = patches.iter().find(|p| p.range_u.start <= u && u <= p.range_u.end && p.range_v.start <= v && v <= p.range_v.end).unwrap();
        prop_assert_eq!(patch.points.len(), (surface.degree_u() + 1) * (surface.degree_v() + 1));
        let d = (patch.point(u, v) - surface.point(u, v)).length();
        prop_assert!(d <= 1e-10 * surface.control_box_diagonal(), "differs by {d:e}");
    }

    #[test]
    fn grid_matches_point_evaluation(surface in surface_strategy(5), nu in 2u32..12, nv in 2u32..12) {
        let mesh = CpuTessellator.tessellate(std::slice::from_ref(&surface), &TessOptions::DEFAULT.with_grid(nu, nv)).unwrap();
        let size = surface.control_box_diagonal();
        for j in 0..nv {
            for i in 0..nu {
                let k = (j * nu + i) as usize;
                let (a, b) = (i as f64 / (nu - 1) as f64, j as f64 / (nv - 1) as f64);
                let s = surface.evaluate(surface.range_u().lerp(a), surface.range_v().lerp(b));
                prop_assert!((mesh.positions[k] - s.position).length() <= 1e-12 * size);
                prop_assert!(angle(mesh.normals[k], s.normal) <= 1e-9, "normal {} vs {}", mesh.normals[k], s.normal);
                prop_assert_eq!(mesh.uvs[k], glam::DVec2::new(a, b));
            }
        }
    }
}

#[test]
fn high_degrees_up_to_twenty_match_the_naive_sum() {
    for (p, q) in [(20, 1), (1, 20), (20, 20), (7, 13)] {
        let (nu, nv) = (p + 3, q + 2);
        let points: Vec<DVec3> = (0..nu * nv)
            .map(|k| {
                DVec3::new(
                    (k % nu) as f64,
                    (k / nu) as f64,
                    ((k * 7919) % 13) as f64 / 13.0,
                )
            })
            .collect();
        let weights: Vec<f64> = (0..nu * nv)
            .map(|k| 0.5 + ((k * 31) % 7) as f64 / 7.0)
            .collect();
        let surface = BSplineSurface::try_new(
            KnotVector::clamped_uniform(p, nu).unwrap(),
            KnotVector::uniform(q, nv).unwrap(),
            &points,
            Some(&weights),
        )
        .unwrap();
        for (a, b) in [(0.0, 0.0), (0.3, 0.7), (1.0, 1.0), (0.5, 0.25)] {
            let (u, v) = params(&surface, a, b);
            let d = (surface.point(u, v) - naive_point(&surface, u, v)).length();
            assert!(
                d <= 1e-12 * surface.control_box_diagonal(),
                "degree ({p},{q}) at ({a},{b}): {d:e}"
            );
        }
    }
}

// ---------------------------------------------------------------- normals, winding, layout

#[test]
fn grid_layout_winding_and_normals() {
    let sphere = sphere(1.0);
    let mesh = CpuTessellator
        .tessellate(
            std::slice::from_ref(&sphere),
            &TessOptions::DEFAULT.with_grid(17, 9),
        )
        .unwrap();
    assert_eq!(mesh.vertex_count(), 17 * 9);
    assert_eq!(mesh.triangle_count(), 2 * 16 * 8);
    // u fastest: vertex 1 is one step along u on the south pole row.
    assert_eq!(mesh.uvs[1], glam::DVec2::new(1.0 / 16.0, 0.0));
    assert_eq!(mesh.uvs[17], glam::DVec2::new(0.0, 1.0 / 8.0));
    assert!(
        mesh.normals
            .iter()
            .all(|n| (n.length() - 1.0).abs() < 1e-12),
        "every normal is a unit vector"
    );
    let mut checked = 0;
    for t in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
        let face = (b - a).cross(c - a);
        if face.length() < 1e-9 {
            continue; // collapsed at a pole
        }
        assert!(face.dot(a) > 0.0, "counter-clockwise seen from outside");
        checked += 1;
    }
    assert!(checked >= 2 * 16 * 6);
}

#[test]
fn teapot_normals_point_out_and_are_never_degenerate() {
    let scene = knotwork::io::read_scene(std::path::Path::new("data/teapot.bpt")).unwrap();
    assert_eq!(scene.surface_list().len(), 32);
    let mesh = CpuTessellator
        .tessellate(&scene.surface_list(), &TessOptions::DEFAULT.with_grid(9, 9))
        .unwrap();
    assert!(
        mesh.normals
            .iter()
            .all(|n| n.is_finite() && (n.length() - 1.0).abs() < 1e-12)
    );
    // Body patches 5–12: normals point away from the z axis.
    for part in &mesh.parts[4..12] {
        for k in part.first_vertex..part.first_vertex + part.vertex_count {
            let (p, n) = (mesh.positions[k as usize], mesh.normals[k as usize]);
            assert!(
                n.dot(DVec3::new(p.x, p.y, 0.0)) > 0.0,
                "body normal {n} at {p}"
            );
        }
    }
    // The lid's knob top (patches 21–24) collapses to the point (0, 0, 3.15): its limit
    // normal is straight up.
    let top = DVec3::new(0.0, 0.0, 3.15);
    let at_top: Vec<DVec3> = (0..mesh.vertex_count())
        .filter(|&k| (mesh.positions[k] - top).length() < 1e-12)
        .map(|k| mesh.normals[k])
        .collect();
    assert!(!at_top.is_empty());
    for n in at_top {
        assert!(angle(n, DVec3::Z) < 1e-9, "knob top normal {n}");
    }
}

/// A surface with no tangent plane anywhere — every control point at one place, or all on
/// one line — gets the documented +Z at every (u, v), finite, and its position; the point's
/// degeneracy threshold is zero (its size is), which must still count a zero S_u × S_v as
/// degenerate.
#[test]
fn surfaces_collapsed_to_a_point_or_a_line_face_up() {
    let knots = || KnotVector::clamped_uniform(2, 3).unwrap();
    let at = DVec3::new(3.0, -2.0, 0.5);
    let point = BSplineSurface::try_new(knots(), knots(), &[at; 9], None).unwrap();
    let line: Vec<DVec3> = (0..9)
        .map(|k| at + DVec3::new(1.0, 2.0, -1.0) * (k % 3 + k / 3) as f64)
        .collect();
    let weights = [1.0, 2.0, 0.5, 1.5, 1.0, 0.25, 4.0, 1.0, 1.0];
    let line = BSplineSurface::try_new(knots(), knots(), &line, Some(&weights)).unwrap();
    for (u, v) in [(0.0, 0.0), (0.5, 0.25), (1.0, 0.75), (0.3, 1.0)] {
        let s = point.evaluate(u, v);
        assert_eq!(s.normal, DVec3::Z, "point at ({u}, {v})");
        assert_eq!(s.position, at);
        let s = line.evaluate(u, v);
        assert_eq!(s.normal, DVec3::Z, "line at ({u}, {v})");
    }
}

#[test]
fn unclamped_uniform_surface_from_the_obj_spec_faces_up() {
    // The spec's uniform bicubic B-spline example: knots -3..4, surf 0 1 0 1, a flat 4×4 net.
    let knots = KnotVector::try_new(3, (-3..=4).map(f64::from).collect()).unwrap();
    let points: Vec<DVec3> = (0..16)
        .map(|k| DVec3::new((k % 4) as f64, (k / 4) as f64, 0.0))
        .collect();
    let surface = BSplineSurface::try_new(knots.clone(), knots, &points, None)
        .unwrap()
        .with_range(Interval::new(0.0, 1.0), Interval::new(0.0, 1.0))
        .unwrap();
    let s = surface.evaluate(0.5, 0.5);
    assert!(angle(s.normal, DVec3::Z) < 1e-15);
    // The uniform cubic B-spline at u = 0 of a uniform knot vector: (P0 + 4P1 + P2)/6.
    assert!(
        (s.position - DVec3::new(1.5, 1.5, 0.0)).length() < 1e-14,
        "{}",
        s.position
    );
}

#[test]
fn piecewise_bezier_joins_segments_at_breakpoints() {
    // Two quadratic segments in u on breakpoints 0, 2, 5; one linear segment in v.
    let row: Vec<DVec3> = (0..5)
        .map(|i| DVec3::new(i as f64, (i * i) as f64, 0.0))
        .collect();
    let mut points = row.clone();
    points.extend(row.iter().map(|p| *p + DVec3::Z));
    let surface =
        piecewise_bezier_surface(2, 1, &[0.0, 2.0, 5.0], &[0.0, 1.0], &points, None).unwrap();
    assert_eq!(surface.count_u(), 5);
    assert_eq!(
        surface.knots_u().knots(),
        &[0.0, 0.0, 0.0, 2.0, 2.0, 5.0, 5.0, 5.0]
    );
    // At the breakpoint the surface passes through the shared control point.
    assert!((surface.point(2.0, 0.0) - row[2]).length() < 1e-15);
    // Segment 2 at global 3.5 is its local 0.5: the Bernstein mid-point of points 2, 3, 4.
    let expected = 0.25 * row[2] + 0.5 * row[3] + 0.25 * row[4];
    assert!((surface.point(3.5, 0.0) - expected).length() < 1e-14);
    let patches = surface.bezier_patches();
    assert_eq!(patches.len(), 2);
    assert_eq!(patches[1].range_u, Interval::new(2.0, 5.0));
}

#[test]
fn curves_evaluate_with_tangents() {
    // Quarter circle as a rational quadratic: every point at distance 1, tangent ⟂ radius.
    let points = [DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
    let curve = bezier_curve(2, &points, Some(&[1.0, S, 1.0])).unwrap();
    for k in 0..=10 {
        let (p, t) = curve.evaluate(k as f64 / 10.0);
        assert!((p.length() - 1.0).abs() < 1e-15);
        assert!(p.dot(t).abs() < 1e-14 * t.length());
    }
    let knots = KnotVector::clamped_uniform(2, 3).unwrap();
    let curve = BSplineCurve::try_new(knots, &points, None)
        .unwrap()
        .with_range(Interval::new(0.25, 0.75))
        .unwrap();
    assert_eq!(curve.range(), Interval::new(0.25, 0.75));
}

#[test]
fn bezier_surface_matches_tensor_bernstein() {
    let points: Vec<DVec3> = (0..12)
        .map(|k| DVec3::new((k % 4) as f64, (k / 4) as f64, ((k * 5) % 3) as f64))
        .collect();
    let surface = bezier_surface(3, 2, &points, None).unwrap();
    let (u, v) = (0.3f64, 0.6f64);
    let bu = [
        (1.0 - u).powi(3),
        3.0 * u * (1.0 - u).powi(2),
        3.0 * u * u * (1.0 - u),
        u.powi(3),
    ];
    let bv = [(1.0 - v).powi(2), 2.0 * v * (1.0 - v), v * v];
    let expected: DVec3 = (0..12).map(|k| bu[k % 4] * bv[k / 4] * points[k]).sum();
    assert!((surface.point(u, v) - expected).length() < 1e-14);
}

#[test]
fn evaluate_grid_and_reused_meshes_match_fresh_tessellation() {
    let teapot = knotwork::io::read_scene(std::path::Path::new("data/teapot.bpt"))
        .unwrap()
        .surface_list();
    let options = TessOptions::DEFAULT.with_grid(7, 5);
    let fresh = CpuTessellator.tessellate(&teapot, &options).unwrap();
    // A mesh that held something else (bigger, other layout) is overwritten completely.
    let mut reused = CpuTessellator
        .tessellate(
            &[sphere(3.0), torus(2.0, 0.5)],
            &TessOptions::DEFAULT.with_grid(40, 40),
        )
        .unwrap();
    CpuTessellator
        .tessellate_into(&teapot, &options, &mut reused)
        .unwrap();
    assert_eq!(reused, fresh);
    // On error the mesh is left as it was.
    let err = CpuTessellator
        .tessellate_into(&teapot, &TessOptions::DEFAULT.with_grid(1, 1), &mut reused)
        .unwrap_err();
    assert!(matches!(err, Error::GridTooSmall { .. }));
    assert_eq!(reused, fresh);
    // The attribute-only layer gives the same positions and normals as the mesh.
    let part = fresh.parts[3];
    let range = part.first_vertex as usize..(part.first_vertex + part.vertex_count) as usize;
    let (mut positions, mut normals) = (vec![DVec3::ZERO; 35], vec![DVec3::ZERO; 35]);
    knotwork::cpu::evaluate_grid_into(&teapot[3], 7, 5, &mut positions, &mut normals).unwrap();
    assert_eq!(positions, fresh.positions[range.clone()]);
    assert_eq!(normals, fresh.normals[range]);
    let short =
        knotwork::cpu::evaluate_grid_into(&teapot[3], 7, 5, &mut positions[..34], &mut normals)
            .unwrap_err();
    assert!(matches!(
        short,
        Error::BufferLength {
            expected: 35,
            found: 34
        }
    ));
    let tiny = knotwork::cpu::evaluate_grid_into(&teapot[3], 1, 35, &mut positions, &mut normals)
        .unwrap_err();
    assert!(matches!(tiny, Error::GridTooSmall { nu: 1, nv: 35 }));
    let flat = knotwork::cpu::evaluate_grid_into(&teapot[3], 35, 1, &mut positions, &mut normals)
        .unwrap_err();
    assert!(matches!(flat, Error::GridTooSmall { nu: 35, nv: 1 }));
    // Two vertices each way is the smallest grid: the patch's corners.
    let (mut corners, mut corner_normals) = (vec![DVec3::ZERO; 4], vec![DVec3::ZERO; 4]);
    knotwork::cpu::evaluate_grid_into(&teapot[3], 2, 2, &mut corners, &mut corner_normals).unwrap();
    let (range_u, range_v) = (teapot[3].range_u(), teapot[3].range_v());
    for (k, corner) in corners.iter().enumerate() {
        let (u, v) = (range_u.lerp((k % 2) as f64), range_v.lerp((k / 2) as f64));
        let expected = teapot[3].evaluate(u, v).position;
        assert!(
            corner.distance(expected) <= 1e-12 * expected.length().max(1.0),
            "corner {k}"
        );
    }
}

// ---------------------------------------------------------------- errors

fn unit_points(n: usize) -> Vec<DVec3> {
    (0..n).map(|k| DVec3::new(k as f64, 0.0, 0.0)).collect()
}

#[test]
fn every_geometry_error_is_reported() {
    let root = |r: Result<KnotVector, Error>| r.unwrap_err();
    assert!(matches!(
        root(KnotVector::try_new(0, vec![0.0, 1.0])),
        Error::DegreeOutOfRange { degree: 0, max: 20 }
    ));
    assert!(matches!(
        root(KnotVector::try_new(21, vec![0.0; 44])),
        Error::DegreeOutOfRange { degree: 21, .. }
    ));
    assert!(matches!(
        root(KnotVector::try_new(1, vec![0.0, f64::NAN, 1.0, 1.0])),
        Error::KnotNotFinite { index: 1, .. }
    ));
    assert!(matches!(
        root(KnotVector::try_new(1, vec![0.0, 0.0, 2.0, 1.0, 3.0, 3.0])),
        Error::KnotsDecreasing {
            index: 3,
            previous: 2.0,
            value: 1.0
        }
    ));
    assert!(matches!(
        root(KnotVector::try_new(2, vec![0.0, 0.0, 0.0, 1.0, 1.0])),
        Error::TooFewKnots {
            found: 5,
            min: 6,
            ..
        }
    ));
    assert!(matches!(
        root(KnotVector::try_new(1, vec![0.0, 0.0, 0.0, 1.0, 1.0])),
        Error::KnotMultiplicity {
            index: 0,
            multiplicity: 3,
            max: 2,
            ..
        }
    ));
    assert!(matches!(
        root(KnotVector::try_new(
            2,
            vec![0.0, 0.0, 0.0, 0.5, 0.5, 0.5, 1.0, 1.0, 1.0]
        )),
        Error::KnotMultiplicity {
            index: 3,
            multiplicity: 3,
            max: 2,
            ..
        }
    ));
    assert!(matches!(
        root(KnotVector::try_new(2, vec![0.0, 1.0, 2.0, 2.0, 3.0, 4.0])),
        Error::EmptyDomain {
            start: 2.0,
            end: 2.0
        }
    ));
    assert!(matches!(
        root(KnotVector::try_new(2, vec![0.0, 1.0, 1.0, 1.0, 1.0, 2.0])),
        Error::KnotMultiplicity { .. }
    ));
    assert!(matches!(
        root(KnotVector::try_new(1, vec![1.0, 1.0, 1.0, 1.0])),
        Error::KnotMultiplicity { .. }
    ));
    assert!(matches!(
        root(KnotVector::from_breakpoints(2, &[0.0, 1.0, 1.0])),
        Error::BreakpointsNotIncreasing { index: 2, .. }
    ));
    assert!(matches!(
        root(KnotVector::clamped_uniform(3, 2)),
        Error::ControlPointCount {
            expected: 4,
            found: 2,
            ..
        }
    ));

    let k = || KnotVector::clamped_uniform(1, 2).unwrap();
    let surface = |points: &[DVec3], weights: Option<&[f64]>| {
        BSplineSurface::try_new(k(), k(), points, weights).unwrap_err()
    };
    assert!(matches!(
        surface(&unit_points(3), None),
        Error::ControlPointCount {
            expected: 4,
            found: 3,
            ..
        }
    ));
    let mut points = unit_points(4);
    points[2].y = f64::INFINITY;
    assert!(matches!(
        surface(&points, None),
        Error::ControlPointNotFinite { index: 2 }
    ));
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(
            matches!(
                surface(&unit_points(4), Some(&[1.0, 1.0, 1.0, bad])),
                Error::InvalidWeight { index: 3, .. }
            ),
            "weight {bad}"
        );
    }
    assert!(matches!(
        surface(&unit_points(4), Some(&[1.0, 1.0])),
        Error::ControlPointCount {
            expected: 4,
            found: 2,
            ..
        }
    ));
    let ok = BSplineSurface::try_new(k(), k(), &unit_points(4), None).unwrap();
    for (a, b) in [
        (-0.1, 0.5),
        (0.2, 1.1),
        (0.5, 0.5),
        (0.6, 0.4),
        (f64::NAN, 1.0),
    ] {
        assert!(
            matches!(
                ok.clone()
                    .with_range(Interval::new(a, b), Interval::new(0.0, 1.0)),
                Err(Error::RangeOutsideDomain { .. })
            ),
            "[{a}, {b}]"
        );
    }
    let tess = |nu, nv, count| {
        CpuTessellator
            .tessellate(
                &vec![ok.clone(); count],
                &TessOptions::DEFAULT.with_grid(nu, nv),
            )
            .unwrap_err()
    };
    assert!(matches!(
        tess(1, 5, 1),
        Error::GridTooSmall { nu: 1, nv: 5 }
    ));
    assert!(matches!(tess(65536, 65536, 2), Error::MeshTooLarge { .. }));
    let curve = BSplineCurve::try_new(k(), &unit_points(3), None).unwrap_err();
    assert!(matches!(
        curve,
        Error::ControlPointCount {
            expected: 2,
            found: 3,
            ..
        }
    ));
}

/// A plan executes only on as many items as it was made for; the mesh is left as it was.
#[test]
fn a_plan_refuses_other_items() {
    let scene = knotwork::io::read_scene(std::path::Path::new("data/teapot.bpt")).unwrap();
    let options = vec![TessOptions::DEFAULT.with_grid(4, 5); 2];
    let plan = knotwork::plan::SurfacePlan::new(&scene.surface_list()[..2], &options).unwrap();
    let mut mesh = knotwork::Mesh::default();
    knotwork::cpu::execute_surfaces(&plan, &scene.surface_list()[..2], &mut mesh).unwrap();
    assert_eq!((mesh.vertex_count(), mesh.triangle_count()), (40, 48));
    let before = mesh.clone();
    let err =
        knotwork::cpu::execute_surfaces(&plan, &scene.surface_list()[..1], &mut mesh).unwrap_err();
    assert!(
        matches!(
            err,
            Error::PlanMismatch {
                planned: 2,
                given: 1
            }
        ),
        "{err}"
    );
    assert_eq!(mesh, before);
}

/// The CPU's f32 output (evaluated row by row, rounded once) is the f64 mesh rounded to f32,
/// bit for bit, without an f64 mesh in between.
#[test]
fn f32_output_is_the_f64_mesh_rounded() {
    let mut surfaces = knotwork::io::read_scene(std::path::Path::new("data/teapot.bpt"))
        .unwrap()
        .surface_list();
    surfaces.truncate(9);
    let options: Vec<TessOptions> = (0..9)
        .map(|k| TessOptions::DEFAULT.with_grid(5 + k, 13 - k))
        .collect();
    let mut wide = knotwork::Mesh::default();
    CpuTessellator
        .tessellate_each_into(&surfaces, &options, &mut wide)
        .unwrap();
    let mut narrow = knotwork::Mesh32::default();
    CpuTessellator
        .tessellate_each_into_f32(&surfaces, &options, &mut narrow)
        .unwrap();
    assert_eq!(narrow, knotwork::Mesh32::from(&wide));
}

/// A scene tessellated into one array per attribute is the interleaved f32 mesh, value for
/// value: where the CPU rounds rows straight into the arrays (surfaces on grids: the teapot
/// on a grid that is not square, a JSON scene whose items have grids of their own) and where
/// the mesh is made interleaved and split (a tolerance; Coons patches and curves in the
/// scene). The memory budget still refuses a mesh too large for it.
#[test]
fn split_f32_scenes_are_the_interleaved_meshes() {
    use knotwork::{SceneOptions, SplitMesh32, Tolerance};
    let grid = TessOptions::DEFAULT.with_grid(37, 12);
    let cases = [
        ("data/teapot.bpt", grid),
        ("data/scene.json", grid),
        (
            "data/teapot.bpt",
            grid.with_tolerance(Tolerance::Relative(1e-3)),
        ),
        ("data/forms.json", grid),
    ];
    for (path, grid) in cases {
        let scene = knotwork::io::read_scene(std::path::Path::new(path)).unwrap();
        let defaults = SceneOptions {
            grid,
            ..SceneOptions::default()
        };
        let interleaved = CpuTessellator
            .tessellate_scene_f32(&scene, &defaults)
            .unwrap();
        let split = CpuTessellator
            .tessellate_scene_split_f32(&scene, &defaults)
            .unwrap();
        assert!(split.vertex_count() > 0, "{path}");
        assert_eq!(split, SplitMesh32::from(interleaved.clone()), "{path}");
        assert_eq!(split.to_interleaved(), interleaved, "{path}");
    }
    let teapot = knotwork::io::read_scene(std::path::Path::new("data/teapot.bpt")).unwrap();
    let small_budget = SceneOptions {
        grid,
        memory_budget: Some(1 << 16),
        ..SceneOptions::default()
    };
    assert!(matches!(
        CpuTessellator.tessellate_scene_split_f32(&teapot, &small_budget),
        Err(Error::OverMemoryBudget { .. })
    ));
}

/// The trait's default f32 call leaves the mesh as it was when the backend fails.
#[test]
fn default_f32_tessellation_keeps_the_mesh_on_error() {
    struct Failing;
    impl Tessellator for Failing {
        fn execute_surfaces(
            &self,
            _: &knotwork::plan::SurfacePlan,
            _: &[BSplineSurface],
            _: &mut knotwork::Mesh,
        ) -> Result<(), Error> {
            Err(Error::GridTooSmall { nu: 1, nv: 1 })
        }
        fn tessellate_coons_into(
            &self,
            _: &[knotwork::geom::patches::CoonsPatch],
            _: &[TessOptions],
            _: &mut knotwork::Mesh,
        ) -> Result<(), Error> {
            unreachable!("not called")
        }
        fn tessellate_curves(
            &self,
            _: &[BSplineCurve],
            _: &[u32],
        ) -> Result<Vec<knotwork::Polyline>, Error> {
            unreachable!("not called")
        }
        fn name(&self) -> String {
            "failing".into()
        }
    }
    let mut mesh = knotwork::Mesh32 {
        polylines: vec![knotwork::Polyline::default()],
        ..knotwork::Mesh32::default()
    };
    let before = mesh.clone();
    assert!(
        Failing
            .tessellate_each_into_f32(&[], &[], &mut mesh)
            .is_err()
    );
    assert_eq!(mesh, before);
}

/// A scene's mesh holds each item's own tessellation in its part, reordered into file order
/// (the Coons patch of data/forms.json stands fifth, between surfaces): positions and
/// triangles of every part equal those of the item tessellated alone.
#[test]
#[cfg(feature = "json")]
fn scene_parts_are_the_items_tessellated_alone() {
    let scene = knotwork::io::read_scene(std::path::Path::new("data/forms.json")).unwrap();
    let defaults = knotwork::SceneOptions::default();
    let mesh = CpuTessellator.tessellate_scene(&scene, &defaults).unwrap();
    assert!(matches!(
        scene.items[4].geometry,
        knotwork::Geometry::Coons(_)
    ));
    for part in &mesh.parts {
        let item = &scene.items[part.item as usize];
        let grid = [item.grid.unwrap_or(defaults.grid)];
        let mut alone = knotwork::Mesh::default();
        match &item.geometry {
            knotwork::Geometry::Surface(s) => CpuTessellator
                .tessellate_each_into(std::slice::from_ref(s), &grid, &mut alone)
                .unwrap(),
            knotwork::Geometry::Coons(p) => CpuTessellator
                .tessellate_coons_into(std::slice::from_ref(&**p), &grid, &mut alone)
                .unwrap(),
            knotwork::Geometry::Curve(_) => unreachable!("curves have no part"),
            knotwork::Geometry::Trimmed(_) | knotwork::Geometry::Shell(_) => {
                unreachable!("forms.json has no trimmed faces or shells")
            }
        }
        let vertices = part.first_vertex as usize..(part.first_vertex + part.vertex_count) as usize;
        assert_eq!(
            mesh.positions[vertices.clone()],
            alone.positions[..],
            "item {}",
            part.item
        );
        assert_eq!(mesh.normals[vertices.clone()], alone.normals[..]);
        assert_eq!(mesh.uvs[vertices], alone.uvs[..]);
        let indices = part.first_index as usize..(part.first_index + part.index_count) as usize;
        let local: Vec<u32> = mesh.indices[indices]
            .iter()
            .map(|i| i - part.first_vertex)
            .collect();
        assert_eq!(local, alone.indices, "item {}", part.item);
    }
}

// ---------------------------------------------------------------- precision far from the origin

/// Offsets of the moved copies: the world origin, the issue's 1e5, and 1e7 — integers, so a
/// control point with six fractional bits moves exactly.
const OFFSETS: [f64; 3] = [0.0, 1e5, 1e7];

/// Normal agreement between a surface and its dyadically moved copy: at regular points, and
/// where |S_u × S_v| vanishes (the limit normal).
const MOVED_NORMAL_BAR: f64 = 1e-12;
const MOVED_LIMIT_NORMAL_BAR: f64 = 1e-9;

/// A surface of dyadic control points (multiples of 1/64 in [-1, 1]) and power-of-two
/// weights in [2⁻¹⁰, 2¹⁰] (about 1e-3..1e3), with optionally collapsed first row, last row
/// and first column (poles, collapsed edges, and corners where they meet the creases that
/// `knots_strategy`'s repeated knots make).
fn dyadic_surface_strategy() -> impl Strategy<Value = BSplineSurface> {
    (1usize..=5, 1usize..=5, 0usize..4, 0usize..4, any::<bool>())
        .prop_flat_map(|(p, q, extra_u, extra_v, rational)| {
            let (nu, nv) = (p + 1 + extra_u, q + 1 + extra_v);
            (
                knots_strategy(p, nu),
                knots_strategy(q, nv),
                prop::collection::vec(prop::array::uniform3(-64i32..=64), nu * nv),
                prop::collection::vec(-10i32..=10, nu * nv),
                Just(rational),
                prop::array::uniform3(any::<bool>()),
            )
        })
        .prop_map(|(ku, kv, points, exponents, rational, collapse)| {
            let (nu, nv) = (ku.control_count(), kv.control_count());
            let mut points: Vec<DVec3> = points
                .into_iter()
                .map(|[x, y, z]| DVec3::new(x.into(), y.into(), z.into()) / 64.0)
                .collect();
            for j in 0..nv {
                for i in 0..nu {
                    let at = j * nu + i;
                    if collapse[0] && j == 0 {
                        points[at] = points[0];
                    } else if collapse[1] && j == nv - 1 && nv > 1 {
                        points[at] = points[(nv - 1) * nu];
                    } else if collapse[2] && i == 0 {
                        points[at] = points[0];
                    }
                }
            }
            let weights: Vec<f64> = exponents.iter().map(|&e| 2f64.powi(e)).collect();
            BSplineSurface::try_new(ku, kv, &points, rational.then_some(&weights[..])).unwrap()
        })
}

/// `surface` with every control point mapped by p ↦ scale·p + offset, weights kept.
fn moved(surface: &BSplineSurface, scale: f64, offset: DVec3) -> BSplineSurface {
    surface.mapped(|p| scale * p + offset)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// Evaluation is invariant under translation by up to 1e7 and power-of-two scales from
    /// 2⁻¹³ (1.2e-4) to 2²⁰ (1e6): the moved control points are exact, so normals agree to
    /// 1e-12 rad (1e-9 rad at degenerate points) and positions to a few ulps of the offset.
    #[test]
    fn evaluation_is_invariant_under_dyadic_moves(
        surface in dyadic_surface_strategy(),
        offset_choice in prop::array::uniform3(0usize..3),
        scale_exponent in -13i32..=20,
        params in prop::collection::vec((0.0f64..=1.0, 0.0f64..=1.0), 6),
    ) {
        let offset = DVec3::from_array(offset_choice.map(|k| OFFSETS[k]));
        let scale = 2f64.powi(scale_exponent);
        let copy = moved(&surface, scale, offset);
        let scale_sq = surface.cross_scale();
        // Range corners and edges (where rows and columns collapse) and interior points.
        let fractions = [(0.0, 0.0), (1.0, 1.0), (0.0, 1.0), (1.0, 0.0), (0.5, 0.0), (0.0, 0.5)];
        for (a, b) in fractions.into_iter().chain(params) {
            let (u, v) = params_at(&surface, a, b);
            let (s, t) = (surface.evaluate(u, v), copy.evaluate(u, v));
            let degenerate = s.du.cross(s.dv).length() <= 1e-6 * scale_sq;
            let bar = if degenerate { MOVED_LIMIT_NORMAL_BAR } else { MOVED_NORMAL_BAR };
            let turned = angle(s.normal, t.normal);
            prop_assert!(turned <= bar, "normal turned {turned:e} rad at ({u}, {v}), degenerate {degenerate}, offset {offset}, scale {scale}");
            let expected = scale * s.position + offset;
            let ulps = 4.0 * f64::EPSILON * (offset.abs().max_element() + scale * s.position.abs().max_element() + scale * surface.control_box_diagonal());
            let moved_by = (t.position - expected).abs().max_element();
            prop_assert!(moved_by <= ulps, "position off by {moved_by:e} (bar {ulps:e}) at ({u}, {v})");
        }
    }
}

fn params_at(surface: &BSplineSurface, a: f64, b: f64) -> (f64, f64) {
    (surface.range_u().lerp(a), surface.range_v().lerp(b))
}

/// The issue's case: an exact rational sphere of radius 0.25 about a centre 1e5 from the
/// origin, read as an OBJ `surf` would give it (Cartesian points and weights, two collapsed
/// pole rows). Every normal, the poles' included, is the outward radius to 1e-9 rad, from
/// point evaluation and from the grid executor; the positions lie on the sphere to 1e-12 of
/// its size plus the rounding of the offset.
#[test]
fn a_sphere_far_from_the_origin_keeps_outward_normals_at_its_poles() {
    let (centre, radius) = (DVec3::new(1.0e5 + 0.3, -7.0e4, 3.0e4 + 0.125), 0.25);
    let at_origin = sphere(radius);
    let (nu, nv) = (at_origin.count_u(), at_origin.count_v());
    let points: Vec<DVec3> = (0..nv)
        .flat_map(|j| (0..nu).map(move |i| (i, j)))
        .map(|(i, j)| at_origin.control_point(i, j) + centre)
        .collect();
    let weights: Vec<f64> = (0..nv)
        .flat_map(|j| (0..nu).map(move |i| (i, j)))
        .map(|(i, j)| at_origin.weight(i, j))
        .collect();
    let far = BSplineSurface::try_new(
        at_origin.knots_u().clone(),
        at_origin.knots_v().clone(),
        &points,
        Some(&weights),
    )
    .unwrap();
    let size = 4.0 * radius;
    let on_sphere = EXACT_REL * size + 4.0 * f64::EPSILON * centre.length();
    let check = |position: DVec3, normal: DVec3, what: &str| {
        let outward = (position - centre).normalize();
        let off = ((position - centre).length() - radius).abs();
        assert!(off <= on_sphere, "{what}: {off:e} off the sphere");
        let turned = angle(normal, outward);
        assert!(
            turned <= 1e-9,
            "{what}: normal {normal} is {turned:e} rad from outward {outward}"
        );
    };
    for k in 0..=16 {
        let u = k as f64 / 16.0;
        let south = far.evaluate(u, 0.0);
        check(south.position, south.normal, "south pole");
        assert!(angle(south.normal, -DVec3::Z) <= 1e-9);
        let north = far.evaluate(u, 1.0);
        check(north.position, north.normal, "north pole");
        assert!(angle(north.normal, DVec3::Z) <= 1e-9);
    }
    let mut mesh = Mesh::default();
    CpuTessellator
        .tessellate_each_into(
            std::slice::from_ref(&far),
            &[TessOptions::DEFAULT.with_grid(33, 33)],
            &mut mesh,
        )
        .unwrap();
    for (position, normal) in mesh.positions.iter().zip(&mesh.normals) {
        check(*position, *normal, "grid vertex");
    }
}

/// Degenerate points of the classic forms — sphere poles, a cone's apex, a planar patch with
/// an edge 1e-9 of its size — near the origin, 1e5 and 1e7 from it, at scales 1e-3, 1 and
/// 1e4: every normal agrees with the analytic one to 1e-9 rad plus what placing the form's
/// control points at the offset rounds.
#[test]
fn degenerate_points_keep_analytic_normals_at_every_placement() {
    use knotwork::geom::shapes::{elliptic_cone, sphere as sphere_at};
    for offset in OFFSETS {
        for scale in [1e-3, 1.0, 1e4] {
            let centre = DVec3::new(offset, -0.5 * offset, 0.25 * offset);
            let place = format!("offset {offset}, scale {scale}");
            // Placing a form's non-dyadic control points (cos, sin, weights) at the offset
            // rounds them by ulps of the offset: that much of the model's size the input
            // itself moves, and its normals with it.
            let bar = 1e-9 + 4.0 * f64::EPSILON * offset / scale;
            // Sphere: outward radius everywhere, poles included.
            let ball = sphere_at(centre, 0.5 * scale);
            for (a, b) in [(0.3, 0.0), (0.7, 1.0), (0.0, 0.0), (0.5, 0.5), (0.2, 0.01)] {
                let (u, v) = params_at(&ball, a, b);
                let s = ball.evaluate(u, v);
                let outward = if b == 0.0 {
                    -DVec3::Z
                } else if b == 1.0 {
                    DVec3::Z
                } else {
                    // Radial, from the same sphere about the world origin: the offset's rounding
                    // of this position would turn a radius of a 1e-3 sphere by ~1e-8 rad.
                    sphere_at(DVec3::ZERO, 0.5 * scale).point(u, v).normalize()
                };
                let turned = angle(s.normal, outward);
                assert!(
                    turned <= bar,
                    "sphere at ({a}, {b}), {place}: {turned:e} rad"
                );
            }
            // Cone x² + y² = z² through its apex (v = 1/2): evaluated from the centre of the
            // range, the apex takes the limit along the diagonal (+u, +v), the upper nappe's
            // normal at that angle, which is 90° from the lower nappe's.
            let cone = elliptic_cone(
                centre,
                1.0,
                1.0,
                Interval::new(0.0, std::f64::consts::TAU),
                Interval::new(-scale, scale),
            )
            .unwrap();
            let (u, v_apex) = params_at(&cone, 0.3, 0.5);
            let apex = cone.evaluate(u, v_apex).normal;
            let width = cone.range_v().width();
            let upper = cone.evaluate(u, v_apex + 1e-3 * width).normal;
            let lower = cone.evaluate(u, v_apex - 1e-3 * width).normal;
            let turned = angle(apex, upper);
            assert!(
                turned <= bar,
                "cone apex, {place}: {turned:e} rad from the upper nappe"
            );
            let across = (angle(apex, lower) - std::f64::consts::FRAC_PI_2).abs();
            assert!(
                across <= bar,
                "cone apex, {place}: {across:e} rad from 90° to the lower nappe"
            );
            // The same cone with u and v swapped: the apex is at the middle of u, and the
            // limit is again taken toward (+u, +v), the same nappe, with S_u and S_v swapped:
            // the opposite normal.
            let swapped = cone.transposed().evaluate(v_apex, u).normal;
            let turned = angle(swapped, -apex);
            assert!(
                turned <= bar,
                "transposed cone apex, {place}: {turned:e} rad"
            );
            // A planar bilinear patch in z = offset whose v = 0 edge is 1e-9 of its size:
            // every normal is +z.
            let eps = 1e-9 * scale;
            let corners = [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(eps, 0.0, 0.0),
                DVec3::new(-scale, scale, 0.0),
                DVec3::new(scale, scale, 0.0),
            ]
            .map(|p| p + centre);
            let linear = KnotVector::try_new(1, vec![0.0, 0.0, 1.0, 1.0]).unwrap();
            let sliver = BSplineSurface::try_new(linear.clone(), linear, &corners, None).unwrap();
            for (a, b) in [(0.0, 0.0), (0.5, 0.0), (1.0, 0.0), (0.5, 0.5), (0.0, 1.0)] {
                let s = sliver.evaluate(a, b);
                let turned = angle(s.normal, DVec3::Z);
                assert!(
                    turned <= bar,
                    "sliver at ({a}, {b}), {place}: {turned:e} rad"
                );
            }
        }
    }
}

/// The degeneracy rule scales with the model and the parameter domain: a twisted bilinear
/// patch whose v = 0 edge is 1e-9 of its size (regular there: S_u × S_v is far above
/// rounding, and its normal is not the limit a collapsed edge would take) keeps the same
/// normals — to 1e-12 rad — at the same fractions of its range when its domain is 2⁻¹⁰..2¹⁰
/// wide each way and its size 2⁻³⁰..2¹³ times its own (all exact: powers of two).
#[test]
fn the_degeneracy_rule_scales_with_the_model_and_its_domain() {
    let corners = [
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(1e-9, 0.0, 0.0),
        DVec3::new(-1.0, 1.0, 0.25),
        DVec3::new(1.0, 1.0, -0.5),
    ];
    let sliver = |width_u: f64, width_v: f64, scale: f64| {
        let knots = |w: f64| KnotVector::try_new(1, vec![0.0, 0.0, w, w]).unwrap();
        let points = corners.map(|p| scale * p);
        BSplineSurface::try_new(knots(width_u), knots(width_v), &points, None).unwrap()
    };
    let fractions = [(0.0, 0.0), (0.5, 0.0), (1.0, 0.0), (0.25, 0.5), (0.0, 1.0)];
    let reference = sliver(1.0, 1.0, 1.0);
    let two = |k: i32| 2f64.powi(k);
    for (width_u, width_v, scale) in [
        (two(10), two(-10), 1.0),
        (two(-10), two(10), two(13)),
        (two(10), two(10), two(-10)),
        (1.0, 1.0, two(-30)),
    ] {
        let moved = sliver(width_u, width_v, scale);
        for (a, b) in fractions {
            let expected = reference.evaluate(a, b).normal;
            let normal = moved.evaluate(a * width_u, b * width_v).normal;
            let turned = angle(normal, expected);
            assert!(
                turned <= 1e-12,
                "domain {width_u} × {width_v}, scale {scale}, at ({a}, {b}): {turned:e} rad"
            );
        }
    }
    // And the edge is regular: its normal is S_u × S_v there, not the collapsed-edge limit.
    let s = reference.evaluate(0.5, 0.0);
    assert!(angle(s.normal, s.du.cross(s.dv)) <= 1e-12);
}

/// Curves and directly evaluated Coons patches are invariant under dyadic moves too: the
/// same position (to ulps of the offset), derivatives and normals.
#[test]
fn curves_and_coons_patches_are_invariant_under_dyadic_moves() {
    use knotwork::geom::patches::{Blend, CoonsBoundaries, coons_patch};
    let cubic = |points: [[f64; 3]; 4], weights: [f64; 4]| {
        let points = points.map(|p| DVec3::from_array(p) / 64.0);
        bezier_curve(3, &points, Some(&weights)).unwrap()
    };
    let boundaries = [
        cubic(
            [[0., 0., 0.], [20., -8., 4.], [44., 6., -2.], [64., 0., 0.]],
            [1., 0.25, 4., 1.],
        ),
        cubic(
            [
                [0., 64., 0.],
                [22., 70., 8.],
                [40., 60., 2.],
                [64., 64., 0.],
            ],
            [1., 2., 1., 1.],
        ),
        cubic(
            [[0., 0., 0.], [-6., 20., 4.], [4., 44., -4.], [0., 64., 0.]],
            [1., 1., 0.5, 1.],
        ),
        cubic(
            [
                [64., 0., 0.],
                [70., 24., 2.],
                [60., 40., 6.],
                [64., 64., 0.],
            ],
            [1., 8., 1., 1.],
        ),
    ];
    for offset in OFFSETS {
        for scale in [2f64.powi(-10), 1.0, 2f64.powi(13)] {
            let shift = DVec3::new(offset, offset, -offset);
            let moved_curves: Vec<BSplineCurve> = boundaries
                .iter()
                .map(|c| {
                    let n = c.homogeneous_points().len();
                    let points: Vec<DVec3> =
                        (0..n).map(|i| scale * c.control_point(i) + shift).collect();
                    let weights: Vec<f64> = (0..n).map(|i| c.weight(i)).collect();
                    BSplineCurve::try_new(c.knots().clone(), &points, Some(&weights)).unwrap()
                })
                .collect();
            let ulps =
                |p: DVec3| 4.0 * f64::EPSILON * (offset + scale * p.abs().max_element() + scale);
            for (curve, copy) in boundaries.iter().zip(&moved_curves) {
                for k in 0..=8 {
                    let t = k as f64 / 8.0;
                    let [p, d1, d2] = curve.derivatives(t);
                    let [q, e1, e2] = copy.derivatives(t);
                    assert!((q - (scale * p + shift)).abs().max_element() <= ulps(p));
                    assert_eq!(e1, scale * d1, "curve C′ at {t}");
                    assert_eq!(e2, scale * d2, "curve C″ at {t}");
                }
            }
            let patch = |c: &[BSplineCurve]| {
                let curves = CoonsBoundaries {
                    v0: &c[0],
                    v1: &c[1],
                    u0: &c[2],
                    u1: &c[3],
                };
                // The corners meet to the rounding of the offset.
                coons_patch(
                    curves,
                    Blend::Cubic,
                    1e-9 * scale + 8.0 * f64::EPSILON * offset,
                )
                .unwrap()
            };
            let (here, there) = (patch(&boundaries), patch(&moved_curves));
            for (u, v) in [(0.0, 0.0), (0.3, 0.7), (1.0, 0.5), (0.5, 1.0), (0.9, 0.1)] {
                let (s, t) = (here.evaluate(u, v), there.evaluate(u, v));
                assert!(
                    (t.position - (scale * s.position + shift))
                        .abs()
                        .max_element()
                        <= ulps(s.position)
                );
                let turned = angle(s.normal, t.normal);
                assert!(
                    turned <= MOVED_NORMAL_BAR,
                    "Coons normal at ({u}, {v}), offset {offset}, scale {scale}: {turned:e} rad"
                );
            }
        }
    }
}

// ---------------------------------------------------------------- against the exact oracle

/// Position bar against the exact oracle, relative to the model's size (plus the rounding of
/// the offset, `OFFSET_ULPS` ulps of it).
const ORACLE_POSITION_REL: f64 = 1e-12;
const OFFSET_ULPS: f64 = 4.0;
/// Normal bars against the exact oracle: regular points (where S_u and S_v are more than 1e-3
/// rad from parallel; the bar grows as 1/sin θ closer to it), and limit normals at points
/// where S_u × S_v vanishes exactly.
const ORACLE_NORMAL_BAR: f64 = 1e-9;
const ORACLE_LIMIT_NORMAL_BAR: f64 = 1e-6;

/// Knots of `degree` for `count` points: clamped or not, interior knots repeated up to the
/// degree (creases), some spans 1e-6 wide.
fn oracle_knots(degree: usize, count: usize) -> impl Strategy<Value = Vec<f64>> {
    let len = count + degree + 1;
    (
        prop::collection::vec((0.0f64..1.0, 0u8..10), len),
        any::<bool>(),
    )
        .prop_map(move |(steps, clamped)| {
            let mut knots = Vec::with_capacity(len);
            let (mut value, mut run) = (0.0f64, 1);
            for (index, &(step, kind)) in steps.iter().enumerate() {
                let clamp = clamped && (index <= degree || index >= len - degree);
                let interior = index > degree && index < len - degree - 1;
                if index > 0 && (clamp || (kind == 0 && interior && run < degree)) {
                    run += 1;
                } else if index > 0 {
                    value += if kind == 1 && interior {
                        1e-6
                    } else {
                        0.1 + step
                    };
                    run = 1;
                }
                knots.push(value);
            }
            knots
        })
}

/// An oracle case: knots, Cartesian points (u fastest) — a perturbed sheet — placed at an
/// offset and scale, weights log-uniform in [1e-3, 1e3], optionally a collapsed first row (a
/// pole or collapsed edge), last row and first column.
#[derive(Debug, Clone)]
struct OracleCase {
    degree: (usize, usize),
    knots_u: Vec<f64>,
    knots_v: Vec<f64>,
    points: Vec<DVec3>,
    weights: Vec<f64>,
}

fn oracle_case() -> impl Strategy<Value = OracleCase> {
    (1usize..=7, 1usize..=7, 0usize..3, 0usize..3)
        .prop_flat_map(|(p, q, extra_u, extra_v)| {
            let (nu, nv) = (p + 1 + extra_u, q + 1 + extra_v);
            (
                Just((p, q)),
                oracle_knots(p, nu),
                oracle_knots(q, nv),
                prop::collection::vec(prop::array::uniform3(-1.0f64..1.0), nu * nv),
                prop::collection::vec(-3.0f64..3.0, nu * nv),
                prop::array::uniform3(any::<bool>()),
                (
                    prop::array::uniform3(0usize..4),
                    prop::array::uniform3(any::<bool>()),
                    -4i32..=6,
                ),
            )
        })
        .prop_map(
            |(degree, knots_u, knots_v, raw, exponents, collapse, (offset, signs, scale))| {
                let nu = knots_u.len() - degree.0 - 1;
                let nv = knots_v.len() - degree.1 - 1;
                let offset = DVec3::from_array(std::array::from_fn(|k| {
                    let magnitude = [0.0, 1e3, 1e5, 1e7][offset[k]];
                    if signs[k] { -magnitude } else { magnitude }
                }));
                let scale = 10f64.powi(scale);
                // A sheet over the unit square, perturbed: shrinking keeps it a sheet, so the
                // only degenerate points are the collapsed rows' and column's.
                let sheet = |k: usize| {
                    let (i, j) = ((k % nu) as f64, (k / nu) as f64);
                    let (du, dv) = ((nu - 1).max(1) as f64, (nv - 1).max(1) as f64);
                    DVec3::new(i / du, j / dv, 0.0)
                };
                let mut points: Vec<DVec3> = raw
                    .iter()
                    .enumerate()
                    .map(|(k, &r)| scale * (sheet(k) + 0.3 * DVec3::from_array(r)) + offset)
                    .collect();
                for j in 0..nv {
                    for i in 0..nu {
                        if collapse[0] && j == 0 {
                            points[i] = points[0];
                        } else if collapse[1] && j == nv - 1 && nv > 1 {
                            points[j * nu + i] = points[j * nu];
                        } else if collapse[2] && i == 0 {
                            points[j * nu] = points[0];
                        }
                    }
                }
                let weights = exponents.iter().map(|&e| 10f64.powf(e)).collect();
                OracleCase {
                    degree,
                    knots_u,
                    knots_v,
                    points,
                    weights,
                }
            },
        )
}

/// A number from the environment variable `name`, else `default` (a malformed value is a
/// mistake in the command line, not something to test with).
fn oracle_setting(name: &str, default: u64) -> u64 {
    std::env::var(name).map_or(default, |value| {
        value
            .parse()
            .unwrap_or_else(|_| panic!("{name}={value} is not a number"))
    })
}

proptest! {
    // A fixed seed: the same cases on every run (CI stays reproducible); other seeds and
    // longer runs with KNOTWORK_ORACLE_SEED and KNOTWORK_ORACLE_CASES, and failures found
    // are kept in cpu.proptest-regressions.
    #![proptest_config(ProptestConfig {
        rng_seed: proptest::test_runner::RngSeed::Fixed(oracle_setting("KNOTWORK_ORACLE_SEED", 20261201)),
        ..ProptestConfig::with_cases(oracle_setting("KNOTWORK_ORACLE_CASES", 32) as u32)
    })]

    /// The f64 path against exact rational evaluation of the same inputs: degrees 1..=7 each
    /// way, creases and 1e-6 spans, weights 1e-3..1e3, placements up to 1e7 from the origin
    /// at scales 1e-4..1e6, collapsed rows and columns. Positions within 1e-12 of the size
    /// (plus ulps of the offset); normals within 1e-9 rad at regular points (1e-9 × 1e-3/sin θ
    /// where S_u and S_v are within 1e-3 rad of parallel); at points where
    /// S_u × S_v vanishes exactly, the limit normal within 1e-6 rad of the exact first-order
    /// limit along the diagonal it is defined by.
    #[test]
    fn cpu_evaluation_matches_the_exact_oracle(
        case in oracle_case(),
        params in prop::collection::vec((0.0f64..=1.0, 0.0f64..=1.0), 3),
    ) {
        let (p, q) = case.degree;
        let surface = BSplineSurface::try_new(
            KnotVector::try_new(p, case.knots_u.clone()).unwrap(),
            KnotVector::try_new(q, case.knots_v.clone()).unwrap(),
            &case.points,
            Some(&case.weights),
        ).unwrap();
        let oracle = common::exact::ExactSurface::new(
            case.degree, &case.knots_u, &case.knots_v, &case.points, &case.weights,
        );
        let size = surface.control_box_diagonal();
        let offset = surface.origin().abs().max_element();
        let position_bar = ORACLE_POSITION_REL * size + OFFSET_ULPS * f64::EPSILON * offset;
        let (ru, rv) = (surface.range_u(), surface.range_v());
        let check = |u: f64, v: f64, position: DVec3, normal: DVec3, what: &str| -> Result<(), TestCaseError> {
            let exact = oracle.evaluate(u, v);
            let off = (position - exact.position).length();
            prop_assert!(off <= position_bar, "{what}: position off by {off:e} (bar {position_bar:e}) at ({u}, {v})");
            if exact.normal == DVec3::ZERO {
                // The limit toward the centre of the range along the diagonal: the exact
                // first-order term's direction (skipped where that vanishes too).
                let step = |x: f64, r: Interval| if x > 0.5 * (r.start + r.end) { -r.width() } else { r.width() };
                if let Some(limit) = oracle.limit_normal(u, v, step(u, ru), step(v, rv)) {
                    let turned = angle(normal, limit);
                    prop_assert!(turned <= ORACLE_LIMIT_NORMAL_BAR, "{what}: limit normal off by {turned:e} at ({u}, {v})");
                }
            } else {
                // The rounding of S_u and S_v turns the normal by about their relative error
                // over sin θ (θ between them): 1e-9 rad where θ is not small, growing as
                // 1/sin θ below 1e-3 (near poles and folds).
                let sin = exact.du.cross(exact.dv).length() / (exact.du.length() * exact.dv.length());
                let bar = ORACLE_NORMAL_BAR * (1e-3 / sin).max(1.0);
                let turned = angle(normal, exact.normal);
                prop_assert!(turned <= bar, "{what}: normal off by {turned:e} (bar {bar:e}, sin θ {sin:e}) at ({u}, {v})");
            }
            Ok(())
        };
        let corners = [(0.0, 0.0), (1.0, 1.0), (0.0, 1.0), (1.0, 0.0), (0.5, 0.0), (0.0, 0.5)];
        for (a, b) in corners.into_iter().chain(params) {
            let (u, v) = (ru.lerp(a), rv.lerp(b));
            let ours = surface.evaluate(u, v);
            check(u, v, ours.position, ours.normal, "evaluate")?;
            // The position alone is the same sum.
            prop_assert_eq!(surface.point(u, v), ours.position);
        }
        // The grid executor's row kernel on a 5 × 4 grid, at the same bars.
        let (grid_u, grid_v) = (5u32, 4u32);
        let mut positions = vec![DVec3::ZERO; 20];
        let mut normals = vec![DVec3::ZERO; 20];
        knotwork::cpu::evaluate_grid_into(&surface, grid_u, grid_v, &mut positions, &mut normals).unwrap();
        for j in 0..grid_v {
            for i in 0..grid_u {
                let (u, v) = (ru.lerp(f64::from(i) / 4.0), rv.lerp(f64::from(j) / 3.0));
                let k = (j * grid_u + i) as usize;
                check(u, v, positions[k], normals[k], "grid")?;
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        rng_seed: proptest::test_runner::RngSeed::Fixed(20261201),
        ..ProptestConfig::with_cases(48)
    })]

    /// Curves against the same exact oracle (a curve is a surface of degree 0 in v):
    /// degrees 1..=7, creases and 1e-6 spans, weights 1e-3..1e3, placements to 1e7 at scales
    /// 1e-4..1e6. Positions within 1e-12 of the size (+ ulps of the offset); C′ within 1e-9
    /// of the larger of |C′| and the size over the parameter width.
    #[test]
    fn cpu_curves_match_the_exact_oracle(
        case in oracle_case(),
        params in prop::collection::vec(0.0f64..=1.0, 4),
    ) {
        // The first row of the case's net as a curve.
        let p = case.degree.0;
        let count = case.knots_u.len() - p - 1;
        let (points, weights) = (&case.points[..count], &case.weights[..count]);
        let curve = BSplineCurve::try_new(
            KnotVector::try_new(p, case.knots_u.clone()).unwrap(),
            points,
            Some(weights),
        ).unwrap();
        let oracle = common::exact::ExactSurface::new((p, 0), &case.knots_u, &[0.0, 1.0], points, weights);
        let (lo, hi) = curve.control_box();
        let size = (hi - lo).length();
        let offset = curve.origin().abs().max_element();
        let position_bar = ORACLE_POSITION_REL * size + OFFSET_ULPS * f64::EPSILON * offset;
        let range = curve.range();
        for t in [0.0, 1.0, 0.5].into_iter().chain(params) {
            let u = range.lerp(t);
            let [position, first, _] = curve.derivatives(u);
            let exact = oracle.evaluate(u, 0.5);
            let off = (position - exact.position).length();
            prop_assert!(off <= position_bar, "position off by {off:e} (bar {position_bar:e}) at {u}");
            let tangent_off = (first - exact.du).length();
            let tangent_bar = 1e-9 * exact.du.length().max(size / range.width());
            prop_assert!(tangent_off <= tangent_bar, "C′ off by {tangent_off:e} (bar {tangent_bar:e}) at {u}");
        }
    }
}

/// The pole the exact oracle found with extreme weights (1.7e-3..987, degree 2×7, at 1e5 and
/// 1e7): S_u × S_v there is rounding noise far above the size-based threshold. The grid
/// executor's SIMD kernel applies the same rounding bound as point evaluation: its normals
/// along the pole row are the limit normal, as `evaluate` gives it, not the noise.
#[test]
fn grid_kernel_takes_the_limit_normal_where_the_quotient_rule_is_noise() {
    let points = [
        DVec3::new(100000.0, 0.0, -10000000.0),
        DVec3::new(100000.0, 0.0, -10000000.0),
        DVec3::new(100000.0, 0.0, -10000000.0),
        DVec3::new(100000.0, 0.1111111111111111, -10000000.0),
        DVec3::new(100000.5, 0.1111111111111111, -10000000.0),
        DVec3::new(100001.0, -0.136547480739072, -10000000.0),
        DVec3::new(100000.0, 0.2222222222222222, -10000000.0),
        DVec3::new(100000.5, 0.2222222222222222, -10000000.0),
        DVec3::new(100001.0, 0.2222222222222222, -10000000.0),
        DVec3::new(100000.0, 0.3333333333333333, -10000000.0),
        DVec3::new(100000.5, 0.3333333333333333, -10000000.0),
        DVec3::new(100001.0, 0.3333333333333333, -10000000.0),
        DVec3::new(100000.0, 0.4444444444444444, -10000000.0),
        DVec3::new(100000.5, 0.4444444444444444, -10000000.0),
        DVec3::new(100001.0, 0.4444444444444444, -10000000.0),
        DVec3::new(100000.0, 0.5555555555555556, -9999999.704097217),
        DVec3::new(100000.5, 0.5555555555555556, -10000000.0),
        DVec3::new(100001.0, 0.5555555555555556, -10000000.261920683),
        DVec3::new(100000.0, 0.6666666666666666, -10000000.0),
        DVec3::new(100000.5, 0.6666666666666666, -10000000.0),
        DVec3::new(100001.0, 0.6666666666666666, -10000000.0),
        DVec3::new(100000.0, 0.7777777777777778, -10000000.0),
        DVec3::new(100000.5, 0.7777777777777778, -10000000.0),
        DVec3::new(100001.0, 0.7777777777777778, -10000000.0),
        DVec3::new(99999.98984741583, 0.7140558896459623, -9999999.742461752),
        DVec3::new(100000.40606798948, 1.0898556816701, -9999999.775627634),
        DVec3::new(100000.98793939839, 0.8398769236258163, -9999999.819914257),
        DVec3::new(99999.759198749, 1.021811289411743, -10000000.21624776),
        DVec3::new(99999.759198749, 1.021811289411743, -10000000.21624776),
        DVec3::new(99999.759198749, 1.021811289411743, -10000000.21624776),
    ];
    let weights = [
        0.003366304062405027,
        30.245420625157454,
        0.5081019892592381,
        987.6288089274271,
        332.0147373828442,
        0.028880533756345167,
        103.72129640043049,
        0.2291917020268556,
        222.47075761681486,
        2.94581918551294,
        0.0023562375847879496,
        6.470150151066336,
        565.5085428365351,
        0.0036994171773649096,
        19.761998806596008,
        0.6254829191179188,
        1.3841391231841427,
        903.916204945095,
        4.112350648478334,
        7.290077003694767,
        0.31446570978492155,
        51.71763544683027,
        0.004292749461942293,
        27.367617674667677,
        5.940437567591831,
        0.0016647027195355031,
        649.2134371841105,
        119.16819404106117,
        27.824241285254928,
        0.005904394486340832,
    ];
    let surface = BSplineSurface::try_new(
        KnotVector::try_new(2, vec![0.0, 0.1, 0.2, 0.30000000000000004, 0.4, 0.5]).unwrap(),
        KnotVector::try_new(
            7,
            vec![
                0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.1, 0.1, 0.2, 0.2, 0.2, 0.2, 0.2, 0.2,
                0.2, 0.2,
            ],
        )
        .unwrap(),
        &points,
        Some(&weights),
    )
    .unwrap();
    let (nu, nv) = (5u32, 4u32);
    let mut mesh = Mesh::default();
    CpuTessellator
        .tessellate_each_into(
            std::slice::from_ref(&surface),
            &[TessOptions::DEFAULT.with_grid(nu, nv)],
            &mut mesh,
        )
        .unwrap();
    let (ru, rv) = (surface.range_u(), surface.range_v());
    for i in 0..nu {
        let u = ru.lerp(f64::from(i) / f64::from(nu - 1));
        let expected = surface.evaluate(u, rv.end).normal;
        let got = mesh.normals[((nv - 1) * nu + i) as usize];
        assert!(
            angle(got, expected) < 1e-9,
            "pole vertex {i}: {got} vs {expected}"
        );
    }
    // At the corner the oracle checked: its exact limit, (0.2935, 0.7809, -0.5515).
    let corner = mesh.normals[(nv * nu - 1) as usize];
    let exact = DVec3::new(0.29349547, 0.78086290, -0.55146491);
    assert!(angle(corner, exact) < 1e-6, "corner normal {corner}");
}

/// A rational bicubic Bezier patch of 16 points (u fastest) and its exact oracle.
fn rational_bezier_with_oracle(
    points: &[DVec3],
    weights: &[f64],
) -> (BSplineSurface, common::exact::ExactSurface) {
    let knots = [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0];
    rational_with_oracle((3, 3), &knots, &knots, points, weights)
}

/// A rational surface of `degrees` (u, v) and the exact oracle of the same input.
fn rational_with_oracle(
    (p, q): (usize, usize),
    knots_u: &[f64],
    knots_v: &[f64],
    points: &[DVec3],
    weights: &[f64],
) -> (BSplineSurface, common::exact::ExactSurface) {
    let surface = BSplineSurface::try_new(
        KnotVector::try_new(p, knots_u.to_vec()).unwrap(),
        KnotVector::try_new(q, knots_v.to_vec()).unwrap(),
        points,
        Some(weights),
    )
    .unwrap();
    let oracle = common::exact::ExactSurface::new((p, q), knots_u, knots_v, points, weights);
    (surface, oracle)
}

/// One heavy weight pinning a bicubic patch near its control point (weight 1e3 among 1e-3,
/// 1e5 from the origin, a far corner making the control box 100× the pinned region): S_u
/// and S_v are small there while the quotient rule cancels terms as large as the box, so
/// the row kernel's own normals measured 1.7e-9 rad off. Point evaluation (summing relative
/// to the dominant control point) and the grid (which hands such vertices to it) hold
/// 1e-13 rad against the exact oracle.
#[test]
fn one_dominant_weight_keeps_normals_exact_on_both_paths() {
    let offset = DVec3::new(1e5, -3e4, 2e5);
    let points: Vec<DVec3> = (0..16)
        .map(|k| {
            let (i, j) = ((k % 4) as f64, (k / 4) as f64);
            offset + DVec3::new(i, j, 0.25 * ((k * 7) % 5) as f64 - 0.5)
        })
        .collect();
    // A far corner makes the control box (and so the local origin) large next to the
    // pinned region's features.
    let mut points = points;
    points[15].z += 100.0;
    let mut weights = vec![1e-3; 16];
    weights[5] = 1e3;
    let (surface, oracle) = rational_bezier_with_oracle(&points, &weights);
    let n = 9u32;
    let mut positions = vec![DVec3::ZERO; 81];
    let mut normals = vec![DVec3::ZERO; 81];
    knotwork::cpu::evaluate_grid_into(&surface, n, n, &mut positions, &mut normals).unwrap();
    let (mut worst_point, mut worst_grid) = (0.0f64, 0.0f64);
    for j in 0..n {
        for i in 0..n {
            let (u, v) = (f64::from(i) / 8.0, f64::from(j) / 8.0);
            let exact = oracle.evaluate(u, v).normal;
            worst_point = worst_point.max(angle(surface.evaluate(u, v).normal, exact));
            worst_grid = worst_grid.max(angle(normals[(j * n + i) as usize], exact));
        }
    }
    // The issue's bar is 1e-9; measured 4.4e-16 (point) and 1.4e-14 (grid), held to 1e-13 —
    // a reference other than the dominant point (e.g. chosen by basis value / weight)
    // measured 2.5e-11, the row kernel alone 1.7e-9.
    assert!(
        worst_point <= 1e-13,
        "point evaluation: {worst_point:e} rad"
    );
    assert!(worst_grid <= 1e-13, "grid: {worst_grid:e} rad");
}

/// A collapsed edge whose next control row collapses to the same point (a bicubic patch
/// with rows 0 and 1 at one point): S_u × S_v vanishes there to third order, so neither the
/// first-order term nor the second-order one (third derivatives) gives the limit, and the
/// normal comes from the last fallback, S_u × S_v a little way (1e-6 of the width) along the
/// diagonal. It must be the limit — within 1e-4 rad of the exact normal 1e-9 of the width
/// from the edge (2.4e-5 measured: the normal turns that much over the fallback's step) —
/// not the +Z left for a surface with no tangent plane anywhere near.
#[test]
fn third_order_degeneracy_takes_the_sampled_limit() {
    let apex = DVec3::new(0.5, 0.5, 1.0);
    let points: Vec<DVec3> = (0..16)
        .map(|k| {
            let (i, j) = ((k % 4) as f64, (k / 4) as f64);
            if j < 2.0 {
                apex
            } else {
                DVec3::new(i / 3.0, j / 3.0, 0.3 * (i - 1.5) * (j - 2.5))
            }
        })
        .collect();
    let weights = [
        1.0, 2.0, 0.5, 1.5, 1.0, 1.0, 1.0, 1.0, 0.7, 1.3, 1.1, 0.9, 1.0, 2.0, 1.0, 0.5,
    ];
    let (surface, oracle) = rational_bezier_with_oracle(&points, &weights);
    for u in [0.0, 0.3, 0.5, 0.8] {
        let ours = surface.evaluate(u, 0.0).normal;
        // Along the diagonal toward the centre: (+u, +v) below u = 0.5, (−u, +v) above.
        let du = if u > 0.5 { -1e-9 } else { 1e-9 };
        let near = oracle.evaluate(u + du, 1e-9).normal;
        let turned = angle(ours, near);
        assert!(
            turned <= 1e-4,
            "u = {u}: {ours} is {turned:e} rad from the exact normal next to the edge {near}"
        );
    }
}

/// A second-order degenerate corner: the conformance suite's bicubic net whose v = 0 row is
/// collapsed to a pole and whose next row leaves the pole's corner radially (P₁₁ − P₀₁ ∥
/// P₀₁ − pole), so at (0, 0) the first-order term vanishes exactly too and the limit comes
/// from third derivatives — here with weights, on a domain [0, 2] × [0, ½] (the diagonal's
/// steps ±2 and ±½ weigh the third derivatives unequally), and transposed (where S_v's
/// directional derivatives carry the term instead of S_u's): within 1e-9 rad of the exact
/// normal 1e-12 along the diagonal.
#[test]
fn a_second_order_degenerate_corner_takes_its_limit_normal() {
    let corner = &knotwork::conformance::second_order_corners()[0];
    let points: Vec<DVec3> = (0..4)
        .flat_map(|j| (0..4).map(move |i| (i, j)))
        .map(|(i, j)| corner.control_point(i, j))
        .collect();
    let weights = [
        1.0, 2.0, 0.5, 1.0, 1.0, 0.5, 2.0, 1.0, 1.0, 1.0, 4.0, 1.0, 0.5, 1.0, 1.0, 2.0,
    ];
    let knots_u = vec![0.0, 0.0, 0.0, 0.0, 2.0, 2.0, 2.0, 2.0];
    let knots_v = vec![0.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.5, 0.5];
    let (surface, oracle) = rational_with_oracle((3, 3), &knots_u, &knots_v, &points, &weights);
    assert_eq!(
        oracle.limit_normal(0.0, 0.0, 2.0, 0.5),
        None,
        "first order vanishes"
    );
    let near = oracle.evaluate(2e-12, 0.5e-12).normal;
    let ours = surface.evaluate(0.0, 0.0).normal;
    let turned = angle(ours, near);
    assert!(turned <= 1e-9, "{ours} is {turned:e} rad from {near}");
    let transposed = surface.transposed().evaluate(0.0, 0.0).normal;
    let turned = angle(transposed, -near);
    assert!(
        turned <= 1e-9,
        "transposed: {transposed} is {turned:e} rad from {}",
        -near
    );
}

/// A second-order degenerate corner off any collapsed edge: S = (u³, v + u², v²) on
/// [0, 2] × [0, ½] has S_u = 0 along u = 0 and, at (0, 0), S_uu ∥ S_v, so the first-order
/// term vanishes there and the limit is the second-order term's, in closed form: S_u × S_v =
/// (4uv, −6u²v, 3u²), along the diagonal (2t, ½t) the direction (4ab, 0, 3a²) with (a, b) =
/// (2, ½): (1, 0, 3)/√10. Unlike at collapsed edges, S_uuu counts (through su2 × S_v) and
/// the steps are not ±1, so the terms' coefficients a², b² show; transposed, S_vvv counts
/// instead (through S_u × sv2) and the normal is the opposite.
#[test]
fn a_second_order_point_off_collapsed_edges_takes_its_limit_normal() {
    // Bezier form on s = u/2, t = 2v: x = 8s³, y = 4s² + t/2, z = t²/4, each a sum of a
    // function of s and one of t, so P_ij = (x_i, y_i + y′_j, z_j).
    let (x, y) = ([0.0, 0.0, 0.0, 8.0], [0.0, 0.0, 4.0 / 3.0, 4.0]);
    let (y_t, z) = ([0.0, 0.25, 0.5], [0.0, 0.0, 0.25]);
    let points: Vec<DVec3> = (0..3)
        .flat_map(|j| (0..4).map(move |i| DVec3::new(x[i], y[i] + y_t[j], z[j])))
        .collect();
    let surface = piecewise_bezier_surface(3, 2, &[0.0, 2.0], &[0.0, 0.5], &points, None).unwrap();
    // The form is the closed one: a point and its cross product inside.
    let (u, v) = (0.7, 0.3);
    let inside = surface.evaluate(u, v);
    assert!((inside.position - DVec3::new(u * u * u, v + u * u, v * v)).length() < 1e-14);
    let exact_cross = DVec3::new(4.0 * u * v, -6.0 * u * u * v, 3.0 * u * u);
    assert!(angle(inside.du.cross(inside.dv), exact_cross) < 1e-14);
    let (a, b) = (2.0, 0.5);
    let limit = DVec3::new(4.0 * a * b, 0.0, 3.0 * a * a).normalize();
    let ours = surface.evaluate(0.0, 0.0).normal;
    assert!(angle(ours, limit) < 1e-12, "{ours} vs {limit}");
    let transposed = surface.transposed().evaluate(0.0, 0.0).normal;
    assert!(
        angle(transposed, -limit) < 1e-12,
        "transposed: {transposed} vs {}",
        -limit
    );
}

/// A fold inside a rational patch: each control column of a bicubic × quadratic patch runs
/// out and back (its first and last points equal, the last weight `ratio` times the first),
/// so the surface turns back on itself where the homogeneous H_v is parallel to H, at
/// v = 1/(1 + √ratio) — ½ for equal weights, ¼ for ninefold ones — where S_v vanishes
/// exactly (and S_uv with it) while S_u does not. There the point is not a control point:
/// relative to the dominant control point it is not zero, so the first-order limit's terms
/// in S count (at collapsed rows, the other tests' degenerate points, the point is the
/// dominant control point and they vanish), those in w_uv·S only where the weights are not
/// symmetric about the fold. Weights 2⁻⁶..2⁶ (times 9) and coordinates on a dyadic grid 2¹⁷
/// from the origin, so the input is exact; normals at the fold against the exact oracle's
/// limit toward the centre, within the issue's 1e-6 rad for limit normals.
#[test]
fn a_fold_inside_a_rational_patch_takes_its_limit_normal() {
    let offset = DVec3::new(131072.0, -65536.0, 32768.0);
    // Rows j = 0, 1, 2 of four points each (u fastest); row 2 repeats row 0's points.
    let row = |j: usize, i: usize| {
        let (x, k) = (i as f64, j as f64);
        match j % 2 {
            0 => (
                DVec3::new(x, 0.25 * x * x, 0.5 * x),
                [2.0, 0.015625, 64.0, 0.5][i],
            ),
            _ => (
                DVec3::new(x + 0.75, 1.5 + 0.25 * k * x, -1.0 + 0.125 * x),
                [0.25, 8.0, 1.0, 32.0][i],
            ),
        }
    };
    let knots_u = vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0];
    let knots_v = vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0];
    for (ratio, fold) in [(1.0, 0.5), (9.0, 0.25)] {
        let (mut points, mut weights) = (Vec::new(), Vec::new());
        for j in 0..3 {
            for i in 0..4 {
                let (p, w) = row(j, i);
                points.push(p + offset);
                weights.push(if j == 2 { ratio * w } else { w });
            }
        }
        let (surface, oracle) = rational_with_oracle((3, 2), &knots_u, &knots_v, &points, &weights);
        for u in [0.125, 0.375, 0.5, 0.75, 0.9375] {
            let exact = oracle.evaluate(u, fold);
            assert_eq!(exact.dv, DVec3::ZERO, "the fold is exact at ({u}, {fold})");
            let step_u = if u > 0.5 { -1.0 } else { 1.0 };
            let limit = oracle
                .limit_normal(u, fold, step_u, 1.0)
                .expect("a first-order limit");
            let ours = surface.evaluate(u, fold);
            assert!(
                ours.position.distance(exact.position)
                    <= 1e-12 * 8.0 + 4.0 * f64::EPSILON * 131072.0
            );
            let turned = angle(ours.normal, limit);
            assert!(
                turned <= 1e-6,
                "({u}, {fold}): normal {} is {turned:e} rad from the limit {limit}",
                ours.normal
            );
        }
    }
}

/// A double cone inside one rational span, the transpose of the fold above: rows apex − C_i
/// and apex + C_i with weights w_i and `ratio`·w_i, so S = apex + f(v)·C(u) with f zero at
/// v = 1/(1 + ratio) — ½ for equal weights, ¼ for threefold ones (where w_uv does not
/// vanish) — where S_u = 0 while S_v ≠ 0. The dominant control point there is a row's, not
/// the apex, so the first-order limit's terms in S × S_v count (they cancel exactly in the
/// true A₁; a wrong coefficient on one leaves a multiple of C_k × C). Weights 2⁻⁶..2⁶ (times
/// 3), dyadic coordinates 2¹⁷ from the origin; normals at the apex against the exact
/// oracle's limit toward the centre, within 1e-6 rad.
#[test]
fn an_apex_inside_a_rational_span_takes_its_limit_normal() {
    let apex = DVec3::new(131072.0, -65536.0, 32768.0);
    let generator = [
        DVec3::new(1.0, 0.0, 0.5),
        DVec3::new(0.5, 1.0, -0.25),
        DVec3::new(-0.5, 1.25, 0.75),
        DVec3::new(-1.0, 0.25, 0.5),
    ];
    let weights_u = [2.0, 0.015625, 64.0, 0.5];
    let knots_u = vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0];
    let knots_v = vec![0.0, 0.0, 1.0, 1.0];
    for (ratio, at) in [(1.0, 0.5), (3.0, 0.25)] {
        let points: Vec<DVec3> = [-1.0, 1.0]
            .iter()
            .flat_map(|side| generator.iter().map(move |c| apex + *side * *c))
            .collect();
        let weights: Vec<f64> = (weights_u.iter().copied())
            .chain(weights_u.iter().map(|w| ratio * w))
            .collect();
        let (surface, oracle) = rational_with_oracle((3, 1), &knots_u, &knots_v, &points, &weights);
        for u in [0.125, 0.375, 0.5, 0.75, 0.9375] {
            let exact = oracle.evaluate(u, at);
            assert_eq!(exact.du, DVec3::ZERO, "the apex is exact at ({u}, {at})");
            let step_u = if u > 0.5 { -1.0 } else { 1.0 };
            let limit = oracle
                .limit_normal(u, at, step_u, 1.0)
                .expect("a first-order limit");
            let ours = surface.evaluate(u, at);
            assert!(ours.position.distance(apex) <= 4.0 * f64::EPSILON * 131072.0);
            let turned = angle(ours.normal, limit);
            assert!(
                turned <= 1e-6,
                "({u}, {at}): normal {} is {turned:e} rad from the limit {limit}",
                ours.normal
            );
        }
    }
}

// ---------------------------------------------------------------- adaptive tessellation

/// A random rational surface for the adaptive tests: degrees 1..=4, knots with
/// multiplicities and 1e-6 spans (clamped or not), weights 0.1..10 or none, with a
/// tolerance 3e-4..1e-1 of its control box's diagonal.
fn adaptive_case() -> impl Strategy<Value = (BSplineSurface, f64)> {
    (1usize..=4, 1usize..=4, 0usize..4, 0usize..4)
        .prop_flat_map(|(p, q, extra_u, extra_v)| {
            let (nu, nv) = (p + 1 + extra_u, q + 1 + extra_v);
            (
                oracle_knots(p, nu),
                oracle_knots(q, nv),
                prop::collection::vec(prop::array::uniform3(-1.0f64..1.0), nu * nv),
                prop::option::of(prop::collection::vec(-1.0f64..1.0, nu * nv)),
                -3.5f64..-1.0,
                Just((p, q)),
            )
        })
        .prop_map(|(knots_u, knots_v, raw, exponents, tolerance, (p, q))| {
            let nu = knots_u.len() - p - 1;
            let points: Vec<DVec3> = raw
                .iter()
                .enumerate()
                .map(|(k, r)| {
                    DVec3::new((k % nu) as f64, (k / nu) as f64, 0.0) + DVec3::from_array(*r)
                })
                .collect();
            let weights: Option<Vec<f64>> =
                exponents.map(|e| e.iter().map(|x| 10f64.powf(*x)).collect());
            let surface = BSplineSurface::try_new(
                KnotVector::try_new(p, knots_u).unwrap(),
                KnotVector::try_new(q, knots_v).unwrap(),
                &points,
                weights.as_deref(),
            )
            .unwrap();
            let diagonal = surface.control_box_diagonal();
            (surface, 10f64.powf(tolerance) * diagonal)
        })
}

proptest! {
    #![proptest_config(ProptestConfig {
        rng_seed: proptest::test_runner::RngSeed::Fixed(20261201),
        ..ProptestConfig::with_cases(48)
    })]

    /// The first- and second-derivative bounds of each Bezier patch of a surface hold
    /// wherever the patch is sampled, rational ones included (weights 0.1..10).
    #[test]
    fn derivative_bounds_hold((surface, _) in adaptive_case()) {
        for patch in surface.bezier_patches() {
            let bound = patch.derivative_bound();
            // Inside the patch: on a knot, evaluation takes the derivatives of the next span.
            for k in 0..25 {
                let (s, t) = (((k % 5) as f64 + 0.5) / 5.0, ((k / 5) as f64 + 0.5) / 5.0);
                let sample = surface.evaluate(patch.range_u.lerp(s), patch.range_v.lerp(t));
                let slack = 1.0 + 1e-9;
                prop_assert!(sample.du.length() <= bound.u * slack + 1e-9, "S_u {} > {}", sample.du.length(), bound.u);
                prop_assert!(sample.dv.length() <= bound.v * slack + 1e-9, "S_v {} > {}", sample.dv.length(), bound.v);
                prop_assert!(sample.duu.length() <= bound.uu * slack + 1e-9, "S_uu {} > {}", sample.duu.length(), bound.uu);
                prop_assert!(sample.duv.length() <= bound.uv * slack + 1e-9, "S_uv {} > {}", sample.duv.length(), bound.uv);
                prop_assert!(sample.dvv.length() <= bound.vv * slack + 1e-9, "S_vv {} > {}", sample.dvv.length(), bound.vv);
            }
        }
    }

    /// A surface tessellated to a tolerance stays within it — at every triangle's centroid
    /// and edge midpoints, against the f64 surface at the same parameter — and its cells
    /// meet without a crack: every edge inside the surface is used once in each direction
    /// (no T-junction, one orientation), the edges used once lie on the boundary of its
    /// parameter range, every triangle turns counter-clockwise in uv, and every vertex is
    /// used. With a longest edge as well, no triangle edge is longer and the tolerance still
    /// holds.
    #[test]
    fn adaptive_meshes_stay_within_their_tolerance((surface, tolerance) in adaptive_case()) {
        let options = TessOptions::DEFAULT.with_tolerance(Tolerance::Absolute(tolerance));
        let mesh = CpuTessellator.tessellate(std::slice::from_ref(&surface), &options).unwrap();
        let worst = worst_deviation(std::slice::from_ref(&surface), &mesh);
        // Rounding of the f64 evaluation, far below any tolerance tested.
        let rounding = 1e-12 * surface.control_box_diagonal();
        prop_assert!(worst <= tolerance + rounding, "deviation {worst:e} over tolerance {tolerance:e}");
        let crack_free = joined_without_cracks(&mesh);
        prop_assert!(crack_free.is_ok(), "{}", crack_free.unwrap_err());
        // With a longest edge too (a tenth of the control box), both hold.
        let max_edge = 0.1 * surface.control_box_diagonal();
        let both = CpuTessellator
            .tessellate(std::slice::from_ref(&surface), &options.with_max_edge(max_edge))
            .unwrap();
        let worst = worst_deviation(std::slice::from_ref(&surface), &both);
        prop_assert!(worst <= tolerance + rounding, "deviation {worst:e} over tolerance {tolerance:e}");
        for t in both.indices.chunks(3) {
            for k in 0..3 {
                let edge = both.positions[t[k] as usize] - both.positions[t[(k + 1) % 3] as usize];
                prop_assert!(edge.length() <= max_edge * (1.0 + 1e-12), "edge {} > {max_edge}", edge.length());
            }
        }
    }
}

/// Whether the adaptive mesh of one surface is joined without a crack: every triangle
/// counter-clockwise in uv, every edge used at most once each way (no T-junction, one
/// orientation), those used once on the boundary of the parameter range, every vertex used.
fn joined_without_cracks(mesh: &Mesh) -> Result<(), String> {
    let mut directed = std::collections::HashSet::new();
    let mut used = vec![false; mesh.positions.len()];
    for t in mesh.indices.chunks(3) {
        let [a, b, c] = [0, 1, 2].map(|k| mesh.uvs[t[k] as usize]);
        if (b - a).perp_dot(c - a) <= 0.0 {
            return Err(format!("triangle {t:?} not counter-clockwise in uv"));
        }
        for k in 0..3 {
            used[t[k] as usize] = true;
            let edge = (t[k], t[(k + 1) % 3]);
            if !directed.insert(edge) {
                return Err(format!("edge {edge:?} used twice one way"));
            }
        }
    }
    if !used.iter().all(|&u| u) {
        return Err("unused vertices".into());
    }
    for &(a, b) in &directed {
        if !directed.contains(&(b, a)) {
            let (p, q) = (mesh.uvs[a as usize], mesh.uvs[b as usize]);
            let on_side = (p.x == q.x && (p.x == 0.0 || p.x == 1.0))
                || (p.y == q.y && (p.y == 0.0 || p.y == 1.0));
            if !on_side {
                return Err(format!("open edge {p} – {q} inside the range"));
            }
        }
    }
    Ok(())
}

/// One surface of many cells (the 32×32 surface at 1e-3 of its diagonal: 13 520 cells, so
/// its triangles are joined in parallel bands of cell rows) is joined without a crack
/// across the bands, and within its tolerance.
#[test]
fn a_surface_joined_in_bands_has_no_cracks() {
    let surfaces = knotwork::io::read_scene(std::path::Path::new("data/peer_bicubic_32x32.obj"))
        .unwrap()
        .surface_list();
    let tolerance = 1e-3 * surfaces[0].control_box_diagonal();
    let options = TessOptions::DEFAULT.with_tolerance(Tolerance::Absolute(tolerance));
    let mesh = CpuTessellator.tessellate(&surfaces, &options).unwrap();
    assert!(
        mesh.indices.len() / 3 > 100_000,
        "{} triangles",
        mesh.indices.len() / 3
    );
    joined_without_cracks(&mesh).unwrap();
    let worst = worst_deviation(&surfaces, &mesh);
    assert!(worst <= tolerance, "{worst:e} > {tolerance:e}");
}

/// The ducky (a rational body closed along u with a pole at each end of v, and the beak and
/// eye beside it) at 1e-2 and 1e-3 of its diagonal: every part within the tolerance —
/// the poles' fans and the body's seam included — and a fair share of it (the bound is
/// not loose by orders).
#[test]
fn the_ducky_meets_its_tolerance_at_its_poles_and_seam() {
    let surfaces = knotwork::io::read_scene(std::path::Path::new("data/ducky.obj"))
        .unwrap()
        .surface_list();
    let diagonal = common::model_diagonal(&surfaces);
    for relative in [1e-2, 1e-3] {
        let tolerance = relative * diagonal;
        let options = TessOptions::DEFAULT.with_tolerance(Tolerance::Absolute(tolerance));
        let mesh = CpuTessellator.tessellate(&surfaces, &options).unwrap();
        for part in &mesh.parts {
            let alone = Mesh {
                parts: vec![*part],
                ..mesh.clone()
            };
            let worst = worst_deviation(&surfaces, &alone);
            println!(
                "ducky part {} at {relative:e}: deviation {:.2} of the tolerance",
                part.item,
                worst / tolerance
            );
            assert!(
                worst <= tolerance,
                "part {}: {worst:e} > {tolerance:e}",
                part.item
            );
            assert!(worst >= 0.2 * tolerance, "part {}: bound loose", part.item);
        }
    }
}

/// The teapot at tolerances 1e-2, 1e-3 and 1e-4 (model units; the teapot is about 7 across):
/// within each, the measured deviation a fair share of it (the bound is not loose by
/// orders), and triangles growing about tenfold per tenfold (the bound is second order:
/// segments grow as 1/√tolerance in each direction). At 1e-3 at most 74 000 triangles:
/// 0.8× the 92 602 of Open CASCADE's BRepMesh at the same deflection.
#[test]
fn the_teapot_meets_each_tolerance_with_second_order_growth() {
    let scene = knotwork::io::read_scene(std::path::Path::new("data/teapot.bpt")).unwrap();
    let surfaces = scene.surface_list();
    let mut triangles = Vec::new();
    for tolerance in [1e-2, 1e-3, 1e-4] {
        let options = TessOptions::DEFAULT.with_tolerance(Tolerance::Absolute(tolerance));
        let mesh = CpuTessellator.tessellate(&surfaces, &options).unwrap();
        let worst = worst_deviation(&surfaces, &mesh);
        println!(
            "teapot at {tolerance:e}: {} triangles, deviation {worst:e} ({:.2} of the tolerance)",
            mesh.indices.len() / 3,
            worst / tolerance
        );
        assert!(worst <= tolerance, "{worst:e} > {tolerance:e}");
        assert!(
            worst >= 0.2 * tolerance,
            "bound loose: {worst:e} for {tolerance:e}"
        );
        triangles.push(mesh.indices.len() as f64 / 3.0);
    }
    assert!(
        triangles[1] <= 74_000.0,
        "{} triangles at 1e-3",
        triangles[1]
    );
    for pair in triangles.windows(2) {
        let growth = pair[1] / pair[0];
        assert!(
            (6.0..=12.0).contains(&growth),
            "triangles grew {growth}× per tenfold"
        );
    }
}

/// At the teapot's bottom pole a grid cell joined to a finer neighbour took the pole and
/// two samples of one meridian in a triangle: on the flat bottom a sliver of no area facing
/// anywhere (4 at 1e-3 and at 1e-4 of the diagonal). Now the join zips from the pole along
/// both meridians: no triangle faces against a corner's normal there.
#[test]
fn the_teapot_pole_has_no_turned_slivers() {
    let surfaces = knotwork::io::read_scene(std::path::Path::new("data/teapot.bpt"))
        .unwrap()
        .surface_list();
    for tolerance_rel in [1e-3, 1e-4] {
        let options = TessOptions::DEFAULT.with_tolerance(Tolerance::Relative(tolerance_rel));
        let mesh = CpuTessellator.tessellate(&surfaces, &options).unwrap();
        let turned = (mesh.indices.chunks(3))
            .filter(|t| {
                let p = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
                let normal = (p[1] - p[0]).cross(p[2] - p[0]);
                t.iter()
                    .any(|&k| normal.dot(mesh.normals[k as usize]) <= 0.0)
            })
            .count();
        assert_eq!(turned, 0, "at {tolerance_rel}: {turned} turned over");
    }
}

/// The largest angle (degrees) between the normals at the ends of any triangle edge of
/// `mesh`, leaving out edges with an end at a vertex where `skip` holds.
fn largest_edge_turn(mesh: &Mesh, skip: impl Fn(usize) -> bool) -> f64 {
    let mut largest = 0.0f64;
    for t in mesh.indices.chunks(3) {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            if !skip(a) && !skip(b) {
                largest = largest.max(mesh.normals[a].angle_between(mesh.normals[b]).to_degrees());
            }
        }
    }
    largest
}

/// `--max-angle`: the normals at the ends of every triangle edge differ by at most the
/// limit — on a torus (rational, no degenerate point), on the teapot (every edge, its poles
/// included) and on a sphere (edges off its two pole vertices, next to which the rates are
/// not bounded) — alone and beside a tolerance, which still holds; halving the angle takes
/// about four times the triangles (segments grow as 1/angle in each direction), and the
/// bound is not loose by orders (alone, the largest turn at least a third of the limit).
#[test]
fn max_angle_holds_between_the_normals_of_every_edge() {
    let teapot = knotwork::io::read_scene(std::path::Path::new("data/teapot.bpt"))
        .unwrap()
        .surface_list();
    let cases: [(&str, Vec<BSplineSurface>, bool, &[f64]); 3] = [
        ("torus", vec![common::torus(2.0, 0.5)], false, &[20.0, 10.0]),
        ("teapot", teapot, false, &[20.0, 10.0]),
        ("sphere", vec![common::sphere(1.0)], true, &[30.0]),
    ];
    for (name, surfaces, skip_poles, angles) in cases {
        let diagonal = surfaces
            .iter()
            .map(|s| s.control_box_diagonal())
            .fold(0.0, f64::max);
        let mut triangles = Vec::new();
        for &degrees in angles {
            let alone = TessOptions::DEFAULT.with_max_angle(degrees);
            let tolerance = 1e-3 * diagonal;
            let both = alone.with_tolerance(Tolerance::Absolute(tolerance));
            for options in [alone, both] {
                let mesh = CpuTessellator.tessellate(&surfaces, &options).unwrap();
                let at_pole =
                    |v: usize| skip_poles && (mesh.uvs[v].y == 0.0 || mesh.uvs[v].y == 1.0);
                let turn = largest_edge_turn(&mesh, at_pole);
                println!(
                    "{name} at {degrees}°{}: {} triangles, largest turn {turn:.2}°",
                    if options.tolerance.is_some() {
                        " and 1e-3"
                    } else {
                        ""
                    },
                    mesh.indices.len() / 3
                );
                assert!(
                    turn <= degrees * (1.0 + 1e-9),
                    "{name}: {turn}° > {degrees}°"
                );
                if options.tolerance.is_none() {
                    assert!(
                        turn >= degrees / 3.0,
                        "{name}: {turn}° for {degrees}°: bound loose"
                    );
                }
                if options.tolerance.is_none() {
                    triangles.push(mesh.indices.len() as f64 / 3.0);
                } else {
                    let worst = worst_deviation(&surfaces, &mesh);
                    assert!(
                        worst <= tolerance * (1.0 + 1e-9),
                        "{name}: {worst:e} > {tolerance:e}"
                    );
                }
            }
        }
        if let [coarse, fine] = triangles[..] {
            let growth = fine / coarse;
            assert!(
                (2.5..=6.0).contains(&growth),
                "{name}: halving the angle took {growth}× the triangles"
            );
        }
    }
}

/// A tolerance that is not a finite positive number is refused with the surface it came
/// with, one too fine to reach within the segment cap is refused as such, and directly
/// evaluated Coons patches (no control net to bound) ask for a grid instead.
#[test]
fn invalid_tolerances_are_refused_by_name() {
    let surfaces = vec![common::sphere(1.0); 2];
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        for tolerance in [Tolerance::Absolute(bad), Tolerance::Relative(bad)] {
            let options = [
                TessOptions::DEFAULT,
                TessOptions::DEFAULT.with_tolerance(tolerance),
            ];
            let err = CpuTessellator
                .tessellate_each_into(&surfaces, &options, &mut Mesh::default())
                .unwrap_err();
            assert!(
                matches!(&err, Error::InSurface { index: 1, source } if matches!(**source, Error::InvalidTolerance { .. })),
                "{err}"
            );
        }
    }
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let options = TessOptions::DEFAULT.with_max_edge(bad);
        let err = CpuTessellator.tessellate(&surfaces, &options).unwrap_err();
        assert!(matches!(err.root(), Error::InvalidMaxEdge { .. }), "{err}");
    }
    for bad in [0.0, -10.0, 180.0, 270.0, f64::NAN, f64::INFINITY] {
        let options = TessOptions::DEFAULT.with_max_angle(bad);
        let err = CpuTessellator.tessellate(&surfaces, &options).unwrap_err();
        assert!(matches!(err.root(), Error::InvalidMaxAngle { .. }), "{err}");
    }
    let too_fine = TessOptions::DEFAULT.with_tolerance(Tolerance::Relative(1e-15));
    let err = CpuTessellator.tessellate(&surfaces, &too_fine).unwrap_err();
    assert!(
        matches!(err.root(), Error::ToleranceTooFine { .. }),
        "{err}"
    );
    let coons = knotwork::plan::GridLayout::new(1, &[too_fine]).unwrap_err();
    assert!(matches!(coons, Error::NoToleranceFor { .. }), "{coons}");
}

// ---------------------------------------------------------------- trimmed faces

use knotwork::geom::{ParamMap, SamplingLimits, TrimLoop, TrimmedSurface, shapes::unit_arc};
use knotwork::plan::plan_trimmed;

/// The circle of `radius` about `centre` in the parameter plane, as rational quadratic arcs
/// over [0, π] and [π, 2π] (a loop of two curves; `reversed`: clockwise).
fn uv_circle(centre: glam::DVec2, radius: f64, reversed: bool) -> TrimLoop {
    let pi = std::f64::consts::PI;
    let halves = if reversed {
        [(2.0 * pi, pi), (pi, 0.0)]
    } else {
        [(0.0, pi), (pi, 2.0 * pi)]
    };
    let curves = halves
        .iter()
        .map(|&(a, b)| {
            let (low, high) = (a.min(b), a.max(b));
            let (knots, mut points) = unit_arc(Interval::new(low, high)).unwrap();
            if a > b {
                points.reverse();
            }
            let cartesian: Vec<DVec3> = points
                .iter()
                .map(|&(x, y, _)| DVec3::new(centre.x + radius * x, centre.y + radius * y, 0.0))
                .collect();
            let weights: Vec<f64> = points.iter().map(|p| p.2).collect();
            BSplineCurve::try_new(knots, &cartesian, Some(&weights)).unwrap()
        })
        .collect();
    TrimLoop { curves }
}

/// A closed polygon in the parameter plane as one degree-1 curve through `corners` (and
/// back to the first).
fn uv_polygon(corners: &[glam::DVec2]) -> TrimLoop {
    let mut points: Vec<DVec3> = corners.iter().map(|c| c.extend(0.0)).collect();
    points.push(points[0]);
    let breaks: Vec<f64> = (0..points.len()).map(|k| k as f64).collect();
    let knots = KnotVector::from_breakpoints(1, &breaks).unwrap();
    TrimLoop {
        curves: vec![BSplineCurve::try_new(knots, &points, None).unwrap()],
    }
}

/// The mesh of a trimmed face at `tolerance` (model units), planned and run on the CPU.
fn trimmed_mesh(face: &TrimmedSurface, tolerance: f64) -> Mesh {
    let limits = SamplingLimits::tolerance(tolerance);
    let plan = plan_trimmed(face, limits).unwrap();
    knotwork::cpu::execute_trimmed(face, &plan)
}

/// The triangles of `mesh` in uv (its parameters as fractions of the range).
fn uv_triangles(mesh: &Mesh) -> Vec<[glam::DVec2; 3]> {
    mesh.indices
        .chunks(3)
        .map(|t| [0, 1, 2].map(|k| mesh.uvs[t[k] as usize]))
        .collect()
}

/// Checks a trimmed mesh's topology: every triangle counter-clockwise in uv, every edge used
/// at most once each way, and the edges used once (the boundary) lie on a loop
/// (`on_loop(uv)` for both ends); returns the uv area the triangles cover.
fn check_trimmed_topology(
    mesh: &Mesh,
    on_loop: impl Fn(glam::DVec2) -> bool,
) -> Result<f64, TestCaseError> {
    let mut directed = std::collections::HashSet::new();
    let mut area = 0.0;
    for t in mesh.indices.chunks(3) {
        let [a, b, c] = [0, 1, 2].map(|k| mesh.uvs[t[k] as usize]);
        let twice = (b - a).perp_dot(c - a);
        // Counter-clockwise, or degenerate within the rounding of uv (a sliver of a few ulps).
        let longest = (b - a).length().max((c - b).length()).max((a - c).length());
        prop_assert!(
            twice > -1e-15 * longest,
            "triangle {t:?} not counter-clockwise in uv: {a} {b} {c} ({twice:e})"
        );
        area += 0.5 * twice;
        for k in 0..3 {
            prop_assert!(
                directed.insert((t[k], t[(k + 1) % 3])),
                "edge used twice one way"
            );
        }
    }
    for &(a, b) in &directed {
        if !directed.contains(&(b, a)) {
            let (p, q) = (mesh.uvs[a as usize], mesh.uvs[b as usize]);
            prop_assert!(
                on_loop(p) && on_loop(q),
                "open edge {p} – {q} inside the face ({} {})",
                on_loop(p),
                on_loop(q)
            );
        }
    }
    Ok(area)
}

/// Total length of the edges of `mesh` that only one triangle uses (its open boundary).
fn open_boundary_length(mesh: &Mesh) -> f64 {
    let mut uses = std::collections::HashMap::new();
    for t in mesh.indices.chunks(3) {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *uses.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    (uses.iter())
        .filter(|&(_, &n)| n == 1)
        .map(|(&(a, b), _)| mesh.positions[a as usize].distance(mesh.positions[b as usize]))
        .sum()
}

/// A loop that crosses the seam of a closed surface (a torus, closed both ways, range
/// [0, 1]²) is the same region as the two loops either side of the seam: one piece with
/// the area of both within 0.1 %, whose open boundary is the loop alone — shorter than the
/// two pieces' by the seam segments they add (twice their length each). Across u = 1 and
/// across v = 0 (the loop given below the range there).
#[test]
fn trimming_loops_may_cross_the_seam_of_a_closed_surface() {
    let torus = knotwork::geom::shapes::torus(DVec3::ZERO, 3.0, 1.0);
    let tolerance = 1e-3;
    let rectangle = |u0: f64, u1: f64, v0: f64, v1: f64| {
        uv_polygon(&[(u0, v0), (u1, v0), (u1, v1), (u0, v1)].map(glam::DVec2::from))
    };
    let face =
        |l: TrimLoop| TrimmedSurface::try_new(torus.clone(), ParamMap::SAME, Some(l), vec![]);
    let area = |mesh: &Mesh| -> f64 {
        (mesh.indices.chunks(3))
            .map(|t| {
                let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    };
    // (the crossing loop, the two pieces, the seam segment's length on the torus).
    let cases = [
        (
            rectangle(0.9, 1.15, 0.3, 0.5),
            [
                rectangle(0.9, 1.0, 0.3, 0.5),
                rectangle(0.0, 0.15, 0.3, 0.5),
            ],
            (torus.point(0.0, 0.3) - torus.point(0.0, 0.5)).length(),
        ),
        (
            rectangle(0.2, 0.4, -0.1, 0.1),
            [rectangle(0.2, 0.4, 0.9, 1.0), rectangle(0.2, 0.4, 0.0, 0.1)],
            (torus.point(0.2, 0.0) - torus.point(0.4, 0.0)).length(),
        ),
    ];
    for (crossing, pieces, seam) in cases {
        let whole = trimmed_mesh(&face(crossing).unwrap(), tolerance);
        let parts: Vec<Mesh> = (pieces.into_iter())
            .map(|l| trimmed_mesh(&face(l).unwrap(), tolerance))
            .collect();
        let parts_area: f64 = parts.iter().map(area).sum();
        let whole_area = area(&whole);
        assert!(
            (whole_area - parts_area).abs() <= 1e-3 * parts_area,
            "area {whole_area} against {parts_area}"
        );
        let parts_boundary: f64 = parts.iter().map(open_boundary_length).sum();
        let whole_boundary = open_boundary_length(&whole);
        // The seam segments are chords of at most the segment's length (two per piece pair).
        assert!(
            whole_boundary < parts_boundary - 1.5 * seam,
            "boundary {whole_boundary} against {parts_boundary} (seam {seam})"
        );
        // Every vertex on the torus: |distance from the tube's circle − 1| within rounding.
        for p in &whole.positions {
            let off = ((p.truncate().length() - 3.0).hypot(p.z) - 1.0).abs();
            assert!(off < 1e-12, "{p} off the torus by {off:e}");
        }
    }
    // Wider than a period: still refused, naming the loop.
    assert!(matches!(
        face(rectangle(0.1, 1.2, 0.3, 0.5)),
        Err(Error::InvalidTrimLoop { loop_index: 0, .. })
    ));
    // A surface of revolution whose loops are given in angles (IGES 120): a cylinder of
    // radius 2 and height 3, the loop from −0.5 to 0.7 rad across its seam at 0 — one
    // piece of the exact area 2·1.2·(0.8 − 0.2)·3 less the chords' shortfall.
    let profile = BSplineCurve::try_new(
        KnotVector::clamped_uniform(1, 2).unwrap(),
        &[DVec3::new(2.0, 0.0, 0.0), DVec3::new(2.0, 0.0, 3.0)],
        None,
    )
    .unwrap();
    let cylinder = knotwork::geom::shapes::revolve(
        &profile,
        DVec3::ZERO,
        DVec3::Z,
        Interval::new(0.0, std::f64::consts::TAU),
    )
    .unwrap();
    let in_angles = ParamMap {
        swap: false,
        u: knotwork::geom::AxisMap::Angle {
            angles: Interval::new(0.0, std::f64::consts::TAU),
        },
        v: knotwork::geom::AxisMap::SAME,
    };
    let band = TrimmedSurface::try_new(
        cylinder,
        in_angles,
        Some(rectangle(-0.5, 0.7, 0.2, 0.8)),
        vec![],
    )
    .unwrap();
    let mesh = trimmed_mesh(&band, tolerance);
    let exact = 2.0 * 1.2 * 0.6 * 3.0;
    let meshed = area(&mesh);
    assert!(
        meshed <= exact && exact - meshed <= 1e-3 * exact,
        "area {meshed} against {exact}"
    );
    // One piece: its open boundary is the loop's four sides (two arcs of 1.2 rad, two
    // segments of 1.8), no seam segment between.
    let boundary = open_boundary_length(&mesh);
    let perimeter = 2.0 * 2.0 * 1.2 + 2.0 * 1.8;
    assert!(
        boundary <= perimeter && perimeter - boundary <= 1e-3 * perimeter,
        "boundary {boundary} against {perimeter}"
    );
}

/// A plane 10 × 10 (model units) trimmed to a disc of radius 4 with a square hole of side 2:
/// the loops' vertices lie on the loops exactly, the mesh covers the region between them
/// with no gap or overlap (edges used once each way, open only along the loops, uv area
/// within the sagitta bound of the exact region), its model area is below the exact
/// π·16 − 4 by at most the chord sagitta along the perimeter, and every triangle faces +z.
#[test]
fn a_disc_with_a_square_hole_is_meshed_within_its_tolerance() {
    let plane = BSplineSurface::try_new(
        KnotVector::clamped_uniform(1, 2).unwrap(),
        KnotVector::clamped_uniform(1, 2).unwrap(),
        &[
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(10.0, 0.0, 0.0),
            DVec3::new(0.0, 10.0, 0.0),
            DVec3::new(10.0, 10.0, 0.0),
        ],
        None,
    )
    .unwrap();
    let centre = glam::DVec2::new(0.5, 0.5);
    let square = [(0.4, 0.4), (0.6, 0.4), (0.6, 0.6), (0.4, 0.6)].map(glam::DVec2::from);
    let face = TrimmedSurface::try_new(
        plane,
        ParamMap::SAME,
        Some(uv_circle(centre, 0.4, false)),
        vec![uv_polygon(&square)],
    )
    .unwrap();
    let tolerance = 1e-3;
    let mesh = trimmed_mesh(&face, tolerance);
    let on_circle = |p: glam::DVec2| ((p - centre).length() - 0.4).abs() < 1e-12;
    let on_square = |p: glam::DVec2| {
        let d = (p - centre).abs();
        d.max_element() <= 0.1 + 1e-12 && (d.max_element() - 0.1).abs() < 1e-12
    };
    let uv_area = check_trimmed_topology(&mesh, |p| on_circle(p) || on_square(p)).unwrap();
    // In uv (the plane is 10 × 10, so uv units are tenths of model units): the exact
    // region less at most the chords' sagitta, tolerance / 10, along the perimeter.
    let exact_uv = std::f64::consts::PI * 0.16 - 0.04;
    let perimeter_uv = 2.0 * std::f64::consts::PI * 0.4;
    assert!(
        uv_area < exact_uv && exact_uv - uv_area <= perimeter_uv * tolerance / 10.0,
        "covered {uv_area} of {exact_uv}"
    );
    let model_area: f64 = mesh
        .indices
        .chunks(3)
        .map(|t| {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
            0.5 * (b - a).cross(c - a).length()
        })
        .sum();
    let exact = std::f64::consts::PI * 16.0 - 4.0;
    let perimeter = 2.0 * std::f64::consts::PI * 4.0;
    assert!(
        model_area < exact && exact - model_area <= perimeter * tolerance,
        "area {model_area} against {exact}"
    );
    for t in mesh.indices.chunks(3) {
        let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
        assert!((b - a).cross(c - a).z > 0.0);
        for &k in t {
            assert!(mesh.normals[k as usize].abs_diff_eq(DVec3::Z, 1e-12));
        }
    }
    // A hole given clockwise, or the outer loop clockwise: the same region.
    let reversed = TrimmedSurface::try_new(
        face.surface().clone(),
        ParamMap::SAME,
        Some(uv_circle(centre, 0.4, true)),
        vec![uv_polygon(&[square[0], square[3], square[2], square[1]])],
    )
    .unwrap();
    let again = trimmed_mesh(&reversed, tolerance);
    let again_area = check_trimmed_topology(&again, |p| on_circle(p) || on_square(p)).unwrap();
    assert!((again_area - uv_area).abs() < 1e-3 * uv_area);
}

/// The largest `off` (a distance from a shape) over 45 points of every triangle of `mesh`
/// (a barycentric grid of step ⅛, corners and edges included).
fn farthest_on_triangles(mesh: &Mesh, off: impl Fn(DVec3) -> f64) -> f64 {
    let steps = 8;
    let mut farthest = 0.0f64;
    for t in mesh.indices.chunks(3) {
        let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
        for i in 0..=steps {
            for j in 0..=steps - i {
                let (s, r) = (i as f64 / steps as f64, j as f64 / steps as f64);
                farthest = farthest.max(off(a + s * (b - a) + r * (c - a)));
            }
        }
    }
    farthest
}

/// A trimmed face on a sphere written as a rational patch (as IGES files write them) is
/// judged by the sphere's closed form, not by the parametrisation's bound: a disc of the
/// rational sphere of radius 2 meshed at 1e-3 holds the sphere within the tolerance at
/// every point sampled on its triangles, with fewer than 2.25 times the triangles any mesh
/// within it needs (a triangle R − √(R² − r²) ≤ tol from the sphere has an enclosing
/// radius r² ≤ 2R·tol − tol², so an area at most the equilateral one's, (3√3/4)·r²).
/// Measured: 3 146 triangles, 1.85× that least count (1 697); by the parametric bound,
/// whose rational arcs carry a tangential part, 4 754 (2.8×).
#[test]
fn trimmed_faces_on_rational_spheres_use_their_tolerance() {
    use knotwork::geom::shapes::sphere;
    let (centre, radius) = (DVec3::new(3.0, -1.0, 0.5), 2.0);
    let face = TrimmedSurface::try_new(
        sphere(centre, radius),
        ParamMap::SAME,
        Some(uv_circle(glam::DVec2::new(0.4, 0.6), 0.2, false)),
        vec![],
    )
    .unwrap();
    let tolerance = 1e-3;
    let mesh = trimmed_mesh(&face, tolerance);
    let farthest = farthest_on_triangles(&mesh, |p| (p.distance(centre) - radius).abs());
    let area: f64 = (mesh.indices.chunks(3))
        .map(|t| {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
            0.5 * (b - a).cross(c - a).length()
        })
        .sum();
    assert!(
        farthest <= tolerance,
        "farthest {farthest:e} from the sphere at tolerance {tolerance:e}"
    );
    let largest_area = 0.75 * 3f64.sqrt() * (2.0 * radius * tolerance - tolerance * tolerance);
    let least = area / largest_area;
    let triangles = mesh.indices.len() / 3;
    assert!(
        (triangles as f64) < 2.25 * least,
        "{triangles} triangles where {least:.0} could hold the tolerance"
    );
}

/// A trimmed face on a circular cylinder written as a rational patch is judged by the
/// cylinder's closed form too, its loops by the straight chords in model space: a band of
/// the rational cylinder of radius 0.5 over 2.6 rad around and 3.5 along, trimmed to its
/// whole range, holds the cylinder within 1e-3 at every point sampled on its triangles and
/// takes at most 1.1 times the 2·n triangles of the fewest chords around, n = ⌈2.6 / (2·acos(1
/// − tol/R))⌉ = 21. Measured: 44 triangles; 64 with loops bisected (no even pieces), 136 before cylinders were recognised.
#[test]
fn trimmed_faces_on_rational_cylinders_use_their_tolerance() {
    use knotwork::geom::shapes::elliptic_cylinder;
    let (centre, radius, tolerance) = (DVec3::new(1.0, 2.0, -3.0), 0.5, 1e-3);
    let (around, height) = (Interval::new(0.3, 2.9), Interval::new(-1.0, 2.5));
    let band = elliptic_cylinder(centre, radius, radius, around, height).unwrap();
    let (ru, rv) = (band.range_u(), band.range_v());
    let corners = [
        (ru.start, rv.start),
        (ru.end, rv.start),
        (ru.end, rv.end),
        (ru.start, rv.end),
    ];
    let face = TrimmedSurface::try_new(
        band,
        ParamMap::SAME,
        Some(uv_polygon(&corners.map(glam::DVec2::from))),
        vec![],
    )
    .unwrap();
    let mesh = trimmed_mesh(&face, tolerance);
    let farthest =
        farthest_on_triangles(&mesh, |p| ((p - centre).truncate().length() - radius).abs());
    assert!(
        farthest <= tolerance,
        "farthest {farthest:e} from the cylinder at tolerance {tolerance:e}"
    );
    let chord_angle = 2.0 * (1.0 - tolerance / radius).acos();
    let fewest = 2 * (around.width() / chord_angle).ceil() as usize;
    let triangles = mesh.indices.len() / 3;
    assert!(
        triangles as f64 <= 1.1 * fewest as f64,
        "{triangles} triangles where {fewest} could hold the tolerance"
    );
}

/// A face's special curves (OBJ `scrv`) are edges of its mesh and its special points (`sp`)
/// vertices, where they lie inside it: on a curved biquadratic trimmed to a disc, a straight
/// special curve and a chain of two are each covered end to end by mesh edges through the
/// mesh vertices on them (and no triangle is crossed by them), the special points inside
/// the disc are vertices and the one outside is not; the deviation still holds.
#[test]
fn special_curves_and_points_are_edges_and_vertices_of_the_mesh() {
    use glam::DVec2;
    use knotwork::geom::SpecialCurve;
    let net: Vec<DVec3> = (0..9)
        .map(|k| {
            DVec3::new(
                (k % 3) as f64,
                (k / 3) as f64,
                [0.0, 1.5, -0.5][k % 3] * [1.0, -1.0, 2.0][k / 3],
            )
        })
        .collect();
    let surface = BSplineSurface::try_new(
        KnotVector::clamped_uniform(2, 3).unwrap(),
        KnotVector::clamped_uniform(2, 3).unwrap(),
        &net,
        None,
    )
    .unwrap();
    let segment = |from: DVec2, to: DVec2| {
        let knots = KnotVector::from_breakpoints(1, &[0.0, 1.0]).unwrap();
        BSplineCurve::try_new(knots, &[from.extend(0.0), to.extend(0.0)], None).unwrap()
    };
    let line = [DVec2::new(0.25, 0.3), DVec2::new(0.8, 0.65)];
    let chain = [
        DVec2::new(0.35, 0.7),
        DVec2::new(0.5, 0.78),
        DVec2::new(0.66, 0.7),
    ];
    let specials = vec![
        SpecialCurve {
            curves: vec![segment(line[0], line[1])],
        },
        SpecialCurve {
            curves: vec![segment(chain[0], chain[1]), segment(chain[1], chain[2])],
        },
    ];
    let inside_points = [DVec2::new(0.45, 0.35), DVec2::new(0.62, 0.4)];
    let outside_point = DVec2::new(0.05, 0.05);
    let face = TrimmedSurface::try_new(
        surface.clone(),
        ParamMap::SAME,
        Some(uv_circle(DVec2::splat(0.5), 0.4, false)),
        vec![],
    )
    .unwrap()
    .with_special(
        specials,
        vec![inside_points[0], inside_points[1], outside_point],
    )
    .unwrap();
    let tolerance = 2e-3 * surface.control_box_diagonal();
    let mesh = trimmed_mesh(&face, tolerance);
    assert!(common::worst_deviation(std::slice::from_ref(&surface), &mesh) <= tolerance);
    let edges: std::collections::HashSet<[u32; 2]> = mesh
        .indices
        .chunks(3)
        .flat_map(|t| (0..3).map(move |k| [t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3])]))
        .collect();
    let near = |a: DVec2, b: DVec2| (a - b).length() < 1e-12;
    for (a, b) in [
        (line[0], line[1]),
        (chain[0], chain[1]),
        (chain[1], chain[2]),
    ] {
        let direction = b - a;
        let mut on: Vec<(f64, u32)> = (0..mesh.uvs.len())
            .filter_map(|k| {
                let p = mesh.uvs[k];
                let t = (p - a).dot(direction) / direction.length_squared();
                let off = (p - a).perp_dot(direction).abs() / direction.length();
                (off < 1e-12 && (-1e-12..=1.0 + 1e-12).contains(&t)).then_some((t, k as u32))
            })
            .collect();
        on.sort_by(|x, y| x.0.total_cmp(&y.0));
        assert!(on.len() >= 2, "{a} – {b}: {} vertices on it", on.len());
        assert!(
            near(mesh.uvs[on[0].1 as usize], a) && near(mesh.uvs[on.last().unwrap().1 as usize], b)
        );
        for pair in on.windows(2) {
            let (p, q) = (pair[0].1, pair[1].1);
            assert!(
                edges.contains(&[p.min(q), p.max(q)]),
                "{a} – {b}: no mesh edge between {} and {}",
                mesh.uvs[p as usize],
                mesh.uvs[q as usize]
            );
        }
        // No triangle edge crosses the special segment between its ends.
        for &[p, q] in &edges {
            let (c, d) = (mesh.uvs[p as usize], mesh.uvs[q as usize]);
            let side = |x: DVec2| direction.perp_dot(x - a);
            let across = |x: DVec2, y: DVec2, u: DVec2, w: DVec2| {
                (y - x).perp_dot(u - x) * (y - x).perp_dot(w - x)
            };
            let scale = direction.length() * (d - c).length();
            assert!(
                !(across(a, b, c, d) < -1e-9 * scale * scale
                    && across(c, d, a, b) < -1e-9 * scale * scale),
                "edge {c} – {d} crosses {a} – {b} (sides {} {})",
                side(c),
                side(d)
            );
        }
    }
    for point in inside_points {
        assert!(
            mesh.uvs.iter().any(|&uv| near(uv, point)),
            "special point {point}"
        );
    }
    assert!(
        !mesh
            .uvs
            .iter()
            .any(|&uv| (uv - outside_point).length() < 1e-3)
    );
    // A special point outside the surface's range is refused by name.
    let refused = TrimmedSurface::try_new(surface, ParamMap::SAME, None, vec![])
        .unwrap()
        .with_special(vec![], vec![DVec2::new(0.5, 0.5), DVec2::new(1.5, 0.5)]);
    assert!(
        matches!(
            refused,
            Err(Error::InvalidSpecial {
                what: "point",
                index: 1,
                ..
            })
        ),
        "{refused:?}"
    );
}

/// A surface with a crease (degree 1 along u, a kink at u = 0.5) trimmed by a circle across
/// it: no triangle straddles the crease, and the deviation stays within the tolerance.
#[test]
fn trimmed_triangles_never_straddle_a_crease() {
    let mut points = Vec::new();
    for j in 0..4 {
        for (x, z) in [(0.0, 0.0), (1.0, 1.0), (2.0, 0.0)] {
            points.push(DVec3::new(x, j as f64 / 1.5, z + 0.1 * (j as f64).powi(2)));
        }
    }
    let surface = BSplineSurface::try_new(
        KnotVector::try_new(1, vec![0.0, 0.0, 0.5, 1.0, 1.0]).unwrap(),
        KnotVector::clamped_uniform(3, 4).unwrap(),
        &points,
        None,
    )
    .unwrap();
    let face = TrimmedSurface::try_new(
        surface.clone(),
        ParamMap::SAME,
        Some(uv_circle(glam::DVec2::new(0.45, 0.5), 0.35, false)),
        vec![],
    )
    .unwrap();
    let tolerance = 1e-3;
    let mesh = trimmed_mesh(&face, tolerance);
    for [a, b, c] in uv_triangles(&mesh) {
        let low = a.x.min(b.x).min(c.x);
        let high = a.x.max(b.x).max(c.x);
        assert!(
            high <= 0.5 || low >= 0.5,
            "triangle {a} {b} {c} straddles u = 0.5"
        );
    }
    let worst = worst_deviation(&[surface], &mesh);
    assert!(worst <= tolerance, "deviation {worst:e}");
}

/// A random trimmed face: a surface of [`adaptive_case`] (tolerance 1e-3..1e-1 of its size),
/// an outer circle in its parameter range, a quadrilateral hole inside it.
fn trimmed_case() -> impl Strategy<Value = (TrimmedSurface, f64, glam::DVec2, f64, [glam::DVec2; 4])>
{
    (
        adaptive_case(),
        -3.0f64..-1.0,
        0.3f64..0.48,
        prop::array::uniform4((0.02f64..0.15, 0.0f64..1.5)),
    )
        .prop_map(|((surface, _), exponent, radius, corners)| {
            let tolerance = 10f64.powf(exponent) * surface.control_box_diagonal();
            let (ru, rv) = (surface.range_u(), surface.range_v());
            let to_range = |f: glam::DVec2| glam::DVec2::new(ru.lerp(f.x), rv.lerp(f.y));
            // The circle in fractions of the range, drawn as an ellipse in parameters.
            let circle = uv_circle(glam::DVec2::ZERO, 1.0, false);
            let centre = glam::DVec2::splat(0.5);
            let curves = circle
                .curves
                .iter()
                .map(|c| {
                    let points: Vec<DVec3> = (0..c.knots().control_count())
                        .map(|i| {
                            to_range(centre + radius * c.control_point(i).truncate()).extend(0.0)
                        })
                        .collect();
                    let weights: Vec<f64> = (0..points.len()).map(|i| c.weight(i)).collect();
                    BSplineCurve::try_new(c.knots().clone(), &points, Some(&weights)).unwrap()
                })
                .collect();
            // A quadrilateral around the centre, one corner per quadrant.
            let hole: [glam::DVec2; 4] = std::array::from_fn(|k| {
                let (r, turn) = corners[k];
                let angle = (k as f64 + turn / 1.5) * std::f64::consts::FRAC_PI_2;
                centre + r * glam::DVec2::new(angle.cos(), angle.sin())
            });
            let face = TrimmedSurface::try_new(
                surface,
                ParamMap::SAME,
                Some(TrimLoop { curves }),
                vec![uv_polygon(&hole.map(to_range))],
            )
            .unwrap();
            (face, tolerance, centre, radius, hole)
        })
}

proptest! {
    #![proptest_config(ProptestConfig {
        rng_seed: proptest::test_runner::RngSeed::Fixed(20261202),
        ..ProptestConfig::with_cases(64)
    })]

    /// A trimmed face stays within its tolerance (centroids and edge midpoints against the
    /// f64 surface), covers the region between its loops with no gap or overlap (edges
    /// used once lie on a loop, the boundary's shoelace area is the triangles' area), no
    /// triangle lies outside the outer circle or inside the hole, and the mesh's boundary
    /// follows the outer circle within the tolerance in model space (every one of 720
    /// points of the circle on the surface that near a boundary edge).
    #[test]
    fn trimmed_faces_stay_within_their_tolerance_inside_their_loops(
        (face, tolerance, centre, radius, hole) in trimmed_case()
    ) {
        let mesh = trimmed_mesh(&face, tolerance);
        prop_assert!(!mesh.indices.is_empty());
        let surface = face.surface().clone();
        let worst = worst_deviation(std::slice::from_ref(&surface), &mesh);
        let rounding = 1e-12 * surface.control_box_diagonal();
        prop_assert!(worst <= tolerance + rounding, "deviation {worst:e} over {tolerance:e}");
        // A boundary vertex is a loop's own point, or a point of a loop's chord (a grid point
        // spade finds on a chord), within a chord's sagitta — here under 5 % of the radius —
        // of the loop: a hole left inside the face would show edges farther in.
        let near = 0.05 * radius;
        let on_circle = |p: glam::DVec2| ((p - centre).length() - radius).abs() < near;
        let on_hole = |p: glam::DVec2| {
            (0..4).any(|k| {
                let (a, b) = (hole[k], hole[(k + 1) % 4]);
                let t = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
                (a + t * (b - a) - p).length() < 1e-9
            })
        };
        let area = check_trimmed_topology(&mesh, |p| on_circle(p) || on_hole(p))?;
        let inside_hole = |p: glam::DVec2| (0..4).all(|k| (hole[(k + 1) % 4] - hole[k]).perp_dot(p - hole[k]) > 1e-12);
        for [a, b, c] in uv_triangles(&mesh) {
            let centroid = (a + b + c) / 3.0;
            prop_assert!((centroid - centre).length() < radius + 1e-9, "centroid {centroid} outside the circle by {:e}", (centroid - centre).length() - radius);
            prop_assert!(!inside_hole(centroid), "centroid {centroid} inside the hole");
        }
        let hole_area = 0.5 * (0..4).map(|k| hole[k].perp_dot(hole[(k + 1) % 4])).sum::<f64>();
        let disc = std::f64::consts::PI * radius * radius;
        prop_assert!(
            area < disc - hole_area + 1e-12,
            "uv area {area} of {} (disc {disc}, hole {hole_area})",
            disc - hole_area
        );
        let mut directed = std::collections::HashSet::new();
        for t in mesh.indices.chunks(3) {
            for k in 0..3 {
                directed.insert((t[k], t[(k + 1) % 3]));
            }
        }
        let boundary: Vec<(DVec3, DVec3)> = (directed.iter())
            .filter(|&&(a, b)| !directed.contains(&(b, a)))
            .map(|&(a, b)| (mesh.positions[a as usize], mesh.positions[b as usize]))
            .collect();
        let (ru, rv) = (surface.range_u(), surface.range_v());
        let farthest = (0..720).map(|k| {
            let angle = k as f64 * std::f64::consts::TAU / 720.0;
            let f = centre + radius * glam::DVec2::new(angle.cos(), angle.sin());
            let p = surface.point(ru.lerp(f.x), rv.lerp(f.y));
            boundary.iter().map(|&(a, b)| {
                let t = ((p - a).dot(b - a) / (b - a).length_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
                p.distance(a + t * (b - a))
            }).fold(f64::INFINITY, f64::min)
        }).fold(0.0, f64::max);
        prop_assert!(
            farthest <= tolerance + rounding,
            "the circle lies {farthest:e} from the mesh's boundary at tolerance {tolerance:e}"
        );
    }
}

/// Loops that are open, outside the range, crossing themselves or enclosing nothing are
/// refused, naming the loop.
#[test]
fn bad_trim_loops_are_refused_by_name() {
    let plane = BSplineSurface::try_new(
        KnotVector::clamped_uniform(1, 2).unwrap(),
        KnotVector::clamped_uniform(1, 2).unwrap(),
        &[DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 0.0)],
        None,
    )
    .unwrap();
    let p = |x: f64, y: f64| glam::DVec2::new(x, y);
    let open = {
        let mut l = uv_polygon(&[p(0.1, 0.1), p(0.9, 0.1), p(0.9, 0.9)]);
        let c = &l.curves[0];
        let points: Vec<DVec3> = (0..c.knots().control_count() - 1)
            .map(|i| c.control_point(i))
            .collect();
        let knots = KnotVector::from_breakpoints(1, &[0.0, 1.0, 2.0]).unwrap();
        l.curves[0] = BSplineCurve::try_new(knots, &points, None).unwrap();
        l
    };
    let problem = |outer: TrimLoop, holes: Vec<TrimLoop>| -> (usize, String) {
        let face = TrimmedSurface::try_new(plane.clone(), ParamMap::SAME, Some(outer), holes)
            .and_then(|face| plan_trimmed(&face, SamplingLimits::tolerance(1e-3)).map(|_| ()));
        match face {
            Err(Error::InvalidTrimLoop {
                loop_index,
                problem,
            }) => (loop_index, problem),
            other => panic!("expected a refused loop, got {other:?}"),
        }
    };
    let whole = || uv_polygon(&[p(0.05, 0.05), p(0.95, 0.05), p(0.95, 0.95), p(0.05, 0.95)]);
    let (index, text) = problem(open, vec![]);
    assert_eq!(index, 0);
    assert!(text.contains("not closed"), "{text}");
    let (index, text) = problem(
        whole(),
        vec![uv_polygon(&[p(0.5, 0.5), p(1.5, 0.5), p(0.5, 0.7)])],
    );
    assert_eq!(index, 1, "{text}");
    assert!(text.contains("outside the surface's range"), "{text}");
    let (index, text) = problem(
        whole(),
        vec![uv_polygon(&[
            p(0.2, 0.2),
            p(0.5, 0.4),
            p(0.5, 0.2),
            p(0.2, 0.3),
        ])],
    );
    assert!(text.contains("crosses"), "{index}: {text}");
    let (index, text) = problem(
        whole(),
        vec![uv_polygon(&[p(0.2, 0.2), p(0.4, 0.4), p(0.3, 0.3)])],
    );
    assert_eq!(index, 1);
    assert!(text.contains("encloses no area"), "{text}");
    let (index, text) = problem(
        whole(),
        vec![uv_polygon(&[p(0.02, 0.5), p(0.5, 0.02), p(0.5, 0.5)])],
    );
    assert!(text.contains("crosses"), "{index}: {text}");
}

/// Patches ruled in one direction (degree 1, weights equal along it) — a cylinder, a cone,
/// a rational extrusion — get their twist bound from the difference of their two rows: 0
/// (to rounding) for the cylinder and the extrusion (S_uv = 0), where the general quotient-rule bound
/// puts a spurious term; the cone's is not 0. Meshes at 1e-2..1e-4 of the size stay within
/// the tolerance (measured at centroids and edge midpoints).
#[test]
fn ruled_rational_patches_bound_their_twist_by_the_rows_difference() {
    use knotwork::geom::{curves, patches, shapes};
    let line = |a: DVec3, b: DVec3| {
        BSplineCurve::try_new(
            KnotVector::try_new(1, vec![0.0, 0.0, 1.0, 1.0]).unwrap(),
            &[a, b],
            None,
        )
        .unwrap()
    };
    let revolve = |profile: &BSplineCurve| {
        shapes::revolve(
            profile,
            DVec3::ZERO,
            DVec3::Z,
            Interval::new(0.0, std::f64::consts::TAU),
        )
        .unwrap()
    };
    let cylinder = revolve(&line(DVec3::new(2.0, 0.0, 0.0), DVec3::new(2.0, 0.0, 3.0)));
    let cone = revolve(&line(DVec3::new(1.0, 0.0, 0.0), DVec3::new(3.0, 0.0, 3.0)));
    let arc = curves::arc(
        DVec3::ZERO,
        2.0,
        DVec3::X,
        DVec3::Y,
        Interval::new(0.0, 4.0),
    )
    .unwrap();
    let extrusion = patches::ruled(&arc, &arc.mapped(|p| p + DVec3::new(0.5, 0.0, 2.0))).unwrap();
    for (name, surface, twist_free) in [
        ("cylinder", &cylinder, true),
        ("cone", &cone, false),
        ("extrusion", &extrusion, true),
    ] {
        let size = surface.control_box_diagonal();
        for patch in surface.bezier_patches() {
            // 0 to the rounding of the rows' differences.
            let twist = patch.derivative_bound().uv;
            assert_eq!(
                twist <= 1e-12 * size,
                twist_free,
                "{name}: twist bound {twist}"
            );
        }
        for relative in [1e-2, 1e-3, 1e-4] {
            let tolerance = relative * size;
            let options =
                TessOptions::DEFAULT.with_tolerance(knotwork::Tolerance::Absolute(tolerance));
            let surfaces = std::slice::from_ref(surface);
            let mesh = CpuTessellator.tessellate(surfaces, &options).unwrap();
            let deviation = worst_deviation(surfaces, &mesh);
            assert!(
                deviation <= tolerance,
                "{name} at {relative}: {deviation} over {tolerance}"
            );
        }
    }
}

/// Trimmed faces and shells are held to the memory budget with their triangles: what they
/// need is their mesh's vertices (64 bytes each in f64) and triangles (12 bytes each). A
/// budget of exactly that meshes them as without one; a byte less is refused, naming both.
#[test]
fn trimmed_faces_and_shells_fit_the_memory_budget_to_the_byte() {
    use knotwork::SceneOptions;
    for path in ["data/single_rounded_cube.iges", "data/abc-0000.step"] {
        let scene = knotwork::io::read_scene(std::path::Path::new(path)).unwrap();
        let unbounded = CpuTessellator
            .tessellate_scene(&scene, &SceneOptions::default())
            .unwrap();
        let needed = 64 * unbounded.positions.len() as u64 + 4 * unbounded.indices.len() as u64;
        let within = |budget| SceneOptions {
            memory_budget: Some(budget),
            ..SceneOptions::default()
        };
        let fitted = CpuTessellator.tessellate_scene(&scene, &within(needed));
        assert_eq!(fitted.unwrap(), unbounded, "{path}");
        match CpuTessellator.tessellate_scene(&scene, &within(needed - 1)) {
            Err(Error::OverMemoryBudget { needed: n, budget }) => {
                assert_eq!((n, budget), (needed, needed - 1), "{path}")
            }
            other => panic!("{path}: {other:?}"),
        }
    }
}

/// Trimmed faces and shells whose options set no tolerance are meshed to
/// `TRIMMED_DEFAULT_TOLERANCE_REL` of the scene's diagonal: the mesh of that relative
/// tolerance, and not the mesh of ten times it.
#[test]
fn trimmed_faces_default_to_their_documented_tolerance() {
    use knotwork::SceneOptions;
    let default_rel = knotwork::cpu::TRIMMED_DEFAULT_TOLERANCE_REL;
    for path in ["data/single_rounded_cube.iges", "data/cube_hole.step"] {
        let scene = knotwork::io::read_scene(std::path::Path::new(path)).unwrap();
        let at = |relative| SceneOptions {
            grid: TessOptions::DEFAULT.with_tolerance(Tolerance::Relative(relative)),
            ..SceneOptions::default()
        };
        let mesh =
            |defaults: &SceneOptions| CpuTessellator.tessellate_scene(&scene, defaults).unwrap();
        let default = mesh(&SceneOptions::default());
        assert_eq!(default, mesh(&at(default_rel)), "{path}");
        assert_ne!(default, mesh(&at(10.0 * default_rel)), "{path}");
    }
}

/// `execute_shell` runs a shell's plan as a scene's meshing does: the same mesh, part for
/// part, for a solid with a hole through it.
#[test]
fn a_shell_plan_executes_to_the_scene_mesh() {
    use knotwork::{Geometry, SceneOptions};
    let scene = knotwork::io::read_scene(std::path::Path::new("data/cube_hole.step")).unwrap();
    assert_eq!(scene.items.len(), 1);
    let Geometry::Shell(shell) = &scene.items[0].geometry else {
        panic!("a STEP solid is a shell")
    };
    let defaults = SceneOptions::default();
    let plan = knotwork::cpu::shell_plan(&scene, &defaults, 0).unwrap();
    let mesh = knotwork::cpu::execute_shell(shell, &plan);
    assert_eq!(mesh.parts.len(), shell.faces().len());
    assert_eq!(
        mesh,
        CpuTessellator.tessellate_scene(&scene, &defaults).unwrap()
    );
}

// ---------------------------------------------------------------- view-dependent frames

/// View-dependent frames at the rates the kernels decide (computed on the host in the
/// kernels' f32) and evaluated in f64: at every triangle's centroid and edge midpoints
/// whose surface point is in view, the projected surface lies within the pixel tolerance of
/// the projected triangle — on the teapot (seams, poles) and the ducky (rational, weights
/// 0.5..1), near and far. Prints how tight the bound is (worst / tolerance).
#[test]
fn view_frames_stay_within_their_pixel_tolerance() {
    use glam::camera::rh::{proj::directx::perspective, view::look_at_mat4};
    use glam::{DVec4, Vec2, Vec3};
    use knotwork::plan::view::{View, ViewOptions, ViewPlan};
    let models = [
        (
            "data/teapot.bpt",
            Vec3::new(0.2, 0.0, 1.2),
            [Vec3::new(2.5, -4.0, 2.5), Vec3::new(12.0, -18.0, 10.0)],
        ),
        (
            "data/ducky.obj",
            Vec3::new(1.5, 0.0, 1.0),
            [Vec3::new(5.0, -6.0, 4.0), Vec3::new(15.0, -20.0, 12.0)],
        ),
    ];
    for (path, target, eyes) in models {
        let surfaces = knotwork::io::read_scene(std::path::Path::new(path))
            .unwrap()
            .surface_list();
        let plan = ViewPlan::new(&surfaces, ViewOptions::default()).unwrap();
        for eye in eyes {
            for tolerance_px in [0.25f32, 1.0] {
                let viewport = Vec2::new(800.0, 600.0);
                let matrix =
                    perspective(0.8, 4.0 / 3.0, 0.05, 500.0) * look_at_mat4(eye, target, Vec3::Z);
                let view = View {
                    view_projection: matrix,
                    viewport,
                    tolerance_px,
                };
                let m = matrix.as_dmat4();
                // Pixels of a point, if it is inside the view volume.
                let pixels = |p: DVec3| -> Option<glam::DVec2> {
                    let c: DVec4 = m * p.extend(1.0);
                    let inside = c.w > 0.0
                        && c.x.abs() <= c.w
                        && c.y.abs() <= c.w
                        && c.z >= 0.0
                        && c.z <= c.w;
                    inside.then(|| {
                        glam::DVec2::new(c.x / c.w + 1.0, c.y / c.w + 1.0)
                            * 0.5
                            * viewport.as_dvec2()
                    })
                };
                let rates = plan.rates(&view);
                assert!(
                    rates.iter().all(|r| r.met),
                    "{path}: every cell meets the tolerance"
                );
                let mesh = knotwork::cpu::execute_view(&plan, &surfaces, &rates).unwrap();
                // One part holding the whole frame.
                assert_eq!(mesh.parts.len(), 1, "{path}");
                assert_eq!(mesh.parts[0].vertex_count as usize, mesh.positions.len());
                assert_eq!(mesh.parts[0].index_count as usize, mesh.indices.len());
                let fewer = &surfaces[..surfaces.len() - 1];
                let mismatch = knotwork::cpu::execute_view(&plan, fewer, &rates).unwrap_err();
                assert!(
                    matches!(mismatch, Error::PlanMismatch { planned, given }
                        if planned == surfaces.len() && given == fewer.len()),
                    "{path}: {mismatch}"
                );
                let layout = plan.layout(&rates);
                let (mut worst, mut measured) = (0.0f64, 0usize);
                for (c, corners) in plan.placed_triangles(&rates, &layout) {
                    let cell = &plan.cells[c as usize];
                    let surface = &surfaces[cell.surface as usize];
                    let positions = corners.map(|(v, _)| mesh.positions[v as usize]);
                    let params = corners.map(|(_, st)| st);
                    for weights in [
                        [1.0 / 3.0; 3],
                        [0.5, 0.5, 0.0],
                        [0.0, 0.5, 0.5],
                        [0.5, 0.0, 0.5],
                    ] {
                        let st = params[0] * weights[0]
                            + params[1] * weights[1]
                            + params[2] * weights[2];
                        let on_surface = surface
                            .point(cell.patch.range_u.lerp(st.x), cell.patch.range_v.lerp(st.y));
                        let on_mesh = positions[0] * weights[0]
                            + positions[1] * weights[1]
                            + positions[2] * weights[2];
                        if let (Some(a), Some(b)) = (pixels(on_surface), pixels(on_mesh)) {
                            worst = worst.max((a - b).length());
                            measured += 1;
                        }
                    }
                }
                println!(
                    "{path} from {eye} at {tolerance_px} px: {} triangles, {measured} points in view, worst {worst:.3} px ({:.2} of the tolerance)",
                    mesh.indices.len() / 3,
                    worst / f64::from(tolerance_px)
                );
                assert!(measured > 1000, "{path}: the model is in view");
                assert!(
                    worst <= f64::from(tolerance_px),
                    "{path}: {worst} px over {tolerance_px}"
                );
            }
        }
    }
}

/// The open edges of `mesh` (used by one triangle) with both ends where `on` holds.
fn open_edges_where(mesh: &Mesh, on: impl Fn(DVec3) -> bool) -> usize {
    open_edges(mesh)
        .into_iter()
        .filter(|&(a, b)| on(mesh.positions[a as usize]) && on(mesh.positions[b as usize]))
        .count()
}

/// Sides a file names as one seam share their vertices, whatever their control points:
/// data/seams.json's right patch has a knot at v = 0.5 its left neighbour lacks (the same
/// boundary curve, other control points, so nothing finds the seam by itself). Sampled to a
/// tolerance, the two come out as one piece with no open edge and no repeated vertex on the
/// shared side (x = 3), within the tolerance — run either way along the side — while
/// without the seam they are two pieces open along it. Sides that are not one curve, and a
/// side named twice, are refused with the seam's index.
#[test]
#[cfg(feature = "json")]
fn seams_a_file_names_share_their_vertices() {
    use knotwork::plan::{Side, SurfaceSide};
    use knotwork::{Geometry, Scene, SceneOptions};
    let scene = knotwork::io::read_scene(std::path::Path::new("data/seams.json")).unwrap();
    assert_eq!(scene.seams.len(), 1);
    let surfaces = scene.surface_list();
    let tolerance = 1e-3 * scene.control_box_diagonal();
    let defaults = SceneOptions {
        grid: TessOptions::DEFAULT.with_tolerance(Tolerance::Absolute(tolerance)),
        ..SceneOptions::default()
    };
    let on_seam = |p: DVec3| (p.x - 3.0).abs() < 1e-12;
    let joined = CpuTessellator.tessellate_scene(&scene, &defaults).unwrap();
    let apart = Scene {
        seams: Vec::new(),
        ..scene.clone()
    };
    let apart = CpuTessellator.tessellate_scene(&apart, &defaults).unwrap();
    assert_eq!(open_edges_and_pieces(&apart).1, 2);
    assert!(open_edges_where(&apart, on_seam) > 0);
    assert_eq!(open_edges_and_pieces(&joined).1, 1);
    assert_eq!(open_edges_where(&joined, on_seam), 0);
    let mut on_side: Vec<f64> = joined
        .positions
        .iter()
        .filter(|p| on_seam(**p))
        .map(|p| p.y)
        .collect();
    on_side.sort_by(f64::total_cmp);
    assert!(on_side.len() > 4, "{} vertices on the seam", on_side.len());
    assert!(
        on_side.windows(2).all(|w| w[1] - w[0] > 1e-9),
        "{on_side:?}"
    );
    let worst = worst_deviation(&surfaces, &joined);
    assert!(worst <= tolerance, "{worst:e} > {tolerance:e}");

    // The right patch run the other way along v: the seam's direction comes from its ends.
    let right = &surfaces[1];
    let flipped: Vec<DVec3> = (0..right.count_v())
        .rev()
        .flat_map(|j| (0..right.count_u()).map(move |i| right.control_point(i, j)))
        .collect();
    let flipped = BSplineSurface::try_new(
        right.knots_u().clone(),
        right.knots_v().clone(),
        &flipped,
        None,
    )
    .unwrap();
    let mut reversed = scene.clone();
    reversed.items[1].geometry = Geometry::Surface(flipped);
    let mesh = CpuTessellator
        .tessellate_scene(&reversed, &defaults)
        .unwrap();
    assert_eq!(open_edges_and_pieces(&mesh).1, 1);
    assert_eq!(open_edges_where(&mesh, on_seam), 0);

    // The left patch's u1 side with the right's far side (x = 6): not one curve.
    let mut far = scene.clone();
    far.seams[0].sides[1].side = Side::Right;
    let error = CpuTessellator
        .tessellate_scene(&far, &defaults)
        .unwrap_err();
    assert!(
        matches!(error.root(), Error::SeamGap { seam: 0, gap, .. } if *gap > 1.0),
        "{error}"
    );
    // A side joined twice.
    let mut twice = scene.clone();
    twice.seams.push(knotwork::plan::Seam {
        sides: [
            SurfaceSide {
                surface: 1,
                side: Side::Left,
            },
            SurfaceSide {
                surface: 0,
                side: Side::Bottom,
            },
        ],
    });
    let error = CpuTessellator
        .tessellate_scene(&twice, &defaults)
        .unwrap_err();
    assert!(
        matches!(error.root(), Error::InvalidSeam { seam: 1, .. }),
        "{error}"
    );
    assert!(error.to_string().contains("u0"), "{error}");
}
