//! Spectra for the spectral integrator ([`super::spectral`]): the wavelengths a path carries,
//! the CIE 1931 colour matching functions, the conversion of the sensed XYZ to the film's
//! linear sRGB, and the up-sampling of the scene's RGB colours to smooth spectra.
//!
//! - Wavelengths: a hero wavelength and three companions equally spaced in the sampling
//!   density's primary space (Wilkie et al. 2014, "Hero wavelength spectral sampling"), drawn
//!   from pbrt-v4's visible-wavelength density `p(l) ~ 1 / cosh^2(0.0072 (l - 538 nm))` on
//!   360-830 nm (pbrt-v4 sec. 4.6.5, `SampleVisibleWavelengths`), which follows the eye's
//!   sensitivity and so spends few samples where nothing is seen.
//! - Colour matching: the multi-lobe piecewise-Gaussian fit of the CIE 1931 2-degree observer
//!   by Wyman, Sloan and Shirley 2013 ("Simple analytic approximations to the CIE XYZ colour
//!   matching functions", JCGT 2(2)), which avoids a table; its error is below the
//!   variability between observers.
//! - Up-sampling (Jakob and Hanika 2019, "A low-dimensional function space for efficient
//!   spectral upsampling"): a reflectance is `S(l) = s(c0 t^2 + c1 t + c2)`, `t` the
//!   wavelength mapped to [0, 1] over 360-830 nm and `s(x) = 1/2 + x / (2 sqrt(1 + x^2))`,
//!   so it is smooth and always in [0, 1] (energy-conserving). The three coefficients of each
//!   colour are solved once per render by Levenberg-Marquardt so that the spectrum seen under
//!   the film's white (D65) gives back the RGB: the round trip is exact up to the solver's
//!   tolerance, which Smits 1999's fixed basis spectra (tabulated for other primaries) are
//!   not by construction. Greys are constant spectra, exactly.
//! - Light: an RGB emission `e` is `2 max(e) S_(e / 2 max(e))(l) D65(l)` (pbrt-v4's
//!   `RGBIlluminantSpectrum`), D65 being CIE's daylight table normalised to luminance 1.
//! - White stays white: the film's white is D65 (sRGB's), and XYZ is turned into RGB by the
//!   sRGB matrix and then divided by the RGB that the same integration gives D65, so a white
//!   (1, 1, 1) light on a grey reflectance `k` renders exactly as `k` and the XYZ path
//!   differs from the RGB one only where products of spectra differ from products of RGB
//!   (coloured light bouncing off coloured surfaces).

use std::sync::LazyLock;

use glam::{Vec3, Vec4};

/// Shortest wavelength sampled, nm.
pub const LAMBDA_MIN_NM: f32 = 360.0;
/// Longest wavelength sampled, nm.
pub const LAMBDA_MAX_NM: f32 = 830.0;
/// Wavelengths a path carries (the hero and its companions).
pub const LANES: usize = 4;

/// The wavelengths of one path and their sampling densities (per nm); a density 0 marks a
/// companion dropped at a dispersive interface ([`Wavelengths::terminate_secondary`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wavelengths {
    /// Wavelengths, nm; lane 0 is the hero.
    pub nm: Vec4,
    /// Sampling density of each, 1/nm.
    pub pdf: Vec4,
}

/// pbrt-v4's `SampleVisibleWavelengths`: the inverse of the visible density's distribution.
#[inline]
pub fn sample_visible_nm(u: f32) -> f32 {
    538.0 - 138.888_89 * (0.856_910_6 - 1.827_502 * u).atanh()
}

/// pbrt-v4's `VisibleWavelengthsPDF`, 1/nm (zero outside 360-830 nm).
#[inline]
pub fn visible_pdf(nm: f32) -> f32 {
    if !(LAMBDA_MIN_NM..=LAMBDA_MAX_NM).contains(&nm) {
        return 0.0;
    }
    let c = (0.0072 * (nm - 538.0)).cosh();
    0.003_939_804 / (c * c)
}

