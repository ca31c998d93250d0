//! The coverage grid: cells on a horizontal plane that add up the power of the rays crossing
//! them, the estimator of Sionna RT's coverage maps.
//!
//! Each ray of a launch of `N` carries the power `P_tx G(dir) / N` (equal solid angle
//! `4 pi / N` per ray on the Fibonacci lattice) times the product of `|Gamma|^2` of its
//! reflections. When a segment crosses the plane `z = h` inside a cell, the cell adds that
//! power divided by `|cos theta|` (theta between the ray and the plane's normal): the power
//! density over the cell is `sum / A` and the average path gain over the cell is
//! `g = (sum / A) (lambda^2 / 4 pi) / P_tx` (an isotropic receiver's effective area), i.e.
//! the power (incoherent) sum over the ray paths crossing the cell.
//!
//! Deposits are added in 32.32 fixed point with integer adds, which are exact and
//! associative: the grid does not depend on the thread count or the order of the rays. The
//! launcher's blocks collect their crossings in a list that is added to the grid when the
//! block is merged ([`CoverageAccumulator::absorb`], one thread at a time) rather than with
//! atomic adds from both threads into the same cells (3-4 % faster on the street canyon).

use std::sync::Mutex;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};

/// Fixed-point scale of the deposits (2^32).
const FIXED_SCALE: f64 = 4_294_967_296.0;
/// Crossings closer to grazing than this `|cos theta|` are counted at this value, bounding a
/// single deposit (the estimator's variance is unbounded at grazing incidence).
pub const MIN_CROSSING_COS: f64 = 1.0e-3;

/// Geometry of a horizontal grid of square cells.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct GridSpec {
    /// Lower corner (x, y) of cell (0, 0), metres.
    pub min_m: [f64; 2],
    /// Cell side, metres.
    pub cell_m: f64,
    /// Cells along x.
    pub nx: usize,
    /// Cells along y.
    pub ny: usize,
    /// Height of the plane, metres.
    pub height_m: f64,
}

impl GridSpec {
    /// Cells of side `cell_m` covering `[min, max]` (the last row and column may overhang).
    pub fn covering(min: [f64; 2], max: [f64; 2], cell_m: f64, height_m: f64) -> Result<Self, String> {
        if !(cell_m.is_finite() && cell_m > 0.0) {
            return Err(format!("cell size {cell_m} m: must be a positive number"));
        }
        if !height_m.is_finite() {
            return Err(format!("grid height {height_m} m: must be finite"));
        }
        if !(max[0] > min[0] && max[1] > min[1] && min.iter().chain(&max).all(|v| v.is_finite())) {
            return Err(format!(
                "grid extent ({}, {}) to ({}, {}): max must exceed min in x and y",
                min[0], min[1], max[0], max[1]
            ));
        }
        let nx = ((max[0] - min[0]) / cell_m - 1e-9).ceil().max(1.0);
        let ny = ((max[1] - min[1]) / cell_m - 1e-9).ceil().max(1.0);
        if nx * ny > 2.0e7 {
            return Err(format!("{nx} x {ny} cells is too many: use a larger cell size"));
        }
        Ok(Self { min_m: min, cell_m, nx: nx as usize, ny: ny as usize, height_m })
    }

    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.nx * self.ny
    }

    /// Index (row-major, x fastest) of the cell holding (x, y).
    #[inline]
    pub fn cell_of(&self, x: f64, y: f64) -> Option<usize> {
        let i = ((x - self.min_m[0]) / self.cell_m).floor();
        let j = ((y - self.min_m[1]) / self.cell_m).floor();
        if i >= 0.0 && j >= 0.0 && (i as usize) < self.nx && (j as usize) < self.ny {
            Some(j as usize * self.nx + i as usize)
        } else {
            None
        }
    }

    /// Centre (x, y) of cell `index`.
    pub fn centre(&self, index: usize) -> [f64; 2] {
        let (i, j) = (index % self.nx, index / self.nx);
        [self.min_m[0] + (i as f64 + 0.5) * self.cell_m, self.min_m[1] + (j as f64 + 0.5) * self.cell_m]
    }

    /// Area of one cell, m^2.
    pub fn cell_area_m2(&self) -> f64 {
        self.cell_m * self.cell_m
    }
}

