//! A homogeneous participating medium (fog): absorption and scattering coefficients per RGB
//! channel and a Henyey-Greenstein phase function, with free-flight sampling by spectral MIS
//! over the channels (\[pbrt-v4\] secs. 11.2 and 14.2 in docs/references.md) and the
//! closed-form Beer-Lambert transmittance.

use glam::{Vec2, Vec3};

use crate::core::sampling::to_world;

/// A homogeneous medium filling the scene (a global fog).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Medium {
    /// Absorption coefficient per channel, 1/m.
    pub sigma_a_per_m: Vec3,
    /// Scattering coefficient per channel, 1/m.
    pub sigma_s_per_m: Vec3,
    /// Henyey-Greenstein asymmetry, in (-1, 1): 0 isotropic, > 0 forward.
    pub g: f32,
}

/// Where a free flight ends ([`Medium::sample_flight`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Flight {
    /// Distance along the ray, metres (`t_max` when it reached the surface).
    pub t: f32,
    /// True when the flight ended by scattering in the medium before `t_max`.
    pub scattered: bool,
    /// What the path throughput is multiplied by: `sigma_s T(t) / p(t)` at a scattering,
    /// `T(t_max) / P(t >= t_max)` at the surface (their expectation is exact per channel).
    pub weight: Vec3,
}

impl Medium {
    /// Checks the numbers; the error names the bad one.
    pub fn validate(&self) -> Result<(), String> {
        let ok = |v: Vec3| v.is_finite() && v.min_element() >= 0.0 && v.max_element() < 1e6;
        if !ok(self.sigma_a_per_m) {
            return Err(format!("fog absorption {} 1/m: each must be in [0, 1e6)", rgb(self.sigma_a_per_m)));
        }
        if !ok(self.sigma_s_per_m) {
            return Err(format!("fog scattering {} 1/m: each must be in [0, 1e6)", rgb(self.sigma_s_per_m)));
        }
        if !(self.g.is_finite() && self.g.abs() < 0.999) {
            return Err(format!("fog asymmetry g {}: must be in (-0.999, 0.999)", self.g));
        }
        Ok(())
    }

    /// Extinction coefficient per channel, 1/m.
    #[inline]
    pub fn sigma_t_per_m(&self) -> Vec3 {
        self.sigma_a_per_m + self.sigma_s_per_m
    }

    /// Beer-Lambert transmittance over `distance_m`: `exp(-sigma_t d)` per channel (1 for a
    /// channel that does not attenuate, even over an infinite distance).
    #[inline]
    pub fn transmittance(&self, distance_m: f32) -> Vec3 {
        self.sigma_t_per_m().map(|s| if s > 0.0 { (-s * distance_m).exp() } else { 1.0 })
    }

    /// A free flight along a ray whose surface is `t_max` away (infinite: none). The channel
    /// whose coefficient draws the distance is chosen uniformly with `u_channel`; the density
    /// is the mean of the three channels' (one-sample MIS, balance heuristic), so a channel
    /// without scattering or one much thinner than the others still gets an unbiased,
    /// bounded weight.
    pub fn sample_flight(&self, t_max: f32, u_channel: f32, u: f32) -> Flight {
        let sigma_t = self.sigma_t_per_m();
        let c = ((u_channel * 3.0) as usize).min(2);
        let t = if sigma_t[c] > 0.0 {
            -(1.0 - u).max(f32::MIN_POSITIVE).ln() / sigma_t[c]
        } else {
            f32::INFINITY
        };
        if t < t_max {
            let tr = self.transmittance(t);
            let pdf = (sigma_t * tr).element_sum() / 3.0;
            let weight = if pdf > 0.0 { self.sigma_s_per_m * tr / pdf } else { Vec3::ZERO };
            return Flight { t, scattered: true, weight };
        }
        let tr = self.transmittance(t_max);
        let survive = tr.element_sum() / 3.0;
        let weight = if survive > 0.0 { tr / survive } else { Vec3::ZERO };
        Flight { t: t_max, scattered: false, weight }
    }