impl Wavelengths {
    /// The hero at `u` and companions at `u + k/4` (mod 1) in the visible density's primary
    /// space (Wilkie et al. 2014's rotation, pbrt-v4's `SampleVisible`).
    pub fn sample_visible(u: f32) -> Self {
        let mut nm = [0.0; LANES];
        let mut pdf = [0.0; LANES];
        for k in 0..LANES {
            let mut up = u + k as f32 / LANES as f32;
            if up >= 1.0 {
                up -= 1.0;
            }
            nm[k] = sample_visible_nm(up).clamp(LAMBDA_MIN_NM, LAMBDA_MAX_NM);
            pdf[k] = visible_pdf(nm[k]);
        }
        Self { nm: Vec4::from_array(nm), pdf: Vec4::from_array(pdf) }
    }

    /// The hero wavelength, nm.
    #[inline]
    pub fn hero_nm(&self) -> f32 {
        self.nm.x
    }

    /// Whether the companions were dropped.
    #[inline]
    pub fn secondary_terminated(&self) -> bool {
        self.pdf.y == 0.0 && self.pdf.z == 0.0 && self.pdf.w == 0.0
    }

    /// Drops the companions, keeping the hero alone with its density divided by the lane
    /// count (pbrt-v4's `TerminateSecondary`): a path that a wavelength-dependent interface
    /// splits can carry one wavelength only, and the hero then stands for all four samples.
    pub fn terminate_secondary(&mut self) {
        if self.secondary_terminated() {
            return;
        }
        self.pdf = Vec4::new(self.pdf.x / LANES as f32, 0.0, 0.0, 0.0);
    }

    /// The film's linear sRGB of the radiances `l` carried at these wavelengths: the mean over
    /// live lanes of `l cmf(l) / pdf(l)`, over the luminance integral of the matching
    /// functions, through the sRGB matrix and the white balance.
    pub fn to_rgb(&self, l: Vec4) -> Vec3 {
        let t = &*TABLES;
        let mut xyz = Vec3::ZERO;
        for k in 0..LANES {
            if self.pdf[k] > 0.0 && l[k] != 0.0 {
                xyz += cie_xyz(self.nm[k]) * (l[k] / self.pdf[k]);
            }
        }
        xyz_to_linear_srgb(xyz / (LANES as f32 * t.y_integral as f32)) / t.white_rgb
    }
}

/// One lobe of Wyman et al.'s fit: a Gaussian of width `s1` below `mu` and `s2` above.
#[inline]
fn lobe(nm: f32, mu: f32, s1: f32, s2: f32) -> f32 {
    let t = (nm - mu) / if nm < mu { s1 } else { s2 };
    (-0.5 * t * t).exp()
}

/// The CIE 1931 2-degree colour matching functions `(x, y, z)` at `nm` by the multi-lobe fit
/// of Wyman, Sloan and Shirley 2013 (their sec. 2.2).
#[inline]
pub fn cie_xyz(nm: f32) -> Vec3 {
    let x = 1.056 * lobe(nm, 599.8, 37.9, 31.0) + 0.362 * lobe(nm, 442.0, 16.0, 26.7)
        - 0.065 * lobe(nm, 501.1, 20.4, 26.2);
    let y = 0.821 * lobe(nm, 568.8, 46.9, 40.5) + 0.286 * lobe(nm, 530.9, 16.3, 31.1);
    let z = 1.217 * lobe(nm, 437.0, 11.8, 36.0) + 0.681 * lobe(nm, 459.0, 26.0, 13.8);
    Vec3::new(x, y, z)
}

/// CIE XYZ to linear sRGB (IEC 61966-2-1; D65 white).
#[inline]
pub fn xyz_to_linear_srgb(xyz: Vec3) -> Vec3 {
    Vec3::new(
        3.240_454_2 * xyz.x - 1.537_138_5 * xyz.y - 0.498_531_4 * xyz.z,
        -0.969_266 * xyz.x + 1.876_010_8 * xyz.y + 0.041_556 * xyz.z,
        0.055_643_4 * xyz.x - 0.204_025_9 * xyz.y + 1.057_225_2 * xyz.z,
    )
}

