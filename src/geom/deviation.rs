//! Proven bounds on how far a sampled mesh strays from its surface, and the sampling rates
//! they imply: what adaptive tessellation plans with (no trial meshing).
//!
//! The rule: a triangle whose vertices lie on S and whose parameter extents are (h, k) —
//! the widths of the smallest (u, v) rectangle holding it — stays within
//! ⅛·(h²·M_uu + 2·h·k·M_uv + k²·M_vv) of S over its parameter triangle, where M bounds
//! |S_uu|, |S_uv|, |S_vv| there. (For the linear interpolant L with barycentric weights λᵢ,
//! S(x) − L(x) = −Σ λᵢ·R(xᵢ − x) with R the Taylor remainder, |R(d)| ≤ ½·(d_u²·M_uu +
//! 2|d_u d_v|·M_uv + d_v²·M_vv); Σ λᵢ·(uᵢ − u)² is a variance of values spread over h, at most
//! h²/4 (Popoviciu), likewise k²/4, and Cauchy–Schwarz bounds the mixed sum by h·k/4.)

use super::BezierPatch;
use super::tensor::Bernstein;
use glam::{DVec2, DVec3, DVec4};

/// Upper bounds of |S_u|, |S_v| (model units per parameter unit) and of |S_uu|, |S_uv|,
/// |S_vv| (per parameter unit squared) over a parameter rectangle, and of the unit normal's
/// rates |N_u|, |N_v| (radians per parameter unit) where they were asked for.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DerivativeBound {
    pub u: f64,
    pub v: f64,
    pub uu: f64,
    pub uv: f64,
    pub vv: f64,
    /// |N_u| and |N_v| over the rectangle except within
    /// [`NORMAL_EXEMPT_FRACTION`](super::normal_turn::NORMAL_EXEMPT_FRACTION) of its width of
    /// points where S_u × S_v vanishes (see [`BezierPatch::normal_rates`]); 0 when no angle
    /// limit asked for them.
    pub normal_u: f64,
    pub normal_v: f64,
}

/// What a sampling must meet: a deviation and, optionally, an edge length (model units) and
/// an angle between the normals at the two ends of any edge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SamplingLimits {
    /// Largest distance between a triangle and the surface (> 0; infinite: no limit).
    pub tolerance: f64,
    /// Longest triangle edge (> 0; infinite: no limit).
    pub max_edge: f64,
    /// Largest angle between the surface normals at the two ends of a triangle edge
    /// (radians, in (0, π); infinite: no limit). Holds inside each surface, away from
    /// degenerate points (see [`DerivativeBound::normal_u`]); across a crease the normals
    /// differ by the crease's own angle.
    pub max_angle: f64,
}

impl SamplingLimits {
    /// A deviation and nothing else.
    pub const fn tolerance(tolerance: f64) -> Self {
        SamplingLimits {
            tolerance,
            max_edge: f64::INFINITY,
            max_angle: f64::INFINITY,
        }
    }
}

impl DerivativeBound {
    /// The longest an edge of parameter extents (h, k) can be: h·|S_u| + k·|S_v| (the mean
    /// value theorem along the edge).
    pub fn edge_length(&self, h: f64, k: f64) -> f64 {
        h * self.u + k * self.v
    }

    /// The deviation bound (model units) of a triangle of parameter extents (h, k) inside
    /// the rectangle: ⅛·(h²·M_uu + 2·h·k·M_uv + k²·M_vv).
    pub fn deviation(&self, h: f64, k: f64) -> f64 {
        0.125 * (h * h * self.uu + 2.0 * h * k * self.uv + k * k * self.vv)
    }

    /// The deviation bound (model units) of a triangle whose corners lie on S at the
    /// parameters `corners` (inside the rectangle): ½·r², r the radius of the smallest circle
    /// around the corners in the coordinates (√a·u, √b·v), where a = M_uu + α·M_uv and
    /// b = M_vv + M_uv/α (2·|d_u d_v| ≤ α·d_u² + d_v²/α for any α > 0; the least over α =
    /// the corners' box's height over width, √(M_vv/M_uu) and 1 is kept). With the module's
    /// rule, |S(x) − L(x)| ≤ ½·Σ λᵢ·|qᵢ − q|² in those coordinates, which is R² − |q − c|²
    /// for the circumcircle (c, R) and peaks at r² over the triangle. For either half of a
    /// grid cell of size (h, k) it is [`deviation`](Self::deviation)`(h, k)`; a well-shaped
    /// triangle of the same area gets less.
    pub fn triangle_deviation(&self, corners: [DVec2; 3]) -> f64 {
        let low = corners[0].min(corners[1]).min(corners[2]);
        let extent = corners[0].max(corners[1]).max(corners[2]) - low;
        let radius_squared = |a: f64, b: f64| {
            let q = corners.map(|p| DVec2::new(a.sqrt() * (p.x - low.x), b.sqrt() * (p.y - low.y)));
            smallest_circle_radius_squared(q)
        };
        if self.uv == 0.0 {
            return 0.5 * radius_squared(self.uu, self.vv);
        }
        [extent.y / extent.x, (self.vv / self.uu).sqrt(), 1.0]
            .into_iter()
            .filter(|alpha| alpha.is_finite() && *alpha > 0.0)
            .map(|alpha| 0.5 * radius_squared(self.uu + alpha * self.uv, self.vv + self.uv / alpha))
            .fold(f64::INFINITY, f64::min)
    }

    /// How far a triangle at the parameters `corners` (inside the rectangle) is from meeting
    /// `limits`: the largest of its deviation bound over the tolerance and, over its edges,
    /// [`edge_length`](Self::edge_length) over the longest edge and
    /// [`normal_turn`](Self::normal_turn) over the angle. At most 1: it meets them.
    pub fn triangle_excess(&self, corners: [DVec2; 3], limits: SamplingLimits) -> f64 {
        let mut excess = self.triangle_deviation(corners) / limits.tolerance;
        for k in 0..3 {
            let d = (corners[(k + 1) % 3] - corners[k]).abs();
            excess = excess
                .max(self.edge_length(d.x, d.y) / limits.max_edge)
                .max(self.normal_turn(d.x, d.y) / limits.max_angle);
        }
        excess
    }

    /// The largest angle (radians) between the normals at the ends of an edge of parameter
    /// extents (h, k) inside the rectangle: h·|N_u| + k·|N_v| (the length of the normal's
    /// path on the unit sphere).
    pub fn normal_turn(&self, h: f64, k: f64) -> f64 {
        h * self.normal_u + k * self.normal_v
    }

    /// Whether every triangle inside a grid cell of size (h, k) meets `limits`: its
    /// deviation, and the edge length and normal turn of the cell's diagonal (the longest
    /// any edge inside it can have).
    pub fn allows(&self, h: f64, k: f64, limits: SamplingLimits) -> bool {
        self.deviation(h, k) <= limits.tolerance
            && self.edge_length(h, k) <= limits.max_edge
            && self.normal_turn(h, k) <= limits.max_angle
    }

    /// The larger of two bounds in every component: a bound over the union of their
    /// rectangles.
    pub fn max(self, other: DerivativeBound) -> DerivativeBound {
        DerivativeBound {
            u: self.u.max(other.u),
            v: self.v.max(other.v),
            uu: self.uu.max(other.uu),
            uv: self.uv.max(other.uv),
            vv: self.vv.max(other.vv),
            normal_u: self.normal_u.max(other.normal_u),
            normal_v: self.normal_v.max(other.normal_v),
        }
    }

