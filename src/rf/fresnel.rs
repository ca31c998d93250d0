//! Complex permittivity and the exact Fresnel reflection and transmission coefficients of a
//! planar interface (air to a lossy dielectric) and of a thin single-layer slab, after
//! ITU-R P.2040-3 sec. 2.1.2 (complex permittivity), sec. 2.2.1.5 (interface, wave incident
//! from air) and sec. 2.2.2.2 (single-layer slab).
//!
//! Sign convention (used by [`crate::rf::propagation`]): TE (s) is the field component along
//! `s = k x n` (perpendicular to the plane of incidence); TM (p) is the component along
//! `p = s x k`, with the same formula for the incident and the reflected direction. With this
//! convention `R_TM -> +1` and `R_TE -> -1` on a perfect conductor, and both tend to -1 at
//! grazing incidence.

/// Vacuum permittivity, F/m.
pub const EPS0: f64 = 8.854_187_812_8e-12;
/// Speed of light in vacuum, m/s.
pub const C0: f64 = 299_792_458.0;

pub use crate::core::complex::Complex;

/// Complex relative permittivity `eta = eps_r' - j sigma / (2 pi f eps0)` (ITU-R P.2040-3
/// sec. 2.1.2; with f in GHz the imaginary part is `17.98 sigma / f`).
pub fn complex_permittivity(relative_permittivity: f64, conductivity_s_per_m: f64, freq_hz: f64) -> Complex {
    Complex::new(relative_permittivity, -conductivity_s_per_m / (std::f64::consts::TAU * freq_hz * EPS0))
}

/// Reflection coefficients (TE, TM) of a plane wave incident from air on a half-space of
/// complex relative permittivity `eta`, at incidence angle theta (from the normal) given by
/// `cos_theta` in [0, 1] (ITU-R P.2040-3 sec. 2.2.1.5):
/// `R_TE = (cos t - sqrt(eta - sin^2 t)) / (cos t + sqrt(eta - sin^2 t))`,
/// `R_TM = (eta cos t - sqrt(eta - sin^2 t)) / (eta cos t + sqrt(eta - sin^2 t))`.
pub fn reflection(eta: Complex, cos_theta: f64) -> (Complex, Complex) {
    let c = cos_theta.clamp(0.0, 1.0);
    let root = (eta - Complex::new(1.0 - c * c, 0.0)).sqrt();
    let cc = Complex::new(c, 0.0);
    let te = (cc - root) / (cc + root);
    let ec = eta.scale(c);
    let tm = (ec - root) / (ec + root);
    (te, tm)
}

/// Reflection and transmission coefficients of a slab of thickness `d_m` in air.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlabCoefficients {
    /// TE reflection coefficient.
    pub r_te: Complex,
    /// TM reflection coefficient.
    pub r_tm: Complex,
    /// TE transmission coefficient.
    pub t_te: Complex,
    /// TM transmission coefficient.
    pub t_tm: Complex,
}

