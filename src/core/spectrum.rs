//! Fixed-size sets of per-band values (RGB, octave bands) with element-wise arithmetic.

use std::ops::{Add, AddAssign, Index, IndexMut, Mul, MulAssign};

/// `N` values, one per band, with element-wise arithmetic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spectrum<const N: usize>(pub [f32; N]);

impl<const N: usize> Spectrum<N> {
    /// Every value 0.
    pub const ZERO: Self = Self([0.0; N]);
    /// Every value 1.
    pub const ONE: Self = Self([1.0; N]);

    /// Every value `v`.
    pub fn splat(v: f32) -> Self {
        Self([v; N])
    }

    /// `f` applied to every value.
    pub fn map(self, f: impl Fn(f32) -> f32) -> Self {
        Self(self.0.map(f))
    }

    /// The largest value.
    pub fn max_value(&self) -> f32 {
        self.0.iter().copied().fold(f32::NEG_INFINITY, f32::max)
    }

    /// The sum of the values.
    pub fn sum(&self) -> f32 {
        self.0.iter().sum()
    }

    /// Whether every value is finite.
    pub fn is_finite(&self) -> bool {
        self.0.iter().all(|v| v.is_finite())
    }
}

impl<const N: usize> Default for Spectrum<N> {
    fn default() -> Self {
        Self::ZERO
    }
}

impl<const N: usize> Index<usize> for Spectrum<N> {
    type Output = f32;
    fn index(&self, i: usize) -> &f32 {
        &self.0[i]
    }
}

impl<const N: usize> IndexMut<usize> for Spectrum<N> {
    fn index_mut(&mut self, i: usize) -> &mut f32 {
        &mut self.0[i]
    }
}

impl<const N: usize> Add for Spectrum<N> {
    type Output = Self;
    fn add(mut self, o: Self) -> Self {
        self += o;
        self
    }
}

impl<const N: usize> AddAssign for Spectrum<N> {
    fn add_assign(&mut self, o: Self) {
        for (a, b) in self.0.iter_mut().zip(o.0) {
            *a += b;
        }
    }
}

impl<const N: usize> Mul for Spectrum<N> {
    type Output = Self;
    fn mul(mut self, o: Self) -> Self {
        self *= o;
        self
    }
}

impl<const N: usize> MulAssign for Spectrum<N> {
    fn mul_assign(&mut self, o: Self) {
        for (a, b) in self.0.iter_mut().zip(o.0) {
            *a *= b;
        }
    }
}

impl<const N: usize> Mul<f32> for Spectrum<N> {
    type Output = Self;
    fn mul(self, s: f32) -> Self {
        self.map(|v| v * s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elementwise_arithmetic() {
        let a = Spectrum([1.0, 2.0, 3.0]);
        let b = Spectrum([0.5, 0.5, 2.0]);
        assert_eq!((a * b).0, [0.5, 1.0, 6.0]);
        assert_eq!((a + b).0, [1.5, 2.5, 5.0]);
        assert_eq!((a * 2.0).0, [2.0, 4.0, 6.0]);
        assert_eq!(a.max_value(), 3.0);
        assert_eq!(a.sum(), 6.0);
        assert!(!Spectrum([f32::NAN, 0.0]).is_finite());
    }
}