    /// The fewest grid cells (n_u · n_v, each ≥ 1) over a `width_u` × `width_v` rectangle
    /// whose cells, of size (h, k) = (width_u / n_u, width_v / n_v), meet `limits` (see
    /// [`allows`](Self::allows)). Counts are capped at `max_segments` per direction; at the
    /// cap the limits may be exceeded, which the caller reports.
    pub fn segments(
        &self,
        (width_u, width_v): (f64, f64),
        limits: SamplingLimits,
        max_segments: u32,
    ) -> (u32, u32) {
        let budget = 8.0 * limits.tolerance;
        // The limits linear in (h, k): a·h + b·k ≤ limit (edge length, normal turn).
        let linear = [
            (self.u, self.v, limits.max_edge),
            (self.normal_u, self.normal_v, limits.max_angle),
        ];
        // The fewest v-segments for a u-spacing h: the largest k with
        // M_vv·k² + 2·M_uv·h·k ≤ 8·tol − M_uu·h² and every linear limit.
        let rows_for = |h: f64| -> Option<u32> {
            let rest = budget - self.uu * h * h;
            if rest <= 0.0 {
                return None;
            }
            let b = self.uv * h;
            let mut k = if rest.is_infinite() {
                f64::INFINITY
            } else if self.vv > 0.0 {
                rest / (b + (b * b + self.vv * rest).sqrt())
            } else if b > 0.0 {
                rest / (2.0 * b)
            } else {
                f64::INFINITY
            };
            for (along_u, along_v, limit) in linear {
                let linear_rest = limit - along_u * h;
                if linear_rest <= 0.0 {
                    return None;
                }
                if along_v > 0.0 {
                    k = k.min(linear_rest / along_v);
                }
            }
            let mut n = (width_v / k).ceil().max(1.0);
            // ceil of a rounded quotient: step past a count that still misses by rounding.
            while n < f64::from(max_segments) && !self.allows(h, width_v / n, limits) {
                n += 1.0;
            }
            Some(n.min(f64::from(max_segments)) as u32)
        };
        // The fewest u-segments that leave room for any v-spacing at all, then a search
        // over the trade between the two directions (the product is minimised over whole
        // numbers: the continuous optimum would round up in both).
        let least = |needed: f64| (needed.floor() + 1.0).min(f64::from(max_segments)) as u32;
        let least_u = linear
            .iter()
            .map(|&(along_u, _, limit)| least(width_u * along_u / limit))
            .fold(least(width_u * (self.uu / budget).sqrt()), u32::max);
        let mut best = (max_segments, max_segments);
        let mut best_cells = u64::from(max_segments) * u64::from(max_segments);
        let last_u = least_u
            .saturating_mul(4)
            .saturating_add(16)
            .min(max_segments);
        // The v-segments never drop below those of h → 0 (fewer u-spacing leaves more room
        // along v), so once n_u times them reaches the best product no larger n_u is better.
        let fewest_v = u64::from(rows_for(0.0).unwrap_or(1));
        for n_u in least_u..=last_u {
            if u64::from(n_u) * fewest_v >= best_cells {
                break;
            }
            if let Some(n_v) = rows_for(width_u / f64::from(n_u)) {
                let cells = u64::from(n_u) * u64::from(n_v);
                if cells < best_cells {
                    (best, best_cells) = ((n_u, n_v), cells);
                }
            }
        }
        best
    }
}

impl BezierPatch {
    /// Bounds of the first and second derivatives of the patch over its parameter ranges,
    /// from its control net (convex-hull property of Bezier derivatives): |S_u| ≤ G_u below.
    /// Polynomial: M_uu = p(p−1)/Δu² · max|Δ²_u P| (M_uv, M_vv likewise). Rational, in
    /// homogeneous coordinates relative to the centre C of the control points' box, with
    /// R = max|P − C|, w_min the least weight and D, W the same difference bounds of
    /// w·(P − C) and of w: |S_u| ≤ G_u = (D_u + W_u·R)/w_min and, from the quotient rule,
    /// M_uu ≤ (D_uu + 2·W_u·G_u + W_uu·R) / w_min, M_uv ≤ (D_uv + W_u·G_v + W_v·G_u +
    /// W_uv·R) / w_min. With equal weights W = 0 and this is the polynomial bound. Needs
    /// positive weights. For a rational patch each component is also bounded by
    /// [`quotient_bound`](Self::quotient_bound) and the smaller kept.
    pub fn derivative_bound(&self) -> DerivativeBound {
        self.tightened(self.magnitude_bound())
    }

    /// `bound` (this patch's [`magnitude_bound`](Self::magnitude_bound)) made the smaller of
    /// it and the [`quotient_bound`](Self::quotient_bound) in every component, for a
    /// rational patch (on a polynomial one its products would amount to degree elevation,
    /// tighter in some components at their cost; the planner keeps the magnitudes there).
    pub fn tightened(&self, bound: DerivativeBound) -> DerivativeBound {
        let rational = self.points.iter().any(|h| h.w != self.points[0].w);
        match rational.then(|| self.quotient_bound()).flatten() {
            Some(quotient) => DerivativeBound {
                u: bound.u.min(quotient.u),
                v: bound.v.min(quotient.v),
                uu: bound.uu.min(quotient.uu),
                uv: bound.uv.min(quotient.uv),
                vv: bound.vv.min(quotient.vv),
                ..bound
            },
            None => bound,
        }
    }

