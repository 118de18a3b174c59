//! An independent oracle: rational B-spline surfaces and curves evaluated in exact rational
//! arithmetic (`num-rational`'s `BigRational`) from their inputs — f64 knots, control points
//! and weights are dyadic rationals, so nothing is rounded until the result is converted to
//! f64 once. Shares no code with knotwork: Cox–de Boor by the textbook recursion, derivatives
//! by the textbook formula, the quotient rule exactly.

use glam::DVec3;
use num_bigint::BigInt;
use num_rational::BigRational;
use num_traits::{Signed, ToPrimitive, Zero};

pub type Q = BigRational;

pub fn q(x: f64) -> Q {
    BigRational::from_float(x).expect("finite input")
}

fn f(x: &Q) -> f64 {
    x.to_f64().expect("representable result")
}

type Q3 = [Q; 3];

fn to_dvec(v: &Q3) -> DVec3 {
    DVec3::new(f(&v[0]), f(&v[1]), f(&v[2]))
}

/// N_(i,p)(t) and its first and second derivatives, right-continuous except at the domain
/// end, which belongs to the last non-empty span (knotwork's convention).
fn basis(knots: &[Q], i: usize, p: usize, t: &Q, end: &Q) -> [Q; 3] {
    if p == 0 {
        let (a, b) = (&knots[i], &knots[i + 1]);
        // Unclamped knots continue past the domain end: the span after it is not the end's.
        let inside = a <= t && t < b && t < end;
        let at_end = t == end && b == end && a < b;
        let one = if inside || at_end {
            Q::from_integer(1.into())
        } else {
            Q::zero()
        };
        return [one, Q::zero(), Q::zero()];
    }
    let left = basis(knots, i, p - 1, t, end);
    let right = basis(knots, i + 1, p - 1, t, end);
    let pq = Q::from_integer(BigInt::from(p));
    let mut out = [Q::zero(), Q::zero(), Q::zero()];
    let d1 = &knots[i + p] - &knots[i];
    if !d1.is_zero() {
        out[0] += (t - &knots[i]) / &d1 * &left[0];
        out[1] += &pq / &d1 * &left[0];
        out[2] += &pq / &d1 * &left[1];
    }
    let d2 = &knots[i + p + 1] - &knots[i + 1];
    if !d2.is_zero() {
        out[0] += (&knots[i + p + 1] - t) / &d2 * &right[0];
        out[1] -= &pq / &d2 * &right[0];
        out[2] -= &pq / &d2 * &right[1];
    }
    out
}

fn cross(a: &Q3, b: &Q3) -> Q3 {
    [
        &a[1] * &b[2] - &a[2] * &b[1],
        &a[2] * &b[0] - &a[0] * &b[2],
        &a[0] * &b[1] - &a[1] * &b[0],
    ]
}

/// The unit vector along `v`, or `None` for the zero vector.
fn direction(v: &Q3) -> Option<DVec3> {
    if v.iter().all(Zero::is_zero) {
        return None;
    }
    // Scaled to a representable size before converting.
    let largest = v.iter().map(|c| c.abs()).max().expect("three components");
    Some(to_dvec(&std::array::from_fn(|k| &v[k] / &largest)).normalize())
}

/// The exact values of a rational tensor-product surface at (u, v), converted to f64 once.
pub struct ExactSample {
    pub position: DVec3,
    pub du: DVec3,
    pub dv: DVec3,
    /// unit(S_u × S_v) of the exact cross product, or zero where it vanishes exactly.
    pub normal: DVec3,
}

/// A rational surface given as its inputs: knots, Cartesian points u fastest, weights.
pub struct ExactSurface {
    pub degree: (usize, usize),
    pub knots_u: Vec<Q>,
    pub knots_v: Vec<Q>,
    /// (x, y, z, w) per control point, u fastest.
    pub points: Vec<(Q3, Q)>,
    pub count_u: usize,
}

impl ExactSurface {
    pub fn new(
        degree: (usize, usize),
        knots_u: &[f64],
        knots_v: &[f64],
        points: &[DVec3],
        weights: &[f64],
    ) -> Self {
        ExactSurface {
            degree,
            knots_u: knots_u.iter().map(|&x| q(x)).collect(),
            knots_v: knots_v.iter().map(|&x| q(x)).collect(),
            points: points
                .iter()
                .zip(weights)
                .map(|(p, &w)| ([q(p.x), q(p.y), q(p.z)], q(w)))
                .collect(),
            count_u: knots_u.len() - degree.0 - 1,
        }
    }