    /// The Henyey-Greenstein phase function for light travelling along `dir` and leaving
    /// along `wi` (both unit), per steradian: `(1 - g^2) / (4 pi (1 + g^2 - 2 g cos)^1.5)`
    /// (\[Henyey1941\] in docs/references.md; \[pbrt-v4\] sec. 11.3.1).
    #[inline]
    pub fn phase(&self, dir: Vec3, wi: Vec3) -> f32 {
        let g = self.g;
        let denom = 1.0 + g * g - 2.0 * g * dir.dot(wi);
        (1.0 - g * g) / (4.0 * std::f32::consts::PI * denom * denom.max(1e-12).sqrt())
    }

    /// A direction drawn from the phase function about `dir` (its density is
    /// [`Medium::phase`], so the sample's weight is 1).
    pub fn sample_phase(&self, dir: Vec3, u: Vec2) -> Vec3 {
        let g = self.g;
        let cos = if g.abs() < 1e-3 {
            1.0 - 2.0 * u.x
        } else {
            let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u.x);
            (1.0 + g * g - s * s) / (2.0 * g)
        }
        .clamp(-1.0, 1.0);
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        let phi = 2.0 * std::f32::consts::PI * u.y;
        to_world(Vec3::new(sin * phi.cos(), sin * phi.sin(), cos), dir).normalize()
    }
}

/// `v` as `R,G,B`, the way the flags take it.
fn rgb(v: Vec3) -> String {
    format!("{},{},{}", v.x, v.y, v.z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::rng::{stream, uniform};

    #[test]
    fn the_phase_function_integrates_to_one_and_its_samples_have_its_mean_cosine() {
        for g in [0.0f32, 0.5, -0.7, 0.9] {
            let m = Medium { sigma_a_per_m: Vec3::ZERO, sigma_s_per_m: Vec3::ONE, g };
            let dir = Vec3::new(0.3, -0.4, 0.866).normalize();
            let mut rng = stream(1, 0, 0);
            let n = 200_000;
            // Uniform directions estimate the integral; HG samples estimate <cos> = g.
            let (mut integral, mut mean_cos) = (0.0f64, 0.0f64);
            for _ in 0..n {
                let w =
                    crate::core::sampling::uniform_sphere(Vec2::new(uniform(&mut rng), uniform(&mut rng)));
                integral += f64::from(m.phase(dir, w)) * 4.0 * std::f64::consts::PI / n as f64;
                let s = m.sample_phase(dir, Vec2::new(uniform(&mut rng), uniform(&mut rng)));
                assert!((s.length() - 1.0).abs() < 1e-4);
                mean_cos += f64::from(s.dot(dir)) / n as f64;
            }
            let tol = if g.abs() > 0.8 { 0.05 } else { 0.01 };
            assert!((integral - 1.0).abs() < tol, "g {g}: integral {integral}");
            assert!((mean_cos - f64::from(g)).abs() < 0.01, "g {g}: mean cosine {mean_cos}");
        }
    }

    #[test]
    fn free_flights_reach_a_surface_with_the_beer_lambert_transmittance() {
        // Per channel, the mean surface weight times the survival indicator is exp(-sigma_t d),
        // and the mean scattering weight is sigma_s / sigma_t (1 - exp(-sigma_t d)).
        let m = Medium {
            sigma_a_per_m: Vec3::new(0.1, 0.5, 0.0),
            sigma_s_per_m: Vec3::new(0.4, 0.0, 1.5),
            g: 0.0,
        };
        let d = 1.7;
        let mut rng = stream(2, 0, 0);
        let n = 400_000;
        let (mut surface, mut scattered) = (Vec3::ZERO, Vec3::ZERO);
        for _ in 0..n {
            let f = m.sample_flight(d, uniform(&mut rng), uniform(&mut rng));
            if f.scattered {
                assert!(f.t < d);
                scattered += f.weight / n as f32;
            } else {
                surface += f.weight / n as f32;
            }
        }
        let st = m.sigma_t_per_m();
        let beer = st.map(|s| (-s * d).exp());
        let scatter = m.sigma_s_per_m / st * (Vec3::ONE - beer);
        for c in 0..3 {
            assert!(
                (surface[c] - beer[c]).abs() < 0.01 * beer[c].max(0.05),
                "channel {c}: {surface} vs {beer}"
            );
            assert!((scattered[c] - scatter[c]).abs() < 0.01, "channel {c}: {scattered} vs {scatter}");
        }
    }
}
