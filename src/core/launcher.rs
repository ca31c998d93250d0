//! The ray launcher shared by the acoustic and radio simulators: rays leave a point source,
//! bounce through the scene, and a payload-specific [`Propagation`] decides what each segment
//! deposits and what each surface does. Speed-ups here land in both simulators.
//!
//! Determinism: ray `i` draws from its own random stream (`rng::stream(seed, domain, i)`), and
//! rays are processed in fixed blocks of [`LAUNCH_BLOCK`] whose results are merged in block
//! order, so the result is the same for any thread count. Accumulators that must also be
//! independent of how blocks are grouped (e.g. across MPI ranks) should add in fixed point.
//! A ray split into copies ([`Propagation::split`]) hands each copy a stream forked from its
//! own ([`super::rng::fork`]), and its copies are traced in the same block: splitting keeps
//! all of this.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::accel::Accel;
use super::hit::Hit;
use super::ray::Ray;

use super::rng::{Rng64, fork, stream, uniform};
use super::sampling::{fibonacci_sphere, uniform_sphere};
use super::share::Share;

/// Rays per block: the unit of work and of deterministic merging.
pub const LAUNCH_BLOCK: usize = 1024;

/// How launch directions are chosen.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum LaunchPattern {
    /// The spherical Fibonacci lattice, randomly rotated per run: equal solid angle per ray.
    #[default]
    Fibonacci,
    /// Independent uniform directions.
    Random,
    /// Every ray along this unit direction (for tests with hand-computed answers).
    Fixed(Vec3),
}

/// What to do after a surface interaction.
pub enum Bounce {
    /// Continue in this (unit) direction.
    Continue(Vec3),
    /// The ray ends here.
    Stop,
}

/// The payload-specific half of the launcher.
pub trait Propagation: Sync {
    /// What a ray carries (band energies, field, power).
    type Payload: Clone;
    /// What a block of rays deposits (histograms, coverage cells).
    type Accum: Send;

    /// An empty accumulator for a block of rays.
    fn new_accum(&self) -> Self::Accum;
    /// Adds `other` (a later block) into `into`.
    fn merge(&self, into: &mut Self::Accum, other: Self::Accum);
    /// The payload of a fresh ray leaving the source in `dir`.
    fn emit(&self, ray_index: u64, dir: Vec3) -> Self::Payload;
    /// A straight flight from `ray.origin` over `(0, length_m]` (the next hit, or
    /// `ray.t_max` if nothing was hit), after `path_before_m` metres and `reflections`
    /// surface interactions. Detectors along the way record the payload here.
    fn segment(
        &self,
        accum: &mut Self::Accum,
        payload: &Self::Payload,
        ray: &Ray,
        length_m: f32,
        path_before_m: f32,
        reflections: u32,
    );
    /// A surface interaction: update the payload (absorption, reflection coefficient) and
    /// choose the outgoing direction.
    fn interact(
        &self,
        accum: &mut Self::Accum,
        payload: &mut Self::Payload,
        hit: &Hit,
        incoming: Vec3,
        path_m: f32,
        rng: &mut Rng64,
    ) -> Bounce;
    /// For a flight's last segment (no surface interaction follows it): how far along `ray`
    /// its deposits can reach, or `None` (the default) to trace it to its hit like any other.
    /// With `Some(reach)` the launcher asks only whether `(0, reach]` is clear, the cheaper
    /// occlusion query, skipped when `reach <= 0`, and calls [`Propagation::segment`] with
    /// `length_m = reach` when it is clear and 0 when it is not. The radio payload deposits
    /// only where a ray crosses the coverage plane, so its last segment needs no closest hit.
    fn last_segment_reach(&self, _payload: &Self::Payload, _ray: &Ray) -> Option<f32> {
        None
    }
    /// Splitting (Lux and Koblinger 1991; docs/acoustics.md, Ray splitting): called when the
    /// ray meets a surface after `path_m` metres, before [`Propagation::interact`]. A result
    /// k > 1 makes the ray k copies, each of which meets the surface on its own (its own
    /// random stream); the implementation divides what the payload carries by k itself, so
    /// the expected deposits stay the same. The default never splits.
    #[inline(always)]
    fn split(&self, _payload: &mut Self::Payload, _path_m: f32) -> u32 {
        1
    }
    /// A change in mid-flight (the stochastic diffraction of a ray that passes near an
    /// edge): asked once per straight flight along `ray` over `(0, length_m]`, after
    /// `reflections` surface interactions, before its deposits. With `Some(d)` the launcher
    /// deposits `(0, d.at_m]` with the payload as it was; then, with `d.dir = Some(dir)`, the
    /// ray goes on from there in `dir` with `d.payload`, without a surface interaction, and
    /// with `d.dir = None` it keeps its line (and the hit already found) and only its
    /// payload changes. With `d.straight = Some(p)` the ray also parts: the flight keeps its
    /// line with payload `p`, and a copy (its own random stream, forked) carries `d.payload`
    /// in `d.dir` (with `d.dir = None`, `d.payload` must hold both and `straight` is
    /// ignored). The default never deflects.
    #[inline(always)]
    fn deflect(
        &self,
        _payload: &Self::Payload,
        _ray: &Ray,
        _length_m: f32,
        _reflections: u32,
        _rng: &mut Rng64,
    ) -> Option<Deflection<Self::Payload>> {
        None
    }
}

