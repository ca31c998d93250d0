//! Distributed runs: the same command on N processes (`mpirun -n N propsim ...`), each doing
//! its [`Share`] of the work, with exact reductions to rank 0, which alone writes outputs.
//!
//! Every reduction is an element-wise integer sum (MPI_SUM on unsigned integers), which is
//! associative and commutative, so the result does not depend on N or on the reduction tree:
//! floats travel as fixed point ([`crate::core::fixed`]) or, when each element comes from
//! exactly one rank (image tiles), as their bit patterns added to zeros.
//!
//! Without the `mpi` feature, or outside `mpirun`, a [`Cluster`] is one process and every
//! reduction is free.

#[cfg(feature = "mpi")]
mod mpi;

use std::cell::Cell;
use std::time::Instant;

use crate::core::Share;

/// Elements per MPI call: MPI counts are 32-bit, so long arrays go in pieces.
const CHUNK: usize = 1 << 24;

/// The transport under a [`Cluster`].
trait Backend {
    fn share(&self) -> Share;
    /// Processes of this job on this machine (for the default thread count).
    fn ranks_on_node(&self) -> usize;
    /// Element-wise sum over all ranks into rank 0's `data` (others' `data` is unchanged).
    fn sum_u64(&self, data: &mut [u64]);
    fn sum_u32(&self, data: &mut [u32]);
    /// Element-wise sum over all ranks into every rank's `data`.
    fn sum_u64_everywhere(&self, data: &mut [u64]);
    /// The largest `value` of any rank, on every rank.
    fn max_u64_everywhere(&self, value: u64) -> u64;
    /// Waits until every rank gets here.
    fn barrier(&self);
}

/// One process: nothing to exchange.
struct Solo;

impl Backend for Solo {
    fn share(&self) -> Share {
        Share::WHOLE
    }
    fn ranks_on_node(&self) -> usize {
        1
    }
    fn sum_u64(&self, _: &mut [u64]) {}
    fn sum_u32(&self, _: &mut [u32]) {}
    fn sum_u64_everywhere(&self, _: &mut [u64]) {}
    fn max_u64_everywhere(&self, value: u64) -> u64 {
        value
    }
    fn barrier(&self) {}
}

/// The processes of one run and the reductions between them, with what they cost (for the
/// scaling figures).
pub struct Cluster {
    backend: Box<dyn Backend>,
    cost: Cell<ReduceCost>,
}

/// What the reductions of a run cost this process.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ReduceCost {
    /// Seconds spent waiting for the other ranks to finish their share (load imbalance).
    pub wait_s: f64,
    /// Seconds spent in the reductions proper, after every rank arrived.
    pub reduce_s: f64,
    /// Bytes this process handed to the reductions.
    pub bytes: u64,
}

impl Cluster {
    /// A single process.
    pub fn solo() -> Self {
        Self::with(Box::new(Solo))
    }

    fn with(backend: Box<dyn Backend>) -> Self {
        Self { backend, cost: Cell::new(ReduceCost::default()) }
    }

    /// The MPI job this process belongs to when built with the `mpi` feature (a job of one
    /// when started without `mpirun`), else a single process.
    pub fn from_environment() -> anyhow::Result<Self> {
        #[cfg(feature = "mpi")]
        {
            Ok(Self::with(Box::new(mpi::MpiBackend::initialize()?)))
        }
        #[cfg(not(feature = "mpi"))]
        {
            Ok(Self::solo())
        }
    }

    /// This process's share of the work.
    pub fn share(&self) -> Share {
        self.backend.share()
    }

    /// Whether this process gathers results, prints and writes outputs.
    pub fn is_root(&self) -> bool {
        self.share().is_root()
    }

    /// Number of processes in the job.
    pub fn size(&self) -> u32 {
        self.share().count
    }

    /// Worker threads per process when none are asked for: the cores this process may use,
    /// divided among the job's processes on the same machine.
    pub fn default_threads(&self) -> usize {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        (cores / self.backend.ranks_on_node().max(1)).max(1)
    }

    /// What the reductions so far cost this process.
    pub fn reduce_cost(&self) -> ReduceCost {
        self.cost.get()
    }

    /// Runs a reduction of `bytes`, timing the wait for the other ranks apart from the
    /// exchange itself.
    fn timed(&self, bytes: usize, f: impl FnOnce()) {
        if self.size() == 1 {
            return;
        }
        let t = Instant::now();
        self.backend.barrier();
        let arrived = Instant::now();
        f();
        let mut c = self.cost.get();
        c.wait_s += (arrived - t).as_secs_f64();
        c.reduce_s += arrived.elapsed().as_secs_f64();
        c.bytes += bytes as u64;
        self.cost.set(c);
    }

