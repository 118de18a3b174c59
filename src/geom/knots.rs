//! Knot vectors: validated at construction, with span lookup.

use crate::error::{Error, Result};

/// Highest polynomial degree knotwork accepts in either direction (the OBJ limit).
pub const MAX_DEGREE: usize = 20;

/// A validated knot vector together with the degree it belongs to.
///
/// Invariants (checked by [`KnotVector::try_new`]): degree in 1..=[`MAX_DEGREE`]; every knot
/// finite; knots non-decreasing; at least 2·(degree+1) knots, so at least degree+1 control
/// points; a non-empty domain `[knot[degree], knot[n]]` where n = len − degree − 1 is the
/// number of control points; multiplicity at most degree+1 for a run touching either end of
/// the vector and at most degree for every interior run.
#[derive(Debug, Clone, PartialEq)]
pub struct KnotVector {
    degree: usize,
    knots: Vec<f64>,
}

impl KnotVector {
    /// Validates `knots` for `degree`.
    pub fn try_new(degree: usize, knots: Vec<f64>) -> Result<Self> {
        check_degree(degree)?;
        for (index, &value) in knots.iter().enumerate() {
            if !value.is_finite() {
                return Err(Error::KnotNotFinite { index, value });
            }
        }
        for index in 1..knots.len() {
            if knots[index] < knots[index - 1] {
                return Err(Error::KnotsDecreasing {
                    index,
                    previous: knots[index - 1],
                    value: knots[index],
                });
            }
        }
        let min = 2 * (degree + 1);
        if knots.len() < min {
            return Err(Error::TooFewKnots {
                found: knots.len(),
                degree,
                min,
            });
        }
        let mut start = 0;
        for run in knots.chunk_by(|a, b| a == b) {
            let (multiplicity, end) = (run.len(), start + run.len());
            let touches_end = start == 0 || end == knots.len();
            let max = if touches_end { degree + 1 } else { degree };
            if multiplicity > max {
                return Err(Error::KnotMultiplicity {
                    index: start,
                    value: knots[start],
                    multiplicity,
                    max,
                });
            }
            start = end;
        }
        let n = knots.len() - degree - 1;
        if knots[degree] >= knots[n] {
            return Err(Error::EmptyDomain {
                start: knots[degree],
                end: knots[n],
            });
        }
        Ok(Self { degree, knots })
    }

    /// The clamped uniform ("standard", open uniform) vector for `count` control points:
    /// degree+1 zeros, then 1, 2, …, then degree+1 copies of count − degree.
    /// For 8 points of degree 3: (0,0,0,0,1,2,3,4,5,5,5,5).
    pub fn clamped_uniform(degree: usize, count: usize) -> Result<Self> {
        check_degree(degree)?;
        if count < degree + 1 {
            return Err(Error::ControlPointCount {
                expected: degree + 1,
                found: count,
                what: "at least degree + 1",
            });
        }
        let last = (count - degree) as f64;
        let knots = (0..count + degree + 1)
            .map(|i| (i as f64 - degree as f64).clamp(0.0, last))
            .collect();
        Self::try_new(degree, knots)
    }

    /// The uniform (periodic, unclamped) vector 0, 1, …, count + degree for `count` control
    /// points; its domain is [degree, count].
    pub fn uniform(degree: usize, count: usize) -> Result<Self> {
        check_degree(degree)?;
        if count < degree + 1 {
            return Err(Error::ControlPointCount {
                expected: degree + 1,
                found: count,
                what: "at least degree + 1",
            });
        }
        Self::try_new(degree, (0..count + degree + 1).map(|i| i as f64).collect())
    }

    /// The breakpoints of a vector that is already that of a piecewise Bezier (the form
    /// [`KnotVector::from_breakpoints`] makes: ends degree+1 times, interior knots exactly
    /// degree times), else `None`.
    pub fn bezier_breakpoints(&self) -> Option<Vec<f64>> {
        let p = self.degree;
        // A piecewise Bezier vector has (knots − 2) / p breakpoints.
        let mut breaks = Vec::with_capacity(self.knots.len().saturating_sub(2) / p.max(1));
        let mut groups = self.knots.chunk_by(|a, b| a == b).peekable();
        while let Some(group) = groups.next() {
            let ends = breaks.is_empty() || groups.peek().is_none();
            if group.len() != if ends { p + 1 } else { p } {
                return None;
            }
            breaks.push(group[0]);
        }
        Some(breaks)
    }

