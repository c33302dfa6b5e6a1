//! A control-loop-style program that uses only a compiled map
//! (`graphspn_generated::demo_floor`): a robot explores the demo office floor
//! breadth-first from place 0, gets noisy evidence about each place it reaches, and
//! after every step fuses it into the map's streaming `State` (`observe`: only the
//! components containing that place are re-evaluated), reads the marginals of all
//! places from it, prints the accuracy of the best labelling against the ground
//! truth, the most uncertain places and the per-step latency (median and p99 over
//! repeated updates) next to what a full stateless recomputation costs.
//!
//! Everything lives in fixed-size arrays; a counting global allocator asserts that
//! the control loop performs zero heap allocations.
//!
//! Run: `cargo run --release --example firmware`

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Write;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use graphspn_generated::demo_floor::{
    self, CLASS_NAMES, Evidence, Marginals, NUM_CLASSES, NUM_PLACES, PLACE_IDS, State,
};
use graphspn_generated::demo_floor_truth::{EDGES, TRUTH};

struct Counting;
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards every call to the system allocator unchanged; only counts them.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Timed repetitions of the per-step update per step.
const REPS: usize = 101;
/// Timed repetitions of the full recomputation per step (for comparison).
const FULL_REPS: usize = 11;
/// Probability that the place-recognition "sensor" favours the true class.
const SENSOR_ACCURACY: f32 = 0.7;

/// A tiny seeded PRNG (SplitMix64): no allocation, reproducible.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// Breadth-first order of the places from place 0 (unreached places appended).
fn bfs_order() -> [usize; NUM_PLACES] {
    let mut order = [0usize; NUM_PLACES];
    let mut seen = [false; NUM_PLACES];
    let (mut head, mut tail) = (0, 0);
    for start in 0..NUM_PLACES {
        if seen[start] {
            continue;
        }
        seen[start] = true;
        order[tail] = start;
        tail += 1;
        while head < tail {
            let p = order[head];
            head += 1;
            for &(a, b) in EDGES.iter() {
                let q = if usize::from(a) == p {
                    usize::from(b)
                } else if usize::from(b) == p {
                    usize::from(a)
                } else {
                    continue;
                };
                if !seen[q] {
                    seen[q] = true;
                    order[tail] = q;
                    tail += 1;
                }
            }
        }
    }
    order
}

/// Noisy evidence about a place of class `truth`: the sensor favours the true class
/// with probability [`SENSOR_ACCURACY`], otherwise a random wrong one.
fn sense(rng: &mut SplitMix, truth: u16) -> [f32; NUM_CLASSES] {
    let mut row = [0.0f32; NUM_CLASSES];
    for x in row.iter_mut() {
        *x = 0.05 + 0.1 * rng.unit();
    }
    if truth == demo_floor::UNKNOWN {
        return [1.0; NUM_CLASSES];
    }
    let favoured = if rng.unit() < SENSOR_ACCURACY {
        usize::from(truth)
    } else {
        (usize::from(truth) + 1 + rng.below(NUM_CLASSES - 1)) % NUM_CLASSES
    };
    row[favoured] = 0.6 + 0.4 * rng.unit();
    row
}

fn argmax(row: &[f32; NUM_CLASSES]) -> usize {
    let mut best = 0;
    for (k, &v) in row.iter().enumerate() {
        if v > row[best] {
            best = k;
        }
    }
    best
}