    /// The largest `value` of any process, known to every process (for sizes that all must
    /// agree on before a sum, such as a histogram's length).
    pub fn max_u64_everywhere(&self, value: u64) -> u64 {
        if self.size() == 1 {
            return value;
        }
        let mut out = value;
        self.timed(8, || out = self.backend.max_u64_everywhere(value));
        out
    }

    /// Element-wise sum over all processes into the root's `data`.
    pub fn sum_u64(&self, data: &mut [u64]) {
        self.timed(data.len() * 8, || data.chunks_mut(CHUNK).for_each(|c| self.backend.sum_u64(c)));
    }

    /// Element-wise sum over all processes into the root's `data`.
    pub fn sum_u32(&self, data: &mut [u32]) {
        self.timed(data.len() * 4, || data.chunks_mut(CHUNK).for_each(|c| self.backend.sum_u32(c)));
    }

    /// Element-wise exact sum of 128-bit fixed-point values into the root's `data`. Each
    /// value travels as four 32-bit limbs in 64-bit words, so limb sums cannot overflow for
    /// fewer than 2^32 processes; the root propagates the carries.
    pub fn sum_u128(&self, data: &mut [u128]) {
        if self.size() == 1 {
            return;
        }
        let mut limbs = to_limbs(data);
        self.sum_u64(&mut limbs);
        if self.is_root() {
            from_limb_sums(&limbs, data);
        }
    }

    /// Element-wise sum over all processes into every process's `data` (for state that
    /// every rank must hold and update alike, such as SPPM's per-pixel photon statistics).
    pub fn sum_u64_everywhere(&self, data: &mut [u64]) {
        self.timed(data.len() * 8, || {
            data.chunks_mut(CHUNK).for_each(|c| self.backend.sum_u64_everywhere(c))
        });
    }

    /// [`Cluster::sum_u128`] into every process's `data`.
    pub fn sum_u128_everywhere(&self, data: &mut [u128]) {
        if self.size() == 1 {
            return;
        }
        let mut limbs = to_limbs(data);
        self.sum_u64_everywhere(&mut limbs);
        from_limb_sums(&limbs, data);
    }

    /// Gathers floats of which each element was computed by exactly one process (the others
    /// hold +0.0 there) into the root's `data`, bit for bit.
    pub fn gather_disjoint_f32(&self, data: &mut [f32]) {
        if self.size() == 1 {
            return;
        }
        let mut bits: Vec<u32> = data.iter().map(|x| x.to_bits()).collect();
        self.sum_u32(&mut bits);
        if self.is_root() {
            for (x, b) in data.iter_mut().zip(bits) {
                *x = f32::from_bits(b);
            }
        }
    }
}

/// Splits each value into four 32-bit limbs, least significant first, one per 64-bit word.
fn to_limbs(data: &[u128]) -> Vec<u64> {
    data.iter().flat_map(|v| (0..4).map(move |k| ((v >> (32 * k)) & 0xffff_ffff) as u64)).collect()
}

/// Reassembles values from sums of their limbs, propagating the carries (modulo 2^128).
fn from_limb_sums(limbs: &[u64], data: &mut [u128]) {
    for (v, l) in data.iter_mut().zip(limbs.chunks_exact(4)) {
        *v = l.iter().enumerate().fold(0u128, |acc, (k, &x)| acc.wrapping_add(u128::from(x) << (32 * k)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_solo_cluster_is_the_whole_work_and_reductions_keep_the_data() {
        let c = Cluster::solo();
        assert_eq!(c.share(), Share::WHOLE);
        assert!(c.is_root() && c.default_threads() >= 1);
        let mut v = vec![u128::MAX - 3, 5, 1 << 100];
        c.sum_u128(&mut v);
        assert_eq!(v, vec![u128::MAX - 3, 5, 1 << 100]);
        let mut f = vec![1.5f32, -0.0];
        c.gather_disjoint_f32(&mut f);
        assert_eq!(f[0], 1.5);
        assert_eq!(c.reduce_cost(), ReduceCost::default());
    }

    #[test]
    fn limb_sums_of_fixed_point_values_carry_exactly() {
        // Three ranks whose values overflow 32-bit limbs many times over; MPI_SUM adds the
        // limbs element-wise in 64-bit words.
        let ranks: Vec<Vec<u128>> = (0..3u128)
            .map(|r| vec![u128::from(u64::MAX) * (r + 1), (1u128 << 95) + r, 0xffff_ffff * r])
            .collect();
        let mut limb_sums = vec![0u64; 12];
        for v in &ranks {
            for (s, l) in limb_sums.iter_mut().zip(to_limbs(v)) {
                *s += l;
            }
        }
        let mut carried = vec![0u128; 3];
        from_limb_sums(&limb_sums, &mut carried);
        let exact: Vec<u128> = (0..3).map(|i| ranks.iter().map(|v| v[i]).sum()).collect();
        assert_eq!(carried, exact);
    }
}