    /// The clamped vector of a piecewise Bezier with the given strictly increasing
    /// breakpoints: end breakpoints repeated degree+1 times, interior ones degree times.
    pub fn from_breakpoints(degree: usize, breakpoints: &[f64]) -> Result<Self> {
        check_degree(degree)?;
        if breakpoints.len() < 2 {
            return Err(Error::TooFewKnots {
                found: breakpoints.len(),
                degree: 1,
                min: 2,
            });
        }
        for (index, &value) in breakpoints.iter().enumerate() {
            if !value.is_finite() {
                return Err(Error::KnotNotFinite { index, value });
            }
            if index > 0 && value <= breakpoints[index - 1] {
                return Err(Error::BreakpointsNotIncreasing { index, value });
            }
        }
        let last = breakpoints.len() - 1;
        let mut knots = Vec::with_capacity(degree * (last + 1) + 2);
        for (index, &b) in breakpoints.iter().enumerate() {
            let repeat = if index == 0 || index == last {
                degree + 1
            } else {
                degree
            };
            knots.extend(std::iter::repeat_n(b, repeat));
        }
        Self::try_new(degree, knots)
    }

    pub fn degree(&self) -> usize {
        self.degree
    }

    pub fn knots(&self) -> &[f64] {
        &self.knots
    }

    /// Number of control points this vector serves: len − degree − 1.
    pub fn control_count(&self) -> usize {
        self.knots.len() - self.degree - 1
    }

    /// The parameter domain `[knot[degree], knot[control_count]]`.
    pub fn domain(&self) -> (f64, f64) {
        (self.knots[self.degree], self.knots[self.control_count()])
    }

    /// True when the first and last degree+1 knots are equal (the curve interpolates its
    /// end control points).
    pub fn is_clamped(&self) -> bool {
        let p = self.degree;
        let k = &self.knots;
        k[0] == k[p] && k[k.len() - 1] == k[k.len() - 1 - p]
    }

    /// Index s of the non-empty span `[knot[s], knot[s+1])` holding `u`, with
    /// degree ≤ s < control_count. Values outside the domain are clamped to it; the domain
    /// end maps to the last non-empty span.
    pub fn find_span(&self, u: f64) -> usize {
        let p = self.degree;
        let n = self.control_count();
        let k = &self.knots;
        // At or past the domain's end: the span of the last knot before it.
        if u >= k[n] {
            return k[..n].partition_point(|&x| x < k[n]) - 1;
        }
        // Else the last knot at or below u, held to the domain's start.
        p + k[p + 1..=n].partition_point(|&x| x <= u.max(k[p]))
    }
}

pub(crate) fn check_degree(degree: usize) -> Result<()> {
    if degree == 0 || degree > MAX_DEGREE {
        return Err(Error::DegreeOutOfRange {
            degree,
            max: MAX_DEGREE,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Breakpoints come back from the vectors `from_breakpoints` makes, and from no other.
    #[test]
    fn bezier_breakpoints_recognise_only_piecewise_bezier_vectors() {
        for (degree, breaks) in [
            (1, vec![0.0, 1.0]),
            (3, vec![-1.0, 0.5, 0.75, 4.0]),
            (2, vec![0.0, 1e-6, 1.0]),
        ] {
            let knots = KnotVector::from_breakpoints(degree, &breaks).unwrap();
            assert_eq!(knots.bezier_breakpoints(), Some(breaks), "{knots:?}");
        }
        let not_bezier = [
            (3, vec![0., 0., 0., 0., 0.5, 1., 1., 1., 1.]), // an interior knot once
            (2, vec![0., 0., 0., 0.25, 0.5, 0.5, 1., 1., 1.]), // one interior knot once
            (2, vec![0., 0., 1., 1., 2., 2., 2.]),          // unclamped start
            (1, vec![0., 0., 1., 2.]),                      // unclamped end
        ];
        for (degree, knots) in not_bezier {
            let knots = KnotVector::try_new(degree, knots).unwrap();
            assert_eq!(knots.bezier_breakpoints(), None, "{knots:?}");
        }
    }
}
