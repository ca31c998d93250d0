//! A density grid for a heterogeneous participating medium: a box of `nx x ny x nz` voxels,
//! each holding a non-negative density at its centre, interpolated trilinearly between the
//! centres and zero outside the box (the layout of pbrt-v4's `SampledGrid`, \[pbrt-v4\]
//! sec. 11.4.3 in docs/references.md).
//!
//! Two file formats (docs/render.md, "Density grid files"):
//! - **text** (any extension but `.raw`): `#` starts a comment to the end of its line; the
//!   first three numbers are `nx ny nz`, then come exactly `nx * ny * nz` densities separated
//!   by any whitespace, x fastest, then y, then z (value `(i, j, k)` is number
//!   `i + nx (j + ny k)`);
//! - **raw** (`.raw`): `nx * ny * nz` little-endian 32-bit floats in the same order, with
//!   the dimensions given by the scene file's `grid_dims`.

use std::path::Path;

use glam::Vec3;

use crate::core::Ray;

/// Cells of the majorant grid along each axis ([`DensityGrid::majorant_segments`]).
pub const MAJORANT_CELLS: usize = 16;

/// Most voxels a grid may have (2^24, 64 MB of densities): a larger count is refused before
/// anything is allocated.
pub const MAX_VOXELS: usize = 1 << 24;

/// A grid of densities over an axis-aligned box.
#[derive(Clone, Debug, PartialEq)]
pub struct DensityGrid {
    /// Voxels along x, y, z (each at least 1).
    pub dims: [usize; 3],
    /// The densities, x fastest, then y, then z; finite and non-negative.
    pub values: Vec<f32>,
    /// Lower corner of the box, metres.
    pub bounds_min: Vec3,
    /// Upper corner of the box, metres (above `bounds_min` on every axis).
    pub bounds_max: Vec3,
    /// The largest density (the majorant of the trilinear interpolation).
    pub max_density: f32,
    /// The largest density each cell of a coarse `MAJORANT_CELLS`^3 grid over the box can
    /// take (the voxels its interpolation reads), x fastest: local majorants, so that
    /// tracking takes short steps only where the medium is dense (\[pbrt-v4\] sec. 11.4.3,
    /// `MajorantGrid`).
    pub majorants: Vec<f32>,
}

impl DensityGrid {
    /// A grid from its parts; the error says what is wrong (dimensions, count, a negative or
    /// non-finite density, or an empty box).
    pub fn new(
        dims: [usize; 3],
        values: Vec<f32>,
        bounds_min: Vec3,
        bounds_max: Vec3,
    ) -> Result<Self, String> {
        check_count(dims, values.len())?;
        if let Some((i, v)) = values.iter().enumerate().find(|(_, v)| !(v.is_finite() && **v >= 0.0)) {
            return Err(format!("density number {} is {v}: densities must be finite and 0 or more", i + 1));
        }
        if !(bounds_min.is_finite() && bounds_max.is_finite() && bounds_min.cmplt(bounds_max).all()) {
            return Err(format!(
                "bounds_min {bounds_min} must be below bounds_max {bounds_max} on every axis (finite)"
            ));
        }
        let max_density = values.iter().copied().fold(0.0f32, f32::max);
        let majorants = majorant_grid(dims, &values);
        Ok(Self { dims, values, bounds_min, bounds_max, max_density, majorants })
    }

