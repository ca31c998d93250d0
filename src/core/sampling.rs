//! Sampling routines on the sphere, hemisphere and square, with their densities.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3};

/// A unit direction uniformly distributed on the sphere from `u` in `[0,1)^2`
/// (pbrt-v4 `SampleUniformSphere`). Density `1 / (4 pi)`.
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = TAU * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Density of [`uniform_sphere`] per steradian.
pub const UNIFORM_SPHERE_PDF: f32 = 1.0 / (4.0 * PI);

/// A standard normal deviate from `u` in `[0,1)^2` (the Box-Muller transform; `u.x` is
/// taken from the open side so the logarithm stays finite).
pub fn standard_normal(u: Vec2) -> f32 {
    (-2.0 * (1.0 - u.x).ln()).sqrt() * (TAU * u.y).cos()
}

/// A cosine-weighted direction about +z (Malley's method on a concentric disk).
/// Density `cos(theta) / pi`.
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Density of [`cosine_hemisphere`] for a direction with cosine `cos_theta` to the axis.
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) / PI
}

/// Shirley-Chiu concentric map from the square to the unit disk (area preserving).
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o == Vec2::ZERO {
        return Vec2::ZERO;
    }
    // The angle is pi/4 times a ratio in [-1, 1], or pi/2 minus that, whose cosine and sine
    // are the sine and cosine of the small angle. Selects, not branches: which case applies
    // is a coin toss per sample.
    let x_major = o.x.abs() > o.y.abs();
    let (num, den) = if x_major { (o.y, o.x) } else { (o.x, o.y) };
    let (sin, cos) = sin_cos_quarter((PI / 4.0) * (num / den));
    den * if x_major { Vec2::new(cos, sin) } else { Vec2::new(sin, cos) }
}

/// `(sin x, cos x)` for `|x| <= pi/4`: Taylor polynomials to degree 9 and 10, whose
/// truncation errors (below 2e-9) are far under an ulp. About a third of the cost of the
/// general `sin_cos`, which must reduce any argument: 3 % of a Cornell box render.
#[inline(always)]
pub fn sin_cos_quarter(x: f32) -> (f32, f32) {
    let x2 = x * x;
    let sin =
        x * (1.0 + x2 * (-1.0 / 6.0 + x2 * (1.0 / 120.0 + x2 * (-1.0 / 5040.0 + x2 * (1.0 / 362_880.0)))));
    let cos = 1.0
        + x2 * (-0.5
            + x2 * (1.0 / 24.0 + x2 * (-1.0 / 720.0 + x2 * (1.0 / 40_320.0 + x2 * (-1.0 / 3_628_800.0)))));
    (sin, cos)
}

/// Uniform point on a triangle as barycentrics `(b1, b2)` (Heitz 2019, low distortion).
pub fn uniform_triangle(u: Vec2) -> Vec2 {
    if u.x < u.y {
        let b0 = u.x / 2.0;
        Vec2::new(b0, u.y - b0)
    } else {
        let b1 = u.y / 2.0;
        Vec2::new(u.x - b1, b1)
    }
}

/// Direction `i` of `n` on the spherical Fibonacci lattice: near-uniform, deterministic,
/// with equal solid angle `4 pi / n` per point (Gonzalez 2010; Keinert et al. 2015).
/// `offset` in `[0,1)` rotates the lattice about z, for randomised repetitions.
#[inline]
pub fn fibonacci_sphere(i: usize, n: usize, offset: f32) -> Vec3 {
    const GOLDEN_ANGLE_TURNS: f64 = 0.381_966_011_250_105_1; // 2 - phi
    let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let turns = (i as f64 * GOLDEN_ANGLE_TURNS + f64::from(offset)).fract();
    // The angle in f64 (the turns of a large index need it), its sine and cosine in f32:
    // the direction is f32 anyway, and `sincosf` is about twice as fast as `sincos`.
    let (sin, cos) = ((std::f64::consts::TAU * turns) as f32).sin_cos();
    let r = r as f32;
    Vec3::new(r * cos, r * sin, z as f32)
}

/// Sample `i` of an `nx` x `ny` stratified pattern, jittered by `u` within its cell.
pub fn stratified_2d(i: usize, nx: usize, ny: usize, u: Vec2) -> Vec2 {
    let (cx, cy) = (i % nx, (i / nx) % ny);
    Vec2::new((cx as f32 + u.x) / nx as f32, (cy as f32 + u.y) / ny as f32)
}

/// An orthonormal basis `(t, b)` completing unit `n` (Duff et al. 2017, branchless).
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), Vec3::new(b, sign + n.y * n.y * a, -n.y))
}

