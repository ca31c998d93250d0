//! A hashed uniform grid over points with a search radius each (SPPM's visible points): a
//! query point finds every point whose sphere may hold it. The structure of pbrt-v4's
//! `SPPMIntegrator` grid (pbrt-v3 sec. 16.2.5): cells as wide as the largest radius, each point
//! listed in every cell its sphere overlaps, cells hashed into about as many buckets as listings.
//! Entries keep their cell's key, so two cells sharing a bucket never report a point twice
//! (pbrt's linked lists do in that case). Built serially: the order of a bucket's entries
//! does not matter to callers that sum exactly.

use glam::{IVec3, Vec3};

use crate::core::rng::mix64;

/// Bits of each packed cell coordinate (a key holds three).
const COORD_BITS: u32 = 21;
/// Largest cell coordinate.
const MAX_COORD: i32 = (1 << COORD_BITS) - 1;

/// The grid.
#[derive(Clone, Debug)]
pub struct PhotonGrid {
    /// The box, cells and buckets.
    cells: Cells,
    /// Start of each bucket's entries in `entries` (one more than the buckets).
    offsets: Vec<u32>,
    /// The entries, grouped by bucket.
    entries: Vec<Entry>,
}

impl PhotonGrid {
    /// A grid over `points`: (id, centre, radius in metres). Points with a radius that is not
    /// positive and finite are left out.
    pub fn build(points: &[(u32, Vec3, f32)]) -> Self {
        let points: Vec<&(u32, Vec3, f32)> =
            points.iter().filter(|(_, p, r)| p.is_finite() && r.is_finite() && *r > 0.0).collect();
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        let mut max_r = 0.0f32;
        for &&(_, p, r) in &points {
            lo = lo.min(p - r);
            hi = hi.max(p + r);
            max_r = max_r.max(r);
        }
        let mut grid = Self { cells: Cells::default(), offsets: vec![0; 2], entries: Vec::new() };
        if points.is_empty() {
            return grid;
        }
        // Cells as wide as the largest radius.
        grid.cells = Cells::new(lo, hi, max_r);
        let ranges: Vec<(Entry, IVec3, IVec3)> = points
            .iter()
            .map(|&&(id, p, r)| {
                let e = Entry { key: 0, id, radius2: r * r, centre: p };
                (e, grid.cells.cell_of_clamped(p - r), grid.cells.cell_of_clamped(p + r))
            })
            .collect();
        let cells: usize = ranges.iter().map(|(_, a, b)| ((*b - *a) + 1).element_product() as usize).sum();
        // About one cell's entries a bucket.
        let buckets = cells.max(1).next_power_of_two();
        grid.cells.mask = buckets as u64 - 1;
        grid.offsets = vec![0; buckets + 1];
        let mask = grid.cells.mask;
        let bucket = |k: u64| (mix64(k) & mask) as usize;
        let mut counts = vec![0u32; buckets];
        for &(_, a, b) in &ranges {
            for_cells(a, b, |c| counts[bucket(key(c))] += 1);
        }
        let mut total = 0u32;
        for (o, c) in grid.offsets.iter_mut().zip(&counts) {
            *o = total;
            total += c;
        }
        grid.offsets[buckets] = total;
        let mut fill: Vec<u32> = grid.offsets[..buckets].to_vec();
        let mut entries = vec![Entry::default(); total as usize];
        for &(e, a, b) in &ranges {
            for_cells(a, b, |c| {
                let k = key(c);
                let slot = &mut fill[bucket(k)];
                entries[*slot as usize] = Entry { key: k, ..e };
                *slot += 1;
            });
        }
        grid.entries = entries;
        grid
    }

    /// Calls `f` with the id of every point within its radius of `p` (distance <= radius).
    #[inline]
    pub fn for_each_within(&self, p: Vec3, mut f: impl FnMut(u32)) {
        let c = ((p - self.cells.lo) * self.cells.inv_cell).floor();
        if !c.is_finite() || c.min_element() < 0.0 {
            return;
        }
        let c = c.as_ivec3();
        if c.cmpge(self.cells.res).any() {
            return;
        }
        let k = key(c);
        let b = self.cells.bucket(k);
        for e in &self.entries[self.offsets[b] as usize..self.offsets[b + 1] as usize] {
            if e.key == k && e.centre.distance_squared(p) <= e.radius2 {
                f(e.id);
            }
        }
    }