    /// Loads a grid file (text, or raw with `raw_dims`), every density times `scale`, over
    /// the box; the error is one line naming the file.
    pub fn load(
        path: &Path,
        raw_dims: Option<[u32; 3]>,
        scale: f32,
        bounds_min: Vec3,
        bounds_max: Vec3,
    ) -> Result<Self, String> {
        let name = path.display();
        let bytes = std::fs::read(path).map_err(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                format!("{name}: density grid file not found")
            } else {
                format!("{name}: cannot read the density grid: {e}")
            }
        })?;
        let raw = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("raw"));
        let (dims, values) = if raw {
            let d = raw_dims.ok_or_else(|| {
                format!("{name}: a raw density grid needs grid_dims = [nx, ny, nz] in the scene")
            })?;
            let dims = d.map(|n| n as usize);
            parse_raw(&bytes, dims).map(|v| (dims, v))
        } else {
            let text =
                std::str::from_utf8(&bytes).map_err(|_| format!("{name}: the density grid is not text"))?;
            parse_text(text)
        }
        .map_err(|e| format!("{name}: {e}"))?;
        if !(scale.is_finite() && scale >= 0.0) {
            return Err(format!("{name}: density_scale {scale} must be finite and 0 or more"));
        }
        let values = values.into_iter().map(|v| v * scale).collect();
        Self::new(dims, values, bounds_min, bounds_max).map_err(|e| format!("{name}: {e}"))
    }

    /// The density at `p`: trilinear between voxel centres, the nearest edge value in the
    /// half voxel along the box's faces, zero outside the box.
    #[inline]
    pub fn density(&self, p: Vec3) -> f32 {
        let size = self.bounds_max - self.bounds_min;
        let q = (p - self.bounds_min) / size;
        if !(q.cmpge(Vec3::ZERO).all() && q.cmple(Vec3::ONE).all()) {
            return 0.0;
        }
        let [nx, ny, nz] = self.dims;
        // Continuous voxel coordinates, centres at integers.
        let axis = |q: f32, n: usize| -> (usize, usize, f32) {
            let x = (q * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
            let i = (x as usize).min(n - 1);
            let j = (i + 1).min(n - 1);
            (i, j, x - i as f32)
        };
        let (x0, x1, fx) = axis(q.x, nx);
        let (y0, y1, fy) = axis(q.y, ny);
        let (z0, z1, fz) = axis(q.z, nz);
        let v = |i: usize, j: usize, k: usize| self.values[i + nx * (j + ny * k)];
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let c00 = lerp(v(x0, y0, z0), v(x1, y0, z0), fx);
        let c10 = lerp(v(x0, y1, z0), v(x1, y1, z0), fx);
        let c01 = lerp(v(x0, y0, z1), v(x1, y0, z1), fx);
        let c11 = lerp(v(x0, y1, z1), v(x1, y1, z1), fx);
        lerp(lerp(c00, c10, fy), lerp(c01, c11, fy), fz)
    }

    /// The part `[t0, t1]` of `[0, t_max]` where `ray` is inside the box (slab test), if any.
    #[inline]
    pub fn clip(&self, ray: &Ray, t_max: f32) -> Option<(f32, f32)> {
        let inv = ray.dir.recip();
        let a = (self.bounds_min - ray.origin) * inv;
        let b = (self.bounds_max - ray.origin) * inv;
        // NaN (a zero direction component on a face) is dropped by max/min.
        let t0 = a.min(b).max_element().max(0.0);
        let t1 = a.max(b).min_element().min(t_max);
        (t0 < t1).then_some((t0, t1))
    }
}

impl DensityGrid {
    /// Walks `ray` (unit direction) through the majorant cells over `[t0, t1]` (inside the
    /// box, from [`DensityGrid::clip`]) by a 3-D DDA (\[Amanatides1987\], as pbrt-v4's
    /// `DDAMajorantIterator`), calling `visit(t_start, t_end, majorant_density)` for each
    /// stretch in order until it returns true.
    pub fn majorant_segments(
        &self,
        ray: &Ray,
        t0: f32,
        t1: f32,
        mut visit: impl FnMut(f32, f32, f32) -> bool,
    ) {
        let n = MAJORANT_CELLS as i32;
        let size = self.bounds_max - self.bounds_min;
        let cell_m = size / MAJORANT_CELLS as f32;
        let start = (ray.at(t0) - self.bounds_min) / cell_m;
        let mut cell = [0i32; 3];
        let mut step = [0i32; 3];
        let mut next_t = [f32::INFINITY; 3];
        let mut delta_t = [f32::INFINITY; 3];
        for a in 0..3 {
            cell[a] = (start[a] as i32).clamp(0, n - 1);
            let d = ray.dir[a];
            if d > 0.0 {
                step[a] = 1;
                let boundary = self.bounds_min[a] + (cell[a] + 1) as f32 * cell_m[a];
                next_t[a] = t0 + (boundary - ray.at(t0)[a]) / d;
                delta_t[a] = cell_m[a] / d;
            } else if d < 0.0 {
                step[a] = -1;
                let boundary = self.bounds_min[a] + cell[a] as f32 * cell_m[a];
                next_t[a] = t0 + (boundary - ray.at(t0)[a]) / d;
                delta_t[a] = -cell_m[a] / d;
            }
        }
        let mut t = t0;
        // A ray crosses at most 3 n cells; the bound keeps a NaN from looping.
        for _ in 0..3 * MAJORANT_CELLS + 3 {
            let axis = if next_t[0] < next_t[1] {
                if next_t[0] < next_t[2] { 0 } else { 2 }
            } else if next_t[1] < next_t[2] {
                1
            } else {
                2
            };
            let end = next_t[axis].min(t1);
            let index = (cell[0] + n * (cell[1] + n * cell[2])) as usize;
            if end > t && visit(t, end, self.majorants[index]) {
                return;
            }
            if end >= t1 {
                return;
            }
            t = end;
            cell[axis] += step[axis];
            if !(0..n).contains(&cell[axis]) {
                return;
            }
            next_t[axis] += delta_t[axis];
        }
    }
}

