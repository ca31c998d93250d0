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
//!
//! A surface with a scattering coefficient `S > 0` adds a third branch, the diffuse
//! reflection (Degli-Esposti et al. 2007, as in Sionna RT): the specular field keeps
//! `sqrt(1 - S^2)` of its amplitude and `S^2` of the reflected power leaves in a direction
//! drawn from the scattering pattern (docs/radio.md, sec. 4).

use std::sync::Arc;

use glam::{DVec3, Vec3};

use super::antenna::Antenna;
use super::coefficient_table::CoefficientTable;
use super::coverage::CoverageAccumulator;
use super::fresnel::{Complex, reflection, slab};
use crate::core::hit::Hit;
use crate::core::launcher::{Bounce, Propagation};
use crate::core::ray::Ray;
use crate::core::rng::Rng64;
use crate::scene::materials::{RadioScattering, ScatteringPattern};
use rand::RngCore;

/// A complex 3-vector: the (phasor) electric field direction and amplitude of a ray.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FieldVec {
    /// Real part.
    pub re: DVec3,
    /// Imaginary part.
    pub im: DVec3,
}

impl FieldVec {
    /// A field with a real vector `v`.
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

    /// The field times the complex `c`.
    pub fn scale(&self, c: Complex) -> Self {
        Self { re: self.re * c.re - self.im * c.im, im: self.re * c.im + self.im * c.re }
    }

    /// The sum of two fields.
    pub fn add(&self, o: &Self) -> Self {
        Self { re: self.re + o.re, im: self.im + o.im }
    }
}

/// The TE and TM basis of an interaction: `s = k x n` (normalised), `p_in = s x k_in`,
/// `p_out = s x k_out` (see [`crate::rf::fresnel`] for the convention).
#[derive(Clone, Copy, Debug)]
pub struct LocalBasis {
    /// TE direction, `k x n` normalised.
    pub s: DVec3,
    /// TM direction of the incoming ray, `s x k_in`.
    pub p_in: DVec3,
    /// TM direction of the outgoing ray, `s x k_out`.
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

    /// The field's TE and TM components `(E_s, E_p)` (along `s` and `p_in`).
    #[inline]
    pub fn components(&self, e: &FieldVec) -> (Complex, Complex) {
        (e.along(self.s), e.along(self.p_in))
    }

    /// [`Self::reflect`] of the field with components `(E_s, E_p)`, times the real `scale`.
    #[inline]
    pub fn reflect_components(
        &self,
        (es, ep): (Complex, Complex),
        r_te: Complex,
        r_tm: Complex,
        scale: f64,
    ) -> FieldVec {
        FieldVec::from_component((r_te * es).scale(scale), self.s)
            .add(&FieldVec::from_component((r_tm * ep).scale(scale), self.p_out))
    }

    /// [`Self::transmit`] of the field with components `(E_s, E_p)`, times the real `scale`.
    #[inline]
    pub fn transmit_components(
        &self,
        (es, ep): (Complex, Complex),
        t_te: Complex,
        t_tm: Complex,
        scale: f64,
    ) -> FieldVec {
        FieldVec::from_component((t_te * es).scale(scale), self.s)
            .add(&FieldVec::from_component((t_tm * ep).scale(scale), self.p_in))
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
    /// Wavelength, metres.
    pub wavelength_m: f64,
    /// Diffuse reflection of each surface (indexed by `SurfaceId`); a surface beyond the end
    /// is purely specular (`S = 0`).
    pub scattering: Vec<RadioScattering>,
    /// The coefficients tabulated over `cos theta` ([`Self::tabulated`]); `None`: computed
    /// exactly at every interaction.
    pub table: Option<Arc<CoefficientTable>>,
}

impl SurfacePhysics {
    /// The same physics with its coefficients tabulated for the launcher's hot loop
    /// (`super::coefficient_table`: within `MAX_TABLE_ERROR` of the exact values).
    pub fn tabulated(mut self) -> Self {
        let table = CoefficientTable::build(&self.eta, self.slab_thickness_m.as_deref(), self.wavelength_m);
        self.table = Some(Arc::new(table));
        self
    }