    /// Evaluates at (u, v), parameters inside the knot domain.
    pub fn evaluate(&self, u: f64, v: f64) -> ExactSample {
        let d = self.derivatives(u, v);
        ExactSample {
            position: to_dvec(&d[0][0]),
            du: to_dvec(&d[1][0]),
            dv: to_dvec(&d[0][1]),
            normal: direction(&cross(&d[1][0], &d[0][1])).unwrap_or(DVec3::ZERO),
        }
    }

    /// The limit of unit(S_u × S_v) at (u, v) approached along (step_u, step_v): the exact
    /// normal where S_u × S_v ≠ 0, else the direction of the first-order term
    /// step_u·(S_u × S_uv + S_uu × S_v) + step_v·(S_u × S_vv + S_uv × S_v); `None` where that
    /// vanishes too.
    pub fn limit_normal(&self, u: f64, v: f64, step_u: f64, step_v: f64) -> Option<DVec3> {
        let d = self.derivatives(u, v);
        let (su, sv) = (&d[1][0], &d[0][1]);
        if let Some(normal) = direction(&cross(su, sv)) {
            return Some(normal);
        }
        let (a, b) = (q(step_u), q(step_v));
        let su1: Q3 = std::array::from_fn(|k| &a * &d[2][0][k] + &b * &d[1][1][k]);
        let sv1: Q3 = std::array::from_fn(|k| &a * &d[1][1][k] + &b * &d[0][2][k]);
        let (x, y) = (cross(&su1, sv), cross(su, &sv1));
        direction(&std::array::from_fn(|k| &x[k] + &y[k]))
    }

    /// d[i][j] = ∂ᵢᵤ∂ⱼᵥ S at (u, v) for i + j ≤ 2, exactly: the homogeneous sums, then the
    /// quotient rule A^(i,j) = Σ C(i,k)·C(j,l)·W^(k,l)·S^(i−k,j−l) solved order by order.
    fn derivatives(&self, u: f64, v: f64) -> [[Q3; 3]; 3] {
        let (p, qd) = self.degree;
        let count_v = self.points.len() / self.count_u;
        let (u, v) = (q(u), q(v));
        let end_u = self.knots_u[self.count_u].clone();
        let end_v = self.knots_v[count_v].clone();
        let bu: Vec<[Q; 3]> = (0..self.count_u)
            .map(|i| basis(&self.knots_u, i, p, &u, &end_u))
            .collect();
        let bv: Vec<[Q; 3]> = (0..count_v)
            .map(|j| basis(&self.knots_v, j, qd, &v, &end_v))
            .collect();
        let zero3 = || [Q::zero(), Q::zero(), Q::zero()];
        // a[i][j], w[i][j]: the homogeneous sums and their derivatives.
        let mut a: [[Q3; 3]; 3] = std::array::from_fn(|_| std::array::from_fn(|_| zero3()));
        let mut w: [[Q; 3]; 3] = std::array::from_fn(|_| std::array::from_fn(|_| Q::zero()));
        for (j, nv) in bv.iter().enumerate() {
            if nv.iter().all(Zero::is_zero) {
                continue;
            }
            for (i, nu) in bu.iter().enumerate() {
                if nu.iter().all(Zero::is_zero) {
                    continue;
                }
                let (point, weight) = &self.points[j * self.count_u + i];
                for di in 0..3 {
                    for dj in 0..3 - di {
                        let b = &nu[di] * &nv[dj] * weight;
                        for k in 0..3 {
                            a[di][dj][k] += &b * &point[k];
                        }
                        w[di][dj] += b;
                    }
                }
            }
        }
        let binomial = |n: usize, k: usize| {
            Q::from_integer(BigInt::from([[1, 0, 0], [1, 1, 0], [1, 2, 1]][n][k]))
        };
        let mut s: [[Q3; 3]; 3] = std::array::from_fn(|_| std::array::from_fn(|_| zero3()));
        for order in 0..3 {
            for i in 0..=order {
                let j = order - i;
                let mut value = a[i][j].clone();
                for k in 0..=i {
                    for l in 0..=j {
                        if k + l > 0 {
                            let c = binomial(i, k) * binomial(j, l) * &w[k][l];
                            for m in 0..3 {
                                value[m] -= &c * &s[i - k][j - l][m];
                            }
                        }
                    }
                }
                s[i][j] = std::array::from_fn(|m| &value[m] / &w[0][0]);
            }
        }
        s
    }
}
