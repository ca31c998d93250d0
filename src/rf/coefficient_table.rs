//! The Fresnel coefficients of every radio surface, tabulated over the cosine of the
//! incidence angle for the launcher's hot loop: one complex-arithmetic-free lookup and a
//! linear interpolation instead of a complex square root, two complex exponentials and four
//! complex divisions per interaction. The coefficients are smooth in `cos theta` (the
//! slab's internal phase `k d sqrt(eta - 1 + cos^2 theta)` is the fastest-varying part), so a
//! cubic through the nearest samples, with the step halved until its error is below
//! [`MAX_TABLE_ERROR`] (tested against the exact formulas in `tests/rf_physics.rs`). The
//! exact formulas stay in [`super::fresnel`]; the coherent point receivers use them directly.

use super::fresnel::{Complex, reflection, slab};
use super::propagation::Coefficients;

/// The largest absolute error of an interpolated coefficient (each has modulus at most 1).
pub const MAX_TABLE_ERROR: f64 = 2.0e-6;

/// First and last number of intervals of a segment (doubled until the error is met).
const FIRST_INTERVALS: usize = 16;
const MAX_INTERVALS: usize = 1 << 16;

/// Where the grazing segment ends: near grazing incidence a thin slab's coefficients turn
/// quickly towards `R = -1` (over a range of `cos theta` about as wide as its internal phase
/// `k d |sqrt(eta)|`), so that part gets its own, finer, step.
const GRAZING_SPLIT: f64 = 1.0 / 16.0;

/// Below this `cos theta` the coefficients are computed exactly: a good conductor's `R_TM`
/// swings from -1 to +1 within `cos theta ~ 1 / sqrt(|eta|)` (1e-4 for ITU metal at 1 GHz),
/// too sharp for a table, and so few rays arrive this close to grazing that it costs nothing.
const EXACT_BELOW: f64 = 1.0 / 256.0;

/// The exact coefficients `[R_TE, R_TM, T_TE, T_TM]` at `c` (no transmission: zeros).
fn exact(eta: Complex, thickness_m: Option<f64>, wavelength_m: f64, c: f64) -> [Complex; 4] {
    match thickness_m {
        Some(d) => {
            let s = slab(eta, c, d, wavelength_m);
            [s.r_te, s.r_tm, s.t_te, s.t_tm]
        }
        None => {
            let (te, tm) = reflection(eta, c);
            [te, tm, Complex::ZERO, Complex::ZERO]
        }
    }
}

/// Uniform samples of the coefficients over `[c0, c1]`, interpolated by the cubic through
/// the four nearest samples (Lagrange; error `O(h^4)`, so a few hundred samples a segment
/// suffice and a table stays in the cache).
#[derive(Clone, Debug)]
struct Segment {
    c0: f64,
    /// Intervals per unit of `cos theta`.
    scale: f64,
    intervals: usize,
    /// Each sample's `[R_TE, R_TM, T_TE, T_TM]` as real and imaginary parts in turn, so that
    /// the interpolation runs as vector arithmetic over the eight numbers.
    rows: Vec<[f64; 8]>,
}

/// `[R_TE, R_TM, T_TE, T_TM]` as the eight numbers of a table row.
fn row(v: [Complex; 4]) -> [f64; 8] {
    let mut r = [0.0; 8];
    for (k, c) in v.iter().enumerate() {
        (r[2 * k], r[2 * k + 1]) = (c.re, c.im);
    }
    r
}

impl Segment {
    /// Halves the step until the interpolation is within half of [`MAX_TABLE_ERROR`] at
    /// the quarter points of every interval, or the step reaches its floor.
    fn build(c0: f64, c1: f64, f: &impl Fn(f64) -> [Complex; 4]) -> Self {
        let mut intervals = FIRST_INTERVALS;
        loop {
            let at = |x: f64| c0 + (c1 - c0) * x / intervals as f64;
            let rows: Vec<[f64; 8]> = (0..=intervals).map(|i| row(f(at(i as f64)))).collect();
            let segment = Self { c0, scale: intervals as f64 / (c1 - c0), intervals, rows };
            let worst = (0..intervals)
                .flat_map(|i| [0.25, 0.5, 0.75].map(|q| at(i as f64 + q)))
                .map(|c| {
                    let (got, want) = (segment.lookup(c), f(c));
                    (0..4).map(|k| (got[k] - want[k]).abs()).fold(0.0, f64::max)
                })
                .fold(0.0, f64::max);
            // (`!(worst <= ..)`: a NaN coefficient also refines, up to the floor.)
            if worst <= 0.5 * MAX_TABLE_ERROR || intervals >= MAX_INTERVALS {
                return segment;
            }
            intervals *= 2;
        }
    }