    /// Reflection coefficients (TE, TM) on `surface` at `cos_theta`, and the transmission
    /// coefficients when walls are slabs: from the table when there is one, else exact.
    #[inline(always)]
    pub fn coefficients(&self, surface: u32, cos_theta: f64) -> Option<Coefficients> {
        match &self.table {
            Some(t) => t.coefficients(surface, cos_theta),
            None => self.exact_coefficients(surface, cos_theta),
        }
    }

    /// [`Self::coefficients`] from the exact formulas of ITU-R P.2040-3 (`super::fresnel`).
    pub fn exact_coefficients(&self, surface: u32, cos_theta: f64) -> Option<Coefficients> {
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

    /// The diffuse reflection of `surface` (`S = 0` when not given).
    pub fn scattering(&self, surface: u32) -> RadioScattering {
        self.scattering.get(surface as usize).copied().unwrap_or_default()
    }

    /// The factor `R = sqrt(1 - S^2)` on the specular reflection coefficients of `surface`
    /// (Sionna RT's reflection reduction factor; docs/radio.md, sec. 4).
    pub fn specular_factor(&self, surface: u32) -> f64 {
        let s = self.scattering(surface).scattering_coefficient;
        (1.0 - s * s).sqrt()
    }
}

/// The radio [`Propagation`]: payload = the ray's field vector, normalised so that its
/// expected `|E|^2` is `G(dir) prod |Gamma|^2` (power relative to `P_tx / N`), the product
/// over the interactions of the branch the path took (`|R|^2` or `|T|^2`).
pub struct RadioPropagation<'a> {
    /// Transmitter antenna.
    pub antenna: Antenna,
    /// Surfaces' radio physics.
    pub physics: &'a SurfacePhysics,
    /// The coverage grid the rays deposit into.
    pub grid: &'a CoverageAccumulator,
}

/// What a block of radio rays leaves behind: its segment count and its grid crossings (cell,
/// fixed-point deposit), added to the grid when the block is merged.
#[derive(Debug, Default)]
pub struct RadioAccum {
    /// Ray segments traced.
    pub segments: u64,
    /// Grid crossings: cell index and fixed-point deposit.
    pub crossings: Vec<(u32, u64)>,
}

/// Below this relative power a ray stops (it can no longer change any cell's value).
const MIN_POWER: f64 = 1.0e-12;

impl Propagation for RadioPropagation<'_> {
    type Payload = FieldVec;
    type Accum = RadioAccum;

    fn new_accum(&self) -> RadioAccum {
        RadioAccum::default()
    }

    /// Adds the block's crossings to the grid (blocks are merged one at a time).
    fn merge(&self, into: &mut RadioAccum, other: RadioAccum) {
        into.segments += other.segments;
        self.grid.absorb(&other.crossings);
    }

    #[inline(always)]
    fn emit(&self, _ray_index: u64, dir: Vec3) -> FieldVec {
        let d = dir.as_dvec3();
        FieldVec::real(self.antenna.polarization(d) * self.antenna.gain(d).sqrt())
    }

    #[inline(always)]
    fn segment(&self, acc: &mut RadioAccum, payload: &FieldVec, ray: &Ray, length_m: f32, _: f32, _: u32) {
        acc.segments += 1;
        if let Some(c) = self.grid.crossing(
            ray.origin.as_dvec3().to_array(),
            ray.dir.as_dvec3().to_array(),
            f64::from(length_m),
            payload.power(),
        ) {
            acc.crossings.push(c);
        }
    }

    /// A last segment deposits only where it crosses the grid plane: it matters up to that
    /// crossing (rounded up to `f32`, so that [`CoverageAccumulator::crossing`] still finds
    /// it), and not at all when the crossing misses the grid.
    #[inline(always)]
    fn last_segment_reach(&self, payload: &FieldVec, ray: &Ray) -> Option<f32> {
        if payload.power() <= 0.0 {
            return Some(0.0);
        }
        let t = self.grid.reach(ray.origin.as_dvec3().to_array(), ray.dir.as_dvec3().to_array());
        let r = t as f32;
        Some(if f64::from(r) < t { r.next_up() } else { r })
    }

