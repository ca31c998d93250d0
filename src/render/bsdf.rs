//! Scattering functions (BSDFs) in a local shading frame whose +z axis is the surface's
//! geometric normal as wound: Lambert, metal with GGX roughness, and smooth glass with the
//! exact Fresnel equations.
//!
//! Conventions follow pbrt-v4 (Pharr, Jakob, Humphreys, *Physically Based Rendering*, 4th ed.,
//! ch. 9): `wo` points away from the surface towards the viewer, `wi` towards the light; `f`
//! does not include the cosine factor; densities are per unit solid angle. Opaque BSDFs are
//! two-sided: they reflect into whichever hemisphere `wo` is in.

use std::f32::consts::{FRAC_1_PI, PI};

use glam::{Vec2, Vec3};

use crate::core::sampling::cosine_hemisphere;

/// GGX `alpha` below which a metal is treated as a perfect mirror: a lobe this narrow cannot be
/// sampled or evaluated reliably in f32 (pbrt-v4 sec. 9.6.1 uses 1e-3 as well).
const SMOOTH_ALPHA: f32 = 1.0e-3;

/// A surface's scattering function.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bsdf {
    /// Ideal diffuse reflection with albedo `albedo` (pbrt-v4 sec. 9.2): `f = albedo / pi`.
    Lambert {
        /// Albedo (linear RGB).
        albedo: Vec3,
    },
    /// Conductor with the GGX (Trowbridge-Reitz) microfacet distribution of roughness `alpha`
    /// (Walter, Marschner, Li, Torrance 2007, "Microfacet models for refraction through rough
    /// surfaces"), Smith height-correlated masking-shadowing (Heitz 2014) and Schlick's Fresnel
    /// from the normal-incidence reflectance `f0`; `alpha < 1e-3` is a perfect mirror.
    /// Sampled by visible normals (Heitz 2018, "Sampling the GGX distribution of visible normals").
    Metal {
        /// Reflectance at normal incidence (linear RGB).
        f0: Vec3,
        /// GGX roughness.
        alpha: f32,
    },
    /// Smooth dielectric interface of relative index `eta` (inside / outside, inside being the
    /// side the normal points away from): reflection and refraction weighted by the exact
    /// unpolarised Fresnel equations, total internal reflection included (pbrt-v4 sec. 9.3, 9.5).
    /// `tint` scales transmitted light (coloured glass).
    Dielectric {
        /// Relative index of refraction (inside / outside).
        eta: f32,
        /// Scale of transmitted light (linear RGB).
        tint: Vec3,
    },
}

/// A direction drawn from a BSDF.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Incident direction in the local frame.
    pub wi: Vec3,
    /// BSDF value (for a delta lobe, the value that makes `f |cos| / pdf` the lobe's weight).
    pub f: Vec3,
    /// Density per solid angle (for a delta lobe, the probability of choosing it).
    pub pdf: f32,
    /// True for a perfect mirror or refraction (a Dirac lobe): it cannot be hit by light sampling.
    pub specular: bool,
}

impl BsdfSample {
    /// `f |cos(wi)| / pdf`: the path-throughput factor of this sample.
    #[inline]
    pub fn weight(&self) -> Vec3 {
        self.f * (self.wi.z.abs() / self.pdf)
    }
}

/// Schlick's approximation of conductor Fresnel reflectance (Schlick 1994).
#[inline]
pub fn fresnel_schlick(f0: Vec3, cos_theta: f32) -> Vec3 {
    let m = (1.0 - cos_theta.abs()).clamp(0.0, 1.0);
    let m5 = m * m * m * m * m;
    f0 + (Vec3::ONE - f0) * m5
}

/// Exact unpolarised Fresnel reflectance of a dielectric interface for light arriving at
/// cosine `cos_i` to the normal, relative index `eta` = n_transmitted / n_incident on the side
/// the normal points to; negative `cos_i` means arriving from the other side (pbrt-v4 sec. 9.3.2,
/// `FrDielectric`). Returns 1 on total internal reflection.
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let (mut cos_i, mut eta) = (cos_i.clamp(-1.0, 1.0), eta);
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
    }
    let sin2_i = 1.0 - cos_i * cos_i;
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_parl * r_parl + r_perp * r_perp)
}

