//! The image being rendered (linear RGB radiance per pixel) and its output as 8-bit sRGB PNG
//! or linear float EXR.

use std::path::Path;

use anyhow::{Context, bail};
use glam::Vec3;

/// A `width` x `height` image of linear RGB values, row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

/// Output formats, chosen by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// 8-bit sRGB PNG (values clamped to [0, 1] before encoding).
    Png,
    /// OpenEXR, linear 32-bit float RGB.
    Exr,
}

impl ImageFormat {
    /// The format named by `path`'s extension, or a one-line error.
    pub fn from_path(path: &Path) -> anyhow::Result<Self> {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("png") => Ok(Self::Png),
            Some("exr") => Ok(Self::Exr),
            Some(e) => bail!("{}: unknown image format \".{e}\" (use .png or .exr)", path.display()),
            None => bail!("{}: no file extension (use .png or .exr)", path.display()),
        }
    }
}

/// The sRGB transfer function (IEC 61966-2-1) of a linear value in [0, 1].
#[inline]
pub fn linear_to_srgb(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 { 12.92 * x } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 }
}

impl Film {
    pub fn new(width: u32, height: u32) -> Self {
        Self { width, height, pixels: vec![Vec3::ZERO; width as usize * height as usize] }
    }

    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Mean of every pixel.
    pub fn mean(&self) -> Vec3 {
        let s: glam::DVec3 = self.pixels.iter().map(|p| p.as_dvec3()).sum();
        (s / self.pixels.len().max(1) as f64).as_vec3()
    }

    /// 8-bit sRGB bytes, RGB interleaved (non-finite values become black).
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.pixels
            .iter()
            .flat_map(|p| {
                let p = if p.is_finite() { *p } else { Vec3::ZERO };
                p.to_array().map(|c| (linear_to_srgb(c) * 255.0 + 0.5) as u8)
            })
            .collect()
    }

    /// Writes the image; the format follows the extension (.png or .exr). Parent directories
    /// are created.
    pub fn write(&self, path: &Path) -> anyhow::Result<()> {
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
                    &self.to_srgb8(),
                    self.width,
                    self.height,
                    image::ColorType::Rgb8,
                    image::ImageFormat::Png,
                )
                .with_context(|| format!("{}: cannot encode PNG", path.display()))?;
                crate::io::atomic::write_bytes(path, png.get_ref())
            }
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