/// A deflection in mid-flight ([`Propagation::deflect`]).
pub struct Deflection<P> {
    /// Where along the ray it happens, metres (in `(0, length)`).
    pub at_m: f32,
    /// The new unit direction (`None`: the same line).
    pub dir: Option<Vec3>,
    /// The payload after it.
    pub payload: P,
    /// A part that goes on along the old line, unchanged in direction (`None`: none).
    pub straight: Option<P>,
}

/// Launch settings.
#[derive(Clone, Copy, Debug)]
pub struct Launch {
    /// Where the rays start.
    pub origin: Vec3,
    /// Number of rays.
    pub rays: u64,
    /// Seed of the random number generator.
    pub seed: u64,
    /// Separates this launch's random streams from other launches with the same seed (e.g.
    /// one per source).
    pub domain: u64,
    /// How launch directions are chosen.
    pub pattern: LaunchPattern,
    /// Surface interactions after which a ray stops.
    pub max_reflections: u32,
    /// Path length after which a ray stops, metres.
    pub max_path_m: f32,
}

/// The random rotation about z of a launch's Fibonacci lattice, shared by all its rays.
fn lattice_rotation(launch: &Launch) -> f32 {
    uniform(&mut stream(launch.seed, launch.domain, u64::MAX))
}

/// A ray in flight: where it goes next, what it carries, how far it has come.
#[derive(Clone)]
struct Flight<P> {
    ray: Ray,
    payload: P,
    path_m: f32,
    reflections: u32,
    rng: Rng64,
}

/// Ray `index`'s flight as it leaves the source.
#[inline(always)]
fn depart<P: Propagation>(prop: &P, launch: &Launch, rotation: f32, index: u64) -> Flight<P::Payload> {
    let mut rng = stream(launch.seed, launch.domain, index);
    let dir = match launch.pattern {
        LaunchPattern::Fibonacci => fibonacci_sphere(index as usize, launch.rays as usize, rotation),
        LaunchPattern::Random => uniform_sphere(Vec2::new(uniform(&mut rng), uniform(&mut rng))),
        LaunchPattern::Fixed(d) => d,
    };
    let payload = prop.emit(index, dir);
    Flight { ray: Ray::new(launch.origin, dir), payload, path_m: 0.0, reflections: 0, rng }
}

/// [`trace_block`] compiled for the best instruction set the traversal uses: the payload's
/// band arithmetic (eight bands a ray) then runs as AVX vectors. Rust never contracts
/// `a * b + c` into a fused multiply-add by itself, so both versions give the same bits.
fn trace_block_best<P: Propagation>(
    accel: &Accel,
    prop: &P,
    launch: &Launch,
    rotation: f32,
    range: (u64, u64),
    accum: &mut P::Accum,
) {
    #[cfg(target_arch = "x86_64")]
    if accel.mesh.traverser().isa() >= super::traverse::Isa::Avx2 {
        // SAFETY: the traversal chose AVX2 only after `is_x86_feature_detected!` found AVX2
        // and FMA on this CPU (`Isa::best`), which the entry point's `target_feature` names.
        unsafe { trace_block_avx2(accel, prop, launch, rotation, range, accum) };
        return;
    }
    trace_block(accel, prop, launch, rotation, range, accum);
}

