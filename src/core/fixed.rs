//! Fixed-point sums: integer addition is associative, so a total added up in any order (any
//! thread count, any split over MPI ranks) is the same to the last bit, unlike a float sum.

/// Fractional bits of the fixed-point scale relative to a caller-chosen unit: values are
/// kept to `unit / 2^64`, and a sum may reach `2^64 unit` before it saturates.
pub const FRACTION_BITS: i32 = 64;

/// `value / unit` in fixed point (negative and NaN values count as 0).
#[inline]
pub fn to_fixed(value: f64, unit: f64) -> u128 {
    // `as` saturates: huge values clamp to u128::MAX instead of wrapping.
    (value / unit * 2f64.powi(FRACTION_BITS)).round() as u128
}

/// The value of a fixed-point sum, in the units it was made with.
#[inline]
pub fn from_fixed(sum: u128, unit: f64) -> f64 {
    sum as f64 * unit * 2f64.powi(-FRACTION_BITS)
}

/// Adds `value` to a fixed-point sum, saturating instead of wrapping.
#[inline]
pub fn add_fixed(sum: &mut u128, value: f64, unit: f64) {
    *sum = sum.saturating_add(to_fixed(value, unit));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_sums_round_trip_and_do_not_depend_on_order() {
        let unit = 1.0e-6;
        let values: Vec<f64> =
            (0..1000).map(|i| 1e-6 * (1.0 + (i as f64 * 0.7).sin()) * 10f64.powi(-(i % 12))).collect();
        let mut forward = 0u128;
        let mut backward = 0u128;
        for v in &values {
            add_fixed(&mut forward, *v, unit);
        }
        for v in values.iter().rev() {
            add_fixed(&mut backward, *v, unit);
        }
        assert_eq!(forward, backward);
        let exact: f64 = values.iter().sum();
        assert!((from_fixed(forward, unit) - exact).abs() < 1e-12 * exact);
        // A value 10^-15 of the unit keeps about 4 significant digits.
        let tiny = 1e-15 * unit;
        assert!((from_fixed(to_fixed(tiny, unit), unit) - tiny).abs() < 1e-3 * tiny);
        assert_eq!(to_fixed(-1.0, unit), 0);
        assert_eq!(to_fixed(f64::NAN, unit), 0);
    }
}