    #[inline(always)]
    fn interact(
        &self,
        _: &mut RadioAccum,
        payload: &mut FieldVec,
        hit: &Hit,
        incoming: Vec3,
        _: f32,
        rng: &mut Rng64,
    ) -> Bounce {
        let k = incoming.as_dvec3();
        let mut uniform = || unit_f64(rng);
        match interaction(self.physics, hit.surface, payload, k, hit.normal.as_dvec3(), &mut uniform) {
            None => Bounce::Stop,
            Some(out) => {
                *payload = out.field;
                // (A transmitted ray's direction is `incoming` itself: f32 to f64 and back is
                // exact.)
                Bounce::Continue(out.direction.as_vec3())
            }
        }
    }
}

/// What a ray becomes at an interaction: its branch, its field (weighted) and its direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interacted {
    /// Which branch the ray took.
    pub branch: Branch,
    /// Its field after the interaction (weighted).
    pub field: FieldVec,
    /// Its new direction.
    pub direction: DVec3,
}

/// One interaction of the one-ray-per-path walk: the field `e` along the unit `k` meets
/// `surface` (unit normal `n`, either side); the branch is drawn in proportion to the powers
/// and weighted by `1 / sqrt(q)` (docs/radio.md, secs. 2 and 4). `uniform` is called only for
/// a choice (never on a specular opaque surface); `None`: the ray stops.
#[inline(always)]
pub fn interaction(
    physics: &SurfacePhysics,
    surface: u32,
    e: &FieldVec,
    k: DVec3,
    n: DVec3,
    uniform: &mut impl FnMut() -> f64,
) -> Option<Interacted> {
    let basis = LocalBasis::new(k, n);
    let (r_te, r_tm, t) = physics.coefficients(surface, basis.cos_theta)?;
    let scattering = physics.scattering(surface);
    let s = scattering.scattering_coefficient;
    let specular =
        |field: FieldVec| Interacted { branch: Branch::Reflected, field, direction: basis.reflected };
    if s == 0.0 {
        // Purely specular: the walk of docs/radio.md, sec. 2, draw for draw. The branch
        // powers follow from the TE and TM components (`s` and `p` are orthonormal), and only
        // the chosen branch's field is built.
        let c = basis.components(e);
        let (ps, pp) = (c.0.norm_sqr(), c.1.norm_sqr());
        let p_r = r_te.norm_sqr() * ps + r_tm.norm_sqr() * pp;
        let Some((t_te, t_tm)) = t else {
            return (p_r >= MIN_POWER).then(|| specular(basis.reflect_components(c, r_te, r_tm, 1.0)));
        };
        let p_t = t_te.norm_sqr() * ps + t_tm.norm_sqr() * pp;
        return match choose_branch(p_r, p_t, uniform())? {
            (Branch::Transmitted, scale) => Some(Interacted {
                branch: Branch::Transmitted,
                field: basis.transmit_components(c, t_te, t_tm, scale),
                direction: k,
            }),
            (_, scale) => Some(specular(basis.reflect_components(c, r_te, r_tm, scale))),
        };
    }
    let reflected = basis.reflect(e, r_te, r_tm);
    // The reflected power splits into (1 - S^2) specular and S^2 diffuse (Sionna RT).
    let p_reflected = reflected.power();
    let p_specular = (1.0 - s * s) * p_reflected;
    let p_diffuse = s * s * p_reflected;
    let transmitted = t.map(|(t_te, t_tm)| basis.transmit(e, t_te, t_tm));
    let p_transmitted = transmitted.map_or(0.0, |f| f.power());
    let (branch, scale) = choose_interaction(p_specular, p_diffuse, p_transmitted, uniform())?;
    match (branch, transmitted) {
        (Branch::Transmitted, Some(tr)) => {
            Some(Interacted { branch, field: tr.scale(Complex::new(scale, 0.0)), direction: k })
        }
        (Branch::Diffuse, _) => {
            // The side the wave came from.
            let n_out = if k.dot(n) < 0.0 { n } else { -n };
            let direction = sample_pattern(scattering.pattern, basis.reflected, n_out, uniform)?;
            let field = diffuse_polarization(e, k, direction, scattering.xpd_coefficient);
            // The pattern is sampled exactly (pdf = f_s), so the carried power is the total
            // `p_specular + p_diffuse + p_transmitted` as on the other branches.
            let total = p_specular + p_diffuse + p_transmitted;
            let carried = field.power();
            if carried.is_nan() || carried <= 0.0 {
                return None;
            }
            Some(Interacted {
                branch,
                field: field.scale(Complex::new((total / carried).sqrt(), 0.0)),
                direction,
            })
        }
        _ => Some(specular(reflected.scale(Complex::new((1.0 - s * s).sqrt() * scale, 0.0)))),
    }
}