    /// The bound by magnitudes of the control net's differences (see
    /// [`derivative_bound`](Self::derivative_bound)): cheap, and for rational patches
    /// looser than the quotient bound.
    pub fn magnitude_bound(&self) -> DerivativeBound {
        let (p, q) = (self.degree_u, self.degree_v);
        let row = p + 1;
        // (w·(P − C), w) of every control point, formed once (on the stack for a bicubic
        // patch), and the differences below from them. With equal weights every weight
        // difference is 0, so C and R do not matter (the terms R multiplies vanish, and
        // differences do not depend on C): the homogeneous points themselves, C = 0, R = 0.
        let equal_weights = self.points.iter().all(|h| h.w == self.points[0].w);
        let mut on_stack = [DVec4::ZERO; 16];
        let mut on_heap = Vec::new();
        let (relative, radius): (&[DVec4], f64) = if equal_weights {
            (&self.points, 0.0)
        } else {
            let relative: &mut [DVec4] = match self.points.len() {
                n if n <= on_stack.len() => &mut on_stack[..n],
                n => {
                    on_heap.resize(n, DVec4::ZERO);
                    &mut on_heap
                }
            };
            for (r, h) in relative.iter_mut().zip(&self.points) {
                *r = (h.truncate() / h.w).extend(h.w);
            }
            let (centre, radius) = box_centre_and_radius(relative.iter().map(|r| r.truncate()));
            for (r, h) in relative.iter_mut().zip(&self.points) {
                *r = (h.truncate() - h.w * centre).extend(h.w);
            }
            (relative, radius)
        };
        // First differences along u (p per row of the net) and along v (rows of p + 1),
        // the second differences from them: uu along each row of those along u, uv and vv
        // between consecutive rows of those along u and along v. Each kind's largest
        // |vector part| and |weight| is what the bound takes.
        let mut first_on_stack = [DVec4::ZERO; 24];
        let mut first_on_heap = Vec::new();
        let (along_u, along_v) = (p * (q + 1), row * q);
        let first: &mut [DVec4] = match along_u + along_v {
            n if n <= first_on_stack.len() => &mut first_on_stack[..n],
            n => {
                first_on_heap.resize(n, DVec4::ZERO);
                &mut first_on_heap
            }
        };
        let (steps_u, steps_v) = first.split_at_mut(along_u);
        let [
            mut first_u,
            mut first_v,
            mut second_uu,
            mut second_uv,
            mut second_vv,
        ] = [Largest::default(); 5];
        if p >= 1 {
            for (points, steps) in relative.chunks_exact(row).zip(steps_u.chunks_exact_mut(p)) {
                for i in 0..p {
                    steps[i] = points[i + 1] - points[i];
                    first_u.take(steps[i]);
                }
                for i in 1..p {
                    second_uu.take(steps[i] - steps[i - 1]);
                }
            }
            for (next, this) in steps_u[p..].iter().zip(&*steps_u) {
                second_uv.take(next - this);
            }
        }
        for ((d, next), this) in steps_v.iter_mut().zip(&relative[row..]).zip(relative) {
            *d = next - this;
            first_v.take(*d);
        }
        for (next, this) in steps_v.get(row..).unwrap_or_default().iter().zip(&*steps_v) {
            second_vv.take(next - this);
        }
        let [first_u, first_v, second_uu, second_uv, second_vv] =
            [first_u, first_v, second_uu, second_uv, second_vv].map(Largest::get);
        let (pf, qf) = (p as f64, q as f64);
        let (wu, wv) = (self.range_u.width(), self.range_v.width());
        let scale_u = pf / wu;
        let scale_v = qf / wv;
        let scale_uu = pf * (pf - 1.0) / (wu * wu);
        let scale_vv = qf * (qf - 1.0) / (wv * wv);
        let scale_uv = pf * qf / (wu * wv);
        let least_weight = self
            .points
            .iter()
            .map(|h| h.w)
            .fold(f64::INFINITY, f64::min);
        let (d_u, w_u) = (scale_u * first_u.0, scale_u * first_u.1);
        let (d_v, w_v) = (scale_v * first_v.0, scale_v * first_v.1);
        let g_u = (d_u + w_u * radius) / least_weight;
        let g_v = (d_v + w_v * radius) / least_weight;
        let general_uv =
            (scale_uv * second_uv.0 + w_u * g_v + w_v * g_u + scale_uv * second_uv.1 * radius)
                / least_weight;
        DerivativeBound {
            u: g_u,
            v: g_v,
            uu: (scale_uu * second_uu.0 + 2.0 * w_u * g_u + scale_uu * second_uu.1 * radius)
                / least_weight,
            uv: general_uv.min(self.ruled_uv_bound().unwrap_or(f64::INFINITY)),
            vv: (scale_vv * second_vv.0 + 2.0 * w_v * g_v + scale_vv * second_vv.1 * radius)
                / least_weight,
            normal_u: 0.0,
            normal_v: 0.0,
        }
    }

    /// Bounds of a rational patch's derivatives from the quotient's own polynomials: with
    /// H = w·(P − C) and w in Bernstein form, w²·S_u = A = H_u·w − H·w_u (B likewise along
    /// v), w³·S_uu = A_u·w − 2·A·w_u, w³·S_uv = A_v·w − 2·A·w_v and w³·S_vv = B_v·w −
    /// 2·B·w_v — polynomials, whose products are formed exactly; each |S_…| is at most the
    /// largest of its numerator's coefficients over the least of its power of w's (a
    /// polynomial in Bernstein form lies within its coefficients). Unlike the bound by
    /// magnitudes, terms that cancel in the quotient rule (w_u·S_u against part of H_uu)
    /// cancel here too, so the bound tends to the true largest values as the patch shrinks
    /// (a sphere's cells, 1/8 of a patch wide: within 1.15× of them, where the magnitudes
    /// give 1.5× or more). `None` where a weight's power has a coefficient ≤ 0.
    pub fn quotient_bound(&self) -> Option<DerivativeBound> {
        let (p, q) = (self.degree_u, self.degree_v);
        let (wu, wv) = (self.range_u.width(), self.range_v.width());
        let (centre, _) = box_centre_and_radius(self.points.iter().map(|h| h.truncate() / h.w));
        let h = Bernstein::new(
            p,
            q,
            (self.points.iter())
                .map(|h| h.truncate() - h.w * centre)
                .collect(),
        );
        let w = Bernstein::new(p, q, self.points.iter().map(|h| h.w).collect());
        let times = |x: f64, v: DVec3| v * x;
        let twice = |x: f64, v: DVec3| v * (2.0 * x);
        let (w_u, w_v) = (w.derivative(false, wu), w.derivative(true, wv));
        let a = (w.product(&h.derivative(false, wu), times)).minus(&w_u.product(&h, times));
        let b = (w.product(&h.derivative(true, wv), times)).minus(&w_v.product(&h, times));
        let square = w.product(&w, |x: f64, y: f64| x * y);
        let cube = square.product(&w, |x: f64, y: f64| x * y);
        let least = |power: &Bernstein<f64>| {
            (power.coefficients.iter()).fold(f64::INFINITY, |m, &c| m.min(c))
        };
        let (least_square, least_cube) = (least(&square), least(&cube));
        if !(least_square > 0.0 && least_cube > 0.0) {
            return None;
        }
        let largest =
            |t: &Bernstein<DVec3>| (t.coefficients.iter()).fold(0.0f64, |m, c| m.max(c.length()));
        let second = |numerator: &Bernstein<DVec3>, along_v: bool, w_d: &Bernstein<f64>| {
            let width = if along_v { wv } else { wu };
            let n = w.product(&numerator.derivative(along_v, width), times);
            largest(&n.minus(&w_d.product(numerator, twice))) / least_cube
        };
        Some(DerivativeBound {
            u: largest(&a) / least_square,
            v: largest(&b) / least_square,
            uu: second(&a, false, &w_u),
            uv: second(&a, true, &w_v),
            vv: second(&b, true, &w_v),
            normal_u: 0.0,
            normal_v: 0.0,
        })
    }

    /// `bound` (one of this patch's derivative bounds) with the normal rates too when
    /// `limits` has an angle limit (they cost a subdivision of the patch).
    pub fn with_normal_rates(
        &self,
        bound: DerivativeBound,
        limits: SamplingLimits,
    ) -> DerivativeBound {
        if limits.max_angle.is_finite() {
            let (normal_u, normal_v) = self.normal_rates();
            DerivativeBound {
                normal_u,
                normal_v,
                ..bound
            }
        } else {
            bound
        }
    }

