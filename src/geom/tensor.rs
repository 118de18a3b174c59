//! Tensor-product polynomials in Bernstein form over a piece of a patch, with exact
//! products and derivatives: what the bounds on a patch's derivatives and normal are built
//! from (a polynomial in Bernstein form lies between its least and largest coefficients).

use super::piecewise::{Value, binomial};

/// A tensor-product polynomial in Bernstein form over a piece: degree (du, dv),
/// coefficients u fastest.
#[derive(Clone, Debug)]
pub(super) struct Bernstein<T> {
    pub(super) du: usize,
    pub(super) dv: usize,
    pub(super) coefficients: Vec<T>,
}

impl<T: Value> Bernstein<T> {
    pub(super) fn new(du: usize, dv: usize, coefficients: Vec<T>) -> Self {
        Bernstein {
            du,
            dv,
            coefficients,
        }
    }

    pub(super) fn at(&self, i: usize, j: usize) -> T {
        self.coefficients[j * (self.du + 1) + i]
    }

    /// The product by `op` (a bilinear product: scalar times vector, cross, dot) with
    /// `other`: C_ij = Σ C(a,i₁)C(b,i₂)/C(a+b,i) · C(c,j₁)C(d,j₂)/C(c+d,j) · op(A_i₁j₁, B_i₂j₂).
    pub(super) fn product<U: Value, R: Value>(
        &self,
        other: &Bernstein<U>,
        op: impl Fn(T, U) -> R,
    ) -> Bernstein<R> {
        let (du, dv) = (self.du + other.du, self.dv + other.dv);
        // op is bilinear: the binomials of each operand are folded into its coefficients
        // once, those of the product divided out at the end.
        let a = self.scaled_by_binomials(false);
        let b = other.scaled_by_binomials(false);
        let mut coefficients = vec![R::default(); (du + 1) * (dv + 1)];
        for j1 in 0..=self.dv {
            for i1 in 0..=self.du {
                let x = a[j1 * (self.du + 1) + i1];
                for j2 in 0..=other.dv {
                    let row = (j1 + j2) * (du + 1) + i1;
                    for i2 in 0..=other.du {
                        let k = row + i2;
                        coefficients[k] = coefficients[k] + op(x, b[j2 * (other.du + 1) + i2]);
                    }
                }
            }
        }
        let product = Bernstein::new(du, dv, coefficients);
        Bernstein {
            coefficients: product.scaled_by_binomials(true),
            ..product
        }
    }

    /// The coefficients times C(du, i)·C(dv, j), or over it when `divide`.
    pub(super) fn scaled_by_binomials(&self, divide: bool) -> Vec<T> {
        let along_u: Vec<f64> = (0..=self.du).map(|i| binomial(self.du, i)).collect();
        let along_v: Vec<f64> = (0..=self.dv).map(|j| binomial(self.dv, j)).collect();
        self.coefficients
            .iter()
            .enumerate()
            .map(|(k, &c)| {
                let scale = along_u[k % (self.du + 1)] * along_v[k / (self.du + 1)];
                if divide { c * (1.0 / scale) } else { c * scale }
            })
            .collect()
    }

    /// The derivative along u (or v when `along_v`) over a piece `width` wide in that
    /// parameter: degree·(c_{i+1} − c_i) / width.
    pub(super) fn derivative(&self, along_v: bool, width: f64) -> Bernstein<T> {
        let (du, dv) = if along_v {
            (self.du, self.dv - 1)
        } else {
            (self.du - 1, self.dv)
        };
        let degree = if along_v { self.dv } else { self.du } as f64;
        let mut coefficients = Vec::with_capacity((du + 1) * (dv + 1));
        for j in 0..=dv {
            for i in 0..=du {
                let (next, this) = if along_v {
                    (self.at(i, j + 1), self.at(i, j))
                } else {
                    (self.at(i + 1, j), self.at(i, j))
                };
                coefficients.push((next - this) * (degree / width));
            }
        }
        Bernstein::new(du, dv, coefficients)
    }

    pub(super) fn minus(&self, other: &Bernstein<T>) -> Bernstein<T> {
        Bernstein {
            coefficients: self
                .coefficients
                .iter()
                .zip(&other.coefficients)
                .map(|(&a, &b)| a - b)
                .collect(),
            ..*self
        }
    }
}

