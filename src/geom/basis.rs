//! B-spline basis functions and their derivatives (Cox–de Boor, in the triangular-table form
//! of Piegl & Tiller's algorithm A2.3), in f64 on fixed-size stack arrays.

use crate::geom::{KnotVector, MAX_DEGREE};

/// Room for the degree+1 non-zero basis functions of the highest supported degree.
pub(crate) const MAX_ORDER: usize = MAX_DEGREE + 1;

/// Basis values and derivatives: `ders[k][r]` is the k-th derivative of N_(span−p+r, p) at u,
/// for k ≤ the requested order (≤ 2) and r in 0..=p.
pub(crate) type BasisDers = [[f64; MAX_ORDER]; 3];

/// Fills `ders` with the values and first `order` (< N) derivatives of the non-zero basis
/// functions at `u` in span `span` (from [`KnotVector::find_span`]); derivatives above the
/// degree are zero.
pub(crate) fn basis_ders<const N: usize>(
    knots: &KnotVector,
    span: usize,
    u: f64,
    order: usize,
    ders: &mut [[f64; MAX_ORDER]; N],
) {
    // The working tables sized to the degree: zeroing the largest (21 × 21) for a cubic
    // took a tenth of a B-rep's meshing time.
    match knots.degree() {
        0..4 => basis_ders_within::<N, 4>(knots, span, u, order, ders),
        4..8 => basis_ders_within::<N, 8>(knots, span, u, order, ders),
        _ => basis_ders_within::<N, MAX_ORDER>(knots, span, u, order, ders),
    }
}

/// [`basis_ders`] with working tables of `C` (> the degree) entries a side.
fn basis_ders_within<const N: usize, const C: usize>(
    knots: &KnotVector,
    span: usize,
    u: f64,
    order: usize,
    ders: &mut [[f64; MAX_ORDER]; N],
) {
    let p = knots.degree();
    for row in ders.iter_mut().take(order + 1).skip(p + 1) {
        row.fill(0.0);
    }
    let order = order.min(p);
    let k = knots.knots();
    // ndu[j][r] (r ≤ j): basis values of degree j in the upper triangle, knot differences in
    // the lower triangle.
    let mut ndu = [[0.0f64; C]; C];
    let mut left = [0.0f64; C];
    let mut right = [0.0f64; C];
    ndu[0][0] = 1.0;
    for j in 1..=p {
        left[j] = u - k[span + 1 - j];
        right[j] = k[span + j] - u;
        let mut saved = 0.0;
        for r in 0..j {
            ndu[j][r] = right[r + 1] + left[j - r];
            let temp = ndu[r][j - 1] / ndu[j][r];
            ndu[r][j] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        ndu[j][j] = saved;
    }
    for j in 0..=p {
        ders[0][j] = ndu[j][p];
    }
    if order == 0 {
        return;
    }
    let mut a = [[0.0f64; C]; 2];
    let p_i = p as isize;
    for r in 0..=p {
        let r_i = r as isize;
        let (mut s1, mut s2) = (0usize, 1usize);
        a[0][0] = 1.0;
        for kd in 1..=order {
            let kd_i = kd as isize;
            let mut d = 0.0;
            let rk = r_i - kd_i;
            let pk = p_i - kd_i;
            if r_i >= kd_i {
                a[s2][0] = a[s1][0] / ndu[(pk + 1) as usize][rk as usize];
                d = a[s2][0] * ndu[rk as usize][pk as usize];
            }
            let j1 = if rk >= -1 { 1 } else { -rk };
            let j2 = if r_i - 1 <= pk { kd_i - 1 } else { p_i - r_i };
            for j in j1..=j2 {
                let j = j as usize;
                let col = (rk + j as isize) as usize;
                a[s2][j] = (a[s1][j] - a[s1][j - 1]) / ndu[(pk + 1) as usize][col];
                d += a[s2][j] * ndu[col][pk as usize];
            }
            if r_i <= pk {
                a[s2][kd] = -a[s1][kd - 1] / ndu[(pk + 1) as usize][r];
                d += a[s2][kd] * ndu[r][pk as usize];
            }
            ders[kd][r] = d;
            std::mem::swap(&mut s1, &mut s2);
        }
    }
    let mut factor = p as f64;
    for (kd, row) in ders.iter_mut().enumerate().take(order + 1).skip(1) {
        for value in row.iter_mut().take(p + 1) {
            *value *= factor;
        }
        factor *= p as f64 - kd as f64;
    }
}

impl KnotVector {
    /// The span holding `u` (see [`KnotVector::find_span`]) and the values of the degree+1
    /// basis functions N_(span−p), …, N_span that are non-zero there; `u` is clamped to the
    /// domain.
    pub fn basis_values(&self, u: f64) -> (usize, Vec<f64>) {
        let (start, end) = self.domain();
        let u = u.clamp(start, end);
        let span = self.find_span(u);
        let mut ders: BasisDers = [[0.0; MAX_ORDER]; 3];
        basis_ders(self, span, u, 0, &mut ders);
        (span, ders[0][..=self.degree()].to_vec())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Derivatives above the degree are zero whatever the buffer held before (it is reused
    /// across calls), and the values and first derivatives are the hat functions'.
    #[test]
    fn derivatives_above_the_degree_are_zero_in_a_reused_buffer() {
        let knots = KnotVector::try_new(1, vec![0.0, 0.0, 0.5, 1.0, 1.0]).unwrap();
        let mut ders: BasisDers = [[7.0; MAX_ORDER]; 3];
        let u = 0.75;
        let span = knots.find_span(u);
        basis_ders(&knots, span, u, 2, &mut ders);
        assert_eq!(ders[0][..2], [0.5, 0.5]);
        assert_eq!(ders[1][..2], [-2.0, 2.0]);
        assert_eq!(ders[2][..2], [0.0, 0.0]);
    }
}