    /// Entries over all cells (a point counts once per cell it overlaps).
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether no point was gridded.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

/// The geometry of a hashed uniform grid (this one, and [`super::point_grid::PointGrid`]):
/// its box, its cells and its buckets.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Cells {
    /// Lower corner of the gridded box.
    pub lo: Vec3,
    /// Cells per metre.
    pub inv_cell: f32,
    /// Cells along each axis.
    pub res: IVec3,
    /// Bucket mask (buckets are a power of two).
    pub mask: u64,
}

impl Cells {
    /// Cells `cell` metres wide over the box `lo..hi`, but never more than [`MAX_COORD`] a
    /// side; no buckets yet.
    pub fn new(lo: Vec3, hi: Vec3, cell: f32) -> Self {
        let extent = (hi - lo).max_element().max(f32::MIN_POSITIVE);
        let inv_cell = 1.0 / cell.max(extent / (MAX_COORD - 1) as f32);
        let res = ((hi - lo) * inv_cell).as_ivec3().clamp(IVec3::ZERO, IVec3::splat(MAX_COORD)) + 1;
        Self { lo, inv_cell, res, mask: 0 }
    }

    /// The cell holding `p`, clamped to the grid.
    pub fn cell_of_clamped(&self, p: Vec3) -> IVec3 {
        ((p - self.lo) * self.inv_cell).floor().as_ivec3().clamp(IVec3::ZERO, self.res - 1)
    }

    /// The bucket of a cell's key.
    #[inline]
    pub fn bucket(&self, key: u64) -> usize {
        (mix64(key) & self.mask) as usize
    }
}

/// A point listed in a cell: the cell's key and the point, kept inline so that a query
/// reads one array.
#[derive(Clone, Copy, Debug, Default)]
struct Entry {
    key: u64,
    id: u32,
    radius2: f32,
    centre: Vec3,
}

/// A cell's packed coordinates (also [`super::point_grid`]'s).
#[inline]
pub(super) fn key(c: IVec3) -> u64 {
    c.x as u64 | (c.y as u64) << COORD_BITS | (c.z as u64) << (2 * COORD_BITS)
}

/// Calls `f` for every cell of the box `a..=b`.
fn for_cells(a: IVec3, b: IVec3, mut f: impl FnMut(IVec3)) {
    for z in a.z..=b.z {
        for y in a.y..=b.y {
            for x in a.x..=b.x {
                f(IVec3::new(x, y, z));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::rng::{stream, uniform};

    /// Every point within its radius of a query is reported exactly once, against brute force.
    #[test]
    fn finds_every_point_in_range_once() {
        let mut rng = stream(5, 1, 0);
        let mut u = || uniform(&mut rng);
        let points: Vec<(u32, Vec3, f32)> =
            (0..2000).map(|i| (i, Vec3::new(u(), u(), 0.3 * u()), 0.002 + 0.05 * u() * u())).collect();
        let grid = PhotonGrid::build(&points);
        for _ in 0..5000 {
            let q = Vec3::new(1.2 * u() - 0.1, 1.2 * u() - 0.1, 0.4 * u() - 0.05);
            let mut found: Vec<u32> = Vec::new();
            grid.for_each_within(q, |id| found.push(id));
            let mut expect: Vec<u32> = points
                .iter()
                .filter(|(_, p, r)| p.distance_squared(q) <= r * r)
                .map(|(i, _, _)| *i)
                .collect();
            found.sort_unstable();
            expect.sort_unstable();
            assert_eq!(found, expect);
        }
        assert!(PhotonGrid::build(&[]).is_empty());
        let mut n = 0;
        PhotonGrid::build(&[(0, Vec3::ONE, f32::NAN)]).for_each_within(Vec3::ONE, |_| n += 1);
        assert_eq!(n, 0);
    }
}
