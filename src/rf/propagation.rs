//! The radio payload of the shared launcher: a ray's complex field vector, reflected (or,
//! when walls are thin slabs, reflected or transmitted) at each surface with the exact
//! Fresnel coefficients of its ITU-R P.2040 material, and deposited into the coverage grid
//! on every crossing of the grid plane.
//!
//! One ray per path: at a slab the ray goes on as *either* the reflected or the transmitted
//! wave, chosen at random with probabilities proportional to the two branches' powers, and
//! its field is divided by the square root of the chosen probability so that every cell's
//! expected deposit is the sum over both branches (docs/radio.md, sec. 2). The work per ray
//! grows with the depth, not with 2^depth.

use glam::{DVec3, Vec3};

use super::antenna::Antenna;
use super::coverage::CoverageAccumulator;
use super::fresnel::{Complex, reflection, slab};
use crate::core::hit::Hit;
use crate::core::launcher::{Bounce, Propagation};
use crate::core::ray::Ray;
use crate::core::rng::Rng64;
use rand::RngCore;

/// A complex 3-vector: the (phasor) electric field direction and amplitude of a ray.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FieldVec {
    pub re: DVec3,
    pub im: DVec3,
}

impl FieldVec {
    pub fn real(v: DVec3) -> Self {
        Self { re: v, im: DVec3::ZERO }
    }

    /// `|E|^2`, the power the field carries relative to its launch normalisation.
    pub fn power(&self) -> f64 {
        self.re.length_squared() + self.im.length_squared()
    }

    /// The complex component along the real unit vector `u`.
    pub fn along(&self, u: DVec3) -> Complex {
        Complex::new(self.re.dot(u), self.im.dot(u))
    }

    /// `c u` for a complex `c` and a real vector `u`.
    pub fn from_component(c: Complex, u: DVec3) -> Self {
        Self { re: u * c.re, im: u * c.im }
    }

    pub fn scale(&self, c: Complex) -> Self {
        Self { re: self.re * c.re - self.im * c.im, im: self.re * c.im + self.im * c.re }
    }

    pub fn add(&self, o: &Self) -> Self {
        Self { re: self.re + o.re, im: self.im + o.im }
    }
}

/// The TE and TM basis of an interaction: `s = k x n` (normalised), `p_in = s x k_in`,
/// `p_out = s x k_out` (see [`crate::rf::fresnel`] for the convention).
#[derive(Clone, Copy, Debug)]
pub struct LocalBasis {
    pub s: DVec3,
    pub p_in: DVec3,
    pub p_out: DVec3,
    /// Cosine of the incidence angle, in [0, 1].
    pub cos_theta: f64,
    /// The specular direction.
    pub reflected: DVec3,
}

impl LocalBasis {
    /// For the unit incoming direction `k` and a unit normal `n` (either side).
    #[inline]
    pub fn new(k: DVec3, n: DVec3) -> Self {
        let kn = k.dot(n);
        // Unit when k and n are: no renormalisation needed.
        let reflected = k - 2.0 * kn * n;
        let mut s = k.cross(n);
        if s.length_squared() < 1e-20 {
            // Normal incidence: any direction perpendicular to k will do.
            let any = if k.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
            s = any - any.dot(k) * k;
        }
        let s = s.normalize();
        Self { s, p_in: s.cross(k), p_out: s.cross(reflected), cos_theta: kn.abs().min(1.0), reflected }
    }

    /// The reflected field `R_TE E_s s + R_TM E_p p_out`.
    pub fn reflect(&self, e: &FieldVec, r_te: Complex, r_tm: Complex) -> FieldVec {
        FieldVec::from_component(r_te * e.along(self.s), self.s)
            .add(&FieldVec::from_component(r_tm * e.along(self.p_in), self.p_out))
    }

    /// The transmitted field `T_TE E_s s + T_TM E_p p_in` (direction unchanged).
    pub fn transmit(&self, e: &FieldVec, t_te: Complex, t_tm: Complex) -> FieldVec {
        FieldVec::from_component(t_te * e.along(self.s), self.s)
            .add(&FieldVec::from_component(t_tm * e.along(self.p_in), self.p_in))
    }
}

