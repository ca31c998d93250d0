//! Real spherical harmonics in the AmbiX convention (ACN channel order, SN3D normalisation)
//! up to order 3, and the plane-wave encoding of Ambisonic impulse responses
//! (docs/acoustics.md, Ambisonics).
//!
//! Directions are unit vectors in propsim's frame as the listener sees it: x front, y left,
//! z up (azimuth counter-clockwise from x, elevation up from the horizontal plane), the
//! convention of AmbiX (Nachbar et al. 2011). A plane wave of signal s(t) from the unit
//! direction u gives channel k the signal s(t) Y_k(u).

use glam::DVec3;

/// Highest Ambisonic order supported.
pub const MAX_ORDER: usize = 3;

/// Channels of order `order`: (order + 1)^2.
pub const fn channels(order: usize) -> usize {
    (order + 1) * (order + 1)
}

/// The real spherical harmonics Y_k of the unit vector `d`, k = ACN index n^2 + n + m, SN3D
/// normalisation (Schmidt semi-normalised: Y_0 = 1, and `sum_m Y_nm(u) Y_nm(v) = P_n(u.v)`,
/// so the sphere integral of Y_nm^2 is 4 pi / (2n + 1)), for the first `channels(order)`
/// channels; `order` is capped at [`MAX_ORDER`]. The formulas in Cartesian form are those of
/// docs/acoustics.md, Ambisonics (`d` need not be exactly unit: it is normalised).
pub fn sh_sn3d(d: DVec3, order: usize) -> Vec<f64> {
    let d = d.try_normalize().unwrap_or(DVec3::X);
    let (x, y, z) = (d.x, d.y, d.z);
    let s3 = 3f64.sqrt();
    let all = [
        1.0,
        y,
        z,
        x,
        s3 * x * y,
        s3 * y * z,
        0.5 * (3.0 * z * z - 1.0),
        s3 * x * z,
        0.5 * s3 * (x * x - y * y),
        (5.0f64 / 8.0).sqrt() * y * (3.0 * x * x - y * y),
        15f64.sqrt() * x * y * z,
        (3.0f64 / 8.0).sqrt() * y * (5.0 * z * z - 1.0),
        0.5 * z * (5.0 * z * z - 3.0),
        (3.0f64 / 8.0).sqrt() * x * (5.0 * z * z - 1.0),
        0.5 * 15f64.sqrt() * z * (x * x - y * y),
        (5.0f64 / 8.0).sqrt() * x * (x * x - 3.0 * y * y),
    ];
    all[..channels(order.min(MAX_ORDER))].to_vec()
}

/// The order n of ACN channel k: floor(sqrt(k)).
pub fn order_of(k: usize) -> usize {
    let mut n = 0;
    while (n + 1) * (n + 1) <= k {
        n += 1;
    }
    n
}

