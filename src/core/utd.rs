//! The uniform theory of diffraction (UTD) coefficient of a wedge, the wave mathematics that
//! sound and radio share: Kouyoumjian and Pathak's transition function and the four
//! cotangent terms of their diffraction coefficient (\[Kouyoumjian1974\] in
//! docs/references.md). The simulators weigh the two reflection terms with their faces'
//! reflection coefficients (radio: Fresnel, after Luebbers; sound: the rigid or absorbing
//! face's pressure reflection factor).
//!
//! ```text
//! D = -e^{-j pi/4} / (2 n sqrt(2 pi k) sin beta0) [
//!       cot((pi + (phi - phi')) / 2n) F(kL a+(phi - phi')) + cot((pi - (phi - phi')) / 2n) F(kL a-(phi - phi'))
//!     + R_0 cot((pi - (phi + phi')) / 2n) F(kL a-(phi + phi')) + R_n cot((pi + (phi + phi')) / 2n) F(kL a+(phi + phi')) ]
//! ```
//!
//! for a wedge of exterior angle `n pi`, source azimuth `phi'` and observer azimuth `phi`
//! (from face 0), wavenumber `k` and distance parameter `L` (`s s' sin^2 beta0 / (s + s')` for
//! a point source).

use super::complex::Complex;

/// `integral_0^inf e^{-j t^2} dt = sqrt(pi / 8) (1 - j)`.
fn fresnel_infinity() -> Complex {
    let a = (std::f64::consts::PI / 8.0).sqrt();
    Complex::new(a, -a)
}

/// Above this argument the transition function is summed from its asymptotic series.
const ASYMPTOTIC_X: f64 = 16.0;

/// `F(x) / sqrt(x) = 2j e^{jx} integral_sqrt(x)^inf e^{-j t^2} dt` for `x >= 0` (finite at 0,
/// where it is `sqrt(pi / 2) (1 + j)`): the transition function of Kouyoumjian and Pathak
/// without its vanishing factor.
pub fn transition_over_sqrt(x: f64) -> Complex {
    let x = if x.is_finite() { x.max(0.0) } else { return Complex::ZERO };
    if x > ASYMPTOTIC_X {
        return transition(x).scale(1.0 / x.sqrt());
    }
    // integral_0^u e^{-j t^2} dt = sum (-j)^m u^{2m+1} / (m! (2m+1)).
    let u = x.sqrt();
    let step = Complex::new(0.0, -x);
    let mut power = Complex::ONE;
    let mut sum = Complex::ZERO;
    for m in 0..200u32 {
        let term = power.scale(u / f64::from(2 * m + 1));
        sum = sum + term;
        if f64::from(m) > x && term.norm_sqr() < 1.0e-36 {
            break;
        }
        power = (power * step).scale(1.0 / f64::from(m + 1));
    }
    Complex::new(0.0, 2.0) * Complex::cis(x) * (fresnel_infinity() - sum)
}

/// The transition function `F(x) = 2j sqrt(x) e^{jx} integral_sqrt(x)^inf e^{-j t^2} dt`,
/// `x >= 0` (Kouyoumjian and Pathak 1974): 0 at 0, tending to 1 for large `x`.
pub fn transition(x: f64) -> Complex {
    if !(x.is_finite() && x > 0.0) {
        return if x == f64::INFINITY { Complex::ONE } else { Complex::ZERO };
    }
    if x <= ASYMPTOTIC_X {
        return transition_over_sqrt(x).scale(x.sqrt());
    }
    // F(x) ~ sum_k (2k - 1)!! (j / 2x)^k.
    let mut term = Complex::ONE;
    let mut sum = Complex::ONE;
    let q = Complex::new(0.0, 0.5 / x);
    for k in 1..64u32 {
        let next = (term * q).scale(f64::from(2 * k - 1));
        if next.norm_sqr() >= term.norm_sqr() {
            break;
        }
        term = next;
        sum = sum + term;
        if term.norm_sqr() < 1.0e-34 {
            break;
        }
    }
    sum
}

/// `cot(psi) F(x)` with `x = kL a`, finite on a shadow or reflection boundary where both
/// factors' limits meet (`cot -> inf`, `F -> 0`): there it is `n sqrt(2 kL) sqrt(x) F(x) / x`
/// in the limit, `sign(sin psi) n sqrt(2 pi kL) e^{j pi / 4}`.
fn cot_times_transition(psi: f64, x: f64, n: f64, kl: f64) -> Complex {
    let (s, c) = psi.sin_cos();
    let ratio = if s.abs() > 1.0e-12 { x.max(0.0).sqrt() / s } else { n * (2.0 * kl).sqrt() };
    transition_over_sqrt(x).scale(c * ratio)
}

