//! Directions of arrival: a fixed grid of direction cells on the sphere, the cube map
//! (docs/acoustics.md, Directions of arrival).
//!
//! A direction belongs to the cube face of its largest component and, on that face, to one
//! of [`SPLIT`] x [`SPLIT`] squares of equal extent in the face coordinates (u, v) = the two
//! other components over the largest, in [-1, 1]. The lookup costs one comparison chain and
//! two divisions (no search), and cells are 54 with [`SPLIT`] = 3: 0.40 sr at a face centre,
//! less towards the cube's corners, 0.23 sr (4 pi / 54, about 27 degrees across) on average:
//! the angular resolution of the rays' directions of arrival, finer than the main lobe of
//! first- to third-order Ambisonics (90 to 45 degrees wide).

use glam::Vec3;

/// Squares per cube-face edge.
pub const SPLIT: usize = 3;

/// Direction cells: 6 faces of [`SPLIT`]^2.
pub const CELLS: usize = 6 * SPLIT * SPLIT;

/// The time bins of the directions of arrival, in histogram bins: `fine` bins each for the
/// first `early` direction bins (the early part, whose directions matter most and change
/// fastest), then `coarse` each (the late, near-diffuse part). Coarse late bins keep the
/// directional record small enough to stay in cache while rays deposit into it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DirectionBins {
    pub fine: usize,
    pub early: usize,
    pub coarse: usize,
}

impl DirectionBins {
    /// The direction bin of histogram bin `bin`.
    #[inline]
    pub fn of(&self, bin: usize) -> usize {
        let (fine, coarse) = (self.fine.max(1), self.coarse.max(1));
        let split = self.early * fine;
        if bin < split { bin / fine } else { self.early + (bin - split) / coarse }
    }

    /// Direction bins covering `bins` histogram bins.
    pub fn count(&self, bins: usize) -> usize {
        if bins == 0 { 0 } else { self.of(bins - 1) + 1 }
    }
}

/// The cell of the direction `d` (need not be unit; zero or non-finite: cell 0).
#[inline]
pub fn cell_of(d: Vec3) -> usize {
    let a = d.abs();
    let (face, major, u, v) = if a.x >= a.y && a.x >= a.z {
        (usize::from(d.x < 0.0), a.x, d.y, d.z)
    } else if a.y >= a.z {
        (2 + usize::from(d.y < 0.0), a.y, d.x, d.z)
    } else {
        (4 + usize::from(d.z < 0.0), a.z, d.x, d.y)
    };
    if !(major > 0.0 && major.is_finite()) {
        return 0;
    }
    let square = |c: f32| (((c / major + 1.0) * 0.5 * SPLIT as f32) as usize).min(SPLIT - 1);
    face * SPLIT * SPLIT + square(u) * SPLIT + square(v)
}

/// The unit direction at face coordinates (`fu`, `fv`) in [0, 1)^2 of cell `cell` (0.5, 0.5:
/// its centre): the inverse of [`cell_of`].
pub fn direction_in(cell: usize, fu: f32, fv: f32) -> Vec3 {
    let cell = cell.min(CELLS - 1);
    let face = cell / (SPLIT * SPLIT);
    let (i, j) = ((cell / SPLIT) % SPLIT, cell % SPLIT);
    let u = ((i as f32 + fu.clamp(0.0, 1.0)) / SPLIT as f32) * 2.0 - 1.0;
    let v = ((j as f32 + fv.clamp(0.0, 1.0)) / SPLIT as f32) * 2.0 - 1.0;
    let sign = if face.is_multiple_of(2) { 1.0 } else { -1.0 };
    let d = match face / 2 {
        0 => Vec3::new(sign, u, v),
        1 => Vec3::new(u, sign, v),
        _ => Vec3::new(u, v, sign),
    };
    d.normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn direction_bins_are_fine_then_coarse() {
        let d = DirectionBins { fine: 10, early: 20, coarse: 100 };
        assert_eq!(
            (d.of(0), d.of(9), d.of(10), d.of(199), d.of(200), d.of(299), d.of(300)),
            (0, 0, 1, 19, 20, 20, 21)
        );
        assert_eq!((d.count(0), d.count(1), d.count(200), d.count(201), d.count(1150)), (0, 1, 20, 21, 30));
    }

    #[test]
    fn cells_round_trip_and_cover_the_sphere() {
        // Every cell's centre (and points near its corners) maps back to it, and a dense
        // Fibonacci lattice visits every cell, with solid angles summing to 4 pi.
        for c in 0..CELLS {
            for (fu, fv) in [(0.5, 0.5), (0.01, 0.01), (0.99, 0.01), (0.01, 0.99), (0.99, 0.99)] {
                assert_eq!(cell_of(direction_in(c, fu, fv)), c, "cell {c} at ({fu}, {fv})");
            }
        }
        let n = 200_000;
        let mut count = vec![0usize; CELLS];
        for i in 0..n {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
            let phi = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
            let r = (1.0 - z * z).sqrt();
            count[cell_of(Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32))] += 1;
        }
        // Solid angle of a face-centre cell, the square [-1/3, 1/3]^2 at distance 1:
        // 4 asin(a b / sqrt((a^2 + 1)(b^2 + 1))) with a = b = 1/3, 4 asin(1/10) = 0.4007 sr.
        let centre = 4.0 * (0.1f64).asin();
        let measured = count[4] as f64 / n as f64 * 4.0 * std::f64::consts::PI;
        assert!((measured - centre).abs() < 0.01 * centre, "{measured} vs {centre}");
        assert!(count.iter().all(|&c| c > 0));
    }
}