/// The shared accumulator a launch deposits into.
pub struct CoverageAccumulator {
    /// The grid.
    pub spec: GridSpec,
    sum: Vec<AtomicU64>,
    paths: Vec<AtomicU32>,
    /// Held while a list of crossings is added ([`Self::absorb`]).
    absorbing: Mutex<()>,
}

impl CoverageAccumulator {
    /// An empty accumulator over `spec`.
    pub fn new(spec: GridSpec) -> Self {
        let n = spec.cells();
        Self {
            spec,
            sum: (0..n).map(|_| AtomicU64::new(0)).collect(),
            paths: (0..n).map(|_| AtomicU32::new(0)).collect(),
            absorbing: Mutex::new(()),
        }
    }

    /// The deposit of a segment from `origin` along the unit `dir` over `(0, length]`
    /// carrying `weight` (power relative to `P_tx / N`): the cell it crosses, if any, and
    /// `weight / |cos theta|` in fixed point.
    #[inline]
    pub fn crossing(&self, origin: [f64; 3], dir: [f64; 3], length: f64, weight: f64) -> Option<(u32, u64)> {
        let dz = dir[2];
        if dz == 0.0 || weight <= 0.0 {
            return None;
        }
        let t = (self.spec.height_m - origin[2]) / dz;
        if !(t > 0.0 && t <= length) {
            return None;
        }
        let cell = self.spec.cell_of(origin[0] + t * dir[0], origin[1] + t * dir[1])?;
        let v = weight / dz.abs().max(MIN_CROSSING_COS);
        Some((cell as u32, (v * FIXED_SCALE).round() as u64))
    }

    /// How far along the unit `dir` from `origin` a segment can deposit (see
    /// [`Self::crossing`]): the distance to its crossing of the grid plane when that lands in
    /// a cell, else 0. A segment of at least this length deposits what an endless one would.
    #[inline]
    pub fn reach(&self, origin: [f64; 3], dir: [f64; 3]) -> f64 {
        let dz = dir[2];
        if dz == 0.0 {
            return 0.0;
        }
        let t = (self.spec.height_m - origin[2]) / dz;
        if t.is_nan()
            || t <= 0.0
            || self.spec.cell_of(origin[0] + t * dir[0], origin[1] + t * dir[1]).is_none()
        {
            return 0.0;
        }
        t
    }

