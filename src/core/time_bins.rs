//! The arrival-time bins of an energy histogram: the one place that turns a path length into
//! a bin, so that every estimator filling the same histogram (stochastic rays, image sources)
//! puts an arrival in the same bin, at the same precision.

/// Histogram bins of width `bin_s` over `[0, bins * bin_s)` for waves travelling at
/// `speed_m_s`: a path of length `L` arrives at `t = L / c` and falls in bin `floor(t / dt)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeBins {
    /// Propagation speed, m/s.
    pub speed_m_s: f64,
    /// Bin width, seconds.
    pub bin_s: f64,
    /// Number of bins.
    pub bins: usize,
}

impl TimeBins {
    /// The bin a path of `path_m` metres arrives in, `floor(path_m / c / dt)` (computed in
    /// f64 whatever the caller's precision); `None` past the last bin, and for a negative or
    /// non-finite length or bin (a zero speed or width).
    #[inline]
    pub fn bin_of_path(&self, path_m: f64) -> Option<usize> {
        let k = path_m / self.speed_m_s / self.bin_s;
        if k.is_nan() || k < 0.0 || k >= self.bins as f64 {
            return None;
        }
        Some(k as usize)
    }

    /// Arrival time of a path of `path_m` metres, seconds.
    #[inline]
    pub fn arrival_s(&self, path_m: f64) -> f64 {
        path_m / self.speed_m_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const BINS: TimeBins = TimeBins { speed_m_s: 343.0, bin_s: 1e-3, bins: 100 };

    #[test]
    fn a_path_falls_in_the_bin_of_its_arrival_time() {
        // 0.343 m per bin: the middle of bin k is at (k + 1/2) 0.343 m.
        for k in [0usize, 1, 7, 42, 99] {
            assert_eq!(BINS.bin_of_path((k as f64 + 0.5) * 0.343), Some(k));
        }
        // Just either side of the edge between bins 9 and 10 (3.43 m, 10 ms).
        assert_eq!(BINS.bin_of_path(3.43 * (1.0 - 1e-9)), Some(9));
        assert_eq!(BINS.bin_of_path(3.43 * (1.0 + 1e-9)), Some(10));
        assert!((BINS.arrival_s(3.43) - 0.01).abs() < 1e-15);
    }

    #[test]
    fn lengths_outside_the_histogram_have_no_bin() {
        assert_eq!(BINS.bin_of_path(100.0 * 0.343 * (1.0 + 1e-9)), None);
        assert_eq!(BINS.bin_of_path(1e300), None);
        assert_eq!(BINS.bin_of_path(-1e-9), None);
        assert_eq!(BINS.bin_of_path(f64::NAN), None);
        assert_eq!(BINS.bin_of_path(f64::INFINITY), None);
        assert_eq!(TimeBins { speed_m_s: 0.0, ..BINS }.bin_of_path(1.0), None);
        assert_eq!(TimeBins { bin_s: 0.0, ..BINS }.bin_of_path(0.0), None);
        assert_eq!(TimeBins { bins: 0, ..BINS }.bin_of_path(0.0), None);
    }
}