/// Reflection coefficients (TE, TM) and, for slabs, transmission coefficients (TE, TM).
pub type Coefficients = (Complex, Complex, Option<(Complex, Complex)>);

/// How surfaces act on radio waves at one frequency.
#[derive(Clone, Debug)]
pub struct SurfacePhysics {
    /// Complex relative permittivity of each surface (indexed by `SurfaceId`); `None`
    /// absorbs (no reflection).
    pub eta: Vec<Option<Complex>>,
    /// Walls are thin slabs that also transmit, each surface (indexed by `SurfaceId`) of
    /// this thickness, metres; or (`None`) opaque half-spaces that only reflect.
    pub slab_thickness_m: Option<Vec<f64>>,
    pub wavelength_m: f64,
}

impl SurfacePhysics {
    /// Reflection coefficients (TE, TM) on `surface` at `cos_theta`, and the transmission
    /// coefficients when walls are slabs.
    pub fn coefficients(&self, surface: u32, cos_theta: f64) -> Option<Coefficients> {
        let eta = (*self.eta.get(surface as usize)?)?;
        Some(match &self.slab_thickness_m {
            None => {
                let (te, tm) = reflection(eta, cos_theta);
                (te, tm, None)
            }
            Some(d) => {
                let s = slab(eta, cos_theta, *d.get(surface as usize)?, self.wavelength_m);
                (s.r_te, s.r_tm, Some((s.t_te, s.t_tm)))
            }
        })
    }
}

/// The radio [`Propagation`]: payload = the ray's field vector, normalised so that its
/// expected `|E|^2` is `G(dir) prod |Gamma|^2` (power relative to `P_tx / N`), the product
/// over the interactions of the branch the path took (`|R|^2` or `|T|^2`).
pub struct RadioPropagation<'a> {
    pub antenna: Antenna,
    pub physics: &'a SurfacePhysics,
    pub grid: &'a CoverageAccumulator,
}

/// Below this relative power a ray stops (it can no longer change any cell's value).
const MIN_POWER: f64 = 1.0e-12;

impl Propagation for RadioPropagation<'_> {
    type Payload = FieldVec;
    type Accum = ();

    fn new_accum(&self) {}

    fn merge(&self, _: &mut (), _: ()) {}

    fn emit(&self, _ray_index: u64, dir: Vec3) -> FieldVec {
        let d = dir.as_dvec3();
        FieldVec::real(self.antenna.polarization(d) * self.antenna.gain(d).sqrt())
    }

    fn segment(&self, _: &mut (), payload: &FieldVec, ray: &Ray, length_m: f32, _: f32, _: u32) {
        self.grid.record(
            ray.origin.as_dvec3().to_array(),
            ray.dir.as_dvec3().to_array(),
            f64::from(length_m),
            payload.power(),
        );
    }

    fn interact(
        &self,
        _: &mut (),
        payload: &mut FieldVec,
        hit: &Hit,
        incoming: Vec3,
        _: f32,
        rng: &mut Rng64,
    ) -> Bounce {
        let basis = LocalBasis::new(incoming.as_dvec3(), hit.normal.as_dvec3());
        let Some((r_te, r_tm, t)) = self.physics.coefficients(hit.surface, basis.cos_theta) else {
            return Bounce::Stop;
        };
        let reflected = basis.reflect(payload, r_te, r_tm);
        let Some((t_te, t_tm)) = t else {
            *payload = reflected;
            if payload.power() < MIN_POWER {
                return Bounce::Stop;
            }
            return Bounce::Continue(basis.reflected.as_vec3());
        };
        let transmitted = basis.transmit(payload, t_te, t_tm);
        match choose_branch(reflected.power(), transmitted.power(), unit_f64(rng)) {
            None => Bounce::Stop,
            Some((Branch::Reflected, scale)) => {
                *payload = reflected.scale(Complex::new(scale, 0.0));
                Bounce::Continue(basis.reflected.as_vec3())
            }
            // A thin slab does not offset the ray: it goes on along its incoming direction,
            // and the launcher's `Ray::spawn` starts it on the far side of the surface (the
            // side the direction points to).
            Some((Branch::Transmitted, scale)) => {
                *payload = transmitted.scale(Complex::new(scale, 0.0));
                Bounce::Continue(incoming)
            }
        }
    }
}