/// Thin single-layer slab (ITU-R P.2040-3 sec. 2.2.2.2), multiple internal reflections
/// summed: with the interface coefficient `R'` of [`reflection`],
/// `q = (2 pi d / lambda) sqrt(eta - sin^2 t)`,
/// `R = R' (1 - e^{-j2q}) / (1 - R'^2 e^{-j2q})` and
/// `T = (1 - R'^2) e^{-jq} / (1 - R'^2 e^{-j2q})`. The transmitted wave leaves parallel to
/// the incident one; `T` is referred to the slab's entry point with the extra free-space
/// phase of the slab's width removed (the ray's own path length already carries it), as in
/// ITU-R P.2040-3's `e^{-j(q - q0)}` factor with `q0 = (2 pi d / lambda) cos t`.
pub fn slab(eta: Complex, cos_theta: f64, d_m: f64, wavelength_m: f64) -> SlabCoefficients {
    let c = cos_theta.clamp(0.0, 1.0);
    let (r_te, r_tm) = reflection(eta, c);
    let k = std::f64::consts::TAU / wavelength_m;
    let root = (eta - Complex::new(1.0 - c * c, 0.0)).sqrt();
    let q = root.scale(k * d_m);
    let q0 = k * d_m * c;
    // e^{-jq} = exp(-j (q.re + j q.im)) = exp(q.im - j q.re).
    let e1 = Complex::new(q.im, -q.re).exp();
    let e2 = e1 * e1;
    let shift = Complex::cis(q0);
    let one = Complex::ONE;
    let coef = |r: Complex| {
        let den = one - r * r * e2;
        (r * (one - e2) / den, (one - r * r) * e1 * shift / den)
    };
    let (r_te_s, t_te) = coef(r_te);
    let (r_tm_s, t_tm) = coef(r_tm);
    SlabCoefficients { r_te: r_te_s, r_tm: r_tm_s, t_te, t_tm }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::itu::itu_lookup;

    fn eta_itu(name: &str, f_ghz: f64) -> Complex {
        let (m, ok) = itu_lookup(name, f_ghz).unwrap();
        assert!(ok);
        complex_permittivity(m.relative_permittivity(f_ghz), m.conductivity_s_per_m(f_ghz), f_ghz * 1e9)
    }

    #[test]
    fn normal_incidence_matches_design_values() {
        // docs/radio.md, Reference values.
        for (name, f, want) in [
            ("concrete", 3.5, 0.3946),
            ("brick", 3.5, 0.3286),
            ("glass", 3.5, 0.4306),
            ("concrete", 2.4, 0.3950),
        ] {
            let (te, tm) = reflection(eta_itu(name, f), 1.0);
            assert!((te.abs() - want).abs() < 5e-4, "{name} {f} GHz: {}", te.abs());
            // At normal incidence TE and TM coincide up to the sign convention.
            assert!((te + tm).abs() < 1e-12);
        }
    }

    #[test]
    fn perfect_conductor_reflects_everything() {
        let pec = Complex::new(1.0, -1e15);
        let metal = eta_itu("metal", 3.5);
        for i in 0..=10 {
            let c = f64::from(i) / 10.0;
            let (te, tm) = reflection(pec, c);
            assert!((te.abs() - 1.0).abs() < 1e-6 && (tm.abs() - 1.0).abs() < 1e-6, "{c}");
            // ITU metal (sigma = 1e7 S/m) is a near-perfect conductor.
            // (TM dips towards grazing incidence: the pseudo-Brewster angle of a conductor.)
            let (te, tm) = reflection(metal, c.max(0.1));
            assert!(te.abs() > 0.999 && tm.abs() > 0.998, "{c}: {} {}", te.abs(), tm.abs());
        }
        let (te, tm) = reflection(pec, 1.0);
        assert!((te + Complex::ONE).abs() < 1e-6 && (tm - Complex::ONE).abs() < 1e-6);
    }

    #[test]
    fn grazing_incidence_and_brewster() {
        let eta = eta_itu("glass", 3.5);
        let (te, tm) = reflection(eta, 0.0);
        assert!((te + Complex::ONE).abs() < 1e-9 && (tm + Complex::ONE).abs() < 1e-9);
        // Near the Brewster angle (tan t = sqrt(eps')) |R_TM| dips close to zero.
        let tb = eta.re.sqrt().atan();
        assert!(reflection(eta, tb.cos()).1.abs() < 0.02);
    }

    #[test]
    fn lossless_slab_conserves_power_and_thin_slab_is_transparent() {
        let eta = Complex::new(4.0, 0.0);
        for c in [1.0, 0.7, 0.3] {
            let s = slab(eta, c, 0.1, 0.0857);
            assert!((s.r_te.norm_sqr() + s.t_te.norm_sqr() - 1.0).abs() < 1e-9);
            assert!((s.r_tm.norm_sqr() + s.t_tm.norm_sqr() - 1.0).abs() < 1e-9);
        }
        let s = slab(eta_itu("concrete", 3.5), 1.0, 1e-6, 0.0857);
        assert!(s.r_te.abs() < 1e-3 && (s.t_te.abs() - 1.0).abs() < 1e-3);
        // A thick lossy slab reflects like a half-space and transmits almost nothing.
        let eta = eta_itu("concrete", 3.5);
        let s = slab(eta, 0.8, 2.0, 0.0857);
        assert!((s.r_te - reflection(eta, 0.8).0).abs() < 1e-3 && s.t_te.abs() < 1e-3);
    }
}