/// Mirror reflection of local `wo` about +z.
#[inline]
pub fn reflect_local(wo: Vec3) -> Vec3 {
    Vec3::new(-wo.x, -wo.y, wo.z)
}

/// Refraction of local `wo` through the interface with normal +z by Snell's law, `eta` as in
/// [`fresnel_dielectric`]. Returns the refracted direction and the relative index actually
/// used (`eta` or `1/eta`), or `None` on total internal reflection.
pub fn refract_local(wo: Vec3, eta: f32) -> Option<(Vec3, f32)> {
    let (n, eta) = if wo.z >= 0.0 { (Vec3::Z, eta) } else { (-Vec3::Z, 1.0 / eta) };
    let cos_i = wo.dot(n);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(((-wo / eta + (cos_i / eta - cos_t) * n).normalize(), eta))
}

/// GGX normal distribution `D(m)` for a microfacet normal `m` in the upper hemisphere.
#[inline]
fn ggx_d(m: Vec3, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let t = m.x * m.x / a2 + m.y * m.y / a2 + m.z * m.z;
    1.0 / (PI * a2 * t * t)
}

/// Smith's `Lambda` for GGX (Heitz 2014, eq. 72).
#[inline]
fn ggx_lambda(w: Vec3, alpha: f32) -> f32 {
    let z2 = w.z * w.z;
    if z2 <= 0.0 {
        return f32::INFINITY;
    }
    let tan2 = (w.x * w.x + w.y * w.y) * alpha * alpha / z2;
    0.5 * ((1.0 + tan2).sqrt() - 1.0)
}

/// Heitz 2018 visible-normal sampling: a microfacet normal seen from `wo` (upper hemisphere).
fn ggx_sample_visible(wo: Vec3, alpha: f32, u: Vec2) -> Vec3 {
    let vh = Vec3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let len2 = vh.x * vh.x + vh.y * vh.y;
    let t1 = if len2 > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt() } else { Vec3::X };
    let t2 = vh.cross(t1);
    let r = u.x.sqrt();
    let phi = 2.0 * PI * u.y;
    let p1 = r * phi.cos();
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
    let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
    Vec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(1.0e-6)).normalize()
}

impl Bsdf {
    /// True when every lobe is a Dirac delta (mirror or smooth glass): light sampling is useless.
    #[inline]
    pub fn is_delta(&self) -> bool {
        match *self {
            Bsdf::Lambert { .. } => false,
            Bsdf::Metal { alpha, .. } => alpha < SMOOTH_ALPHA,
            Bsdf::Dielectric { .. } => true,
        }
    }

    /// True when [`Bsdf::sample`] picks one of several lobes with its number `uc` (glass:
    /// reflection or refraction); the other BSDFs ignore it, so the path loop draws none.
    #[inline]
    pub fn has_lobes(&self) -> bool {
        matches!(self, Bsdf::Dielectric { .. })
    }