fn main() {
    let order = bfs_order();
    let labelled = TRUTH.iter().filter(|&&t| t != demo_floor::UNKNOWN).count();
    let mut out = std::io::stdout().lock();
    let _ = writeln!(
        out,
        "demo floor: {NUM_PLACES} places ({labelled} annotated), {NUM_CLASSES} classes, {} decompositions; exploring breadth-first from place {}",
        demo_floor::NUM_DECOMPOSITIONS,
        PLACE_IDS[0]
    );
    let _ = out.flush();
    let mut rng = SplitMix(2018);
    // Unvisited places carry no information: uniform rows (the state's start).
    let mut state = State::new();
    let mut evidence: Evidence = [[1.0; NUM_CLASSES]; NUM_PLACES];
    let mut marginals: Marginals = [[0.0; NUM_CLASSES]; NUM_PLACES];
    let mut full: Marginals = [[0.0; NUM_CLASSES]; NUM_PLACES];
    let mut lat = [0u32; REPS];
    let mut full_lat = [0u32; FULL_REPS];
    let mut all_p50 = [0u32; NUM_PLACES];
    let mut all_full = [0u32; NUM_PLACES];
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    for (step, &place) in order.iter().enumerate() {
        let truth = TRUTH[place];
        let row = sense(&mut rng, truth);
        // The step: fuse the observation, read all marginals from the cache.
        let mut ll = match state
            .observe(place, &row)
            .and_then(|()| state.marginals(&mut marginals))
        {
            Ok(v) => v,
            Err(e) => {
                let _ = writeln!(out, "step {step}: inference failed: {e}");
                return;
            }
        };
        evidence[place] = state.evidence()[place];
        // Its latency: the same update (re-setting the fused row) and marginals.
        for l in lat.iter_mut() {
            let t = Instant::now();
            let fused = state.evidence()[place];
            ll = match state
                .set_evidence(place, &fused)
                .and_then(|()| state.marginals(&mut marginals))
            {
                Ok(v) => v,
                Err(e) => {
                    let _ = writeln!(out, "step {step}: inference failed: {e}");
                    return;
                }
            };
            *l = t.elapsed().as_nanos() as u32;
        }
        // What a full stateless recomputation of the same marginals costs.
        for l in full_lat.iter_mut() {
            let t = Instant::now();
            let _ = demo_floor::marginals(&evidence, &mut full);
            *l = t.elapsed().as_nanos() as u32;
        }
        full_lat.sort_unstable();
        all_full[step] = full_lat[FULL_REPS / 2];
        lat.sort_unstable();
        let (p50, p99) = (lat[REPS / 2], lat[REPS * 99 / 100]);
        all_p50[step] = p50;
        let (mut right, mut right_visited) = (0usize, 0usize);
        // The three places whose best class is least certain.
        let mut uncertain = [(f32::INFINITY, 0usize); 3];
        for (p, row) in marginals.iter().enumerate() {
            let best = argmax(row);
            if TRUTH[p] != demo_floor::UNKNOWN && best == usize::from(TRUTH[p]) {
                right += 1;
                if order[..=step].contains(&p) {
                    right_visited += 1;
                }
            }
            let conf = row[best];
            if conf < uncertain[2].0 {
                uncertain[2] = (conf, p);
                uncertain.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
            }
        }
        let visited_labelled = order[..=step]
            .iter()
            .filter(|&&p| TRUTH[p] != demo_floor::UNKNOWN)
            .count()
            .max(1);
        let seen = argmax(&evidence[place]);
        let _ = writeln!(
            out,
            "step {:>3} place {:>3} ({:>3} seen as {:>3}) ln S {:>8.2} | accuracy {:>5.1}% all, {:>5.1}% visited | uncertain {:>3} ({:.2}) {:>3} ({:.2}) {:>3} ({:.2}) | step p50 {:>6.1} µs p99 {:>6.1} µs (full pass {:>6.1} µs)",
            step,
            PLACE_IDS[place],
            if truth == demo_floor::UNKNOWN {
                "?"
            } else {
                CLASS_NAMES[usize::from(truth)]
            },
            CLASS_NAMES[seen],
            ll,
            100.0 * right as f64 / labelled.max(1) as f64,
            100.0 * right_visited as f64 / visited_labelled as f64,
            PLACE_IDS[uncertain[0].1],
            uncertain[0].0,
            PLACE_IDS[uncertain[1].1],
            uncertain[1].0,
            PLACE_IDS[uncertain[2].1],
            uncertain[2].0,
            f64::from(p50) / 1e3,
            f64::from(p99) / 1e3,
            f64::from(full_lat[FULL_REPS / 2]) / 1e3,
        );
    }
    let allocations = ALLOCATIONS.load(Ordering::Relaxed) - before;
    all_p50.sort_unstable();
    all_full.sort_unstable();
    let (step_us, full_us) = (
        f64::from(all_p50[NUM_PLACES / 2]) / 1e3,
        f64::from(all_full[NUM_PLACES / 2]) / 1e3,
    );
    let _ = writeln!(
        out,
        "control loop: {NUM_PLACES} steps x {REPS} updates, median step (observe + marginals) {step_us:.1} µs vs {full_us:.1} µs for a full recomputation ({:.0}x), state {} bytes, heap allocations in the loop: {allocations}",
        full_us / step_us.max(1e-3),
        demo_floor::STATE_BYTES
    );
    assert_eq!(allocations, 0, "the control loop allocated");
}
