//! Reproducible random streams: one independent PCG stream per (seed, work item), so results
//! do not depend on how items are spread over threads or processes.

use rand::{RngCore, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// The random generator used everywhere in propsim (PCG-64 MCG, O'Neill 2014).
pub type Rng64 = Pcg64Mcg;

/// SplitMix64 finaliser (Steele, Lea, Flood 2014): a bijective 64-bit mix.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The generator for work item `index` (a pixel, a ray, a cell) of a run seeded by `seed`.
/// `domain` separates independent uses of the same index (e.g. camera vs. light sampling).
#[inline]
pub fn stream(seed: u64, domain: u64, index: u64) -> Rng64 {
    let key = mix64(mix64(mix64(seed) ^ domain.wrapping_mul(0xD6E8_FEB8_6659_FD93)) ^ index);
    let lo = mix64(key);
    let hi = mix64(key ^ 0xA076_1D64_78BD_642F);
    Rng64::from_seed(((u128::from(hi) << 64) | u128::from(lo)).to_le_bytes())
}

/// A new independent stream drawn from `rng` (for a copy of a split ray): its key is two
/// draws of `rng`, mixed as in [`stream`]. Deterministic: the same `rng` state forks the
/// same stream.
pub fn fork(rng: &mut Rng64) -> Rng64 {
    let key = mix64(rng.next_u64()) ^ rng.next_u64();
    let lo = mix64(key);
    let hi = mix64(key ^ 0xA076_1D64_78BD_642F);
    Rng64::from_seed(((u128::from(hi) << 64) | u128::from(lo)).to_le_bytes())
}

/// A uniform float in `[0, 1)` with 24 random bits.
#[inline]
pub fn uniform(rng: &mut Rng64) -> f32 {
    (rng.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_key_same_stream_different_key_different_stream() {
        let a: Vec<u32> = (0..4).map(|_| 0).scan(stream(7, 1, 42), |r, _| Some(r.next_u32())).collect();
        let b: Vec<u32> = (0..4).map(|_| 0).scan(stream(7, 1, 42), |r, _| Some(r.next_u32())).collect();
        let c: Vec<u32> = (0..4).map(|_| 0).scan(stream(7, 1, 43), |r, _| Some(r.next_u32())).collect();
        let d: Vec<u32> = (0..4).map(|_| 0).scan(stream(7, 2, 42), |r, _| Some(r.next_u32())).collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert_ne!(a, d);
    }

    #[test]
    fn forks_are_reproducible_and_differ_from_each_other_and_the_parent() {
        let draw = |r: &mut Rng64| (0..4).map(|_| r.next_u32()).collect::<Vec<u32>>();
        let (mut a, mut b) = (stream(7, 1, 42), stream(7, 1, 42));
        let (fa1, fa2) = (draw(&mut fork(&mut a)), draw(&mut fork(&mut a)));
        let (fb1, fb2) = (draw(&mut fork(&mut b)), draw(&mut fork(&mut b)));
        assert_eq!((&fa1, &fa2), (&fb1, &fb2));
        assert_ne!(fa1, fa2);
        assert_ne!(fa1, draw(&mut a));
    }

    #[test]
    fn uniform_is_in_unit_interval_with_right_mean() {
        let mut r = stream(1, 0, 0);
        let n = 100_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let u = uniform(&mut r);
            assert!((0.0..1.0).contains(&u));
            sum += f64::from(u);
        }
        // Standard error of the mean: sqrt(1/12 / n) ~ 0.0009.
        assert!((sum / f64::from(n) - 0.5).abs() < 0.005);
    }
}
