//! The image being rendered (linear RGB radiance per pixel) and its output as 8-bit sRGB PNG
//! or linear float EXR.
//!
//! A PNG is a picture for a screen: its values are multiplied by 2^exposure, tone mapped into
//! [0, 1] ([`ToneMap`]) and encoded with the sRGB curve ([`Display`]). An EXR keeps the
//! scene-referred linear radiance untouched (no exposure, no tone map), for compositing and
//! measurement.

use std::path::Path;

use anyhow::{Context, bail};
use glam::Vec3;

/// A `width` x `height` image of linear RGB values, row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Pixel values, row-major from the top left.
    pub pixels: Vec<Vec3>,
}

/// Output formats, chosen by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// 8-bit sRGB PNG (values clamped to [0, 1] before encoding).
    Png,
    /// numpy's `.npy`: the linear values as float32 of shape (height, width, 3)
    /// ([`Film::to_array`]).
    Npy,
    /// OpenEXR, linear 32-bit float RGB.
    Exr,
}

impl ImageFormat {
    /// The format named by `path`'s extension, or a one-line error.
    pub fn from_path(path: &Path) -> anyhow::Result<Self> {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("png") => Ok(Self::Png),
            Some("exr") => Ok(Self::Exr),
            Some("npy") => Ok(Self::Npy),
            Some(e) => bail!("{}: unknown image format \".{e}\" (use .png, .exr or .npy)", path.display()),
            None => bail!("{}: no file extension (use .png, .exr or .npy)", path.display()),
        }
    }
}

/// The sRGB transfer function (IEC 61966-2-1) of a linear value in [0, 1].
#[inline]
pub fn linear_to_srgb(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 { 12.92 * x } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 }
}

/// Rec. 709 luminance of linear RGB.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// How linear radiance (after exposure) is brought into [0, 1] for an 8-bit PNG.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ToneMap {
    /// Values clipped at 1: bright areas burn out (the PNGs of propsim before 0.1's tone maps).
    None,
    /// Narkowicz's fit of the ACES filmic curve (2016), per channel:
    /// x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14), clipped to [0, 1]. A toe and a
    /// shoulder: highlights roll off instead of clipping, shadows gain contrast.
    #[default]
    Aces,
    /// Reinhard (2002) on luminance: each pixel scaled by L' / L with L' = L / (1 + L), then
    /// clipped to [0, 1]; keeps hues, compresses every brightness a little.
    Reinhard,
}

impl ToneMap {
    /// The tone map's name.
    pub fn name(self) -> &'static str {
        match self {
            ToneMap::None => "none",
            ToneMap::Aces => "aces",
            ToneMap::Reinhard => "reinhard",
        }
    }

    /// The display-linear value in [0, 1] of exposed linear radiance `c`.
    #[inline]
    pub fn apply(self, c: Vec3) -> Vec3 {
        let c = c.max(Vec3::ZERO);
        let mapped = match self {
            ToneMap::None => c,
            ToneMap::Aces => (c * (2.51 * c + 0.03)) / (c * (2.43 * c + 0.59) + 0.14),
            ToneMap::Reinhard => {
                let l = luminance(c);
                if l > 0.0 { c * (1.0 / (1.0 + l)) } else { Vec3::ZERO }
            }
        };
        mapped.clamp(Vec3::ZERO, Vec3::ONE)
    }
}

impl std::str::FromStr for ToneMap {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "none" => Ok(ToneMap::None),
            "aces" => Ok(ToneMap::Aces),
            "reinhard" => Ok(ToneMap::Reinhard),
            _ => Err(format!("\"{s}\": expected none, aces or reinhard")),
        }
    }
}

/// Largest exposure magnitude accepted, stops (2^30 is far past any useful picture).
pub const MAX_EXPOSURE_EV: f32 = 30.0;

/// How a PNG shows the film: exposure, then tone map, then the sRGB curve. EXR ignores it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Display {
    /// Exposure, stops: radiance is multiplied by 2^`exposure_ev` before the tone map.
    pub exposure_ev: f32,
    /// Tone map.
    pub tone_map: ToneMap,
}

impl Default for Display {
    /// No exposure change, ACES filmic.
    fn default() -> Self {
        Self { exposure_ev: 0.0, tone_map: ToneMap::Aces }
    }
}