/// `local` (about +z) expressed in the frame whose z axis is unit `n`.
pub fn to_world(local: Vec3, n: Vec3) -> Vec3 {
    let (t, b) = orthonormal_basis(n);
    t * local.x + b * local.y + n * local.z
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quarter_sine_and_cosine_match_the_library_to_an_ulp_or_two() {
        for k in -1000..=1000 {
            let x = (k as f32 / 1000.0) * std::f32::consts::FRAC_PI_4;
            let (sin, cos) = sin_cos_quarter(x);
            let (s64, c64) = f64::from(x).sin_cos();
            assert!(
                (f64::from(sin) - s64).abs() <= 2.5e-7 * s64.abs().max(1e-3),
                "sin({x}) = {sin}, not {s64}"
            );
            assert!((f64::from(cos) - c64).abs() <= 1.2e-7, "cos({x}) = {cos}, not {c64}");
        }
    }
    use crate::core::rng::{stream, uniform};

    fn u2(r: &mut crate::core::rng::Rng64) -> Vec2 {
        Vec2::new(uniform(r), uniform(r))
    }

    #[test]
    fn uniform_sphere_is_unit_and_unbiased() {
        let mut r = stream(3, 0, 0);
        let n = 200_000;
        let mut mean = Vec3::ZERO;
        let mut zz = 0.0;
        for _ in 0..n {
            let d = uniform_sphere(u2(&mut r));
            assert!((d.length() - 1.0).abs() < 1e-5);
            mean += d;
            zz += d.z * d.z;
        }
        mean /= n as f32;
        assert!(mean.length() < 0.01);
        // E[z^2] = 1/3 on the sphere.
        assert!((zz / n as f32 - 1.0 / 3.0).abs() < 0.005);
    }

    #[test]
    fn cosine_hemisphere_matches_its_density() {
        // E[cos theta] under p = cos/pi is 2/3.
        let mut r = stream(4, 0, 0);
        let n = 200_000;
        let mut sum = 0.0;
        for _ in 0..n {
            let d = cosine_hemisphere(u2(&mut r));
            assert!(d.z >= 0.0 && (d.length() - 1.0).abs() < 1e-4);
            sum += d.z;
        }
        assert!((sum / n as f32 - 2.0 / 3.0).abs() < 0.005);
        // The density integrates to one: integral of cos/pi over the hemisphere.
        let m = 400;
        let mut integral = 0.0f64;
        for i in 0..m {
            let theta = (i as f64 + 0.5) / m as f64 * std::f64::consts::FRAC_PI_2;
            integral += f64::from(cosine_hemisphere_pdf(theta.cos() as f32))
                * theta.sin()
                * std::f64::consts::TAU
                * (std::f64::consts::FRAC_PI_2 / m as f64);
        }
        assert!((integral - 1.0).abs() < 1e-3);
    }

    #[test]
    fn fibonacci_lattice_is_balanced() {
        let n = 10_000;
        let mut mean = Vec3::ZERO;
        let mut upper = 0;
        for i in 0..n {
            let d = fibonacci_sphere(i, n, 0.3);
            assert!((d.length() - 1.0).abs() < 1e-5);
            mean += d;
            upper += usize::from(d.z > 0.0);
        }
        assert!((mean / n as f32).length() < 1e-3);
        assert_eq!(upper, n / 2);
        // Equal-area: any octant gets 1/8 of the points within 1 %.
        let octant = (0..n).filter(|&i| {
            let d = fibonacci_sphere(i, n, 0.0);
            d.x > 0.0 && d.y > 0.0 && d.z > 0.0
        });
        assert!((octant.count() as f32 / n as f32 - 0.125).abs() < 0.00125);
    }

    #[test]
    fn triangle_and_disk_samples_stay_inside() {
        let mut r = stream(5, 0, 0);
        let mut mean = Vec2::ZERO;
        for _ in 0..50_000 {
            let b = uniform_triangle(u2(&mut r));
            assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6);
            mean += b;
            assert!(concentric_disk(u2(&mut r)).length() <= 1.0 + 1e-6);
        }
        // Centroid of a uniform triangle: (1/3, 1/3).
        assert!((mean / 50_000.0 - Vec2::splat(1.0 / 3.0)).length() < 0.01);
    }

    #[test]
    fn stratified_samples_cover_their_cells() {
        for i in 0..16 {
            let s = stratified_2d(i, 4, 4, Vec2::splat(0.5));
            assert!((s.x - ((i % 4) as f32 + 0.5) / 4.0).abs() < 1e-6);
            assert!((s.y - ((i / 4) as f32 + 0.5) / 4.0).abs() < 1e-6);
        }
    }

    #[test]
    fn basis_is_orthonormal() {
        let mut r = stream(6, 0, 0);
        for _ in 0..1000 {
            let n = uniform_sphere(u2(&mut r));
            let (t, b) = orthonormal_basis(n);
            assert!(t.dot(b).abs() < 1e-5 && t.dot(n).abs() < 1e-5 && b.dot(n).abs() < 1e-5);
            assert!((t.length() - 1.0).abs() < 1e-5 && (b.length() - 1.0).abs() < 1e-5);
            assert!((to_world(Vec3::Z, n) - n).length() < 1e-5);
        }
    }
}
