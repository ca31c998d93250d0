//! A hashed uniform grid for fixed-radius searches over points (VCM's light vertices): cells
//! twice the radius wide, each point listed once, in its own cell, so a query reads the at
//! most 2 x 2 x 2 cells its ball overlaps. Cells are hashed into about as many buckets as
//! points (the scheme of pbrt-v3 sec. 16.2.5, one listing a point); entries keep their cell's
//! key, so two cells sharing a bucket never report a point twice. Built by a stable counting
//! sort, so a query reports points in one fixed order.

use glam::{IVec3, Vec3};

use super::photon_grid::{Cells, key};

/// The grid.
#[derive(Clone, Debug)]
pub struct PointGrid {
    /// The box, cells and buckets.
    cells: Cells,
    /// The search radius squared, m^2.
    radius2: f32,
    /// The search radius, metres.
    radius: f32,
    /// Start of each bucket's entries in `entries` (one more than the buckets).
    offsets: Vec<u32>,
    /// The entries, grouped by bucket, in the order of their ids within a bucket.
    entries: Vec<Entry>,
}

/// A point in its cell.
#[derive(Clone, Copy, Debug, Default)]
struct Entry {
    key: u64,
    id: u32,
    p: Vec3,
}

impl PointGrid {
    /// A grid over `points` (id, position) for searches of `radius_m`. Points that are not
    /// finite are left out; a radius that is not positive and finite finds nothing.
    pub fn build(points: &[(u32, Vec3)], radius_m: f32) -> Self {
        let mut grid = Self {
            cells: Cells::default(),
            radius2: 0.0,
            radius: 0.0,
            offsets: vec![0; 2],
            entries: Vec::new(),
        };
        if !(radius_m.is_finite() && radius_m > 0.0) {
            return grid;
        }
        let (lo, hi) = points
            .iter()
            .filter(|(_, p)| p.is_finite())
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), (_, p)| (lo.min(*p), hi.max(*p)));
        if !(lo.is_finite() && hi.is_finite()) {
            return grid;
        }
        grid.cells = Cells::new(lo, hi, 2.0 * radius_m);
        grid.radius = radius_m;
        grid.radius2 = radius_m * radius_m;
        let keyed: Vec<Entry> = points
            .iter()
            .filter(|(_, p)| p.is_finite())
            .map(|&(id, p)| Entry { key: key(grid.cells.cell_of_clamped(p)), id, p })
            .collect();
        let buckets = keyed.len().max(1).next_power_of_two();
        grid.cells.mask = buckets as u64 - 1;
        let mut counts = vec![0u32; buckets + 1];
        for e in &keyed {
            counts[grid.cells.bucket(e.key) + 1] += 1;
        }
        for b in 0..buckets {
            counts[b + 1] += counts[b];
        }
        let mut fill = counts[..buckets].to_vec();
        let mut entries = vec![Entry::default(); keyed.len()];
        for e in keyed {
            let slot = &mut fill[grid.cells.bucket(e.key)];
            entries[*slot as usize] = e;
            *slot += 1;
        }
        grid.offsets = counts;
        grid.entries = entries;
        grid
    }

    /// Calls `f` with the id of every point within the radius of `q` (distance <= radius), in
    /// one fixed order.
    #[inline]
    pub fn for_each_within(&self, q: Vec3, mut f: impl FnMut(u32)) {
        if self.entries.is_empty() || !q.is_finite() {
            return;
        }
        let c = &self.cells;
        let a = ((q - self.radius - c.lo) * c.inv_cell).floor().max(Vec3::ZERO);
        let b = ((q + self.radius - c.lo) * c.inv_cell).floor().min((c.res - 1).as_vec3());
        if a.cmpgt(b).any() {
            return;
        }
        let (a, b) = (a.as_ivec3(), b.as_ivec3());
        for z in a.z..=b.z {
            for y in a.y..=b.y {
                for x in a.x..=b.x {
                    let k = key(IVec3::new(x, y, z));
                    let bucket = c.bucket(k);
                    let range = self.offsets[bucket] as usize..self.offsets[bucket + 1] as usize;
                    for e in &self.entries[range] {
                        if e.key == k && e.p.distance_squared(q) <= self.radius2 {
                            f(e.id);
                        }
                    }
                }
            }
        }
    }

    /// Points gridded.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether no point was gridded.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::rng::{stream, uniform};

    /// Every point within the radius of a query is reported exactly once, against brute force,
    /// and in ascending id order within a cell's listing (a fixed order).
    #[test]
    fn finds_every_point_in_range_once() {
        let mut rng = stream(5, 2, 0);
        let mut u = || uniform(&mut rng);
        for radius in [0.003f32, 0.04, 0.3] {
            let points: Vec<(u32, Vec3)> =
                (0..3000).map(|i| (i, Vec3::new(u() - 0.5, u(), 0.3 * u()))).collect();
            let grid = PointGrid::build(&points, radius);
            assert_eq!(grid.len(), points.len());
            let mut hits = 0;
            for _ in 0..4000 {
                let q = Vec3::new(1.2 * u() - 0.6, 1.2 * u() - 0.1, 0.4 * u() - 0.05);
                let mut found: Vec<u32> = Vec::new();
                grid.for_each_within(q, |id| found.push(id));
                let mut expect: Vec<u32> = points
                    .iter()
                    .filter(|(_, p)| p.distance_squared(q) <= radius * radius)
                    .map(|(i, _)| *i)
                    .collect();
                found.sort_unstable();
                expect.sort_unstable();
                hits += expect.len();
                assert_eq!(found, expect, "radius {radius}");
            }
            assert!(hits > 0, "radius {radius}: no query found a point");
        }
        assert!(PointGrid::build(&[], 0.1).is_empty());
        let mut n = 0;
        PointGrid::build(&[(0, Vec3::ONE)], f32::NAN).for_each_within(Vec3::ONE, |_| n += 1);
        PointGrid::build(&[(0, Vec3::NAN)], 0.1).for_each_within(Vec3::ONE, |_| n += 1);
        assert_eq!(n, 0);
    }
}