impl Display {
    /// Linear values clipped at 1 (no exposure, no tone map).
    pub const LINEAR: Display = Display { exposure_ev: 0.0, tone_map: ToneMap::None };

    /// Checks the exposure; the error is one line.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.exposure_ev.is_finite() && self.exposure_ev.abs() <= MAX_EXPOSURE_EV) {
            return Err(format!(
                "exposure {} EV: must be a number between -{MAX_EXPOSURE_EV} and {MAX_EXPOSURE_EV}",
                self.exposure_ev
            ));
        }
        Ok(())
    }

    /// The display-linear value in [0, 1] of linear radiance `c` (before the sRGB curve).
    #[inline]
    pub fn map(&self, c: Vec3) -> Vec3 {
        let c = if c.is_finite() { c } else { Vec3::ZERO };
        self.tone_map.apply(c * self.exposure_ev.exp2())
    }
}

impl Film {
    /// A black image of `width` x `height` pixels.
    pub fn new(width: u32, height: u32) -> Self {
        Self { width, height, pixels: vec![Vec3::ZERO; width as usize * height as usize] }
    }

    /// The pixel at column `x`, row `y`.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[(y * self.width + x) as usize]
    }

    /// The linear RGB values as an array of shape (height, width, 3): pixel (x, y) from the
    /// top left at `[y, x, channel]`.
    pub fn to_array(&self) -> ndarray::Array3<f32> {
        let (w, h) = (self.width as usize, self.height as usize);
        ndarray::Array3::from_shape_fn((h, w, 3), |(y, x, c)| self.pixels[y * w + x][c])
    }

    /// Mean of every pixel.
    pub fn mean(&self) -> Vec3 {
        let s: glam::DVec3 = self.pixels.iter().map(|p| p.as_dvec3()).sum();
        (s / self.pixels.len().max(1) as f64).as_vec3()
    }

    /// 8-bit sRGB bytes, RGB interleaved, of the linear values clipped at 1 (non-finite values
    /// become black).
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.to_srgb8_with(&Display::LINEAR)
    }

    /// 8-bit sRGB bytes, RGB interleaved, as `display` shows the film.
    pub fn to_srgb8_with(&self, display: &Display) -> Vec<u8> {
        self.pixels
            .iter()
            .flat_map(|p| display.map(*p).to_array().map(|c| (linear_to_srgb(c) * 255.0 + 0.5) as u8))
            .collect()
    }

    /// Writes the image, a PNG of the linear values clipped at 1 ([`Display::LINEAR`]) or a
    /// linear EXR; see [`Film::write_with`].
    pub fn write(&self, path: &Path) -> anyhow::Result<()> {
        self.write_with(path, &Display::LINEAR)
    }

    /// Writes the image; the format follows the extension: .png as `display` shows it, .exr
    /// linear and untouched. Parent directories are created.
    pub fn write_with(&self, path: &Path, display: &Display) -> anyhow::Result<()> {
        let format = ImageFormat::from_path(path)?;
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("{}: cannot create directory", dir.display()))?;
        }
        match format {
            ImageFormat::Png => {
                let mut png = std::io::Cursor::new(Vec::new());
                image::write_buffer_with_format(
                    &mut png,
                    &self.to_srgb8_with(display),
                    self.width,
                    self.height,
                    image::ColorType::Rgb8,
                    image::ImageFormat::Png,
                )
                .with_context(|| format!("{}: cannot encode PNG", path.display()))?;
                crate::io::atomic::write_bytes(path, png.get_ref())
            }
            ImageFormat::Npy => crate::io::npy::write_npy(path, &self.to_array()),
            ImageFormat::Exr => {
                use exr::prelude::WritableImage as _;
                let w = self.width as usize;
                let channels =
                    exr::prelude::SpecificChannels::rgb(|exr::math::Vec2(x, y): exr::math::Vec2<usize>| {
                        let p = self.pixels[y * w + x];
                        (p.x, p.y, p.z)
                    });
                // Chunks compressed one after the other: in parallel they land in the file in
                // the order they finish, and the same image gives different bytes.
                let mut exr_bytes = std::io::Cursor::new(Vec::new());
                exr::prelude::Image::from_channels((w, self.height as usize), channels)
                    .write()
                    .non_parallel()
                    .to_buffered(&mut exr_bytes)
                    .with_context(|| format!("{}: cannot encode EXR", path.display()))?;
                crate::io::atomic::write_bytes(path, exr_bytes.get_ref())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_curve_endpoints_and_midpoint() {
        assert_eq!(linear_to_srgb(0.0), 0.0);
        assert!((linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
        // 18 % grey is about 46 % in sRGB.
        assert!((linear_to_srgb(0.18) - 0.4614).abs() < 1e-3);
        assert!((linear_to_srgb(5.0) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn tone_maps_follow_their_formulas() {
        let aces = |x: f32| (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14);
        for x in [0.0f32, 0.05, 0.18, 0.5, 1.0, 2.0] {
            let c = Vec3::splat(x);
            let d = Display { exposure_ev: 0.0, tone_map: ToneMap::Aces };
            assert!((d.map(c).x - aces(x).min(1.0)).abs() < 1e-6, "aces {x}");
            let r = Display { exposure_ev: 0.0, tone_map: ToneMap::Reinhard }.map(c);
            assert!((r.x - x / (1.0 + x)).abs() < 1e-6, "reinhard {x}");
            assert_eq!(Display::LINEAR.map(c).x, x.min(1.0));
            // +1 EV doubles the value the tone map receives.
            let up = Display { exposure_ev: 1.0, tone_map: ToneMap::Aces };
            assert!((up.map(c).x - aces(2.0 * x).min(1.0)).abs() < 1e-6, "exposure {x}");
        }
        // Highlights roll off instead of clipping; the curve never decreases.
        let mut last = 0.0;
        for i in 0..200 {
            let v = Display::default().map(Vec3::splat(i as f32 * 0.1)).x;
            assert!(v >= last && v <= 1.0);
            last = v;
        }
        assert!(Display::default().map(Vec3::splat(1.0)).x < 1.0);
        assert!(Display { exposure_ev: f32::NAN, tone_map: ToneMap::Aces }.validate().is_err());
        assert!(Display { exposure_ev: 31.0, tone_map: ToneMap::Aces }.validate().is_err());
        assert!(Display { exposure_ev: -3.0, tone_map: ToneMap::None }.validate().is_ok());
        assert_eq!("Reinhard".parse::<ToneMap>(), Ok(ToneMap::Reinhard));
        assert!("filmic".parse::<ToneMap>().is_err());
    }

    #[test]
    fn writes_png_and_exr_and_rejects_other_extensions() -> anyhow::Result<()> {
        let dir = tempfile::tempdir().unwrap();
        let mut f = Film::new(3, 2);
        f.pixels[1] = Vec3::new(0.5, 2.0, 0.0);
        f.write(&dir.path().join("a.png")).unwrap();
        f.write(&dir.path().join("sub/a.exr")).unwrap();
        let png = image::open(dir.path().join("a.png")).unwrap().to_rgb8();
        assert_eq!(png.get_pixel(1, 0).0, [188, 255, 0]);
        let exr = exr::prelude::read_first_rgba_layer_from_file(
            dir.path().join("sub/a.exr"),
            |r, _| vec![(0.0f32, 0.0f32, 0.0f32); r.width() * r.height()],
            |v: &mut Vec<(f32, f32, f32)>, p, (r, g, b, _a): (f32, f32, f32, f32)| {
                v[p.y() * 3 + p.x()] = (r, g, b)
            },
        )
        .unwrap();
        assert_eq!(exr.layer_data.channel_data.pixels[1], (0.5, 2.0, 0.0));
        // The same image gives the same bytes: an image of many compressed chunks, of uneven
        // cost (smooth rows and noisy rows), written several times.
        let mut big = Film::new(512, 512);
        let mut r = crate::core::rng::stream(3, 0, 0);
        for (i, p) in big.pixels.iter_mut().enumerate() {
            let noisy = (i / 512) % 64 < 24;
            *p = if noisy { Vec3::splat(crate::core::rng::uniform(&mut r)) } else { Vec3::splat(0.25) };
        }
        let path = |k: usize| dir.path().join(format!("b{k}.exr"));
        let files: Vec<Vec<u8>> = (0..6)
            .map(|k| big.write(&path(k)).and_then(|()| Ok(std::fs::read(path(k))?)))
            .collect::<anyhow::Result<_>>()?;
        assert!(files.iter().all(|f| *f == files[0]), "writes of one image differ");
        assert!(f.write(&dir.path().join("a.jpg")).is_err());
        assert!(f.write(&dir.path().join("a")).is_err());
        Ok(())
    }
}