/// CIE standard illuminant D65, relative spectral power from 360 to 830 nm every 10 nm
/// (CIE 15:2004, Table T.1; 100 at 560 nm).
const D65_10NM: [f32; 48] = [
    46.6383, 52.0891, 49.9755, 54.6482, 82.7549, 91.486, 93.4318, 86.6823, 104.865, 117.008, 117.812,
    114.861, 115.923, 108.811, 109.354, 107.802, 104.79, 107.689, 104.405, 104.046, 100.0, 96.3342, 95.788,
    88.6856, 90.0062, 89.5991, 87.6987, 83.2886, 83.6992, 80.0268, 80.2146, 82.2778, 78.2842, 69.7213,
    71.6091, 74.349, 61.604, 69.8856, 75.087, 63.5927, 46.4182, 66.8054, 63.3828, 64.304, 59.4519, 51.959,
    57.4406, 60.3125,
];

/// D65 at `nm` by linear interpolation of the table, relative (100 at 560 nm).
fn d65_relative(nm: f64) -> f64 {
    let x = ((nm - 360.0) / 10.0).clamp(0.0, (D65_10NM.len() - 1) as f64);
    let i = (x.floor() as usize).min(D65_10NM.len() - 2);
    let f = x - i as f64;
    f64::from(D65_10NM[i]) * (1.0 - f) + f64::from(D65_10NM[i + 1]) * f
}

/// D65 normalised to luminance 1: `integral D65 y / integral y = 1`.
#[inline]
pub fn d65(nm: f32) -> f32 {
    (d65_relative(f64::from(nm)) * TABLES.d65_scale) as f32
}

/// Integration step of the tables and of the up-sampling fit, nm.
const STEP_NM: f64 = 1.0;

/// Numbers the conversions share, integrated once.
struct Tables {
    /// `integral y(l) dl` over 360-830 nm, nm.
    y_integral: f64,
    /// Factor from the relative D65 table to luminance 1.
    d65_scale: f64,
    /// The linear sRGB of normalised D65 before white balance (close to (1, 1, 1)).
    white_rgb: Vec3,
    /// Per wavelength of the grid: the trapezoid weight times what a reflectance there adds
    /// to each white-balanced RGB channel under D65.
    rgb_weights: Vec<(f64, [f64; 3])>,
}

static TABLES: LazyLock<Tables> = LazyLock::new(|| {
    let n = ((f64::from(LAMBDA_MAX_NM - LAMBDA_MIN_NM)) / STEP_NM).round() as usize;
    let grid: Vec<(f64, f64)> = (0..=n)
        .map(|i| {
            let w = if i == 0 || i == n { 0.5 * STEP_NM } else { STEP_NM };
            (f64::from(LAMBDA_MIN_NM) + i as f64 * STEP_NM, w)
        })
        .collect();
    let cmf = |nm: f64| {
        let c = cie_xyz(nm as f32);
        [f64::from(c.x), f64::from(c.y), f64::from(c.z)]
    };
    let y_integral: f64 = grid.iter().map(|&(nm, w)| w * cmf(nm)[1]).sum();
    let d65_y: f64 = grid.iter().map(|&(nm, w)| w * cmf(nm)[1] * d65_relative(nm)).sum();
    let d65_scale = y_integral / d65_y;
    let to_rgb = |xyz: [f64; 3]| {
        let v = xyz_to_linear_srgb(Vec3::new(xyz[0] as f32, xyz[1] as f32, xyz[2] as f32));
        [f64::from(v.x), f64::from(v.y), f64::from(v.z)]
    };
    // The sRGB matrix is linear: per-wavelength RGB weights sum to the white's RGB.
    let raw: Vec<(f64, [f64; 3])> = grid
        .iter()
        .map(|&(nm, w)| {
            let c = cmf(nm);
            let k = w * d65_relative(nm) * d65_scale / y_integral;
            (nm, to_rgb([c[0] * k, c[1] * k, c[2] * k]))
        })
        .collect();
    let mut white = [0.0f64; 3];
    for (_, rgb) in &raw {
        for j in 0..3 {
            white[j] += rgb[j];
        }
    }
    let rgb_weights = raw.iter().map(|&(nm, rgb)| (nm, [0, 1, 2].map(|j| rgb[j] / white[j]))).collect();
    Tables {
        y_integral,
        d65_scale,
        white_rgb: Vec3::new(white[0] as f32, white[1] as f32, white[2] as f32),
        rgb_weights,
    }
});