/// [`trace_block`] with AVX, AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,fma,sse4.1,popcnt")]
fn trace_block_avx2<P: Propagation>(
    accel: &Accel,
    prop: &P,
    launch: &Launch,
    rotation: f32,
    range: (u64, u64),
    accum: &mut P::Accum,
) {
    trace_block(accel, prop, launch, rotation, range, accum);
}

/// Traces rays `first..last` of a launch to their ends. On trees large enough for streams
/// ([`super::traverse::Traverser::streams`]), every ray still in flight is traced through one
/// batch query per bounce ([`Accel::closest_hits_into`], the code that `propsim bench trace`
/// measures); then each deposits its segment and meets its surface in ray order. Smaller
/// scenes stay in the cache, where the batch query is the single-ray query in a loop: there
/// each ray is traced to its end on its own ([`Accel::closest_hit`], the same query), which
/// keeps the ray in registers instead of cycling a block's flights through memory (measured
/// on the shoebox of `benches/peers`, see docs/performance.md). Either way the order of
/// deposits depends only on the block and the scene, never on threads.
#[inline(always)]
fn trace_block<P: Propagation>(
    accel: &Accel,
    prop: &P,
    launch: &Launch,
    rotation: f32,
    (first, last): (u64, u64),
    accum: &mut P::Accum,
) {
    // Copies made by splitting: traced after the flight that made them (last made, first).
    let mut copies: Vec<Flight<P::Payload>> = Vec::new();
    if !accel.mesh.traverser().streams() {
        for i in first..last {
            // The launched flight stays on the stack; copies wait in `copies`.
            let mut launched = Some(depart(prop, launch, rotation, i));
            while let Some(mut flight) = launched.take().or_else(|| copies.pop()) {
                loop {
                    let ray = Ray { t_max: (launch.max_path_m - flight.path_m).max(0.0), ..flight.ray };
                    match last_segment(accel, prop, launch, accum, &mut flight, &ray, &mut copies) {
                        Last::Done => break,
                        Last::Deflected => continue,
                        Last::Trace => {}
                    }
                    let hit = accel.closest_hit(&ray);
                    if !step(prop, launch, accum, &mut flight, &ray, hit.as_ref(), &mut copies) {
                        break;
                    }
                }
            }
        }
        return;
    }
    let mut flights: Vec<Flight<P::Payload>> =
        (first..last).map(|i| depart(prop, launch, rotation, i)).collect();
    let mut rays: Vec<Ray> = Vec::with_capacity(flights.len());
    let mut hits: Vec<Option<Hit>> = Vec::with_capacity(flights.len());
    while !flights.is_empty() {
        // Last segments (see `last_segment`) end here, without the batch query.
        // (A deflected flight stays: its new ray is traced below.)
        flights.retain_mut(|f| {
            let ray = Ray { t_max: (launch.max_path_m - f.path_m).max(0.0), ..f.ray };
            last_segment(accel, prop, launch, accum, f, &ray, &mut copies) != Last::Done
        });
        rays.clear();
        rays.extend(flights.iter().map(|f| Ray { t_max: (launch.max_path_m - f.path_m).max(0.0), ..f.ray }));
        // Every entry is overwritten by the query: only new ones need a value.
        hits.resize(rays.len(), None);
        accel.closest_hits_into(&rays, &mut hits);
        // Flights that go on are kept in order at the front (a stable compaction in place).
        let mut kept = 0;
        for (i, (ray, hit)) in rays.iter().zip(&hits).enumerate() {
            if step(prop, launch, accum, &mut flights[i], ray, hit.as_ref(), &mut copies) {
                if kept != i {
                    flights.swap(kept, i);
                }
                kept += 1;
            }
        }
        flights.truncate(kept);
        flights.append(&mut copies);
    }
}