/// A Bernstein polynomial's value at the centre of its piece (de Casteljau at ½, ½).
pub(super) fn centre_value<T: Value>(p: &Bernstein<T>) -> T {
    let halve = |mut values: Vec<T>| {
        while values.len() > 1 {
            values = values.windows(2).map(|w| (w[0] + w[1]) * 0.5).collect();
        }
        values[0]
    };
    let rows: Vec<T> = p
        .coefficients
        .chunks_exact(p.du + 1)
        .map(|row| halve(row.to_vec()))
        .collect();
    halve(rows)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// Σᵢⱼ C(du,i)·sⁱ(1−s)^(du−i) · C(dv,j)·tʲ(1−t)^(dv−j) · c_ij: the polynomial's value at
    /// local parameters (s, t) ∈ [0, 1]², summed term by term.
    fn value<T: Value>(p: &Bernstein<T>, s: f64, t: f64) -> T {
        let basis = |n: usize, k: usize, x: f64| {
            binomial(n, k) * x.powi(k as i32) * (1.0 - x).powi((n - k) as i32)
        };
        let mut sum = T::default();
        for j in 0..=p.dv {
            for i in 0..=p.du {
                sum = sum + p.at(i, j) * (basis(p.du, i, s) * basis(p.dv, j, t));
            }
        }
        sum
    }

    /// A scalar polynomial of degree (2, 1) and a vector one of degree (1, 3), with
    /// coefficients of both signs and different sizes.
    fn operands() -> (Bernstein<f64>, Bernstein<DVec3>) {
        let scalar = Bernstein::new(2, 1, vec![1.0, -0.5, 2.0, 0.25, 3.0, -1.5]);
        let vector = Bernstein::new(
            1,
            3,
            (0..8)
                .map(|k| {
                    let k = k as f64;
                    DVec3::new(k - 3.0, 0.5 * k * k - 2.0, (k * 0.7).sin())
                })
                .collect(),
        );
        (scalar, vector)
    }

    fn grid() -> impl Iterator<Item = (f64, f64)> {
        (0..=6).flat_map(|a| (0..=6).map(move |b| (a as f64 / 6.0, b as f64 / 6.0)))
    }

    /// Products are the pointwise products of their operands, for a scalar times a vector
    /// and for the cross and dot products of vectors, to 1e-13 of their size; their degrees
    /// add.
    #[test]
    fn products_are_pointwise_products() {
        let (scalar, vector) = operands();
        let scaled = scalar.product(&vector, |x: f64, v: DVec3| v * x);
        let rate = vector.derivative(false, 2.0);
        let crossed = vector.product(&rate, |a: DVec3, b: DVec3| a.cross(b));
        let dotted = vector.product(&vector, |a: DVec3, b: DVec3| a.dot(b));
        assert_eq!((scaled.du, scaled.dv), (3, 4));
        assert_eq!((crossed.du, crossed.dv), (1, 6));
        assert_eq!((dotted.du, dotted.dv), (2, 6));
        for (s, t) in grid() {
            let (x, v) = (value(&scalar, s, t), value(&vector, s, t));
            let v_u = value(&rate, s, t);
            for (got, want) in [
                (value(&scaled, s, t), v * x),
                (value(&crossed, s, t), v.cross(v_u)),
                (DVec3::splat(value(&dotted, s, t)), DVec3::splat(v.dot(v))),
            ] {
                assert!(
                    (got - want).length() <= 1e-13 * (1.0 + want.length()),
                    "({s}, {t}): {got} vs {want}"
                );
            }
        }
    }

    /// The derivative along u and along v over a piece of width w is the polynomial's rate
    /// in that parameter (central differences of its values, step 1e-5, to 1e-8), and the
    /// difference of two polynomials is that of their values.
    #[test]
    fn derivatives_and_differences_are_pointwise() {
        let (_, vector) = operands();
        let other = Bernstein::new(
            1,
            3,
            vector
                .coefficients
                .iter()
                .map(|c| DVec3::new(c.y, c.z, c.x) * 0.5)
                .collect(),
        );
        let (width_u, width_v) = (0.5, 4.0);
        let (d_u, d_v) = (
            vector.derivative(false, width_u),
            vector.derivative(true, width_v),
        );
        assert_eq!((d_u.du, d_u.dv, d_v.du, d_v.dv), (0, 3, 1, 2));
        let step = 1e-5;
        for (s, t) in grid() {
            let (s, t) = (0.01 + 0.98 * s, 0.01 + 0.98 * t);
            let rate_u = (value(&vector, s + step, t) - value(&vector, s - step, t))
                / (2.0 * step * width_u);
            let rate_v = (value(&vector, s, t + step) - value(&vector, s, t - step))
                / (2.0 * step * width_v);
            assert!(
                (value(&d_u, s, t) - rate_u).length() <= 1e-8,
                "({s}, {t}) along u"
            );
            assert!(
                (value(&d_v, s, t) - rate_v).length() <= 1e-8,
                "({s}, {t}) along v"
            );
            let difference = value(&vector.minus(&other), s, t);
            let want = value(&vector, s, t) - value(&other, s, t);
            assert!((difference - want).length() <= 1e-14 * (1.0 + want.length()));
        }
    }

    /// The centre value is the value at (½, ½), of a polynomial of unequal degrees.
    #[test]
    fn the_centre_value_is_the_value_at_the_centre() {
        let (scalar, vector) = operands();
        assert!((centre_value(&scalar) - value(&scalar, 0.5, 0.5)).abs() <= 1e-15);
        assert!((centre_value(&vector) - value(&vector, 0.5, 0.5)).length() <= 1e-14);
    }
}