/// `a(beta) = 2 cos^2((2 n pi N - beta) / 2)` with `N` the integer nearest to a solution of
/// `2 pi n N - beta = sign pi`.
fn a_of(beta: f64, n: f64, sign: f64) -> f64 {
    let big_n = ((beta + sign * std::f64::consts::PI) / (std::f64::consts::TAU * n)).round();
    let c = ((std::f64::consts::TAU * n * big_n - beta) / 2.0).cos();
    2.0 * c * c
}

/// The four terms of a wedge's UTD coefficient for one source and observer azimuth and one
/// wavenumber: combine them with the faces' reflection coefficients by
/// [`WedgeTerms::coefficient`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WedgeTerms {
    /// `-e^{-j pi/4} / (2 n sqrt(2 pi k) sin beta0)`.
    pub prefactor: Complex,
    /// The incident-field terms `t1 + t2` (the shadow boundary's).
    pub incident: Complex,
    /// The reflection term of face 0, `t3`.
    pub face_0: Complex,
    /// The reflection term of face n, `t4`.
    pub face_n: Complex,
}

impl WedgeTerms {
    /// The terms for exterior angle `n pi`, observer azimuth `phi`, source azimuth `phi_p`
    /// (radians from face 0), wavenumber `k` (1/m), distance parameter `l` (m) and
    /// `sin beta0` (see the module doc). Finite on the shadow and reflection boundaries.
    pub fn new(n: f64, phi: f64, phi_p: f64, k: f64, l: f64, sin_beta0: f64) -> Self {
        use std::f64::consts::PI;
        let kl = k * l;
        let (dm, sm) = (phi - phi_p, phi + phi_p);
        let t1 = cot_times_transition((PI + dm) / (2.0 * n), kl * a_of(dm, n, 1.0), n, kl);
        let t2 = cot_times_transition((PI - dm) / (2.0 * n), kl * a_of(dm, n, -1.0), n, kl);
        let t3 = cot_times_transition((PI - sm) / (2.0 * n), kl * a_of(sm, n, -1.0), n, kl);
        let t4 = cot_times_transition((PI + sm) / (2.0 * n), kl * a_of(sm, n, 1.0), n, kl);
        let prefactor =
            -Complex::cis(-PI / 4.0).scale(1.0 / (2.0 * n * (std::f64::consts::TAU * k).sqrt() * sin_beta0));
        Self { prefactor, incident: t1 + t2, face_0: t3, face_n: t4 }
    }

    /// The diffraction coefficient with reflection coefficients `r0` of face 0 (for the
    /// incident ray) and `rn` of face n (for the diffracted ray).
    pub fn coefficient(&self, r0: Complex, rn: Complex) -> Complex {
        self.prefactor * (self.incident + r0 * self.face_0 + rn * self.face_n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transition_function_limits_and_continuity() {
        assert_eq!(transition(0.0), Complex::ZERO);
        // Small x: F ~ (sqrt(pi x) - 2x e^{j pi/4}) e^{j (pi/4 + x)} (Kouyoumjian and Pathak).
        let x = 1e-6;
        let f = transition(x);
        let q = Complex::cis(std::f64::consts::FRAC_PI_4);
        let expect = (Complex::new((std::f64::consts::PI * x).sqrt(), 0.0) - q.scale(2.0 * x))
            * Complex::cis(std::f64::consts::FRAC_PI_4 + x);
        assert!((f - expect).abs() < 1e-6 * expect.abs());
        // Large x: F -> 1 + j / 2x.
        let f = transition(1e4);
        assert!((f - Complex::new(1.0, 0.5e-4)).abs() < 1e-8);
        // The series and the asymptotic sum meet (the latter's smallest term is 1e-7 there).
        let (a, b) = (transition(ASYMPTOTIC_X), transition(ASYMPTOTIC_X * (1.0 + 1e-12)));
        assert!((a - b).abs() < 3e-7, "{a:?} {b:?}");
        // Values from the Fresnel integrals C and S to 30 digits (mpmath), to 15 here.
        for (x, re, im) in [
            (0.1, 0.368_103_567_800_482, 0.234_452_962_292_473),
            (1.0, 0.809_525_481_747_408, 0.232_199_390_055_264),
            (10.0, 0.993_041_127_011_626, 0.048_351_495_561_654),
            (16.0, 0.997_162_202_013_751, 0.030_817_191_851_341),
        ] {
            assert!((transition(x) - Complex::new(re, im)).abs() < 1e-9, "F({x}) = {:?}", transition(x));
        }
        assert!(transition(f64::NAN) == Complex::ZERO);
    }
}