    /// Records a segment (see [`Self::crossing`]) at once, with atomic adds.
    #[inline]
    pub fn record(&self, origin: [f64; 3], dir: [f64; 3], length: f64, weight: f64) {
        if let Some((cell, fixed)) = self.crossing(origin, dir, length, weight) {
            self.sum[cell as usize].fetch_add(fixed, Ordering::Relaxed);
            self.paths[cell as usize].fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Adds a list of crossings ([`Self::crossing`]) with plain loads and stores, one list at a
    /// time. Must not run while another thread calls [`Self::record`] on this grid (the
    /// launcher records through lists only).
    pub fn absorb(&self, crossings: &[(u32, u64)]) {
        let _one_at_a_time = self.absorbing.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        for &(cell, fixed) in crossings {
            let (sum, paths) = (&self.sum[cell as usize], &self.paths[cell as usize]);
            sum.store(sum.load(Ordering::Relaxed).wrapping_add(fixed), Ordering::Relaxed);
            paths.store(paths.load(Ordering::Relaxed).wrapping_add(1), Ordering::Relaxed);
        }
    }

    /// The average path gain of every cell (linear, 0 where no ray crossed) for a launch of
    /// `rays` rays at `wavelength_m`: `g = S lambda^2 / (4 pi N A)` with `S` the cell's sum.
    pub fn finish(&self, rays: u64, wavelength_m: f64) -> Coverage {
        self.totals().finish(rays, wavelength_m)
    }

    /// The raw fixed-point sums and crossing counts, e.g. to add up over processes.
    pub fn totals(&self) -> CellTotals {
        CellTotals {
            spec: self.spec,
            sum: self.sum.iter().map(|s| s.load(Ordering::Relaxed)).collect(),
            paths: self.paths.iter().map(|p| p.load(Ordering::Relaxed)).collect(),
        }
    }
}

/// A launch's deposits per cell in fixed point: integer sums, exact in any order.
#[derive(Clone, Debug, PartialEq)]
pub struct CellTotals {
    /// The grid.
    pub spec: GridSpec,
    /// Sum of `weight / |cos theta|` per cell, scaled by `FIXED_SCALE`.
    pub sum: Vec<u64>,
    /// Ray crossings per cell.
    pub paths: Vec<u32>,
}

impl CellTotals {
    /// See [`CoverageAccumulator::finish`].
    pub fn finish(&self, rays: u64, wavelength_m: f64) -> Coverage {
        let k = wavelength_m * wavelength_m
            / (4.0 * std::f64::consts::PI * rays as f64 * self.spec.cell_area_m2() * FIXED_SCALE);
        Coverage {
            spec: self.spec,
            path_gain: self.sum.iter().map(|&s| s as f64 * k).collect(),
            paths: self.paths.clone(),
        }
    }
}

/// A finished coverage map.
#[derive(Clone, Debug)]
pub struct Coverage {
    /// The grid.
    pub spec: GridSpec,
    /// Average path gain over each cell, linear (0 = no ray).
    pub path_gain: Vec<f64>,
    /// Ray crossings per cell.
    pub paths: Vec<u32>,
}

impl Coverage {
    /// A map of `spec` that no ray reached.
    pub fn empty(spec: GridSpec) -> Self {
        Self { spec, path_gain: vec![0.0; spec.cells()], paths: vec![0; spec.cells()] }
    }

    /// Adds another map of the same grid (another transmitter).
    pub fn add(&mut self, other: &Coverage) {
        for (a, b) in self.path_gain.iter_mut().zip(&other.path_gain) {
            *a += b;
        }
        for (a, b) in self.paths.iter_mut().zip(&other.paths) {
            *a += b;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_cover_the_extent_and_index_round_trips() {
        let g = GridSpec::covering([-2.0, -1.0], [2.0, 1.5], 0.5, 1.5).unwrap();
        assert_eq!((g.nx, g.ny), (8, 5));
        for i in 0..g.cells() {
            let c = g.centre(i);
            assert_eq!(g.cell_of(c[0], c[1]), Some(i));
        }
        assert_eq!(g.cell_of(-2.1, 0.0), None);
        assert!(GridSpec::covering([0.0, 0.0], [1.0, 1.0], 0.0, 1.5).is_err());
        assert!(GridSpec::covering([0.0, 0.0], [0.0, 1.0], 1.0, 1.5).is_err());
    }

    #[test]
    fn a_crossing_deposits_weight_over_cos() {
        let g = GridSpec::covering([0.0, 0.0], [10.0, 10.0], 1.0, 1.5).unwrap();
        let acc = CoverageAccumulator::new(g);
        let d = [0.6, 0.0, -0.8];
        acc.record([1.0, 5.5, 3.5], d, 10.0, 2.0);
        // Crosses z = 1.5 after 2.5 m at x = 2.5.
        let cov = acc.finish(1, (4.0 * std::f64::consts::PI).sqrt());
        let cell = g.cell_of(2.5, 5.5).unwrap();
        assert!((cov.path_gain[cell] - 2.0 / 0.8).abs() < 1e-9);
        assert_eq!(cov.paths.iter().sum::<u32>(), 1);
        // A segment too short to reach the plane deposits nothing.
        acc.record([1.0, 5.5, 3.5], d, 2.0, 2.0);
        assert_eq!(acc.finish(1, 1.0).paths.iter().sum::<u32>(), 1);
    }
}