/// The direction of the largest response of a basic (mode-matching, N3D-weighted) beam
/// steered over the sphere: `b(v) = sum_k (2 n_k + 1) Y_k(v) c_k`, where `c_k` is a
/// snapshot of the channels (for a plane wave from u, `b(v) = sum_n (2n + 1) P_n(u.v)`,
/// largest at v = u). A grid of 2 degrees, then two refinements at a tenth of the step.
/// Used to check the encoding (a plane wave decodes to its direction).
pub fn steer_peak(c: &[f64]) -> DVec3 {
    let order = order_of(c.len().max(1) - 1);
    let beam = |v: DVec3| -> f64 {
        sh_sn3d(v, order)
            .iter()
            .zip(c)
            .enumerate()
            .map(|(k, (y, ck))| (2 * order_of(k) + 1) as f64 * y * ck)
            .sum()
    };
    let dir = |az: f64, el: f64| DVec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
    let (mut best, mut best_az, mut best_el) = (f64::NEG_INFINITY, 0.0, 0.0);
    let mut step = 2f64.to_radians();
    let (mut az_range, mut el_range) =
        ((-180.0f64.to_radians(), 180f64.to_radians()), (-90f64.to_radians(), 90f64.to_radians()));
    for _ in 0..3 {
        let mut el = el_range.0;
        while el <= el_range.1 + 1e-12 {
            let mut az = az_range.0;
            while az <= az_range.1 + 1e-12 {
                let b = beam(dir(az, el));
                if b > best {
                    (best, best_az, best_el) = (b, az, el);
                }
                az += step;
            }
            el += step;
        }
        az_range = (best_az - 2.0 * step, best_az + 2.0 * step);
        el_range = (
            (best_el - 2.0 * step).max(-std::f64::consts::FRAC_PI_2),
            (best_el + 2.0 * step).min(std::f64::consts::FRAC_PI_2),
        );
        step /= 10.0;
    }
    dir(best_az, best_el)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(az_deg: f64, el_deg: f64) -> DVec3 {
        let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
        DVec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
    }

    #[test]
    fn sn3d_harmonics_match_their_angular_closed_forms() {
        // The SN3D real harmonics in azimuth phi and elevation theta (AmbiX; Zotter and Frank,
        // Ambisonics, Springer 2019, table of the first orders): each channel against its
        // textbook form at a spread of directions.
        for (a, e) in [(0.0, 0.0), (30.0, 10.0), (-75.0, 45.0), (160.0, -60.0), (95.0, 80.0), (-140.0, -20.0)]
        {
            let y = sh_sn3d(dir(a, e), 3);
            let (p, t) = (f64::to_radians(a), f64::to_radians(e));
            let (ct, st) = (t.cos(), t.sin());
            let want = [
                1.0,
                p.sin() * ct,
                st,
                p.cos() * ct,
                3f64.sqrt() / 2.0 * (2.0 * p).sin() * ct * ct,
                3f64.sqrt() / 2.0 * p.sin() * (2.0 * t).sin(),
                0.5 * (3.0 * st * st - 1.0),
                3f64.sqrt() / 2.0 * p.cos() * (2.0 * t).sin(),
                3f64.sqrt() / 2.0 * (2.0 * p).cos() * ct * ct,
                (5.0f64 / 8.0).sqrt() * (3.0 * p).sin() * ct.powi(3),
                15f64.sqrt() / 2.0 * (2.0 * p).sin() * st * ct * ct,
                (3.0f64 / 8.0).sqrt() * p.sin() * ct * (5.0 * st * st - 1.0),
                0.5 * st * (5.0 * st * st - 3.0),
                (3.0f64 / 8.0).sqrt() * p.cos() * ct * (5.0 * st * st - 1.0),
                15f64.sqrt() / 2.0 * (2.0 * p).cos() * st * ct * ct,
                (5.0f64 / 8.0).sqrt() * (3.0 * p).cos() * ct.powi(3),
            ];
            for k in 0..16 {
                assert!((y[k] - want[k]).abs() < 1e-12, "({a}, {e}) ACN {k}: {} vs {}", y[k], want[k]);
            }
        }
    }

    #[test]
    #[allow(clippy::needless_range_loop)]
    fn sn3d_obeys_the_addition_theorem_and_the_norms() {
        // sum_m Y_nm(u) Y_nm(v) = P_n(u.v) (Legendre polynomials), and the sphere integral of
        // Y_k Y_l is 4 pi / (2n + 1) delta_kl (a 200 x 400 midpoint grid in cos(theta), phi).
        let legendre = |n: usize, x: f64| match n {
            0 => 1.0,
            1 => x,
            2 => 0.5 * (3.0 * x * x - 1.0),
            _ => 0.5 * (5.0 * x * x * x - 3.0 * x),
        };
        for (u, v) in [
            (dir(10.0, 20.0), dir(-100.0, 35.0)),
            (dir(0.0, 90.0), dir(45.0, -10.0)),
            (dir(70.0, 5.0), dir(70.0, 5.0)),
        ] {
            let (yu, yv) = (sh_sn3d(u, 3), sh_sn3d(v, 3));
            for n in 0..=3 {
                let s: f64 = (n * n..(n + 1) * (n + 1)).map(|k| yu[k] * yv[k]).sum();
                assert!((s - legendre(n, u.dot(v))).abs() < 1e-12, "order {n}");
            }
        }
        let (nt, np) = (200, 400);
        let mut gram = [[0.0f64; 16]; 16];
        for i in 0..nt {
            let z = -1.0 + (i as f64 + 0.5) * 2.0 / nt as f64;
            for j in 0..np {
                let phi = (j as f64 + 0.5) * 2.0 * std::f64::consts::PI / np as f64;
                let r = (1.0 - z * z).sqrt();
                let y = sh_sn3d(DVec3::new(r * phi.cos(), r * phi.sin(), z), 3);
                let w = 4.0 * std::f64::consts::PI / (nt * np) as f64;
                for k in 0..16 {
                    for l in 0..16 {
                        gram[k][l] += w * y[k] * y[l];
                    }
                }
            }
        }
        for k in 0..16 {
            for l in 0..16 {
                let want =
                    if k == l { 4.0 * std::f64::consts::PI / (2 * order_of(k) + 1) as f64 } else { 0.0 };
                // The midpoint rule in cos(theta) errs by O(h^2) = 1e-4 times the integrand's
                // second derivative (up to about 10 at order 3).
                assert!((gram[k][l] - want).abs() < 1e-3, "({k}, {l}): {}", gram[k][l]);
            }
        }
    }

    #[test]
    fn a_plane_wave_decodes_to_its_direction_within_two_degrees() {
        for order in 1..=3 {
            for (a, e) in [(0.0, 0.0), (37.0, 12.0), (-120.0, -33.0), (179.0, 61.0), (80.0, -85.0)] {
                let u = dir(a, e);
                let found = steer_peak(&sh_sn3d(u, order));
                let err = u.dot(found).clamp(-1.0, 1.0).acos().to_degrees();
                assert!(err < 2.0, "order {order}, ({a}, {e}): {err} degrees off");
            }
        }
    }
}