    /// A bound on |S_uv| for a patch ruled in one direction: degree 1 in v with weights
    /// equal along v (or the same with u and v exchanged), as cylinders, cones and
    /// extrusions of rational curves are. Then S = C₀(u) + t·D(u) with t = (v − v₀)/Δv and
    /// D = C₁ − C₀ the rational curve of the differences of the two rows over the same
    /// weights, so S_uv = D′(u)/Δv, bounded like a first derivative (see
    /// [`derivative_bound`](Self::derivative_bound)) — where the general bound's quotient
    /// rule terms W_u·G_v would not cancel (a cylinder's S_uv is 0). `None` otherwise.
    fn ruled_uv_bound(&self) -> Option<f64> {
        let (p, q) = (self.degree_u, self.degree_v);
        let row = p + 1;
        let at = |i: usize, j: usize| self.points[j * row + i];
        // The two rows' homogeneous points `first(k)` and `second(k)`, k = 0..=degree along
        // the curved direction: their weights, and the differences of their points.
        let rows = |degree: usize,
                    first: &dyn Fn(usize) -> DVec4,
                    second: &dyn Fn(usize) -> DVec4|
         -> Option<(Vec<f64>, Vec<DVec3>)> {
            (0..=degree)
                .map(|k| {
                    let (a, b) = (first(k), second(k));
                    (a.w == b.w).then(|| (a.w, (b.truncate() - a.truncate()) / a.w))
                })
                .collect::<Option<Vec<_>>>()
                .map(|pairs| pairs.into_iter().unzip())
        };
        // (The degree is checked first: the rows are only gathered for a ruled patch.)
        let (weights, differences, degree, along, across) = if q == 1
            && let Some((w, d)) = rows(p, &|i| at(i, 0), &|i| at(i, 1))
        {
            (w, d, p, self.range_u.width(), self.range_v.width())
        } else if p == 1
            && let Some((w, d)) = rows(q, &|j| at(0, j), &|j| at(1, j))
        {
            (w, d, q, self.range_v.width(), self.range_u.width())
        } else {
            return None;
        };
        let (centre, radius) = box_centre_and_radius(differences.iter().copied());
        let scale = degree as f64 / along;
        let (mut d_first, mut w_first) = (0.0f64, 0.0f64);
        for k in 0..degree {
            let next = weights[k + 1] * (differences[k + 1] - centre);
            let this = weights[k] * (differences[k] - centre);
            d_first = d_first.max((next - this).length());
            w_first = w_first.max((weights[k + 1] - weights[k]).abs());
        }
        let least_weight = weights.iter().copied().fold(f64::INFINITY, f64::min);
        Some(scale * (d_first + w_first * radius) / least_weight / across)
    }

    /// The patch restricted to the parameters between fractions `from` and `to` (0 ≤ from <
    /// to ≤ 1) of its u range: de Casteljau subdivision of each row, exact up to rounding.
    pub fn restricted_u(&self, from: f64, to: f64) -> BezierPatch {
        self.restricted(false, from, to)
    }

    /// [`restricted_u`](Self::restricted_u) into `strip`, reusing its storage.
    pub fn restrict_u_into(&self, from: f64, to: f64, strip: &mut BezierPatch) {
        self.restrict_into(false, from, to, strip);
    }

    /// [`restricted_u`](Self::restricted_u) along v.
    pub fn restricted_v(&self, from: f64, to: f64) -> BezierPatch {
        self.restricted(true, from, to)
    }

    /// [`restricted_v`](Self::restricted_v) into `piece`, reusing its storage (cells
    /// along one strip are bounded one after another without an allocation each).
    pub fn restrict_v_into(&self, from: f64, to: f64, piece: &mut BezierPatch) {
        self.restrict_into(true, from, to, piece);
    }

    /// The restriction along u, or v where `along_v`, into a new patch.
    fn restricted(&self, along_v: bool, from: f64, to: f64) -> BezierPatch {
        let mut restricted = BezierPatch {
            points: Vec::with_capacity(self.points.len()),
            ..*self
        };
        self.restrict_into(along_v, from, to, &mut restricted);
        restricted
    }

    /// The restriction along u, or v where `along_v`, into `into` (its points' storage
    /// reused): every polygon along that direction restricted in place.
    fn restrict_into(&self, along_v: bool, from: f64, to: f64, into: &mut BezierPatch) {
        let row = self.degree_u + 1;
        into.points.clear();
        into.points.extend_from_slice(&self.points);
        (into.degree_u, into.degree_v) = (self.degree_u, self.degree_v);
        (into.range_u, into.range_v) = (self.range_u, self.range_v);
        let range = if along_v {
            for first in 0..row {
                restrict_in_place(&mut into.points, first, row, self.degree_v + 1, from, to);
            }
            &mut into.range_v
        } else {
            for first in (0..into.points.len()).step_by(row) {
                restrict_in_place(&mut into.points, first, 1, row, from, to);
            }
            &mut into.range_u
        };
        *range = super::Interval::new(range.lerp(from), range.lerp(to));
    }
}

/// Replaces the Bezier polygon `points[first + k·stride]`, k < count, by its polygon over
/// local parameters [from, to] ⊆ [0, 1]: two de Casteljau passes in place, no allocation.
/// The first keeps the right part at `from` (after level r, entry k < count − r holds the
/// level-r point b_k^r, so entry j ends as b_j^(count−1−j)); the second the left part at
/// the rescaled `to`, running from the other end.
fn restrict_in_place(
    points: &mut [DVec4],
    first: usize,
    stride: usize,
    count: usize,
    from: f64,
    to: f64,
) {
    let at = |k: usize| first + k * stride;
    if from > 0.0 {
        for level in 1..count {
            for k in 0..count - level {
                points[at(k)] = points[at(k)].lerp(points[at(k + 1)], from);
            }
        }
    }
    if to < 1.0 {
        let t = (to - from) / (1.0 - from);
        for level in 1..count {
            for k in (level..count).rev() {
                points[at(k)] = points[at(k - 1)].lerp(points[at(k)], t);
            }
        }
    }
}

/// The largest |vector part| and |weight| of the differences given to [`Largest::take`].
#[derive(Clone, Copy, Default)]
struct Largest {
    vector_squared: f64,
    weight: f64,
}

impl Largest {
    #[inline]
    fn take(&mut self, d: DVec4) {
        // Plain comparisons: the same as f64::max on these (never NaN-first) values,
        // without its NaN handling in the innermost loop of the planner.
        let (v, w) = (d.truncate().length_squared(), d.w.abs());
        if v > self.vector_squared {
            self.vector_squared = v;
        }
        if w > self.weight {
            self.weight = w;
        }
    }

    fn get(self) -> (f64, f64) {
        (self.vector_squared.sqrt(), self.weight)
    }
}

/// The centre C of the bounding box of `points` and the largest |P − C| (the reference point
/// and radius the derivative bounds are taken relative to).
pub(crate) fn box_centre_and_radius(points: impl Iterator<Item = DVec3> + Clone) -> (DVec3, f64) {
    let (low, high) = points.clone().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(low, high), x| (low.min(x), high.max(x)),
    );
    let centre = 0.5 * (low + high);
    let radius_squared = points
        .map(|x| (x - centre).length_squared())
        .fold(0.0, f64::max);
    (centre, radius_squared.sqrt())
}

/// The squared radius of the smallest circle around three points of the plane.
fn smallest_circle_radius_squared(q: [DVec2; 3]) -> f64 {
    let sides = [0, 1, 2].map(|k| q[(k + 1) % 3].distance_squared(q[(k + 2) % 3]));
    let area_twice = (q[1] - q[0]).perp_dot(q[2] - q[0]);
    enclosing_radius_squared(sides, area_twice * area_twice)
}