/// The branch a ray takes at a slab.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Branch {
    Reflected,
    Transmitted,
}

/// A uniform `f64` in `[0, 1)` with 53 random bits.
fn unit_f64(rng: &mut Rng64) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / 9_007_199_254_740_992.0)
}

/// The unbiased choice between the reflected branch (power `p_r`) and the transmitted one
/// (`p_t`) for a uniform `u` in `[0, 1)`: transmitted when `u (p_r + p_t) < p_t`, i.e. with
/// probability `q_t = p_t / (p_r + p_t)`, else reflected (`q_r = p_r / (p_r + p_t)`), and the
/// amplitude factor `1 / sqrt(q)` of the chosen branch, which makes the expected power
/// `q_r (p_r / q_r) + q_t (p_t / q_t) = p_r + p_t` (docs/radio.md, sec. 2). The carried power
/// after the choice is `p_r + p_t` on either branch, at most the incident power (a passive
/// slab), so weights never grow. `None` when both branches carry less than the cut-off.
pub fn choose_branch(p_r: f64, p_t: f64, u: f64) -> Option<(Branch, f64)> {
    let total = p_r + p_t;
    // (NaN fails this test too.)
    if total.is_nan() || total < MIN_POWER {
        return None;
    }
    if u * total < p_t {
        Some((Branch::Transmitted, (total / p_t).sqrt()))
    } else {
        Some((Branch::Reflected, (total / p_r).sqrt()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_branch_choice_is_proportional_to_power_and_unbiased() {
        // Over a uniform grid of u the mean weighted power of each branch is its own power.
        let (p_r, p_t) = (0.3, 0.05);
        let n = 100_000;
        let (mut sum_r, mut sum_t, mut count_t) = (0.0, 0.0, 0);
        for i in 0..n {
            let u = (f64::from(i) + 0.5) / f64::from(n);
            let (b, scale) = choose_branch(p_r, p_t, u).unwrap();
            match b {
                Branch::Reflected => sum_r += p_r * scale * scale,
                Branch::Transmitted => {
                    sum_t += p_t * scale * scale;
                    count_t += 1;
                }
            }
        }
        assert!((f64::from(count_t) / f64::from(n) - p_t / (p_r + p_t)).abs() < 1e-4);
        assert!((sum_r / f64::from(n) - p_r).abs() < 1e-4 * p_r, "{}", sum_r / f64::from(n));
        assert!((sum_t / f64::from(n) - p_t).abs() < 1e-4 * p_t, "{}", sum_t / f64::from(n));
        // A branch without power is never chosen; nothing at all stops the ray.
        assert_eq!(choose_branch(0.2, 0.0, 0.0).map(|c| c.0), Some(Branch::Reflected));
        assert_eq!(choose_branch(0.0, 0.2, 0.999).map(|c| c.0), Some(Branch::Transmitted));
        assert_eq!(choose_branch(0.0, 0.0, 0.5), None);
        assert_eq!(choose_branch(f64::NAN, 0.1, 0.5), None);
    }

    #[test]
    fn conductor_reflection_cancels_the_tangential_field() {
        // Perfect conductor: the incident plus reflected tangential field vanishes at the
        // surface whatever the polarisation and angle.
        let n = DVec3::Z;
        let (te, tm) = reflection(Complex::new(1.0, -1e15), 0.5);
        for k in [DVec3::new(0.6, 0.0, -0.8), DVec3::new(0.3, 0.4, -(0.75f64).sqrt())] {
            let k = k.normalize();
            let b = LocalBasis::new(k, n);
            for pol in [b.s, b.p_in, (b.s + b.p_in).normalize()] {
                let e = FieldVec::real(pol);
                let r = b.reflect(&e, te, tm);
                let total = e.add(&r);
                let tangential = total.re - total.re.dot(n) * n;
                assert!(tangential.length() < 1e-6, "{tangential}");
                assert!((r.power() - 1.0).abs() < 1e-6);
                assert!(r.re.dot(b.reflected).abs() < 1e-9);
            }
        }
    }
}