/// What [`last_segment`] did with a flight.
#[derive(PartialEq)]
enum Last {
    /// The flight's last segment was deposited: it is over.
    Done,
    /// It was deflected in mid-flight and goes on (its next ray is new).
    Deflected,
    /// It must be traced as usual.
    Trace,
}

/// `f`'s segment along `ray` when it is its last, without a closest-hit query where none is
/// needed: a ray that leaves the scene's box meets nothing, and on a segment after which no
/// interaction may follow, a propagation that knows how far its deposits reach
/// ([`Propagation::last_segment_reach`]) needs only an occlusion query. A ray leaving the
/// box may still be deflected on its way out ([`Propagation::deflect`]).
#[inline(always)]
fn last_segment<P: Propagation>(
    accel: &Accel,
    prop: &P,
    launch: &Launch,
    accum: &mut P::Accum,
    f: &mut Flight<P::Payload>,
    ray: &Ray,
    copies: &mut Vec<Flight<P::Payload>>,
) -> Last {
    let leaving = accel.leaves_bounds(ray);
    if !leaving && f.reflections < launch.max_reflections {
        return Last::Trace;
    }
    if leaving {
        match deflect(prop, accum, f, ray, ray.t_max, copies) {
            Bend::Turned => return Last::Deflected,
            Bend::Reweighted => return Last::Done,
            Bend::Straight => {}
        }
    }
    match prop.last_segment_reach(&f.payload, ray) {
        Some(reach) => {
            let reach = reach.min(ray.t_max);
            let clear = reach > 0.0 && (leaving || !accel.occluded(&Ray { t_max: reach, ..*ray }));
            prop.segment(accum, &f.payload, ray, if clear { reach } else { 0.0 }, f.path_m, f.reflections);
        }
        None if leaving => prop.segment(accum, &f.payload, ray, ray.t_max, f.path_m, f.reflections),
        None => return Last::Trace,
    }
    Last::Done
}

/// What [`deflect`] did.
#[derive(PartialEq)]
enum Bend {
    /// Nothing: the flight's segment is still to be deposited.
    Straight,
    /// The flight was cut and turned: it goes on from the turning point.
    Turned,
    /// Only the payload changed in mid-flight: the whole segment was deposited, and the
    /// flight goes on to the same hit.
    Reweighted,
}

/// Asks whether `f`, flying along `ray` for `length_m`, is deflected on the way
/// ([`Propagation::deflect`]); if so deposits the part before, and turns the flight or
/// deposits the rest with the new payload.
#[inline(always)]
fn deflect<P: Propagation>(
    prop: &P,
    accum: &mut P::Accum,
    f: &mut Flight<P::Payload>,
    ray: &Ray,
    length_m: f32,
    copies: &mut Vec<Flight<P::Payload>>,
) -> Bend {
    let Some(d) = prop.deflect(&f.payload, ray, length_m, f.reflections, &mut f.rng) else {
        return Bend::Straight;
    };
    prop.segment(accum, &f.payload, ray, d.at_m, f.path_m, f.reflections);
    match (d.dir, d.straight) {
        (Some(dir), Some(straight)) => {
            let rng = fork(&mut f.rng);
            let turned = Ray::new(ray.at(d.at_m), dir);
            copies.push(Flight { ray: turned, payload: d.payload, path_m: f.path_m + d.at_m, rng, ..*f });
            f.payload = straight;
            let rest = Ray { origin: ray.at(d.at_m), t_max: ray.t_max - d.at_m, ..*ray };
            prop.segment(accum, &f.payload, &rest, length_m - d.at_m, f.path_m + d.at_m, f.reflections);
            Bend::Reweighted
        }
        (Some(dir), None) => {
            f.payload = d.payload;
            f.path_m += d.at_m;
            f.ray = Ray::new(ray.at(d.at_m), dir);
            Bend::Turned
        }
        (None, _) => {
            f.payload = d.payload;
            let rest = Ray { origin: ray.at(d.at_m), t_max: ray.t_max - d.at_m, ..*ray };
            prop.segment(accum, &f.payload, &rest, length_m - d.at_m, f.path_m + d.at_m, f.reflections);
            Bend::Reweighted
        }
    }
}