/// The film's white-balanced linear sRGB of a reflectance spectrum `s` seen under D65, by
/// 1-nm trapezoid integration: what [`RgbSpectrum::fit`] inverts.
pub fn reflectance_to_rgb(s: impl Fn(f32) -> f32) -> Vec3 {
    let mut rgb = [0.0f64; 3];
    for &(nm, w) in &TABLES.rgb_weights {
        let v = f64::from(s(nm as f32));
        for j in 0..3 {
            rgb[j] += v * w[j];
        }
    }
    Vec3::new(rgb[0] as f32, rgb[1] as f32, rgb[2] as f32)
}

/// `s(x) = 1/2 + x / (2 sqrt(1 + x^2))`: a sigmoid onto (0, 1), infinite `x` at the ends.
#[inline]
fn sigmoid(x: f64) -> f64 {
    if x.is_infinite() {
        return if x > 0.0 { 1.0 } else { 0.0 };
    }
    0.5 + x / (2.0 * (1.0 + x * x).sqrt())
}

/// The wavelength mapped to [0, 1] over the sampled range.
#[inline]
fn unit_nm(nm: f64) -> f64 {
    (nm - f64::from(LAMBDA_MIN_NM)) / f64::from(LAMBDA_MAX_NM - LAMBDA_MIN_NM)
}

/// A smooth reflectance up-sampled from an RGB colour (Jakob and Hanika 2019).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RgbSpectrum {
    /// The sigmoid's polynomial coefficients `c0 t^2 + c1 t + c2`.
    c: [f64; 3],
}

impl RgbSpectrum {
    /// The constant spectrum `v` (in [0, 1]).
    pub fn constant(v: f32) -> Self {
        let s = 2.0 * f64::from(v.clamp(0.0, 1.0)) - 1.0;
        // s(x) = v for x = s / sqrt(1 - s^2); infinite at 0 and 1.
        let x = if s.abs() >= 1.0 { s * f64::INFINITY } else { s / (1.0 - s * s).sqrt() };
        Self { c: [0.0, 0.0, x] }
    }

    /// The spectrum whose white-balanced RGB under D65 is `rgb` (components clamped to
    /// [0, 1]): a grey is constant; a colour is solved by Levenberg-Marquardt on the three
    /// coefficients from the flat 0.5 spectrum. Colours a smooth reflectance cannot reach
    /// (a component 0 or 1 with others between) end at the nearest one found.
    pub fn fit(rgb: Vec3) -> Self {
        let rgb = rgb.clamp(Vec3::ZERO, Vec3::ONE);
        if rgb.x == rgb.y && rgb.y == rgb.z {
            return Self::constant(rgb.x);
        }
        let target = [f64::from(rgb.x), f64::from(rgb.y), f64::from(rgb.z)];
        let weights = &TABLES.rgb_weights;
        // Residual and Jacobian of the RGB in the coefficients.
        let eval = |c: [f64; 3]| {
            let mut r = [-target[0], -target[1], -target[2]];
            let mut jac = [[0.0f64; 3]; 3];
            for &(nm, w) in weights {
                let t = unit_nm(nm);
                let x = (c[0] * t + c[1]) * t + c[2];
                let s = sigmoid(x);
                let ds = 0.5 / (1.0 + x * x).powf(1.5);
                let basis = [t * t, t, 1.0];
                for j in 0..3 {
                    r[j] += s * w[j];
                    for k in 0..3 {
                        jac[j][k] += ds * basis[k] * w[j];
                    }
                }
            }
            (r, jac)
        };
        let norm2 = |r: [f64; 3]| r.iter().map(|x| x * x).sum::<f64>();
        let mut c = [0.0f64; 3];
        let (mut r, mut jac) = eval(c);
        let mut err = norm2(r);
        let mut mu = 1e-4;
        for _ in 0..300 {
            if err < 1e-14 {
                break;
            }
            // (J^T J + mu diag(J^T J)) d = -J^T r.
            let mut a = [[0.0f64; 3]; 3];
            let mut g = [0.0f64; 3];
            for i in 0..3 {
                for k in 0..3 {
                    a[i][k] = (0..3).map(|j| jac[j][i] * jac[j][k]).sum();
                }
                g[i] = -(0..3).map(|j| jac[j][i] * r[j]).sum::<f64>();
            }
            for (i, row) in a.iter_mut().enumerate() {
                row[i] *= 1.0 + mu;
                row[i] += 1e-12;
            }
            let Some(d) = solve3(a, g) else { break };
            let candidate = [c[0] + d[0], c[1] + d[1], c[2] + d[2]];
            let (rc, jc) = eval(candidate);
            let ec = norm2(rc);
            if ec.is_finite() && ec < err {
                (c, r, jac, err) = (candidate, rc, jc, ec);
                mu = (mu / 3.0).max(1e-12);
            } else {
                mu *= 4.0;
                if mu > 1e12 {
                    break;
                }
            }
        }
        Self { c }
    }

