//! Statistical room-acoustics estimates: Sabine's and Eyring's reverberation times.

use crate::scene::materials::{BAND_COUNT, BandValues};

/// Sabine and Eyring reverberation times per band, seconds:
/// T_Sabine = 24 ln10 V / (c (sum S_i a_i + 4 m V)) and T_Eyring with sum S_i a_i replaced by
/// -S ln(1 - a_mean) (Kuttruff, Room Acoustics, eqs. 5.24 and 5.29; test values in
/// docs/acoustics.md, Reference values).
/// `areas_m2[i]` and `absorption[i]` belong to surface i; `air_per_m` is m per band.
pub fn reverberation_times(
    volume_m3: f64,
    areas_m2: &[f64],
    absorption: &[BandValues],
    air_per_m: &BandValues,
    speed_m_s: f64,
) -> ([f64; BAND_COUNT], [f64; BAND_COUNT]) {
    let total_area: f64 = areas_m2.iter().sum();
    let mut sabine = [f64::INFINITY; BAND_COUNT];
    let mut eyring = [f64::INFINITY; BAND_COUNT];
    let k = 24.0 * std::f64::consts::LN_10 * volume_m3 / speed_m_s;
    for b in 0..BAND_COUNT {
        let equivalent: f64 = areas_m2.iter().zip(absorption).map(|(s, a)| s * f64::from(a[b])).sum();
        let air = 4.0 * f64::from(air_per_m[b]) * volume_m3;
        let mean = (equivalent / total_area).min(1.0 - 1e-12);
        sabine[b] = k / (equivalent + air);
        eyring[b] = k / (-total_area * (1.0 - mean).ln() + air);
    }
    (sabine, eyring)
}

/// Reverberation time of a diffuse field whose free path lengths have relative variance
/// `gamma2` (Kuttruff, Room Acoustics, sec. 5.5): the decay rate of Eyring's formula times
/// (1 + gamma^2 / 2 ln(1 - a)). Rays that travel longer between reflections lose energy more
/// slowly, so with any spread of path lengths the decay is slower than Eyring's.
pub fn kuttruff_time_s(
    volume_m3: f64,
    area_m2: f64,
    mean_absorption: f64,
    air_per_m: f64,
    gamma2: f64,
    speed_m_s: f64,
) -> f64 {
    let l = (1.0 - mean_absorption).ln();
    let surface = -area_m2 * l * (1.0 + 0.5 * gamma2 * l);
    24.0 * std::f64::consts::LN_10 * volume_m3 / (speed_m_s * (surface + 4.0 * air_per_m * volume_m3))
}

/// Mean and relative variance (gamma^2 = var / mean^2) of the free path length between
/// diffuse (Lambert) reflections in a `size` box: chords from uniform points on the walls in
/// cosine-distributed directions, by Monte Carlo. The mean is 4V/S (Kuttruff eq. 4.2).
pub fn box_free_path_statistics(size: [f64; 3], samples: u64, seed: u64) -> (f64, f64) {
    use crate::core::rng::{stream, uniform};
    let [x, y, z] = size;
    let faces = [(x * y, 2), (x * y, 2), (x * z, 1), (x * z, 1), (y * z, 0), (y * z, 0)];
    let total: f64 = faces.iter().map(|f| f.0).sum();
    let (mut sum, mut sum2) = (0.0, 0.0);
    for i in 0..samples {
        let mut r = stream(seed, 0xc40d, i);
        let mut pick = f64::from(uniform(&mut r)) * total;
        let mut face = 0;
        while face < 5 && pick >= faces[face].0 {
            pick -= faces[face].0;
            face += 1;
        }
        let axis = faces[face].1;
        let high = face % 2 == 1;
        let mut p =
            [f64::from(uniform(&mut r)) * x, f64::from(uniform(&mut r)) * y, f64::from(uniform(&mut r)) * z];
        p[axis] = if high { size[axis] } else { 0.0 };
        let (u1, u2) = (f64::from(uniform(&mut r)), f64::from(uniform(&mut r)));
        let (rho, phi) = (u1.sqrt(), std::f64::consts::TAU * u2);
        let mut d = [0.0; 3];
        let others: Vec<usize> = (0..3).filter(|&k| k != axis).collect();
        d[others[0]] = rho * phi.cos();
        d[others[1]] = rho * phi.sin();
        d[axis] = (1.0 - u1).sqrt() * if high { -1.0 } else { 1.0 };
        let mut t = f64::INFINITY;
        for k in 0..3 {
            if d[k] > 0.0 {
                t = t.min((size[k] - p[k]) / d[k]);
            } else if d[k] < 0.0 {
                t = t.min(-p[k] / d[k]);
            }
        }
        sum += t;
        sum2 += t * t;
    }
    let n = samples as f64;
    let mean = sum / n;
    (mean, (sum2 / n - mean * mean) / (mean * mean))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shoebox_values_from_design_notes() {
        // 10 x 8 x 3 m, c = 343: a = 0.1 -> Sabine 1.443 s, Eyring 1.369 s;
        // a = 0.3 -> 0.481 s, 0.405 s.
        for (a, s, e) in [(0.1f32, 1.443, 1.369), (0.3, 0.481, 0.405)] {
            let (sab, eyr) =
                reverberation_times(240.0, &[268.0], &[[a; BAND_COUNT]], &[0.0; BAND_COUNT], 343.0);
            assert!((sab[3] - s).abs() < 0.001, "{}", sab[3]);
            assert!((eyr[3] - e).abs() < 0.001, "{}", eyr[3]);
        }
    }

    #[test]
    fn free_path_mean_is_four_v_over_s_and_variance_reduces_to_eyring() {
        let (mean, gamma2) = box_free_path_statistics([10.0, 8.0, 3.0], 200_000, 1);
        assert!((mean - 4.0 * 240.0 / 268.0).abs() < 0.01 * mean, "{mean}");
        assert!(gamma2 > 0.3 && gamma2 < 0.5, "{gamma2}");
        // gamma^2 = 0 is Eyring's formula.
        let e = kuttruff_time_s(240.0, 268.0, 0.3, 0.0, 0.0, 343.0);
        assert!((e - 0.405).abs() < 0.001);
        assert!(kuttruff_time_s(240.0, 268.0, 0.3, 0.0, gamma2, 343.0) > e * 1.05);
    }
}