/// Most draws of the directive pattern's rejection sampler (each is accepted with probability
/// at least 1/2, so the cap is never reached in practice; the ray then stops).
const MAX_PATTERN_DRAWS: u32 = 64;

/// A unit vector drawn from the pattern `f_s` over the hemisphere of `n_out` (the incident
/// side), `k_r` the specular direction: cosine-weighted (Lambertian), or the directive lobe
/// about `k_r` by inverse CDF, rejected below the surface (docs/radio.md, sec. 4).
pub fn sample_pattern(
    pattern: ScatteringPattern,
    k_r: DVec3,
    n_out: DVec3,
    uniform: &mut impl FnMut() -> f64,
) -> Option<DVec3> {
    match pattern {
        ScatteringPattern::Lambertian => {
            let (u1, u2) = (uniform(), uniform());
            // cos(theta) = sqrt(1 - u1): the density cos(theta) / pi over solid angle.
            let (sin_t, cos_t) = (u1.sqrt(), (1.0 - u1).sqrt());
            let (sin_p, cos_p) = (std::f64::consts::TAU * u2).sin_cos();
            let (a, b) = orthonormal_basis(n_out);
            Some((a * (sin_t * cos_p) + b * (sin_t * sin_p) + n_out * cos_t).normalize())
        }
        ScatteringPattern::Directive { alpha_r } => {
            let (a, b) = orthonormal_basis(k_r);
            let exponent = 1.0 / (f64::from(alpha_r) + 1.0);
            for _ in 0..MAX_PATTERN_DRAWS {
                let (u1, u2) = (uniform(), uniform());
                // x = (1 + cos psi) / 2 has the density (alpha + 1) x^alpha on [0, 1].
                let cos_psi = (2.0 * (1.0 - u1).powf(exponent) - 1.0).clamp(-1.0, 1.0);
                let sin_psi = (1.0 - cos_psi * cos_psi).max(0.0).sqrt();
                let (sin_p, cos_p) = (std::f64::consts::TAU * u2).sin_cos();
                let d = (a * (sin_psi * cos_p) + b * (sin_psi * sin_p) + k_r * cos_psi).normalize();
                if d.dot(n_out) > 0.0 {
                    return Some(d);
                }
            }
            None
        }
    }
}

/// The pattern `f_s(k_i, k_s)` per steradian over the hemisphere of `n_out`: `cos / pi` or
/// `((1 + k_r . k_s) / 2)^alpha / F_alpha` (Degli-Esposti et al. 2007 via Sionna RT's EM primer).
pub fn pattern_density(pattern: ScatteringPattern, k_r: DVec3, n_out: DVec3, k_s: DVec3) -> f64 {
    let cos_s = k_s.dot(n_out);
    if cos_s <= 0.0 {
        return 0.0;
    }
    match pattern {
        ScatteringPattern::Lambertian => cos_s / std::f64::consts::PI,
        ScatteringPattern::Directive { alpha_r } => {
            let lobe = ((1.0 + k_r.dot(k_s)) / 2.0).max(0.0).powi(alpha_r as i32);
            lobe / directive_normalisation(alpha_r, k_r.dot(n_out).clamp(0.0, 1.0))
        }
    }
}