    /// The reflectance at `nm`, in [0, 1].
    #[inline]
    pub fn eval(&self, nm: f32) -> f32 {
        let t = unit_nm(f64::from(nm));
        sigmoid((self.c[0] * t + self.c[1]) * t + self.c[2]) as f32
    }

    /// The reflectance at each of four wavelengths.
    #[inline]
    pub fn eval4(&self, nm: Vec4) -> Vec4 {
        Vec4::new(self.eval(nm.x), self.eval(nm.y), self.eval(nm.z), self.eval(nm.w))
    }
}

/// An emission spectrum up-sampled from RGB: `scale S(l) D65(l)`, `scale = 2 max(rgb)`
/// (pbrt-v4's `RGBIlluminantSpectrum`), so that its RGB is `rgb` and white light is D65.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RgbIlluminant {
    /// `2 max(rgb)`; zero for black.
    pub scale: f32,
    /// The shape, fitted to `rgb / scale` (components at most 1/2).
    pub shape: RgbSpectrum,
}

impl RgbIlluminant {
    /// The illuminant of RGB radiance (or intensity) `rgb`, non-negative components.
    pub fn new(rgb: Vec3) -> Self {
        let rgb = rgb.max(Vec3::ZERO);
        let m = rgb.max_element();
        if !(m > 0.0 && m.is_finite()) {
            return Self { scale: 0.0, shape: RgbSpectrum::constant(0.0) };
        }
        Self { scale: 2.0 * m, shape: RgbSpectrum::fit(rgb / (2.0 * m)) }
    }

    /// The spectral radiance at each of four wavelengths.
    #[inline]
    pub fn eval4(&self, nm: Vec4) -> Vec4 {
        if self.scale == 0.0 {
            return Vec4::ZERO;
        }
        let d = Vec4::new(d65(nm.x), d65(nm.y), d65(nm.z), d65(nm.w));
        self.scale * self.shape.eval4(nm) * d
    }
}

/// Solves the 3x3 system `a x = b` by Cramer's rule; `None` when singular.
fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    if !(d.is_finite() && d.abs() > 1e-300) {
        return None;
    }
    let mut x = [0.0; 3];
    for (k, xk) in x.iter_mut().enumerate() {
        let mut m = a;
        for i in 0..3 {
            m[i][k] = b[i];
        }
        *xk = det(m) / d;
    }
    Some(x)
}

/// `integral y(l) dl` of the tabulated CIE 1931 observer, 106.857 nm (CIE 15:2004; the
/// constant of pbrt-v4's `CIE_Y_integral`): the fit's integral must come close to it.
pub const CIE_Y_INTEGRAL_NM: f64 = 106.856_895;

