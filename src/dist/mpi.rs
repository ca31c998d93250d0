//! The MPI transport (rsmpi): `MPI_Reduce` with `MPI_SUM` to rank 0 on the world communicator,
//! and `MPI_Allreduce` with `MPI_MAX` for the sizes every rank must agree on and with `MPI_SUM`
//! for state every rank updates alike.

use mpi::Threading;
use mpi::collective::SystemOperation;
use mpi::environment::Universe;
use mpi::topology::SimpleCommunicator;
use mpi::traits::{Communicator, CommunicatorCollectives, Equivalence, Root};

use super::Backend;
use crate::core::Share;

pub(super) struct MpiBackend {
    world: SimpleCommunicator,
    share: Share,
    ranks_on_node: usize,
    // Dropped last: finalises MPI when the run ends.
    _universe: Universe,
}

impl MpiBackend {
    pub(super) fn initialize() -> anyhow::Result<Self> {
        // Only the main thread calls MPI; rayon's workers never do.
        let (universe, _) = mpi::initialize_with_threading(Threading::Funneled)
            .ok_or_else(|| anyhow::anyhow!("MPI was already initialised"))?;
        let world = universe.world();
        let share = Share::new(world.rank() as u32, world.size() as u32)
            .ok_or_else(|| anyhow::anyhow!("MPI reported an invalid rank"))?;
        let ranks_on_node = world.split_shared(world.rank()).size().max(1) as usize;
        Ok(Self { world, share, ranks_on_node, _universe: universe })
    }

    fn sum<T: Equivalence + Copy>(&self, data: &mut [T]) {
        let root = self.world.process_at_rank(0);
        if self.share.is_root() {
            let send = data.to_vec();
            root.reduce_into_root(&send[..], data, SystemOperation::sum());
        } else {
            root.reduce_into(&data[..], SystemOperation::sum());
        }
    }
}

impl Backend for MpiBackend {
    fn share(&self) -> Share {
        self.share
    }
    fn ranks_on_node(&self) -> usize {
        self.ranks_on_node
    }
    fn sum_u64(&self, data: &mut [u64]) {
        self.sum(data);
    }
    fn sum_u32(&self, data: &mut [u32]) {
        self.sum(data);
    }
    fn sum_u64_everywhere(&self, data: &mut [u64]) {
        let send = data.to_vec();
        self.world.all_reduce_into(&send[..], data, SystemOperation::sum());
    }
    fn max_u64_everywhere(&self, value: u64) -> u64 {
        let mut out = 0u64;
        self.world.all_reduce_into(&value, &mut out, SystemOperation::max());
        out
    }
    fn barrier(&self) {
        self.world.barrier();
    }
}