/// One bounce of `flight` along `ray`, which met `hit` (or nothing): the segment's deposits,
/// then the surface. True if the flight goes on; copies split off at the surface that go on
/// are pushed to `copies`.
#[inline(always)]
fn step<P: Propagation>(
    prop: &P,
    launch: &Launch,
    accum: &mut P::Accum,
    f: &mut Flight<P::Payload>,
    ray: &Ray,
    hit: Option<&Hit>,
    copies: &mut Vec<Flight<P::Payload>>,
) -> bool {
    let length = hit.map_or(ray.t_max, |h| h.t);
    match deflect(prop, accum, f, ray, length, copies) {
        Bend::Turned => return true,
        Bend::Reweighted => {}
        Bend::Straight => prop.segment(accum, &f.payload, ray, length, f.path_m, f.reflections),
    }
    let Some(hit) = hit else { return false };
    f.path_m += hit.t;
    if f.reflections >= launch.max_reflections {
        return false;
    }
    for _ in 1..prop.split(&mut f.payload, f.path_m) {
        let mut copy = Flight { rng: fork(&mut f.rng), ..f.clone() };
        if bounce(prop, accum, &mut copy, ray, hit) {
            copies.push(copy);
        }
    }
    bounce(prop, accum, f, ray, hit)
}

/// `f`, which came along `ray`, meets the surface at `hit`. True if it goes on.
#[inline(always)]
fn bounce<P: Propagation>(
    prop: &P,
    accum: &mut P::Accum,
    f: &mut Flight<P::Payload>,
    ray: &Ray,
    hit: &Hit,
) -> bool {
    match prop.interact(accum, &mut f.payload, hit, ray.dir, f.path_m, &mut f.rng) {
        Bounce::Continue(d) => {
            f.ray = Ray::spawn(hit.point, hit.normal, d);
            f.reflections += 1;
            true
        }
        Bounce::Stop => false,
    }
}

/// Launches `launch.rays` rays in parallel and returns the merged accumulator; `progress` is
/// called with the number of rays finished after each block.
pub fn launch<P: Propagation>(
    accel: &Accel,
    prop: &P,
    launch: &Launch,
    progress: &(dyn Fn(u64) + Sync),
) -> P::Accum {
    launch_share(accel, prop, launch, Share::WHOLE, progress)
}

/// Like [`launch`] for `share`'s blocks only (one MPI rank's part: blocks are dealt
/// round-robin), merged in block order. The accumulators of all shares together hold the
/// same deposits as one whole launch; they add up to it exactly if the accumulator sums in
/// fixed point.
pub fn launch_share<P: Propagation>(
    accel: &Accel,
    prop: &P,
    launch: &Launch,
    share: Share,
    progress: &(dyn Fn(u64) + Sync),
) -> P::Accum {
    // Each worker thread takes the next block in order and hands its accumulator to the
    // merge queue, which adds blocks in block order as soon as they are ready: no thread waits
    // for a group's last block, and whoever completes the next block in order merges.
    let offset = lattice_rotation(launch);
    let blocks: Vec<u64> = share.units(launch.rays.div_ceil(RAYS_PER_BLOCK)).collect();
    let next_block = AtomicUsize::new(0);
    let queue = Mutex::new(MergeQueue { pending: BTreeMap::new(), next: 0, merging: false });
    let total = Mutex::new(prop.new_accum());
    let workers = rayon::current_num_threads().clamp(1, blocks.len().max(1));
    (0..workers).into_par_iter().for_each(|_| {
        loop {
            let k = next_block.fetch_add(1, Ordering::Relaxed);
            let Some(&b) = blocks.get(k) else { break };
            let mut acc = prop.new_accum();
            let first = b * RAYS_PER_BLOCK;
            let last = (first + RAYS_PER_BLOCK).min(launch.rays);
            trace_block_best(accel, prop, launch, offset, (first, last), &mut acc);
            progress(last - first);
            merge_in_order(prop, &queue, &total, k, acc);
        }
    });
    total.into_inner().unwrap_or_else(PoisonError::into_inner)
}