/// The local majorants of a grid: for each of the `MAJORANT_CELLS`^3 cells, the largest
/// value among the voxels whose centres bracket a point of the cell.
fn majorant_grid(dims: [usize; 3], values: &[f32]) -> Vec<f32> {
    let n = MAJORANT_CELLS;
    // The voxel range each cell's interpolation reads along one axis of `voxels`.
    let range = |cell: usize, voxels: usize| -> (usize, usize) {
        let lo = (cell as f32 / n as f32 * voxels as f32 - 0.5).floor().max(0.0) as usize;
        let hi = ((cell + 1) as f32 / n as f32 * voxels as f32 - 0.5).floor() as isize + 1;
        (lo.min(voxels - 1), (hi.max(0) as usize).min(voxels - 1))
    };
    let mut out = vec![0.0f32; n * n * n];
    for c in 0..n {
        let (k0, k1) = range(c, dims[2]);
        for b in 0..n {
            let (j0, j1) = range(b, dims[1]);
            for a in 0..n {
                let (i0, i1) = range(a, dims[0]);
                let mut m = 0.0f32;
                for k in k0..=k1 {
                    for j in j0..=j1 {
                        for i in i0..=i1 {
                            m = m.max(values[i + dims[0] * (j + dims[1] * k)]);
                        }
                    }
                }
                out[a + n * (b + n * c)] = m;
            }
        }
    }
    out
}

/// `nx * ny * nz`, refused when a dimension is 0 or the count exceeds [`MAX_VOXELS`].
fn voxel_count(dims: [usize; 3]) -> Result<usize, String> {
    if dims.contains(&0) {
        return Err(format!("empty density grid: dimensions {} x {} x {}", dims[0], dims[1], dims[2]));
    }
    dims.iter().try_fold(1usize, |acc, &n| acc.checked_mul(n)).filter(|&n| n <= MAX_VOXELS).ok_or_else(|| {
        format!("density grid {} x {} x {} has more than {MAX_VOXELS} voxels", dims[0], dims[1], dims[2])
    })
}

/// The text format: `nx ny nz` then the densities; `#` comments.
pub fn parse_text(text: &str) -> Result<([usize; 3], Vec<f32>), String> {
    let mut words = text.lines().flat_map(|l| l.split('#').next().unwrap_or("").split_whitespace());
    let mut dims = [0usize; 3];
    for (axis, d) in ["nx", "ny", "nz"].iter().zip(dims.iter_mut()) {
        let w = words.next().ok_or_else(|| format!("empty density grid: no {axis} in the header"))?;
        *d = w.parse().map_err(|_| format!("header {axis} \"{w}\" is not a whole number"))?;
    }
    let voxels = voxel_count(dims)?;
    let mut values = Vec::with_capacity(voxels);
    for w in words {
        if values.len() == voxels {
            return Err(format!(
                "more than {voxels} densities for a {} x {} x {} grid",
                dims[0], dims[1], dims[2]
            ));
        }
        let v: f32 =
            w.parse().map_err(|_| format!("density number {} \"{w}\" is not a number", values.len() + 1))?;
        values.push(v);
    }
    check_count(dims, values.len())?;
    Ok((dims, values))
}

/// An error unless `found` densities fill a grid of `dims`.
fn check_count(dims: [usize; 3], found: usize) -> Result<(), String> {
    let voxels = voxel_count(dims)?;
    if found == voxels {
        return Ok(());
    }
    Err(format!("{found} densities for a {} x {} x {} grid (expected {voxels})", dims[0], dims[1], dims[2]))
}