/// `F_alpha(theta_i) = 2^-alpha sum_k C(alpha, k) I_k`, the hemisphere integral of the
/// directive lobe (Degli-Esposti et al. 2007 via Sionna RT's EM primer; docs/radio.md, sec. 4).
fn directive_normalisation(alpha: u32, cos_theta_i: f64) -> f64 {
    let sin2 = 1.0 - cos_theta_i * cos_theta_i;
    let mut total = 0.0;
    // C(alpha, k) / 2^alpha, built up term by term (no overflow for large alpha).
    let mut weight = 0.5f64.powi(alpha as i32);
    // The partial sum of C(2w, w) (sin^2 / 4)^w for odd k, extended as k grows.
    let (mut odd_sum, mut odd_term, mut w_done) = (0.0, 1.0, 0u32);
    for k in 0..=alpha {
        let i_k = if k % 2 == 0 {
            std::f64::consts::TAU / f64::from(k + 1)
        } else {
            while w_done <= (k - 1) / 2 {
                odd_sum += odd_term;
                // C(2w + 2, w + 1) / C(2w, w) = (2w + 1)(2w + 2) / (w + 1)^2.
                let w = f64::from(w_done);
                odd_term *= (2.0 * w + 1.0) * (2.0 * w + 2.0) / ((w + 1.0) * (w + 1.0)) * sin2 / 4.0;
                w_done += 1;
            }
            std::f64::consts::TAU / f64::from(k + 1) * cos_theta_i * odd_sum
        };
        total += weight * i_k;
        weight *= f64::from(alpha - k) / f64::from(k + 1);
    }
    total
}

/// Two unit vectors completing the unit `n` to a right-handed orthonormal basis (Duff et al.
/// 2017, "Building an orthonormal basis, revisited", JCGT 6(1)).
fn orthonormal_basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), DVec3::new(b, sign + n.y * n.y * a, -n.y))
}

/// The spherical unit vectors `(theta_hat, phi_hat)` of the direction `k` (zenith from +z,
/// azimuth from +x; `phi = 0` on the z axis), the basis of Sionna RT's scattered field.
pub fn theta_phi_basis(k: DVec3) -> (DVec3, DVec3) {
    let sin_t = k.x.hypot(k.y);
    let (cos_p, sin_p) = if sin_t > 1e-12 { (k.x / sin_t, k.y / sin_t) } else { (1.0, 0.0) };
    let cos_t = k.z;
    (DVec3::new(cos_t * cos_p, cos_t * sin_p, -sin_t), DVec3::new(-sin_p, cos_p, 0.0))
}

/// The diffusely scattered field: `e` on `(theta_hat, phi_hat)` of `k_in`, turned by the
/// rotation `[[sqrt(1-K_x), -sqrt(K_x)], [sqrt(K_x), sqrt(1-K_x)]]` onto those of `k_s`
/// (Degli-Esposti et al. 2011 eq. 9 as in Sionna RT, no random phases; docs/radio.md, sec. 4).
pub fn diffuse_polarization(e: &FieldVec, k_in: DVec3, k_s: DVec3, xpd_coefficient: f64) -> FieldVec {
    let (t_in, p_in) = theta_phi_basis(k_in);
    let (t_s, p_s) = theta_phi_basis(k_s);
    let (e_t, e_p) = (e.along(t_in), e.along(p_in));
    let (a, b) = ((1.0 - xpd_coefficient).sqrt(), xpd_coefficient.sqrt());
    FieldVec::from_component(e_t.scale(a) - e_p.scale(b), t_s)
        .add(&FieldVec::from_component(e_t.scale(b) + e_p.scale(a), p_s))
}

/// The branch a ray takes at a surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Branch {
    /// Specular reflection.
    Reflected,
    /// Transmission through the wall.
    Transmitted,
    /// Diffuse reflection (a surface with `S > 0`).
    Diffuse,
}

/// A uniform `f64` in `[0, 1)` with 53 random bits.
#[inline]
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
#[inline]
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