    /// The BSDF value for the pair (non-delta lobes only; zero for Dirac lobes).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z * wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        match *self {
            Bsdf::Lambert { albedo } => albedo * FRAC_1_PI,
            Bsdf::Metal { f0, alpha } => {
                if alpha < SMOOTH_ALPHA {
                    return Vec3::ZERO;
                }
                let s = wo.z.signum();
                let (wo, wi) = (wo * s, wi * s);
                let m = (wo + wi).normalize();
                let g2 = 1.0 / (1.0 + ggx_lambda(wo, alpha) + ggx_lambda(wi, alpha));
                fresnel_schlick(f0, wo.dot(m)) * (ggx_d(m, alpha) * g2 / (4.0 * wo.z * wi.z))
            }
            Bsdf::Dielectric { .. } => Vec3::ZERO,
        }
    }

    /// Density per solid angle with which [`Bsdf::sample`] returns `wi` (zero for Dirac lobes).
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z * wi.z <= 0.0 {
            return 0.0;
        }
        match *self {
            Bsdf::Lambert { .. } => wi.z.abs() * FRAC_1_PI,
            Bsdf::Metal { alpha, .. } => {
                if alpha < SMOOTH_ALPHA {
                    return 0.0;
                }
                let s = wo.z.signum();
                let (wo, wi) = (wo * s, wi * s);
                let m = (wo + wi).normalize();
                // Visible-normal density D_wo(m) = G1(wo) max(0, wo.m) D(m) / wo.z, times the
                // reflection Jacobian 1 / (4 wo.m) (Heitz 2018, eq. 17; Walter et al. 2007, eq. 14).
                let g1 = 1.0 / (1.0 + ggx_lambda(wo, alpha));
                g1 * ggx_d(m, alpha) / (4.0 * wo.z)
            }
            Bsdf::Dielectric { .. } => 0.0,
        }
    }

    /// Draws an incident direction for `wo`; `u` and `uc` are uniform in `[0,1)`.
    pub fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        match *self {
            Bsdf::Lambert { albedo } => {
                let mut wi = cosine_hemisphere(u);
                if wo.z < 0.0 {
                    wi.z = -wi.z;
                }
                let pdf = wi.z.abs() * FRAC_1_PI;
                (pdf > 0.0).then_some(BsdfSample { wi, f: albedo * FRAC_1_PI, pdf, specular: false })
            }
            Bsdf::Metal { f0, alpha } => {
                if alpha < SMOOTH_ALPHA {
                    let wi = reflect_local(wo);
                    let f = fresnel_schlick(f0, wo.z) / wi.z.abs();
                    return Some(BsdfSample { wi, f, pdf: 1.0, specular: true });
                }
                let s = wo.z.signum();
                let wo_up = wo * s;
                let m = ggx_sample_visible(wo_up, alpha, u);
                let wi_up = 2.0 * wo_up.dot(m) * m - wo_up;
                if wi_up.z <= 0.0 {
                    return None;
                }
                let wi = wi_up * s;
                let pdf = self.pdf(wo, wi);
                (pdf > 0.0).then(|| BsdfSample { wi, f: self.eval(wo, wi), pdf, specular: false })
            }
            Bsdf::Dielectric { eta, tint } => {
                let r = fresnel_dielectric(wo.z, eta);
                if uc < r {
                    let wi = reflect_local(wo);
                    return Some(BsdfSample { wi, f: Vec3::splat(r / wi.z.abs()), pdf: r, specular: true });
                }
                let (wi, eta_used) = refract_local(wo, eta)?;
                // Radiance is compressed by eta^2 entering a denser medium (pbrt-v4 sec. 9.5.2).
                let t = (1.0 - r) / (eta_used * eta_used);
                Some(BsdfSample { wi, f: tint * (t / wi.z.abs()), pdf: 1.0 - r, specular: true })
            }
        }
    }

    /// Reflectance colour for display shading (raycast): albedo, f0 or tint.
    pub fn base_color(&self) -> Vec3 {
        match *self {
            Bsdf::Lambert { albedo } => albedo,
            Bsdf::Metal { f0, .. } => f0,
            Bsdf::Dielectric { tint, .. } => tint,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::rng::{Rng64, stream, uniform};
    use crate::core::sampling::uniform_sphere;

    fn u2(r: &mut Rng64) -> Vec2 {
        Vec2::new(uniform(r), uniform(r))
    }

    fn all_bsdfs() -> Vec<Bsdf> {
        vec![
            Bsdf::Lambert { albedo: Vec3::new(1.0, 0.5, 0.0) },
            Bsdf::Metal { f0: Vec3::ONE, alpha: 0.05 },
            Bsdf::Metal { f0: Vec3::ONE, alpha: 0.3 },
            Bsdf::Metal { f0: Vec3::ONE, alpha: 1.0 },
            Bsdf::Metal { f0: Vec3::new(0.9, 0.6, 0.3), alpha: 0.0 },
            Bsdf::Dielectric { eta: 1.5, tint: Vec3::ONE },
            Bsdf::Dielectric { eta: 1.33, tint: Vec3::ONE },
        ]
    }

    #[test]
    fn only_bsdfs_with_lobes_read_the_lobe_number() {
        // The path loop draws `uc` only for `has_lobes`: the others must not depend on it, and
        // glass must (else the flag would be stale).
        let mut rng = stream(12, 0, 0);
        for bsdf in all_bsdfs() {
            let mut depends = false;
            for _ in 0..200 {
                let wo = uniform_sphere(u2(&mut rng));
                let u = u2(&mut rng);
                let [a, b] = [0.05, 0.95].map(|uc| bsdf.sample(wo, u, uc).map(|s| (s.wi, s.pdf)));
                depends |= a != b;
            }
            assert_eq!(depends, bsdf.has_lobes(), "{bsdf:?}");
        }
    }

    /// Directional albedo `integral f |cos| dwi` by importance sampling, for several `wo`
    /// on both sides: never above 1 (energy conservation).
    #[test]
    fn every_bsdf_conserves_energy() {
        let mut rng = stream(11, 0, 0);
        for bsdf in all_bsdfs() {
            let mut largest = 0.0f32;
            for cos_o in [1.0f32, 0.7, 0.3, 0.05, -0.5, -0.9] {
                let wo = Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
                let n = 20_000;
                let mut sum = Vec3::ZERO;
                for _ in 0..n {
                    if let Some(s) = bsdf.sample(wo, u2(&mut rng), uniform(&mut rng)) {
                        let w = s.weight();
                        assert!(w.is_finite() && w.min_element() >= 0.0, "{bsdf:?} weight {w}");
                        // Energy, not radiance: undo the eta^2 radiance scaling of refraction.
                        let energy = match bsdf {
                            Bsdf::Dielectric { eta, .. } if s.wi.z * wo.z < 0.0 => {
                                let e = if wo.z > 0.0 { eta } else { 1.0 / eta };
                                e * e
                            }
                            _ => 1.0,
                        };
                        sum += w * energy;
                    }
                }
                let albedo = sum / n as f32;
                largest = largest.max(albedo.max_element());
                assert!(albedo.max_element() <= 1.0 + 0.01, "{bsdf:?} cos_o {cos_o}: albedo {albedo}");
            }
            eprintln!("{bsdf:?}: largest directional albedo {largest:.4}");
        }
        // A white Lambert reflects everything; a white smooth metal too; clear glass loses nothing.
        for (bsdf, expect) in [
            (Bsdf::Lambert { albedo: Vec3::ONE }, 1.0),
            (Bsdf::Metal { f0: Vec3::ONE, alpha: 0.0 }, 1.0),
            (Bsdf::Dielectric { eta: 1.5, tint: Vec3::ONE }, f32::NAN),
        ] {
            let wo = Vec3::new(0.6, 0.0, 0.8);
            let mut sum = 0.0;
            for _ in 0..10_000 {
                if let Some(s) = bsdf.sample(wo, u2(&mut rng), uniform(&mut rng)) {
                    // For glass count energy, not radiance: undo the 1/eta^2 compression.
                    let eta2 = if s.wi.z < 0.0 { 1.5f32 * 1.5 } else { 1.0 };
                    sum += s.weight().x * if expect.is_nan() { eta2 } else { 1.0 };
                }
            }
            assert!((sum / 10_000.0 - 1.0).abs() < 0.01, "{bsdf:?}: {}", sum / 10_000.0);
        }
    }

    /// The density `pdf()` reports integrates to at most one and matches the histogram of
    /// directions `sample()` draws (chi-square-like comparison on a coarse sphere grid).
    #[test]
    fn sampled_and_evaluated_densities_agree() {
        let mut rng = stream(12, 0, 0);
        // Lobes narrower than alpha 0.3 are too sharp for this bin grid: for them only the
        // sample-by-sample agreement of `sample` with `pdf` and `eval` is checked.
        let wide = |b: &Bsdf| !matches!(b, Bsdf::Metal { alpha, .. } if *alpha < 0.3);
        for bsdf in all_bsdfs().into_iter().filter(|b| !b.is_delta()) {
            for wo in [Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.8, 0.0, 0.6), Vec3::new(0.3, 0.4, -0.866)] {
                let wo = wo.normalize();
                // Integral of pdf over the sphere by uniform sampling.
                let n = 200_000;
                let mut integral = 0.0f64;
                for _ in 0..n {
                    let wi = uniform_sphere(u2(&mut rng));
                    integral += f64::from(bsdf.pdf(wo, wi)) * 4.0 * std::f64::consts::PI;
                }
                let integral = integral / f64::from(n);
                assert!(!wide(&bsdf) || integral <= 1.02, "{bsdf:?} {wo}: pdf integrates to {integral}");
                // Histogram of sampled directions vs pdf integrated over bins (theta x phi).
                const NT: usize = 8;
                const NP: usize = 8;
                let mut hist = [[0u32; NP]; NT];
                let mut accepted = 0;
                let m = 100_000;
                for _ in 0..m {
                    if let Some(s) = bsdf.sample(wo, u2(&mut rng), uniform(&mut rng)) {
                        assert!((bsdf.pdf(wo, s.wi) - s.pdf).abs() <= 1e-3 * s.pdf.max(1.0), "{bsdf:?}");
                        assert!((bsdf.eval(wo, s.wi) - s.f).abs().max_element() <= 1e-3 * s.f.max_element());
                        let (ti, pi) = bin(s.wi, NT, NP);
                        hist[ti][pi] += 1;
                        accepted += 1;
                    }
                }
                if !wide(&bsdf) {
                    continue;
                }
                // Expected counts by midpoint integration of the pdf on a fine grid inside each bin.
                let k = 16;
                for (ti, row) in hist.iter().enumerate() {
                    for (pi, &count) in row.iter().enumerate() {
                        let mut p = 0.0f64;
                        for a in 0..k {
                            for b in 0..k {
                                let ct = 1.0 - 2.0 * ((ti * k + a) as f64 + 0.5) / (NT * k) as f64;
                                let phi =
                                    ((pi * k + b) as f64 + 0.5) / (NP * k) as f64 * std::f64::consts::TAU;
                                let st = (1.0 - ct * ct).sqrt();
                                let wi =
                                    Vec3::new((st * phi.cos()) as f32, (st * phi.sin()) as f32, ct as f32);
                                p += f64::from(bsdf.pdf(wo, wi));
                            }
                        }
                        let cell = 4.0 * std::f64::consts::PI / (NT * NP * k * k) as f64;
                        let expected = p * cell * f64::from(m);
                        let got = f64::from(count);
                        let tol = 5.0 * expected.sqrt() + 0.02 * expected + 10.0;
                        assert!(
                            (got - expected).abs() <= tol,
                            "{bsdf:?} wo {wo} bin {ti},{pi}: {got} vs {expected}"
                        );
                    }
                }
                assert!(accepted > 0);
            }
        }
    }

    fn bin(w: Vec3, nt: usize, np: usize) -> (usize, usize) {
        let ti = (((1.0 - w.z) / 2.0) * nt as f32).clamp(0.0, nt as f32 - 1.0) as usize;
        let phi = w.y.atan2(w.x).rem_euclid(std::f32::consts::TAU);
        let pi = ((phi / std::f32::consts::TAU) * np as f32).clamp(0.0, np as f32 - 1.0) as usize;
        (ti, pi)
    }

    #[test]
    fn fresnel_matches_known_values() {
        // Normal incidence glass: ((1.5-1)/(1.5+1))^2 = 0.04, from either side.
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert!((fresnel_dielectric(-1.0, 1.5) - 0.04).abs() < 1e-6);
        // Brewster angle: parallel component vanishes; R = r_perp^2 / 2.
        let tb = 1.5f32.atan();
        let r = fresnel_dielectric(tb.cos(), 1.5);
        let (ci, ct) = (tb.cos(), (1.0 - (tb.sin() / 1.5).powi(2)).sqrt());
        let rs = (ci - 1.5 * ct) / (ci + 1.5 * ct);
        assert!((r - 0.5 * rs * rs).abs() < 1e-5);
        // Total internal reflection inside glass beyond the critical angle asin(1/1.5) = 41.8 deg.
        let c = (45f32).to_radians().cos();
        assert_eq!(fresnel_dielectric(-c, 1.5), 1.0);
        let d = std::f32::consts::FRAC_1_SQRT_2;
        assert!(refract_local(Vec3::new(d, 0.0, -d), 1.5).is_none());
        // Snell: sin t = sin i / 1.5.
        let (t, _) = refract_local(Vec3::new(0.6, 0.0, 0.8), 1.5).unwrap();
        assert!((t.x.abs() - 0.4).abs() < 1e-5 && t.z < 0.0);
    }
}