/// The raw format: little-endian f32s, `dims` from the scene file.
pub fn parse_raw(bytes: &[u8], dims: [usize; 3]) -> Result<Vec<f32>, String> {
    let voxels = voxel_count(dims)?;
    if bytes.len() != 4 * voxels {
        return Err(format!(
            "{} bytes for a {} x {} x {} grid of 32-bit floats (expected {})",
            bytes.len(),
            dims[0],
            dims[1],
            dims[2],
            4 * voxels
        ));
    }
    Ok(bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_text_format_reads_x_fastest_and_interpolates_between_centres() {
        let (dims, values) = parse_text("# a ramp\n2 1 1\n1.0 3.0 # x = 0, 1\n").expect("parses");
        let g = DensityGrid::new(dims, values, Vec3::ZERO, Vec3::new(2.0, 1.0, 1.0)).expect("valid");
        // Centres at x = 0.5 (1) and 1.5 (3): linear between, constant beyond, zero outside.
        assert_eq!(g.density(Vec3::new(0.25, 0.5, 0.5)), 1.0);
        assert!((g.density(Vec3::new(1.0, 0.5, 0.5)) - 2.0).abs() < 1e-6);
        assert_eq!(g.density(Vec3::new(1.9, 0.5, 0.5)), 3.0);
        assert_eq!(g.density(Vec3::new(2.1, 0.5, 0.5)), 0.0);
        assert_eq!(g.max_density, 3.0);
    }

    #[test]
    fn local_majorants_bound_the_density_along_any_ray() {
        // A pseudo-random 5 x 7 x 3 grid; rays in several directions, densities sampled finely.
        let values: Vec<f32> = (0..105).map(|i| ((i * 37 % 11) as f32) * 0.3).collect();
        let g =
            DensityGrid::new([5, 7, 3], values, Vec3::new(-1.0, 0.0, 0.5), Vec3::new(2.0, 1.5, 1.0)).unwrap();
        for (o, d) in [
            (Vec3::new(-2.0, 0.7, 0.7), Vec3::new(1.0, 0.1, 0.05)),
            (Vec3::new(3.0, 1.4, 0.9), Vec3::new(-1.0, -0.4, -0.2)),
            (Vec3::new(0.5, -1.0, 0.75), Vec3::Y),
        ] {
            let ray = Ray::new(o, d.normalize());
            let (t0, t1) = g.clip(&ray, 100.0).expect("the ray meets the box");
            let mut covered = t0;
            g.majorant_segments(&ray, t0, t1, |a, b, m| {
                assert!((a - covered).abs() < 1e-4, "stretches are contiguous: {a} after {covered}");
                covered = b;
                for k in 0..=50 {
                    let t = a + (b - a) * k as f32 / 50.0;
                    assert!(g.density(ray.at(t)) <= m + 1e-5, "density above the local majorant");
                }
                false
            });
            assert!((covered - t1).abs() < 1e-4, "the walk ends at {covered}, not {t1}");
        }
    }

    #[test]
    fn bad_grids_are_refused_with_the_reason() {
        assert!(parse_text("0 4 4").unwrap_err().contains("empty"));
        assert!(parse_text("").unwrap_err().contains("empty"));
        assert!(parse_text("2 2 1 1 1 1").unwrap_err().contains("3 densities"));
        assert!(parse_text("1 1 1 1 2").unwrap_err().contains("more than 1"));
        assert!(parse_text("70000 70000 70000").unwrap_err().contains("more than"));
        let neg = DensityGrid::new([1, 1, 2], vec![1.0, -0.5], Vec3::ZERO, Vec3::ONE).unwrap_err();
        assert!(neg.contains("number 2 is -0.5"), "{neg}");
        let nan = DensityGrid::new([1, 1, 1], vec![f32::NAN], Vec3::ZERO, Vec3::ONE).unwrap_err();
        assert!(nan.contains("NaN"), "{nan}");
        let flat = DensityGrid::new([1, 1, 1], vec![1.0], Vec3::ZERO, Vec3::new(1.0, 0.0, 1.0)).unwrap_err();
        assert!(flat.contains("bounds_min"), "{flat}");
        assert!(parse_raw(&[0u8; 7], [1, 1, 2]).unwrap_err().contains("7 bytes"));
    }
}