/// [`choose_branch`] with a third branch, the diffuse reflection (power `p_d`): transmitted
/// when `u P < p_t`, diffuse when `p_t <= u P < p_t + p_d`, else specular, `P` the sum of the
/// three, each with the amplitude factor `1 / sqrt(q) = sqrt(P / p)` (docs/radio.md, secs. 2
/// and 4).
pub fn choose_interaction(p_r: f64, p_d: f64, p_t: f64, u: f64) -> Option<(Branch, f64)> {
    let total = p_r + p_d + p_t;
    if total.is_nan() || total < MIN_POWER {
        return None;
    }
    let x = u * total;
    if x < p_t {
        Some((Branch::Transmitted, (total / p_t).sqrt()))
    } else if x < p_t + p_d {
        Some((Branch::Diffuse, (total / p_d).sqrt()))
    } else if p_r > 0.0 {
        Some((Branch::Reflected, (total / p_r).sqrt()))
    } else if p_d > 0.0 {
        // Rounding put `u P` at the very top with no specular power.
        Some((Branch::Diffuse, (total / p_d).sqrt()))
    } else {
        Some((Branch::Transmitted, (total / p_t).sqrt()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_2, PI, TAU};

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
                Branch::Diffuse => panic!("no diffuse branch without a scattering coefficient"),
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

    use crate::core::rng::stream;

    fn concrete_slab(s: f64, xpd: f64, pattern: ScatteringPattern) -> SurfacePhysics {
        // ITU-R P.2040-3 concrete at 3.5 GHz: eps' = 5.24, sigma = 0.1231 S/m (docs/radio.md).
        let eta = super::super::fresnel::complex_permittivity(5.24, 0.1231, 3.5e9);
        SurfacePhysics {
            eta: vec![Some(eta)],
            slab_thickness_m: Some(vec![0.1]),
            wavelength_m: super::super::fresnel::C0 / 3.5e9,
            scattering: vec![RadioScattering { scattering_coefficient: s, xpd_coefficient: xpd, pattern }],
            table: None,
        }
    }

    #[test]
    fn one_interaction_keeps_the_energy_balance_of_its_three_branches() {
        // A mixed-polarisation field meets a scattering concrete slab at 50 degrees. Over a
        // uniform grid of the branch draw, the mean weighted power of each branch is the
        // closed form: specular (1 - S^2) P_R, diffuse S^2 P_R, transmitted P_T, with
        // P_R = |R_TE E_s|^2 + |R_TM E_p|^2 and P_T likewise (ITU-R P.2040-3 slab).
        let (s, xpd) = (0.6, 0.3);
        let physics = concrete_slab(s, xpd, ScatteringPattern::Lambertian);
        let n = DVec3::Z;
        let t = 50f64.to_radians();
        let k = DVec3::new(t.sin(), 0.0, -t.cos());
        let sv = k.cross(n).normalize();
        let pv = sv.cross(k);
        let e = FieldVec::from_component(Complex::new(0.6, 0.2), sv)
            .add(&FieldVec::from_component(Complex::new(-0.3, 0.7), pv));
        let c = super::super::fresnel::slab(physics.eta[0].unwrap(), t.cos(), 0.1, physics.wavelength_m);
        let (e_s, e_p) = (e.along(sv).norm_sqr(), e.along(pv).norm_sqr());
        let p_r = c.r_te.norm_sqr() * e_s + c.r_tm.norm_sqr() * e_p;
        let p_t = c.t_te.norm_sqr() * e_s + c.t_tm.norm_sqr() * e_p;
        let want = [(1.0 - s * s) * p_r, s * s * p_r, p_t];
        let count = 1_000_000u32;
        let mut sums = [0.0f64; 3];
        for i in 0..count {
            // The branch draw on a uniform grid, the direction's from Weyl sequences.
            let mut draws = [
                (f64::from(i) + 0.5) / f64::from(count),
                (f64::from(i) * 0.618_033_988_749_894_9).fract(),
                (f64::from(i) * 0.414_213_562_373_095_1).fract(),
            ]
            .into_iter();
            let mut uniform = || draws.next().unwrap();
            let out = interaction(&physics, 0, &e, k, n, &mut uniform).unwrap();
            let slot = match out.branch {
                Branch::Reflected => {
                    assert_eq!(out.direction, LocalBasis::new(k, n).reflected);
                    0
                }
                Branch::Diffuse => {
                    // Scattered back into the incident side, a transverse wave.
                    assert!(out.direction.z > 0.0);
                    assert!(out.field.along(out.direction).abs() < 1e-9 * out.field.power().sqrt());
                    1
                }
                Branch::Transmitted => {
                    assert_eq!(out.direction, k);
                    2
                }
            };
            sums[slot] += out.field.power();
        }
        for (b, (sum, w)) in sums.iter().zip(want).enumerate() {
            let mean = sum / f64::from(count);
            assert!((mean - w).abs() < 1e-4 * w, "branch {b}: {mean} against {w}");
        }
        let total: f64 = sums.iter().sum::<f64>() / f64::from(count);
        assert!((total - (p_r + p_t)).abs() < 1e-4 * (p_r + p_t));
    }

    #[test]
    fn the_cross_polarised_share_of_a_diffuse_wave_is_k_x() {
        // A purely theta-polarised incident wave: the scattered field has K_x of its power on
        // phi_hat and 1 - K_x on theta_hat of the scattered direction (Sionna RT's XPD matrix).
        let k_in = DVec3::new(0.6, 0.0, -0.8);
        let (t_in, _) = theta_phi_basis(k_in);
        let e = FieldVec::from_component(Complex::new(0.3, -0.4), t_in);
        for k_s in [DVec3::new(0.1, 0.5, 0.86).normalize(), DVec3::Z, DVec3::new(-0.7, 0.0, 0.7).normalize()]
        {
            let (t_s, p_s) = theta_phi_basis(k_s);
            assert!((t_s.cross(p_s) - k_s).length() < 1e-12);
            for xpd in [0.0, 0.25, 1.0] {
                let out = diffuse_polarization(&e, k_in, k_s, xpd);
                assert!((out.power() - e.power()).abs() < 1e-12);
                assert!((out.along(p_s).norm_sqr() - xpd * e.power()).abs() < 1e-12);
                assert!((out.along(t_s).norm_sqr() - (1.0 - xpd) * e.power()).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn lambertian_directions_follow_cos_theta_sin_theta() {
        // The sampled zenith angle about a tilted normal has the density 2 cos(t) sin(t)
        // (f_s = cos(t) / pi over the hemisphere): each 5-degree bin holds
        // sin^2(t2) - sin^2(t1) of the samples, and the azimuth is uniform.
        let n_out = DVec3::new(0.3, -0.2, 0.93).normalize();
        let k_r = DVec3::new(0.5, 0.1, 0.2).normalize();
        let mut rng = stream(11, 0, 0);
        let mut uniform = || unit_f64(&mut rng);
        let (a, _) = orthonormal_basis(n_out);
        let samples = 1_000_000;
        let (mut theta_bins, mut phi_bins) = ([0u32; 18], [0u32; 12]);
        for _ in 0..samples {
            let d = sample_pattern(ScatteringPattern::Lambertian, k_r, n_out, &mut uniform).unwrap();
            assert!((d.length() - 1.0).abs() < 1e-12 && d.dot(n_out) >= 0.0);
            let t = d.dot(n_out).clamp(-1.0, 1.0).acos();
            theta_bins[((t / (FRAC_PI_2 / 18.0)) as usize).min(17)] += 1;
            let tangent = d - d.dot(n_out) * n_out;
            let phi = tangent.dot(n_out.cross(a)).atan2(tangent.dot(a)) + PI;
            phi_bins[((phi / (TAU / 12.0)) as usize).min(11)] += 1;
        }
        let check = |count: u32, p: f64, what: &str| {
            let expected = p * f64::from(samples);
            let sigma = (expected * (1.0 - p)).sqrt();
            assert!(
                (f64::from(count) - expected).abs() < 4.0 * sigma + 1.0,
                "{what}: {count} against {expected}"
            );
        };
        for (i, &c) in theta_bins.iter().enumerate() {
            let (t1, t2) = (i as f64 * FRAC_PI_2 / 18.0, (i + 1) as f64 * FRAC_PI_2 / 18.0);
            check(c, t2.sin().powi(2) - t1.sin().powi(2), &format!("theta bin {i}"));
        }
        for (i, &c) in phi_bins.iter().enumerate() {
            check(c, 1.0 / 12.0, &format!("phi bin {i}"));
        }
    }

    /// The integral of `f` over the hemisphere around +z (midpoint rule in theta and phi).
    fn hemisphere_integral(steps: usize, f: impl Fn(DVec3) -> f64) -> f64 {
        let (dt, dp) = (FRAC_PI_2 / steps as f64, TAU / steps as f64);
        let mut sum = 0.0;
        for i in 0..steps {
            let t = (i as f64 + 0.5) * dt;
            let (st, ct) = t.sin_cos();
            for j in 0..steps {
                let p = (j as f64 + 0.5) * dp;
                sum += f(DVec3::new(st * p.cos(), st * p.sin(), ct)) * st;
            }
        }
        sum * dt * dp
    }

    #[test]
    fn scattering_patterns_integrate_to_one_over_the_hemisphere() {
        for theta_i_deg in [0.0f64, 20.0, 45.0, 70.0, 85.0, 89.9] {
            let t = theta_i_deg.to_radians();
            let k_r = DVec3::new(t.sin(), 0.0, t.cos());
            let mut patterns = vec![ScatteringPattern::Lambertian];
            patterns.extend([1, 2, 3, 4, 7, 20, 50].map(|alpha_r| ScatteringPattern::Directive { alpha_r }));
            for pattern in patterns {
                let integral = hemisphere_integral(800, |k_s| pattern_density(pattern, k_r, DVec3::Z, k_s));
                assert!((integral - 1.0).abs() < 1e-3, "{pattern:?} at {theta_i_deg} deg: {integral}");
            }
        }
    }

    #[test]
    fn directive_directions_follow_the_normalised_pattern() {
        // Samples binned in zenith (10 degrees) and azimuth (30 degrees) about the normal,
        // against the pattern integrated over each bin; near grazing the rejection step
        // discards about half of the lobe.
        let mut rng = stream(12, 0, 0);
        let mut uniform = || unit_f64(&mut rng);
        for (theta_i_deg, alpha_r) in [(60.0f64, 5), (85.0, 2)] {
            let pattern = ScatteringPattern::Directive { alpha_r };
            let t = theta_i_deg.to_radians();
            let k_r = DVec3::new(t.sin(), 0.0, t.cos());
            let samples = 500_000;
            let mut bins = [[0u32; 12]; 9];
            for _ in 0..samples {
                let d = sample_pattern(pattern, k_r, DVec3::Z, &mut uniform).unwrap();
                let theta = d.z.clamp(-1.0, 1.0).acos();
                let phi = d.y.atan2(d.x) + PI;
                bins[((theta / (FRAC_PI_2 / 9.0)) as usize).min(8)]
                    [((phi / (TAU / 12.0)) as usize).min(11)] += 1;
            }
            for (i, row) in bins.iter().enumerate() {
                for (j, &c) in row.iter().enumerate() {
                    // The bin's probability: the pattern integrated over it (20 x 20 midpoints).
                    let (t0, p0) = (i as f64 * FRAC_PI_2 / 9.0, j as f64 * TAU / 12.0 - PI);
                    let (dt, dp) = (FRAC_PI_2 / 9.0 / 20.0, TAU / 12.0 / 20.0);
                    let mut prob = 0.0;
                    for a in 0..20 {
                        let th = t0 + (f64::from(a) + 0.5) * dt;
                        for b in 0..20 {
                            let ph = p0 + (f64::from(b) + 0.5) * dp;
                            let k_s = DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
                            prob += pattern_density(pattern, k_r, DVec3::Z, k_s) * th.sin() * dt * dp;
                        }
                    }
                    let expected = prob * f64::from(samples);
                    let sigma = (expected * (1.0 - prob)).sqrt();
                    assert!(
                        (f64::from(c) - expected).abs() < 4.0 * sigma + 1e-3 * expected + 1.0,
                        "{theta_i_deg} deg, alpha {alpha_r}, bin ({i}, {j}): {c} against {expected}"
                    );
                }
            }
        }
    }

    #[test]
    fn without_diffuse_power_the_three_way_choice_is_the_two_way_one() {
        for i in 0..1000 {
            let u = (f64::from(i) + 0.5) / 1000.0;
            for (p_r, p_t) in [(0.3, 0.05), (0.0, 0.2), (0.2, 0.0), (1e-13, 1e-14)] {
                assert_eq!(choose_interaction(p_r, 0.0, p_t, u), choose_branch(p_r, p_t, u));
            }
        }
        assert_eq!(choose_interaction(0.0, 0.0, 0.0, 0.5), None);
        assert_eq!(choose_interaction(0.0, 0.3, 0.0, 0.999).map(|c| c.0), Some(Branch::Diffuse));
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
