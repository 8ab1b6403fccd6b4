//! A sum of f64 terms that does not depend on their order or grouping: each term is rounded once
//! to a multiple of 2⁻⁶⁴ (which changes no term of magnitude 2⁻¹² or more: its last bit is
//! coarser) and added as an integer, so sums made in parts (threads, shards) and added in any
//! grouping are the same bit for bit. The comparison's quantile search sums its weights (cell
//! areas in m², or 1) so that a sharded comparison finds the quantiles one process finds.

/// 2⁶⁴: the terms' fixed point.
const SCALE: f64 = 18_446_744_073_709_551_616.0;

/// The sum, in units of 2⁻⁶⁴ (room for sums of magnitude up to 2⁶³ ≈ 9.2·10¹⁸: the Earth's
/// area is 5.1·10¹⁴ m²; past it the sum saturates).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExactSum(i128);

impl ExactSum {
    /// Adds a term (NaN adds nothing).
    pub fn add(&mut self, x: f64) {
        self.0 = self.0.saturating_add((x * SCALE) as i128);
    }

    /// Adds another sum.
    pub fn join(&mut self, other: ExactSum) {
        self.0 = self.0.saturating_add(other.0);
    }

    /// The sum, rounded once to the nearest f64.
    pub fn value(self) -> f64 {
        self.0 as f64 / SCALE
    }

    /// The sum's units of 2⁻⁶⁴ (to write it down exactly).
    pub fn units(self) -> i128 {
        self.0
    }

    /// A sum from its units.
    pub fn from_units(units: i128) -> ExactSum {
        ExactSum(units)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sum_is_the_same_in_any_order_and_grouping_and_exact_where_f64_is() {
        let terms: Vec<f64> =
            (0..10_000u32).map(|k| 1.0 + f64::from(crate::maths::pcg(k) % 1_000_000) * 1.37e-3).collect();
        let mut forward = ExactSum::default();
        terms.iter().for_each(|&t| forward.add(t));
        let mut backward = ExactSum::default();
        terms.iter().rev().for_each(|&t| backward.add(t));
        let mut parts = ExactSum::default();
        for chunk in terms.chunks(777).rev() {
            let mut part = ExactSum::default();
            chunk.iter().for_each(|&t| part.add(t));
            parts.join(part);
        }
        assert_eq!(forward, backward);
        assert_eq!(forward, parts);
        // f64 summation depends on the order here; the exact sum is within an f64 rounding of
        // the true one (compensated summation as the check).
        let naive_forward: f64 = terms.iter().sum();
        let naive_backward: f64 = terms.iter().rev().sum();
        assert_ne!(naive_forward.to_bits(), naive_backward.to_bits(), "pick terms whose f64 sum depends on order");
        let (mut s, mut c) = (0f64, 0f64);
        for &t in &terms {
            let y = t - c;
            let u = s + y;
            c = (u - s) - y;
            s = u;
        }
        assert!((forward.value() - s).abs() <= s * f64::EPSILON, "{} {s}", forward.value());
        // Terms of 2⁻¹² and more are kept exactly; NaN adds nothing.
        let mut small = ExactSum::default();
        small.add(2f64.powi(-12));
        small.add(f64::NAN);
        assert_eq!(small.value(), 2f64.powi(-12));
        assert_eq!(ExactSum::from_units(forward.units()), forward);
    }
}
