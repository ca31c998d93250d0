//! A share of the work: which of `count` equal participants (MPI ranks) this process is, and
//! which units of work (ray blocks, image tiles) it owns.
//!
//! Units are dealt round-robin (unit `i` belongs to participant `i mod count`), so neighbouring
//! units, which cost about the same (rays of one latitude band of the launch lattice, tiles of
//! one image row), are spread over every participant: the load balances without a scheduler.

/// This process's part of the work.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Share {
    /// Index of this participant, `0..count`; 0 is the root that gathers and writes.
    pub rank: u32,
    /// Number of participants, at least 1.
    pub count: u32,
}

impl Share {
    /// All the work, in one process.
    pub const WHOLE: Share = Share { rank: 0, count: 1 };

    /// Participant `rank` of `count`; `None` unless `rank < count`.
    pub fn new(rank: u32, count: u32) -> Option<Share> {
        (rank < count).then_some(Share { rank, count })
    }

    /// Whether this participant gathers the results and writes the outputs.
    pub fn is_root(self) -> bool {
        self.rank == 0
    }

    /// Whether unit `index` of the work is this participant's.
    pub fn owns(self, index: u64) -> bool {
        index % u64::from(self.count) == u64::from(self.rank)
    }

    /// The units of `0..units` that are this participant's, in increasing order.
    pub fn units(self, units: u64) -> impl Iterator<Item = u64> {
        (u64::from(self.rank)..units).step_by(self.count as usize)
    }
}

impl Default for Share {
    fn default() -> Self {
        Share::WHOLE
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_unit_has_exactly_one_owner_for_any_count() {
        for count in 1..=7u32 {
            for units in [0u64, 1, 5, 64, 1001] {
                let mut seen = vec![0u32; units as usize];
                for rank in 0..count {
                    let share = Share::new(rank, count).unwrap();
                    for u in share.units(units) {
                        assert!(share.owns(u));
                        seen[u as usize] += 1;
                    }
                }
                assert!(seen.iter().all(|&n| n == 1), "count {count}, units {units}");
            }
        }
        assert_eq!(Share::new(3, 3), None);
        assert!(Share::WHOLE.is_root() && !Share::new(1, 2).unwrap().is_root());
    }

    #[test]
    fn round_robin_shares_differ_by_at_most_one_unit() {
        let sizes: Vec<usize> = (0..3).map(|r| Share::new(r, 3).unwrap().units(100).count()).collect();
        assert_eq!(sizes, vec![34, 33, 33]);
    }
}