/// The squared radius of the smallest circle around a triangle (in the plane or in space)
/// from its squared side lengths and its doubled area squared: half the longest side where
/// the triangle is right or obtuse (or flat), else its circumradius.
pub(crate) fn enclosing_radius_squared(sides: [f64; 3], doubled_area_squared: f64) -> f64 {
    let longest = sides[0].max(sides[1]).max(sides[2]);
    // Right or obtuse: the longest side's square is at least the other two's sum.
    if 2.0 * longest >= sides[0] + sides[1] + sides[2] || doubled_area_squared == 0.0 {
        return 0.25 * longest;
    }
    // R = abc / (4·area), area = √doubled_area_squared / 2, so
    // R² = a²b²c² / (4·doubled_area_squared).
    (0.25 * sides[0] * sides[1] * sides[2] / doubled_area_squared).max(0.25 * longest)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Interval;

    /// A rational patch of degrees 3 × 2 over [1, 3] × [−1, 0.5] with uneven weights.
    fn patch() -> BezierPatch {
        let points = (0..12)
            .map(|k| {
                let (i, j) = ((k % 4) as f64, (k / 4) as f64);
                let w = 0.5 + 0.3 * i + 0.7 * j * j;
                DVec4::new(i, j, (i * j).sin() + 0.25 * i * i, 1.0) * w
            })
            .collect();
        BezierPatch {
            degree_u: 3,
            degree_v: 2,
            points,
            range_u: Interval::new(1.0, 3.0),
            range_v: Interval::new(-1.0, 0.5),
        }
    }

    /// Restricting in u, then v (and at one end only) gives the same surface over the
    /// smaller rectangle — the exact de Casteljau sub-polygons: positions agree to rounding
    /// on a grid of points.
    #[test]
    fn restriction_keeps_the_surface() {
        let whole = patch();
        let piece = whole.restricted_u(0.2, 0.7).restricted_v(0.1, 0.9);
        let head = whole.restricted_u(0.0, 0.5);
        let tail = whole.restricted_v(0.5, 1.0);
        let size = 4.0;
        for (part, u0, u1, v0, v1) in [
            (&piece, 1.4, 2.4, -0.85, 0.35),
            (&head, 1.0, 2.0, -1.0, 0.5),
            (&tail, 1.0, 3.0, -0.25, 0.5),
        ] {
            assert!(
                (part.range_u.start - u0).abs() < 1e-15 && (part.range_u.end - u1).abs() < 1e-15
            );
            assert!(
                (part.range_v.start - v0).abs() < 1e-15 && (part.range_v.end - v1).abs() < 1e-15
            );
            for a in 0..=6 {
                for b in 0..=6 {
                    let u = u0 + (u1 - u0) * a as f64 / 6.0;
                    let v = v0 + (v1 - v0) * b as f64 / 6.0;
                    let gap = (part.point(u, v) - whole.point(u, v)).length();
                    assert!(gap <= 1e-14 * size, "({u}, {v}): {gap:e}");
                }
            }
        }
        assert_eq!(whole.restricted_u(0.0, 1.0).points, whole.points);
    }

    /// |S_u|, |S_v|, |S_uu|, |S_uv|, |S_vv| of a bound, in the order [`sampled`] gives them.
    fn components(bound: DerivativeBound) -> [f64; 5] {
        [bound.u, bound.v, bound.uu, bound.uv, bound.vv]
    }

    /// Each component of `there` within `relative` of the same one of `here`.
    fn assert_same_bounds(
        name: &str,
        here: DerivativeBound,
        there: DerivativeBound,
        relative: f64,
    ) {
        for (c, (a, b)) in components(here)
            .into_iter()
            .zip(components(there))
            .enumerate()
        {
            assert!(
                (a - b).abs() <= relative * a,
                "{name}, component {c}: {a} vs {b}"
            );
        }
    }

    /// The largest |S_u|, |S_v|, |S_uu|, |S_uv|, |S_vv| at 17 × 17 points of a patch, by
    /// central differences of its points (step 1e-4 of its widths).
    fn sampled(patch: &BezierPatch) -> [f64; 5] {
        let (hu, hv) = (1e-4 * patch.range_u.width(), 1e-4 * patch.range_v.width());
        let s = |u: f64, v: f64| patch.point(u, v);
        let mut most = [0.0f64; 5];
        for a in 0..=16 {
            for b in 0..=16 {
                let u = patch.range_u.lerp(0.001 + 0.998 * a as f64 / 16.0);
                let v = patch.range_v.lerp(0.001 + 0.998 * b as f64 / 16.0);
                let values = [
                    (s(u + hu, v) - s(u - hu, v)) / (2.0 * hu),
                    (s(u, v + hv) - s(u, v - hv)) / (2.0 * hv),
                    (s(u + hu, v) - 2.0 * s(u, v) + s(u - hu, v)) / (hu * hu),
                    (s(u + hu, v + hv) - s(u + hu, v - hv) - s(u - hu, v + hv) + s(u - hu, v - hv))
                        / (4.0 * hu * hv),
                    (s(u, v + hv) - 2.0 * s(u, v) + s(u, v - hv)) / (hv * hv),
                ];
                for (m, d) in most.iter_mut().zip(values) {
                    *m = m.max(d.length());
                }
            }
        }
        most
    }

    /// The quotient bound holds (every sampled derivative at most it, to the differences'
    /// own error) and the kept bound is the smaller of it and the bound by magnitudes, on a
    /// rational 3 × 2 patch and on cells of a sphere's patches. And it is tight where the
    /// magnitudes are not: on those cells (a quarter of a patch each) every component within
    /// 1.9× of the largest value sampled (the magnitudes: up to 3.1×), and as cells shrink
    /// it tends to the true values (1/8 × 1/8 of a patch: second derivatives within 1.15×)
    /// while the magnitudes keep their excess (still 1.5× or more: the quotient rule's
    /// terms, added in absolute value, do not cancel).
    #[test]
    fn the_quotient_bound_holds_and_is_tight() {
        let sphere = crate::geom::shapes::sphere(DVec3::new(3.0, -1.0, 2.0), 2.0);
        let (mut cells, mut small) = (vec![patch()], Vec::new());
        for quarter in sphere.bezier_patches() {
            for (u0, u1) in [(0.0, 0.5), (0.5, 1.0)] {
                let strip = quarter.restricted_u(u0, u1);
                cells.extend([strip.restricted_v(0.1, 0.5), strip.restricted_v(0.5, 0.9)]);
            }
            small.push(quarter.restricted_u(0.5, 0.625).restricted_v(0.25, 0.375));
        }
        let ratios = |cell: &BezierPatch| {
            let quotient = cell.quotient_bound().expect("positive weights");
            let magnitudes = cell.magnitude_bound();
            let kept = cell.derivative_bound();
            let most = sampled(cell);
            let (bounds, loose, kept) = (
                components(quotient),
                components(magnitudes),
                components(kept),
            );
            for c in 0..5 {
                assert!(
                    most[c] <= bounds[c] * (1.0 + 1e-5) + 1e-9,
                    "component {c}: {} > {}",
                    most[c],
                    bounds[c]
                );
                assert_eq!(kept[c], bounds[c].min(loose[c]));
            }
            let ratio = |b: [f64; 5]| [0, 1, 2, 3, 4].map(|c| b[c] / most[c]);
            (ratio(bounds), ratio(loose))
        };
        let worst = |a: f64, b: f64| a.max(b);
        let (mut tight, mut loose) = (0.0f64, 0.0f64);
        for (k, cell) in cells.iter().enumerate() {
            let (t, l) = ratios(cell);
            if k > 0 {
                tight = t.iter().copied().fold(tight, worst);
                loose = l.iter().copied().fold(loose, worst);
            }
        }
        assert!(
            tight <= 1.9 && loose >= 2.5,
            "quotient {tight}×, magnitudes {loose}×"
        );
        let (mut tight, mut loose) = (0.0f64, f64::INFINITY);
        for cell in &small {
            let (t, l) = ratios(cell);
            tight = [t[2], t[3], t[4]].iter().copied().fold(tight, worst);
            loose = loose.min(l[2].max(l[4]));
        }
        assert!(
            tight <= 1.15 && loose >= 1.4,
            "small cells: quotient {tight}×, magnitudes {loose}×"
        );
    }

    /// The larger of the bounds of a patch's four quarters bounds every derivative over the
    /// whole patch (sampled to the differences' own error), each component the larger of
    /// the quarters' — here below the whole patch's own bound by magnitudes, whose box of
    /// control points is wider.
    #[test]
    fn the_union_of_quarters_bounds_the_whole() {
        let whole = patch();
        let quarters = [(0.0, 0.5), (0.5, 1.0)].map(|(u0, u1)| {
            let strip = whole.restricted_u(u0, u1);
            [strip.restricted_v(0.0, 0.5), strip.restricted_v(0.5, 1.0)]
        });
        let bounds = quarters.as_flattened().iter().map(|q| q.magnitude_bound());
        let union = bounds.clone().reduce(DerivativeBound::max).unwrap();
        let most = sampled(&whole);
        let own = components(whole.magnitude_bound());
        for c in 0..5 {
            let largest = bounds.clone().map(|b| components(b)[c]).fold(0.0, f64::max);
            assert_eq!(components(union)[c], largest);
            assert!(most[c] <= largest * (1.0 + 1e-5) + 1e-9, "component {c}");
            assert!(largest < own[c], "component {c}: {largest} ≥ {}", own[c]);
        }
    }

    /// The largest error of the linear interpolant of `f` over the triangle `corners`,
    /// sampled on a fine barycentric lattice plus the circumcentre's and the sides' middles.
    fn interpolation_error(f: &dyn Fn(DVec2) -> f64, corners: [DVec2; 3]) -> f64 {
        let values = corners.map(f);
        let error = |l: [f64; 3]| {
            let p = corners[0] * l[0] + corners[1] * l[1] + corners[2] * l[2];
            (f(p) - (values[0] * l[0] + values[1] * l[1] + values[2] * l[2])).abs()
        };
        let n = 60;
        let mut largest: f64 = 0.0;
        for i in 0..=n {
            for j in 0..=n - i {
                let (a, b) = (i as f64 / n as f64, j as f64 / n as f64);
                largest = largest.max(error([a, b, 1.0 - a - b]));
            }
        }
        for k in 0..3 {
            let mut l = [0.5; 3];
            l[k] = 0.0;
            largest = largest.max(error(l));
        }
        largest
    }

    /// The triangle bound depends on the corners' differences only: moved by 2²⁷ or by
    /// (−2³⁰, 2²⁰) in the parameters (a knot vector far from 0), corners on a 2⁻⁴ grid give
    /// the same bound to 1e-12 — the moved corners are exact, and so are their differences
    /// from the lowest corner, where scaling the absolute coordinates first would leave
    /// only the rounding of their 2²⁸-sized products.
    #[test]
    fn the_triangle_bound_does_not_depend_on_where_the_parameters_lie() {
        let corners = [
            DVec2::new(0.0, 0.0),
            DVec2::new(0.375, 0.125),
            DVec2::new(0.0625, 0.5),
        ];
        let mixed = DerivativeBound {
            uu: 3.0,
            uv: 0.5,
            vv: 2.0,
            ..Default::default()
        };
        let unmixed = DerivativeBound { uv: 0.0, ..mixed };
        for bound in [mixed, unmixed] {
            let here = bound.triangle_deviation(corners);
            for offset in [
                DVec2::splat(2f64.powi(27)),
                DVec2::new(-(2f64.powi(30)), 2f64.powi(20)),
            ] {
                let there = bound.triangle_deviation(corners.map(|c| c + offset));
                assert!(
                    (there - here).abs() <= 1e-12 * here,
                    "{bound:?} moved by {offset}: {there} where {here}"
                );
            }
        }
    }

    /// On z = ½·(A·u² + B·v²) the triangle bound is the exact largest deviation (the
    /// interpolant's error is ½·(R² − |q − c|²) in (√A·u, √B·v)); with a mixed term it still
    /// holds; and for the halves of a grid cell it is the cell's bound.
    #[test]
    fn the_triangle_bound_holds_and_is_exact_on_paraboloids() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..200 {
            let corners = [(); 3].map(|_| DVec2::new(4.0 * next() - 2.0, 3.0 * next() - 1.0));
            let area = (corners[1] - corners[0])
                .perp_dot(corners[2] - corners[0])
                .abs();
            if area < 1e-3 {
                continue;
            }
            let (a, b, c) = (0.1 + 3.0 * next(), 0.1 + 3.0 * next(), 2.0 * next() - 1.0);
            let bound = |uu: f64, uv: f64, vv: f64| DerivativeBound {
                uu,
                uv,
                vv,
                ..Default::default()
            };
            // Exact without a mixed term (sampling finds the peak within 0.5 %).
            let paraboloid = |p: DVec2| 0.5 * (a * p.x * p.x + b * p.y * p.y);
            let exact = bound(a, 0.0, b).triangle_deviation(corners);
            let measured = interpolation_error(&paraboloid, corners);
            assert!(
                measured <= exact * (1.0 + 1e-12) && measured >= 0.995 * exact,
                "{corners:?}: measured {measured}, bound {exact}"
            );
            // With one: |f_uv| = |c| bounds it, and the bound holds.
            let mixed = |p: DVec2| paraboloid(p) + c * p.x * p.y;
            let held = bound(a, c.abs(), b).triangle_deviation(corners);
            assert!(interpolation_error(&mixed, corners) <= held * (1.0 + 1e-12));
        }
        // The two halves of a cell of size (h, k): the cell's own bound.
        let cell = DerivativeBound {
            uu: 2.0,
            uv: 0.7,
            vv: 5.0,
            ..Default::default()
        };
        let (h, k) = (0.3, 0.1);
        let expected = cell.deviation(h, k);
        for half in [
            [DVec2::ZERO, DVec2::new(h, 0.0), DVec2::new(h, k)],
            [DVec2::ZERO, DVec2::new(h, k), DVec2::new(0.0, k)],
        ] {
            let got = cell.triangle_deviation(half);
            assert!(
                (got - expected).abs() <= 1e-14 * expected,
                "{got} vs {expected}"
            );
        }
    }

    /// The mixed term's bound is the least over its three α: each gives the unmixed bound
    /// of (M_uu + α·M_uv, M_vv + M_uv/α). The triangle and bound are one where α =
    /// √(M_vv/M_uu) = √12 is the least, 7 % under α = 1 and the box's ratio (found by
    /// search over triangles on a ⅛ grid).
    #[test]
    fn the_mixed_triangle_bound_is_the_least_over_its_alphas() {
        let corners = [
            DVec2::new(0.5, 0.125),
            DVec2::new(0.625, 1.0),
            DVec2::new(1.0, 0.5),
        ];
        let mixed = DerivativeBound {
            uu: 0.25,
            uv: 1.0,
            vv: 3.0,
            ..Default::default()
        };
        let unmixed_at = |alpha: f64| {
            DerivativeBound {
                uu: mixed.uu + alpha * mixed.uv,
                uv: 0.0,
                vv: mixed.vv + mixed.uv / alpha,
                ..Default::default()
            }
            .triangle_deviation(corners)
        };
        let alphas = [0.875 / 0.5, (mixed.vv / mixed.uu).sqrt(), 1.0];
        let least = alphas
            .map(unmixed_at)
            .into_iter()
            .fold(f64::INFINITY, f64::min);
        let got = mixed.triangle_deviation(corners);
        assert!((got - least).abs() <= 1e-14 * least, "{got} vs {least}");
        let others = unmixed_at(alphas[0]).min(unmixed_at(alphas[2]));
        assert!(
            others >= 1.05 * least,
            "√(M_vv/M_uu) decides here: {others} vs {least}"
        );
    }

    /// A triangle's excess is the worst of its deviation, its longest edge and its widest
    /// normal turn, each over its limit.
    #[test]
    fn the_triangle_excess_is_the_worst_limit() {
        let bound = DerivativeBound {
            u: 2.0,
            v: 3.0,
            uu: 1.0,
            vv: 1.0,
            normal_u: 0.5,
            normal_v: 0.25,
            ..Default::default()
        };
        // Right isosceles, legs 1, away from the origin and with its longest edge closing
        // the loop (corner 2 back to corner 0): r² = ½, deviation ¼; edges (1, 0), (0, 1),
        // (1, 1).
        let corners =
            [(1.0, 0.0), (0.0, 0.0), (0.0, 1.0)].map(|(u, v)| DVec2::new(3.0 + u, 5.0 + v));
        let deviation = bound.triangle_deviation(corners);
        assert!((deviation - 0.25).abs() < 1e-15, "{deviation}");
        let limits = |tolerance, max_edge, max_angle| SamplingLimits {
            tolerance,
            max_edge,
            max_angle,
        };
        let excess = |l| bound.triangle_excess(corners, l);
        assert_eq!(excess(limits(0.5, f64::INFINITY, f64::INFINITY)), 0.5);
        // The longest edge, (1, 1): 2 + 3.
        assert_eq!(excess(limits(1.0, 2.5, f64::INFINITY)), 2.0);
        // The widest turn, (1, 1): 0.5 + 0.25.
        assert_eq!(excess(limits(1.0, f64::INFINITY, 0.25)), 3.0);
    }

    /// `segments` gives the fewest cells that meet the limits: the least n_u·n_v over a
    /// search of every (n_u, n_v) up to the cap, and the cells it gives meet them. The cases
    /// bind each limit in turn: the mixed quadratic; a linear edge limit whose v rate is not
    /// 1; a surface so flat over a wide rectangle that one cell does; no M_vv beside M_uv;
    /// a split of u that leaves v whole ((2, 1) where (1, 3) came first); and a deviation
    /// whose closed-form spacing rounds to a count one short (found by search), which the
    /// stepping past rounding must catch.
    #[test]
    fn segments_are_the_fewest_cells_that_meet_the_limits() {
        let quadratic = |uu, uv, vv| DerivativeBound {
            uu,
            uv,
            vv,
            ..Default::default()
        };
        let edge = DerivativeBound {
            u: 1.0,
            v: 0.5,
            ..Default::default()
        };
        let limits = |tolerance, max_edge| SamplingLimits {
            tolerance,
            max_edge,
            max_angle: f64::INFINITY,
        };
        let cases = [
            (
                quadratic(1.0, 0.5, 2.0),
                (1.0, 2.0),
                limits(0.01, f64::INFINITY),
            ),
            (edge, (3.0, 2.0), limits(f64::INFINITY, 0.3)),
            (
                quadratic(1e-3, 0.0, 1e-3),
                (10.0, 10.0),
                limits(1.0, f64::INFINITY),
            ),
            (
                quadratic(1.0, 0.25, 0.0),
                (1.0, 1.0),
                limits(1e-3, f64::INFINITY),
            ),
            (edge, (1.0, 1.0), limits(f64::INFINITY, 1.2)),
            (
                quadratic(0.0, 0.0, 1.1394882591841724),
                (1.0, 1.0),
                limits(0.0004396173839445109, f64::INFINITY),
            ),
        ];
        let cap = 64;
        for (k, (bound, (width_u, width_v), limits)) in cases.into_iter().enumerate() {
            let allows = |n_u: u32, n_v: u32| {
                bound.allows(width_u / f64::from(n_u), width_v / f64::from(n_v), limits)
            };
            let fewest = (1..=cap)
                .filter_map(|n_u| (1..=cap).find(|&n_v| allows(n_u, n_v)).map(|n_v| n_u * n_v))
                .min()
                .expect("the cases meet their limits under the cap");
            let (n_u, n_v) = bound.segments((width_u, width_v), limits, cap);
            assert!(
                allows(n_u, n_v),
                "case {k}: ({n_u}, {n_v}) misses the limits"
            );
            assert_eq!(n_u * n_v, fewest, "case {k}: ({n_u}, {n_v})");
        }
    }

    /// The bound by magnitudes holds, nearly tight, where the weights' own differences
    /// carry it: a straight strip run at uneven speed (degree 2 along u, weights 1, 2, 1:
    /// S_uu up to 9.92 against a bound of 10.14, of which W_uu·R/w_min gives 2; the same
    /// strip along v, S_vv) and a twisted
    /// bilinear patch with weights (1, ½; ½, 1) (S_uv up to 15.7 against 16.1, W_uv·R/w_min
    /// 2.3 of it), and a twisted ruled one with weights 1, 4 along u (S_uv up to 3.98
    /// against its rows' bound of 4). Each term the quotient rule adds is needed there.
    #[test]
    fn the_bound_by_magnitudes_holds_where_the_weights_bend_the_parametrisation() {
        let rational = |degree_u: usize, corners: &[(f64, f64, f64, f64)]| BezierPatch {
            degree_u,
            degree_v: 1,
            points: (corners.iter())
                .map(|&(x, y, z, w)| DVec4::new(x * w, y * w, z * w, w))
                .collect(),
            range_u: Interval::new(0.0, 1.0),
            range_v: Interval::new(0.0, 1.0),
        };
        let strip = rational(
            2,
            &[
                (0.0, 0.0, 0.0, 1.0),
                (0.5, 0.0, 0.0, 2.0),
                (1.0, 0.0, 0.0, 1.0),
                (0.0, 0.0625, 0.0, 1.0),
                (0.5, 0.0625, 0.0, 2.0),
                (1.0, 0.0625, 0.0, 1.0),
            ],
        );
        let twisted = rational(
            1,
            &[
                (1.0, 0.0, 0.5, 1.0),
                (0.0, -0.5, -1.0, 0.5),
                (0.0, 1.0, -1.0, 0.5),
                (1.0, 0.0, 0.5, 1.0),
            ],
        );
        // Ruled (weights equal along v), its rows' differences (0, 1, 0) and (0, 1, 1) over
        // weights 1 and 4: S_uv = 4·(0, 0, 1)/w(u)², the ruled bound's W·R term exact.
        let ruled = rational(
            1,
            &[
                (0.0, 0.0, 0.0, 1.0),
                (1.0, 0.0, 0.0, 4.0),
                (0.0, 1.0, 0.0, 1.0),
                (1.0, 1.0, 1.0, 4.0),
            ],
        );
        // The strip run along v instead: S_vv's weight term the same way.
        let (row, rows) = (strip.degree_u + 1, strip.degree_v + 1);
        let strip_along_v = BezierPatch {
            degree_u: strip.degree_v,
            degree_v: strip.degree_u,
            points: (0..row * rows)
                .map(|k| strip.points[(k % rows) * row + k / rows])
                .collect(),
            range_u: strip.range_v,
            range_v: strip.range_u,
        };
        for (name, patch, component, within) in [
            ("strip", strip, 2, 0.95),
            ("strip along v", strip_along_v, 4, 0.95),
            ("twisted", twisted, 3, 0.95),
            ("ruled", ruled, 3, 0.99),
        ] {
            let bounds = components(patch.magnitude_bound());
            let most = sampled(&patch);
            for c in 0..5 {
                // (Second differences where S is straight: rounding of ~1e-7.)
                assert!(
                    most[c] <= bounds[c] * (1.0 + 1e-5) + 1e-6,
                    "{name}, component {c}: {} > {}",
                    most[c],
                    bounds[c]
                );
            }
            assert!(
                most[component] >= within * bounds[component],
                "{name}: {} against {}",
                most[component],
                bounds[component]
            );
        }
    }

    /// Both bounds of a rational patch stay the same when it is moved 2²⁰ away, as its
    /// derivatives do: to 1e-9 of each (measured: 2e-11; the moved homogeneous points are
    /// rounded to ~2²⁰·2⁻⁵² ≈ 2e-10 of the patch's size 4).
    #[test]
    fn the_bounds_do_not_depend_on_where_the_patch_lies() {
        let near = patch();
        let offset = DVec3::new(1048576.0, -524288.0, 262144.0);
        let far = BezierPatch {
            points: (near.points.iter())
                .map(|h| ((h.truncate() / h.w + offset) * h.w).extend(h.w))
                .collect(),
            ..near.clone()
        };
        for (name, here, there) in [
            ("magnitudes", near.magnitude_bound(), far.magnitude_bound()),
            (
                "quotient",
                near.quotient_bound().expect("positive weights"),
                far.quotient_bound().expect("positive weights"),
            ),
        ] {
            assert_same_bounds(name, here, there, 1e-9);
        }
    }

    /// An overall scale of the weights leaves a rational patch as it was, and the bound by
    /// magnitudes with it (to rounding); at weights ~1e-120 the cube of w underflows to
    /// zero, and the quotient bound is refused rather than divided by it: the kept bound is
    /// the magnitudes'.
    #[test]
    fn weights_whose_cube_underflows_keep_the_bound_by_magnitudes() {
        let patch = patch();
        let tiny = BezierPatch {
            points: patch.points.iter().map(|h| *h * 1e-120).collect(),
            ..patch.clone()
        };
        let there = tiny.magnitude_bound();
        assert_same_bounds("magnitudes", patch.magnitude_bound(), there, 1e-14);
        assert!(patch.quotient_bound().is_some());
        assert_eq!(tiny.quotient_bound(), None);
        assert_eq!(tiny.derivative_bound(), there);
    }

    /// Ruled patches (degree 1 along v, weights equal along v) get |S_uv| from their rows'
    /// differences: 0 on a quarter cylinder (to rounding; the general bound by magnitudes,
    /// whose quotient-rule terms W_u·G_v do not cancel, is 6 there), and on a quarter
    /// of a cone (z in [1, 2]), whose S_uv is the radial rate, it holds, within 1.9×. The
    /// same with u and v exchanged.
    #[test]
    fn ruled_patches_bound_their_twist_by_their_rows_differences() {
        use crate::geom::shapes::{elliptic_cone, elliptic_cylinder};
        let quarter = Interval::new(0.0, std::f64::consts::FRAC_PI_2);
        let first = |surface: crate::geom::BSplineSurface| surface.bezier_patches()[0].clone();
        let cylinder = first(
            elliptic_cylinder(DVec3::ZERO, 2.0, 2.0, quarter, Interval::new(0.0, 3.0)).unwrap(),
        );
        let cone =
            first(elliptic_cone(DVec3::ZERO, 1.0, 1.0, quarter, Interval::new(1.0, 2.0)).unwrap());
        for patch in [&cylinder, &cone] {
            assert_eq!((patch.degree_u, patch.degree_v), (2, 1));
        }
        // The same patches with u and v exchanged: ruled along u.
        let transposed = |patch: &BezierPatch| BezierPatch {
            degree_u: patch.degree_v,
            degree_v: patch.degree_u,
            points: (0..patch.points.len())
                .map(|k| patch.points[(k % 2) * 3 + k / 2])
                .collect(),
            range_u: patch.range_v,
            range_v: patch.range_u,
        };
        for (name, cylinder, cone) in [
            ("ruled along v", cylinder.clone(), cone.clone()),
            ("ruled along u", transposed(&cylinder), transposed(&cone)),
        ] {
            let twist = cylinder.magnitude_bound().uv;
            assert!(twist <= 1e-12, "{name}: {twist:e}");
            let cone_twist = cone.magnitude_bound().uv;
            let most = sampled(&cone)[3];
            assert!(
                most > 0.5 && most <= cone_twist * (1.0 + 1e-5) + 1e-9,
                "{name}: {most} vs {cone_twist}"
            );
            // As tight as a first derivative's bound of the quarter circle of differences
            // (1.83× here; the largest weight term |w₁ − w₀|, not a sum, and each row's own
            // weight on its own difference from the centre).
            assert!(cone_twist <= 1.9 * most, "{name}: {cone_twist} vs {most}");
        }
    }

    /// A polynomial patch (all weights equal, here 2) keeps its bound by magnitudes as it
    /// is: the quotient bound, formed from products of Bernstein polynomials, is for
    /// rational patches only. (On a polynomial patch its products amount to degree
    /// elevation, which tightens the control net's hull: |S_v| 1.95 against 2.59 here.)
    #[test]
    fn a_polynomial_patch_keeps_its_bound_by_magnitudes() {
        let rational = patch();
        let polynomial = BezierPatch {
            points: (rational.points.iter())
                .map(|h| (h.truncate() / h.w * 2.0).extend(2.0))
                .collect(),
            ..rational.clone()
        };
        let cheap = polynomial.magnitude_bound();
        let quotient = polynomial.quotient_bound().expect("positive weights");
        assert!(quotient.v < 0.8 * cheap.v, "{quotient:?} vs {cheap:?}");
        assert_eq!(polynomial.derivative_bound(), cheap);
    }

    /// The bound by magnitudes of a biquadratic net P_ij = (i², j², i·j) + offset over
    /// [1, 3] × [−1, 0.5] is the surface's true largest derivatives, in closed form: its
    /// second differences are constant ((2, 0, 0) along u, (0, 2, 0) along v, (0, 0, 1)
    /// mixed), so S_uu = 2·Δ²/w_u² everywhere (likewise S_vv, S_uv = 4·Δ_uv/(w_u·w_v)), and
    /// |S_u| = 2·|Δ_u|/w_u is largest at the corner where |Δ_u P| = |(3, 0, 2)| is (|S_v|
    /// likewise, (0, 3, 2)). Each difference and each scale by the ranges' widths shows.
    #[test]
    fn the_bound_by_magnitudes_of_a_biquadratic_net_is_its_closed_form() {
        let offset = DVec3::new(-40.0, 7.0, 1.0e3);
        let points = (0..9)
            .map(|k| {
                let (i, j) = ((k % 3) as f64, (k / 3) as f64);
                (DVec3::new(i * i, j * j, i * j) + offset).extend(1.0)
            })
            .collect();
        let net = BezierPatch {
            degree_u: 2,
            degree_v: 2,
            points,
            range_u: Interval::new(1.0, 3.0),
            range_v: Interval::new(-1.0, 0.5),
        };
        let (wu, wv) = (2.0, 1.5);
        let want = [
            2.0 * 13f64.sqrt() / wu,
            2.0 * 13f64.sqrt() / wv,
            4.0 / (wu * wu),
            4.0 / (wu * wv),
            4.0 / (wv * wv),
        ];
        let bound = components(net.magnitude_bound());
        for (c, (got, want)) in bound.into_iter().zip(want).enumerate() {
            assert!(
                (got - want).abs() <= 1e-12 * want,
                "component {c}: {got} vs {want}"
            );
        }
        // And they are the surface's own largest values (central differences).
        for (c, (most, want)) in sampled(&net).into_iter().zip(want).enumerate() {
            assert!(
                (most - want).abs() <= 1e-3 * want,
                "component {c}: {most} vs {want}"
            );
        }
    }
}