/// [`LAUNCH_BLOCK`] as the ray-index type.
const RAYS_PER_BLOCK: u64 = LAUNCH_BLOCK as u64;

/// Finished blocks' accumulators waiting for their turn to be merged.
struct MergeQueue<A> {
    /// By position in the share's block list.
    pending: BTreeMap<usize, A>,
    /// The position merged next.
    next: usize,
    /// A thread is merging: the others only leave their blocks here.
    merging: bool,
}

/// Leaves block `k`'s accumulator in `queue`; unless another thread is merging, merges every
/// block that is next in order into `total` (outside the queue's lock), until none is ready.
/// One merger at a time, taking runs in order, so blocks are merged in block order.
fn merge_in_order<P: Propagation>(
    prop: &P,
    queue: &Mutex<MergeQueue<P::Accum>>,
    total: &Mutex<P::Accum>,
    k: usize,
    acc: P::Accum,
) {
    let lock = || queue.lock().unwrap_or_else(PoisonError::into_inner);
    let mut guard = lock();
    guard.pending.insert(k, acc);
    if guard.merging {
        return;
    }
    guard.merging = true;
    loop {
        let q = &mut *guard;
        let mut ready = Vec::new();
        while let Some(a) = q.pending.remove(&q.next) {
            ready.push(a);
            q.next += 1;
        }
        if ready.is_empty() {
            q.merging = false;
            return;
        }
        drop(guard);
        let mut t = total.lock().unwrap_or_else(PoisonError::into_inner);
        for a in ready {
            prop.merge(&mut t, a);
        }
        drop(t);
        guard = lock();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::{BuildQuality, TriangleMesh};

    /// Counts segments and total path length; reflects specularly without loss.
    struct Counter;

    impl Propagation for Counter {
        type Payload = ();
        type Accum = (u64, f64, u64);
        fn new_accum(&self) -> Self::Accum {
            (0, 0.0, 0)
        }
        fn merge(&self, into: &mut Self::Accum, o: Self::Accum) {
            into.0 += o.0;
            into.1 += o.1;
            into.2 += o.2;
        }
        fn emit(&self, _: u64, _: Vec3) {}
        fn segment(&self, a: &mut Self::Accum, _: &(), _: &Ray, len: f32, _: f32, _: u32) {
            a.0 += 1;
            a.1 += f64::from(len);
        }
        fn interact(
            &self,
            a: &mut Self::Accum,
            _: &mut (),
            hit: &Hit,
            d: Vec3,
            _: f32,
            _: &mut Rng64,
        ) -> Bounce {
            a.2 += 1;
            Bounce::Continue(d - 2.0 * d.dot(hit.normal) * hit.normal)
        }
    }

    /// Like [`Counter`], with a weight per ray: every ray splits into three copies of a
    /// third of its weight at its first surface, and each reflection draws from its stream.
    struct Splitter;

    impl Propagation for Splitter {
        /// (weight, split already)
        type Payload = (f64, bool);
        /// (segments, weighted length, draws summed)
        type Accum = (u64, f64, f64);
        fn new_accum(&self) -> Self::Accum {
            (0, 0.0, 0.0)
        }
        fn merge(&self, into: &mut Self::Accum, o: Self::Accum) {
            into.0 += o.0;
            into.1 += o.1;
            into.2 += o.2;
        }
        fn emit(&self, _: u64, _: Vec3) -> (f64, bool) {
            (1.0, false)
        }
        fn segment(&self, a: &mut Self::Accum, p: &(f64, bool), _: &Ray, len: f32, _: f32, _: u32) {
            a.0 += 1;
            a.1 += p.0 * f64::from(len);
        }
        fn interact(
            &self,
            a: &mut Self::Accum,
            _: &mut (f64, bool),
            hit: &Hit,
            d: Vec3,
            _: f32,
            rng: &mut Rng64,
        ) -> Bounce {
            a.2 += f64::from(uniform(rng));
            Bounce::Continue(d - 2.0 * d.dot(hit.normal) * hit.normal)
        }
        fn split(&self, p: &mut (f64, bool), _: f32) -> u32 {
            if p.1 {
                return 1;
            }
            *p = (p.0 / 3.0, true);
            3
        }
    }

    #[test]
    fn split_copies_share_the_weight_and_the_result_is_the_same_for_any_thread_count() {
        let mut mesh = TriangleMesh::default();
        let s = mesh.surface_id("wall");
        mesh.push_box(Vec3::ZERO, Vec3::new(10.0, 8.0, 3.0), 1, s);
        let accel = Accel::build(&mesh, Vec::new(), BuildQuality::default());
        let launch = Launch {
            origin: Vec3::new(2.0, 3.0, 1.5),
            rays: 3000,
            seed: 7,
            domain: 0,
            pattern: LaunchPattern::Fibonacci,
            max_reflections: 10_000,
            max_path_m: 50.0,
        };
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| super::launch(&accel, &Splitter, &launch, &|_| {}))
        };
        let (segments, weighted, draws) = run(1);
        // The copies together travel what the ray would have: weight x length = rays x path.
        assert!((weighted - 3000.0 * 50.0).abs() < 1e-6 * 3000.0 * 50.0, "{weighted}");
        // Three flights after the first hit: about three times the segments of one.
        let (plain, _, _) = super::launch(&accel, &Counter, &launch, &|_| {});
        assert!(segments > 2 * plain && segments < 3 * plain, "{segments} vs {plain}");
        // One uniform draw per reflection (every segment but the launches ends in one).
        assert!((draws / (segments - 3000) as f64 - 0.5).abs() < 0.01);
        assert_eq!(run(2), (segments, weighted, draws));
        let mut parts = (0, 0.0, 0.0);
        for rank in 0..3 {
            Splitter.merge(
                &mut parts,
                launch_share(&accel, &Splitter, &launch, Share::new(rank, 3).unwrap(), &|_| {}),
            );
        }
        assert_eq!(parts.0, segments);
        assert!((parts.1 - weighted).abs() < 1e-9 * weighted);
    }

    #[test]
    fn every_ray_travels_the_full_path_in_a_closed_room_for_any_thread_count() {
        let mut mesh = TriangleMesh::default();
        let s = mesh.surface_id("wall");
        mesh.push_box(Vec3::ZERO, Vec3::new(10.0, 8.0, 3.0), 1, s);
        let accel = Accel::build(&mesh, Vec::new(), BuildQuality::default());
        let launch = Launch {
            origin: Vec3::new(2.0, 3.0, 1.5),
            rays: 5000,
            seed: 7,
            domain: 0,
            pattern: LaunchPattern::Fibonacci,
            max_reflections: 10_000,
            max_path_m: 100.0,
        };
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| super::launch(&accel, &Counter, &launch, &|_| {}))
        };
        let (segments, length, hits) = run(1);
        // No ray escapes and none stops early: total length = rays x max path.
        assert!((length - 5000.0 * 100.0).abs() < 1e-3 * 5000.0 * 100.0, "{length}");
        assert_eq!(segments, hits + 5000);
        // Mean free path of a box, 4V/S = 4 * 240 / 268 = 3.58 m: about 100 / 3.58 hits per ray.
        let mean_free_path = 5000.0 * 100.0 / hits as f64;
        assert!((mean_free_path - 4.0 * 240.0 / 268.0).abs() < 0.1, "{mean_free_path}");
        assert_eq!(run(2), (segments, length, hits));
        // Three shares hold every ray once: their counts add up to the whole launch's.
        let mut parts = (0, 0.0, 0);
        for rank in 0..3 {
            let share = Share::new(rank, 3).unwrap();
            let p = launch_share(&accel, &Counter, &launch, share, &|_| {});
            assert!(p.0 > 0, "share {rank} traced nothing");
            Counter.merge(&mut parts, p);
        }
        assert_eq!((parts.0, parts.2), (segments, hits));
        assert!((parts.1 - length).abs() < 1e-9 * length);
    }
}