    #[inline(always)]
    fn lookup(&self, c: f64) -> [Complex; 4] {
        // Samples j..j+3 around x (shifted inwards at the ends), u = x - j in [0, 3].
        let x = ((c - self.c0) * self.scale).clamp(0.0, self.intervals as f64);
        let j = (x as usize).saturating_sub(1).min(self.intervals - 3);
        let u = x - j as f64;
        let (u1, u2, u3) = (u - 1.0, u - 2.0, u - 3.0);
        let w =
            [-u1 * u2 * u3 * (1.0 / 6.0), u * u2 * u3 * 0.5, -u * u1 * u3 * 0.5, u * u1 * u2 * (1.0 / 6.0)];
        let [r0, r1, r2, r3] = [&self.rows[j], &self.rows[j + 1], &self.rows[j + 2], &self.rows[j + 3]];
        let mut v = [0.0; 8];
        for (i, x) in v.iter_mut().enumerate() {
            *x = w[0] * r0[i] + w[1] * r1[i] + w[2] * r2[i] + w[3] * r3[i];
        }
        [0, 1, 2, 3].map(|k| Complex::new(v[2 * k], v[2 * k + 1]))
    }
}

/// One material's coefficients over `cos theta` in `[0, 1]`: a grazing and a main segment.
#[derive(Clone, Debug)]
struct Table {
    eta: Complex,
    thickness_m: Option<f64>,
    wavelength_m: f64,
    slab: bool,
    grazing: Segment,
    main: Segment,
}

impl Table {
    fn build(eta: Complex, thickness_m: Option<f64>, wavelength_m: f64) -> Self {
        let f = |c: f64| exact(eta, thickness_m, wavelength_m, c);
        Self {
            eta,
            thickness_m,
            wavelength_m,
            slab: thickness_m.is_some(),
            grazing: Segment::build(EXACT_BELOW, GRAZING_SPLIT, &f),
            main: Segment::build(GRAZING_SPLIT, 1.0, &f),
        }
    }

    #[inline(always)]
    fn lookup(&self, cos_theta: f64) -> Coefficients {
        let c = cos_theta.clamp(0.0, 1.0);
        let v = if c >= GRAZING_SPLIT {
            self.main.lookup(c)
        } else if c >= EXACT_BELOW {
            self.grazing.lookup(c)
        } else {
            exact(self.eta, self.thickness_m, self.wavelength_m, c)
        };
        (v[0], v[1], self.slab.then_some((v[2], v[3])))
    }
}

/// The tables of all surfaces, one per distinct (permittivity, thickness) pair.
#[derive(Clone, Debug, Default)]
pub struct CoefficientTable {
    /// Index into `tables` of each surface (by `SurfaceId`); `None`: no radio data.
    of_surface: Vec<Option<u32>>,
    tables: Vec<Table>,
}

impl CoefficientTable {
    /// Tabulates each surface's coefficients: `eta` per surface (`None`: absorbs), the slab
    /// thicknesses when walls transmit (`None`: opaque half-spaces).
    pub fn build(eta: &[Option<Complex>], slab_thickness_m: Option<&[f64]>, wavelength_m: f64) -> Self {
        let mut keys: Vec<(Complex, Option<f64>)> = Vec::new();
        let mut tables = Vec::new();
        let of_surface = eta
            .iter()
            .enumerate()
            .map(|(surface, e)| {
                let e = (*e)?;
                let d = match slab_thickness_m {
                    Some(t) => Some(*t.get(surface)?),
                    None => None,
                };
                let found = keys.iter().position(|k| k.0 == e && k.1 == d);
                Some(match found {
                    Some(i) => i as u32,
                    None => {
                        keys.push((e, d));
                        tables.push(Table::build(e, d, wavelength_m));
                        (tables.len() - 1) as u32
                    }
                })
            })
            .collect();
        Self { of_surface, tables }
    }

    /// The interpolated coefficients of `surface` at `cos_theta` (as
    /// `SurfacePhysics::exact_coefficients`); `None` when the surface has no radio data.
    #[inline(always)]
    pub fn coefficients(&self, surface: u32, cos_theta: f64) -> Option<Coefficients> {
        let t = (*self.of_surface.get(surface as usize)?)?;
        Some(self.tables[t as usize].lookup(cos_theta))
    }
}
