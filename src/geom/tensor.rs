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