/// `integral y(l) dl` of the fitted matching function over the sampled range, nm.
pub fn fitted_y_integral_nm() -> f64 {
    TABLES.y_integral
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_visible_density_is_normalised_and_inverted_by_its_sampler() {
        // Midpoint integral of the density over 360-830 nm: 1.
        let n = 47_000;
        let h = f64::from(LAMBDA_MAX_NM - LAMBDA_MIN_NM) / f64::from(n);
        let total: f64 = (0..n)
            .map(|i| f64::from(visible_pdf(LAMBDA_MIN_NM + ((f64::from(i) + 0.5) * h) as f32)) * h)
            .sum();
        assert!((total - 1.0).abs() < 2e-3, "{total}");
        // The sampler's histogram follows the density.
        let m = 200_000;
        let mut below_500 = 0;
        for i in 0..m {
            let nm = sample_visible_nm((i as f32 + 0.5) / m as f32);
            assert!((LAMBDA_MIN_NM - 1.0..=LAMBDA_MAX_NM + 1.0).contains(&nm));
            below_500 += usize::from(nm < 500.0);
        }
        let want: f64 = (0..4000)
            .map(|i| f64::from(visible_pdf(360.0 + (i as f32 + 0.5) * 140.0 / 4000.0)) * 140.0 / 4000.0)
            .sum();
        assert!((below_500 as f64 / m as f64 - want).abs() < 3e-3, "{below_500} vs {want}");
    }

    #[test]
    fn the_cmf_fit_integrates_like_the_cie_tables() {
        // The CIE 1931 functions each integrate to 106.86 nm (equal-energy white has x = y = z).
        let y = fitted_y_integral_nm();
        assert!((y / CIE_Y_INTEGRAL_NM - 1.0).abs() < 0.01, "{y}");
        let mut xyz = Vec3::ZERO;
        for i in 0..470 {
            xyz += cie_xyz(360.5 + i as f32);
        }
        assert!((xyz.x / xyz.y - 1.0).abs() < 0.02 && (xyz.z / xyz.y - 1.0).abs() < 0.02, "{xyz}");
        // D65's chromaticity (0.3127, 0.3290), IEC 61966-2-1.
        let mut d = Vec3::ZERO;
        for i in 0..470 {
            let nm = 360.5 + i as f32;
            d += cie_xyz(nm) * d65(nm);
        }
        let s = d.x + d.y + d.z;
        assert!((d.x / s - 0.3127).abs() < 0.003 && (d.y / s - 0.3290).abs() < 0.003, "{d}");
    }

    #[test]
    fn up_sampled_reflectances_give_their_rgb_back_and_stay_in_0_1() {
        for rgb in [
            Vec3::new(0.63, 0.065, 0.05),
            Vec3::new(0.14, 0.45, 0.091),
            Vec3::new(0.725, 0.71, 0.68),
            Vec3::new(0.2, 0.3, 0.8),
            Vec3::new(0.9, 0.9, 0.2),
            Vec3::splat(0.5),
            Vec3::ONE,
        ] {
            let s = RgbSpectrum::fit(rgb);
            let back = reflectance_to_rgb(|nm| s.eval(nm));
            assert!((back - rgb).abs().max_element() < 0.01 * rgb.max_element(), "{rgb} -> {back}");
            for i in 0..=470 {
                let v = s.eval(360.0 + i as f32);
                assert!((0.0..=1.0).contains(&v), "{rgb}: {v}");
            }
        }
        // An illuminant keeps its RGB, and white is D65: its XYZ has D65's chromaticity.
        let e = RgbIlluminant::new(Vec3::new(17.0, 12.0, 4.0));
        let back = reflectance_to_rgb(|nm| e.eval4(Vec4::splat(nm)).x / d65(nm));
        assert!((back - Vec3::new(17.0, 12.0, 4.0)).abs().max_element() < 0.17, "{back}");
    }

    #[test]
    fn terminating_the_companions_keeps_the_hero_for_all() {
        let mut w = Wavelengths::sample_visible(0.3);
        let p = w.pdf.x;
        w.terminate_secondary();
        assert_eq!(w.pdf, Vec4::new(p / 4.0, 0.0, 0.0, 0.0));
        // The hero alone at density p/4 gives four times its lane's share: the same mean.
        let l = Vec4::new(1.0, 5.0, 5.0, 5.0);
        let one = w.to_rgb(l);
        let mut w2 = Wavelengths::sample_visible(0.3);
        w2.pdf = Vec4::new(p, 0.0, 0.0, 0.0);
        assert!((one - 4.0 * w2.to_rgb(l)).abs().max_element() < 1e-4 * one.abs().max_element());
    }
}
